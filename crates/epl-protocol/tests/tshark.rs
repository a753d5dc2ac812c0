//! Independent oracle: Motus-encoded SoC, PReq, PRes, SoA and ASnd (IdentResponse,
//! StatusResponse, NMT command) frames written to a classic pcap (linktype 1) must decode in
//! tshark with the same fields and without malformed/expert errors (`specs/oracles.md`).
//! tshark is required: this test fails when it is missing.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use std::process::Command;
use std::time::Duration;

use motus_epl_protocol::*;
use pcap_file::pcap::{PcapHeader, PcapPacket, PcapWriter};
use pcap_file::DataLink;

const MN: MacAddr = MacAddr([0x02, 0, 0, 0, 0, 0xf0]);
const CN: MacAddr = MacAddr([0x02, 0, 0, 0, 0, 0x01]);

fn frames() -> Vec<EplFrame> {
    let soc = Soc {
        flags: Flags::PS,
        net_time: NetTime { seconds: 1_795_262_863, nanoseconds: 500 },
        relative_time: 50_000,
        ..Soc::default()
    };
    let preq = PReq { flags: Flags::RD, pdo_version: 0x10, payload: vec![0x11, 0x22], ..PReq::default() };
    let pres = PRes {
        nmt_state: NmtState::Operational,
        flags: Flags::RD,
        pr_rs: PrRs { pr: 3, rs: 1, link: 0 },
        pdo_version: 0x10,
        payload: vec![1, 2, 3, 4],
        reserved: 0,
    };
    let soa = Soa::new(NmtState::Operational, RequestedService::StatusRequest, 1);
    let ident = IdentResponse {
        flags: Flags::empty(),
        pr_rs: PrRs::default(),
        nmt_state: NmtState::PreOperational1,
        epl_version: 0x20,
        feature_flags: 0x0000_0245,
        mtu: 300,
        poll_in_size: 36,
        poll_out_size: 36,
        response_time: 50_000,
        device_type: 0x000F_0191,
        vendor_id: 0x1234,
        product_code: 7,
        revision_number: 0x0002_0007,
        serial_number: 99,
        vendor_ext1: [0; 8],
        verify_conf_date: 0,
        verify_conf_time: 0,
        app_sw_date: 0,
        app_sw_time: 0,
        ip_address: "192.168.100.1".parse().unwrap(),
        subnet_mask: "255.255.255.0".parse().unwrap(),
        default_gateway: "192.168.100.254".parse().unwrap(),
        host_name: FixedText::Text("motus-cn1".into()),
        vendor_ext2: vec![],
        reserved1: 0,
        reserved2: 0,
        reserved3: 0,
    };
    let status = StatusResponse {
        flags: Flags::EC,
        pr_rs: PrRs { pr: 0, rs: 0, link: 0 },
        nmt_state: NmtState::Operational,
        static_errors: [0; 8],
        entries: vec![],
        reserved: [0; 3],
    };
    let cmd = NmtCommand { command: NmtCommandId::StartNode, data: vec![], reserved: 0 };
    vec![
        EplFrame::new(MN, MacAddr::BROADCAST, 255, 240, Message::Soc(soc)),
        EplFrame::new(MN, CN, 1, 240, Message::PReq(preq)),
        EplFrame::new(CN, MacAddr::BROADCAST, 255, 1, Message::PRes(pres)),
        EplFrame::new(MN, MacAddr::BROADCAST, 255, 240, Message::Soa(soa)),
        EplFrame::new(CN, MacAddr::BROADCAST, 255, 1, Message::Asnd(Asnd::IdentResponse(ident))),
        EplFrame::new(CN, MacAddr::BROADCAST, 255, 1, Message::Asnd(Asnd::StatusResponse(status))),
        EplFrame::new(MN, MacAddr::BROADCAST, 1, 240, Message::Asnd(Asnd::NmtCommand(cmd))),
    ]
}

/// A tshark number field: decimal, or hex with 0x (tshark prints BASE_HEX fields that way).
fn num(s: &str) -> u64 {
    match s.strip_prefix("0x") {
        Some(h) => u64::from_str_radix(h, 16).unwrap(),
        None => s.parse().unwrap(),
    }
}

fn tshark(args: &[&str]) -> String {
    let out = Command::new("tshark")
        .args(args)
        .output()
        .expect("tshark must be installed (apt-get install tshark)");
    assert!(out.status.success(), "tshark {args:?} failed: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout).unwrap()
}

#[test]
fn tshark_decodes_motus_frames() {
    let dir = std::env::temp_dir().join(format!("motus-epl-tshark-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("f.pcap");
    {
        let file = std::fs::File::create(&path).unwrap();
        let header = PcapHeader { datalink: DataLink::ETHERNET, ..PcapHeader::default() };
        let mut w = PcapWriter::with_header(file, header).unwrap();
        for (i, f) in frames().iter().enumerate() {
            let bytes = f.encode().unwrap();
            let t = Duration::from_micros(100 * u64::try_from(i).unwrap());
            w.write_packet(&PcapPacket::new(t, u32::try_from(bytes.len()).unwrap(), &bytes)).unwrap();
        }
    }
    let p = path.to_str().unwrap();
    let fields = [
        "epl.mtyp",
        "epl.src",
        "epl.dest",
        "epl.soc.ps",
        "epl.soc.relativetime",
        "epl.preq.rd",
        "epl.preq.size",
        "epl.pres.stat",
        "epl.pres.rd",
        "epl.pres.pr",
        "epl.pres.rs",
        "epl.pres.size",
        "epl.soa.svid",
        "epl.soa.svtg",
        "epl.soa.eplv",
        "epl.asnd.svid",
        "epl.asnd.ires.ip",
        "epl.asnd.ires.hostname",
        "epl.asnd.ires.mtu",
        "epl.asnd.sres.stat",
        "epl.asnd.nmtcommand.cid",
    ];
    let mut args = vec!["-r", p, "-T", "fields", "-E", "separator=|"];
    for f in &fields {
        args.push("-e");
        args.push(f);
    }
    let out = tshark(&args);
    let rows: Vec<Vec<&str>> = out.lines().map(|l| l.split('|').collect()).collect();
    assert_eq!(rows.len(), 7, "{out}");
    let col = |row: usize, name: &str| rows[row][fields.iter().position(|f| *f == name).unwrap()];
    // Message type, source, destination of every frame.
    let expected = [
        ("1", "240", "255"),
        ("3", "240", "1"),
        ("4", "1", "255"),
        ("5", "240", "255"),
        ("6", "1", "255"),
        ("6", "1", "255"),
        ("6", "240", "1"),
    ];
    for (i, (t, s, d)) in expected.iter().enumerate() {
        assert_eq!(
            (col(i, "epl.mtyp"), col(i, "epl.src"), col(i, "epl.dest")),
            (*t, *s, *d),
            "row {i}: {out}"
        );
    }
    assert_eq!(col(0, "epl.soc.ps"), "1", "{out}");
    assert_eq!(col(0, "epl.soc.relativetime"), "50000", "{out}");
    assert_eq!(col(1, "epl.preq.rd"), "1", "{out}");
    assert_eq!(col(1, "epl.preq.size"), "2", "{out}");
    assert_eq!(num(col(2, "epl.pres.stat")), 0xfd, "{out}");
    assert_eq!(
        (col(2, "epl.pres.rd"), col(2, "epl.pres.pr"), col(2, "epl.pres.rs")),
        ("1", "3", "1"),
        "{out}"
    );
    assert_eq!(col(2, "epl.pres.size"), "4", "{out}");
    assert_eq!((col(3, "epl.soa.svid"), col(3, "epl.soa.svtg")), ("2", "1"), "{out}");
    assert_eq!(
        (num(col(4, "epl.asnd.svid")), num(col(5, "epl.asnd.svid")), num(col(6, "epl.asnd.svid"))),
        (1, 2, 4),
        "{out}"
    );
    assert_eq!(col(4, "epl.asnd.ires.ip"), "192.168.100.1", "{out}");
    assert_eq!(col(4, "epl.asnd.ires.hostname"), "motus-cn1", "{out}");
    assert_eq!(col(4, "epl.asnd.ires.mtu"), "300", "{out}");
    assert_eq!(num(col(5, "epl.asnd.sres.stat")), 0xfd, "{out}");
    assert_eq!(num(col(6, "epl.asnd.nmtcommand.cid")), 0x21, "{out}");

    // No malformed frames and no expert errors or warnings.
    let expert = tshark(&["-q", "-z", "expert", "-r", p]);
    for bad in ["Malformed", "Errors (", "Warnings ("] {
        assert!(!expert.contains(bad), "tshark expert info: {expert}");
    }
    let verbose = tshark(&["-r", p, "-V"]);
    assert!(!verbose.contains("Malformed"), "{verbose}");
    assert!(verbose.contains("Ethernet POWERLINK"));
    std::fs::remove_dir_all(&dir).unwrap();
}
