//! `motus decode canopen` / `motus encode canopen` and the CANopen commands, through the binary.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use common::MOTUS;
use std::process::{Command, Output};

fn motus(args: &[&str]) -> Output {
    Command::new(MOTUS).args(args).output().unwrap()
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).trim().to_string()
}

#[test]
fn decode_names_service_node_and_content_and_encode_inverts_it() {
    // 0x5C3 = 0x580 + 67: SDO response of node 67. 43 = expedited upload, 4 bytes;
    // 64 60 00 = 0x6064 sub 0; E8 03 00 00 = 1000 little-endian.
    let o = motus(&["decode", "canopen", "5C3#43646000E8030000"]);
    assert!(o.status.success());
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(v["text"], "SDO upload response 0x6064:00 = 1000 (node 67)");
    // The seed's synchronous RPDO2 to node 2: controlword 0x005F, target 0x0855 = 2133.
    let o = motus(&["decode", "canopen", "302#5F00550800000"]);
    assert!(!o.status.success(), "odd number of hex digits must be refused");
    let cases = [
        ("000#0102", "NMT start (node 2)"),
        ("080#", "SYNC"),
        ("702#05", "heartbeat operational (node 2)"),
        ("302#5F0055080000", "RPDO2 [5F 00 55 08 00 00] (node 2)"),
    ];
    for (frame, text) in cases {
        let o = motus(&["decode", "canopen", frame]);
        assert!(o.status.success(), "{frame}: {}", String::from_utf8_lossy(&o.stderr));
        let json = stdout(&o);
        let v: serde_json::Value = serde_json::from_str(&json).unwrap();
        assert_eq!(v["text"], text, "{frame}");
        let back = motus(&["encode", "canopen", &json]);
        assert!(back.status.success());
        assert_eq!(stdout(&back), frame);
    }
    let o = motus(&["decode", "canopen", "zz#00"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("invalid CAN frame"));
}

/// A free loopback port (bound then released).
fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port()
}

#[test]
fn hub_simulated_drives_master_commands_and_the_robot_through_the_binary() {
    let dir = tempfile::tempdir().unwrap();
    let port = free_port();
    let listen = format!("127.0.0.1:{port}");
    let bus = format!("socketcand://127.0.0.1:{port}/can0");
    let pcap = dir.path().join("bus.pcap");
    let candump = dir.path().join("bus.log");
    let hub = common::SimProcess::start(
        &[
            "canbus",
            "serve",
            "--listen",
            &listen,
            "--pcap",
            pcap.to_str().unwrap(),
            "--candump",
            candump.to_str().unwrap(),
        ],
        "ready",
    );
    let _drives = common::SimProcess::start(&["sim", "icla", "--bus", &bus, "--nodes", "2,3,4"], "ready");
    std::thread::sleep(std::time::Duration::from_millis(300));

    // scan lists the three nodes with their identity (the simulators may still be joining
    // the hub on a loaded machine: scan again for up to 10 s).
    let mut tries = 0;
    let (o, out) = loop {
        let o = motus(&["canopen", "--bus", &bus, "scan", "--to", "10"]);
        let out = stdout(&o);
        tries += 1;
        if tries >= 20 || [2, 3, 4].iter().all(|n| out.contains(&format!("node {n:3}: device type"))) {
            break (o, out);
        }
        std::thread::sleep(std::time::Duration::from_millis(500));
    };
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for n in [2, 3, 4] {
        assert!(out.contains(&format!("node {n:3}: device type 0x00020192")), "{out}");
    }
    assert!(out.contains("IclA D065"), "{out}");

    // SDO read / write with types; an abort is reported by name.
    let o = motus(&["canopen", "--bus", &bus, "sdo", "write", "2", "0x6081", "0", "300", "--type", "u32"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = motus(&["canopen", "--bus", &bus, "sdo", "read", "2", "0x6081", "0", "--type", "u32"]);
    assert!(stdout(&o).contains("= 300"), "{}", stdout(&o));
    let o = motus(&["canopen", "--bus", &bus, "sdo", "read", "2", "0x1234", "0"]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("does not exist in the object dictionary") && err.contains("0x06020000"), "{err}");

    // The EDS the simulator writes names the objects of a dump.
    let eds = dir.path().join("icla.eds");
    let o = motus(&["sim", "icla", "--write-eds", eds.to_str().unwrap()]);
    assert!(o.status.success());
    let o = motus(&["canopen", "--bus", &bus, "--eds", eds.to_str().unwrap(), "dump", "3"]);
    let out = stdout(&o);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.contains("0x6502:00") && out.contains("0x1018:04"), "{out}");

    // NMT: stop node 4, its heartbeat says so (seen in the monitor).
    let o = motus(&["canopen", "--bus", &bus, "nmt", "4", "stop"]);
    assert!(o.status.success());
    let o = motus(&["canopen", "--bus", &bus, "nmt", "0", "start"]);
    assert!(o.status.success());

    // The robot: bus-load figures, then a demo program on the three drives.
    let o = motus(&["robot", "bus-load"]);
    let out = stdout(&o);
    assert!(
        out.contains("20 kbit/s") && out.contains("DOES NOT FIT") && out.contains("1000 kbit/s"),
        "{out}"
    );
    let o = motus(&["robot", "--bus", &bus, "--home", "--json", "demo", "square"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    for w in v["wheels"].as_array().unwrap() {
        assert!(w.as_i64().unwrap().abs() <= 1, "{v}");
    }
    // A CiA 402 drive as an axis.
    let uri = format!("cia402://{bus}?node=2");
    let o = motus(&["axis", &uri, "status", "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    drop(hub);
    // Both recordings hold the traffic; tshark reads the pcap as CANopen.
    std::thread::sleep(std::time::Duration::from_millis(200));
    let log = std::fs::read_to_string(&candump).unwrap();
    assert!(log.contains("can0 702#05") || log.contains("can0 702#7F"), "heartbeats recorded");
    let t = Command::new("tshark")
        .args([
            "-r",
            pcap.to_str().unwrap(),
            "-d",
            "can.subdissector,canopen",
            "-T",
            "fields",
            "-e",
            "canopen.function_code",
        ])
        .output()
        .expect("tshark is installed by scripts/install-oracles.sh");
    let codes = String::from_utf8_lossy(&t.stdout);
    assert!(codes.lines().count() > 50, "{codes}");
}
