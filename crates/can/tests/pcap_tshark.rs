//! A pcap capture written by `PcapCapture` is decoded by tshark (an independent
//! decoder) as CANopen, with the services named. Fails when tshark is missing.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_can::decorate::PcapCapture;
use motus_can::{CanBus, CanFrame, MemoryHub};
use std::process::Command;
use std::time::Duration;

#[test]
fn tshark_names_the_canopen_services() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("capture.pcap");
    let hub = MemoryHub::new();
    let master = PcapCapture::create(hub.connect(), &path).unwrap();
    let drive = hub.connect();
    // Frames by hand from CiA 301: NMT start node 5; SYNC; SDO upload request 0x1000:00
    // to node 5 and its expedited response (0x00020192); TPDO1 of node 5; heartbeat
    // of node 5 (0x05 = operational); an extended-id frame to check the EFF flag.
    let sent = [
        CanFrame::new(0x000, &[0x01, 0x05]).unwrap(),
        CanFrame::new(0x080, &[]).unwrap(),
        CanFrame::new(0x605, &[0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]).unwrap(),
    ];
    let received = [
        CanFrame::new(0x585, &[0x43, 0x00, 0x10, 0x00, 0x92, 0x01, 0x02, 0x00]).unwrap(),
        CanFrame::new(0x185, &[0x37, 0x06, 0x00, 0x00]).unwrap(),
        CanFrame::new(0x705, &[0x05]).unwrap(),
        CanFrame::with_format(0x1ABC_DEF0, true, &[0xAA]).unwrap(),
    ];
    for f in &sent {
        master.send(f).unwrap();
    }
    for f in &received {
        drive.send(f).unwrap();
        assert_eq!(&master.recv(Duration::from_secs(1)).unwrap().unwrap().frame, f);
    }
    drop(master);

    let out = Command::new("tshark")
        .arg("-r")
        .arg(&path)
        .args(["-d", "can.subdissector,canopen", "-T", "fields", "-E", "separator=;"])
        .args(["-e", "can.id", "-e", "can.len", "-e", "canopen.function_code", "-e", "canopen.node_id"])
        .args(["-e", "canopen.sdo.main_idx", "-e", "_ws.col.Info", "-e", "can.flags.xtd"])
        .output()
        .expect("tshark must be installed");
    assert!(out.status.success(), "tshark failed: {}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8(out.stdout).unwrap();
    let lines: Vec<Vec<&str>> = text.lines().map(|l| l.split(';').collect()).collect();
    assert_eq!(lines.len(), 7, "{text}");
    // can.id (decimal), can.len, function code, node id, SDO index, info column, EFF flag.
    let ids: Vec<&str> = lines.iter().map(|l| l[0]).collect();
    let want_ids: Vec<String> =
        [0x000, 0x080, 0x605, 0x585, 0x185, 0x705, 0x1ABC_DEF0].iter().map(|i: &u32| i.to_string()).collect();
    assert_eq!(ids, want_ids, "{text}");
    let lens: Vec<&str> = lines.iter().map(|l| l[1]).collect();
    assert_eq!(lens, ["2", "0", "8", "8", "4", "1", "1"], "{text}");
    // Wireshark's CANopen function codes: NMT 0, SYNC 1, PDO1 tx 3, SDO tx 0xb,
    // SDO rx 0xc, NMT error control 0xe.
    let codes: Vec<&str> = lines.iter().take(6).map(|l| l[2]).collect();
    assert_eq!(
        codes,
        ["0x00000000", "0x00000001", "0x0000000c", "0x0000000b", "0x00000003", "0x0000000e"],
        "{text}"
    );
    let xtd: Vec<&str> = lines.iter().map(|l| l[6]).collect();
    assert!(xtd[..6].iter().all(|x| *x == "0" || *x == "False"), "{text}");
    assert!(xtd[6] == "1" || xtd[6] == "True", "{text}");
    let info: Vec<String> = lines.iter().map(|l| l[5].to_uppercase()).collect();
    assert!(info[0].contains("NMT"), "{text}");
    assert!(info[1].contains("SYNC"), "{text}");
    assert!(info[2].contains("SDO"), "{text}");
    assert!(info[3].contains("SDO"), "{text}");
    assert!(info[4].contains("PDO"), "{text}");
    assert!(info[5].contains("NMT ERROR CONTROL") || info[5].contains("HEARTBEAT"), "{text}");
    assert_eq!(lines[2][4], "0x1000", "SDO index decoded: {text}");
    assert_eq!(lines[4][3], "0x00000005", "node id of the TPDO: {text}");
}
