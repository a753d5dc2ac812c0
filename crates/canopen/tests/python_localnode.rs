//! Interoperability: Motus's master against python-canopen 2.4.1's `LocalNode` (an
//! independent SDO server / NMT slave / heartbeat and EMCY producer) over Motus's
//! socketcand hub on 127.0.0.1. Fails (never skips) when python3 or canopen is missing.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use std::io::Read;
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::time::{Duration, Instant};

use motus_can::socketcand::{Hub, HubConfig, SocketcandBus};
use motus_canopen::{Master, MasterEvent, NmtCommand, NmtState, SdoAbortCode};

fn next_event(
    rx: &std::sync::mpsc::Receiver<MasterEvent>,
    timeout: Duration,
    pred: impl Fn(&MasterEvent) -> bool,
) -> MasterEvent {
    let deadline = Instant::now() + timeout;
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        match rx.recv_timeout(left) {
            Ok(e) if pred(&e) => return e,
            Ok(_) => {}
            Err(e) => panic!("event not seen within {timeout:?}: {e}"),
        }
    }
}

#[test]
fn master_against_python_canopen_local_node() {
    let hub = Hub::start(HubConfig {
        listen: "127.0.0.1:0".parse().unwrap(),
        bitrate: None,
        channel: "can0".into(),
    })
    .unwrap();
    let bus = SocketcandBus::connect(hub.local_addr(), "can0").unwrap();
    let m = Master::new(Arc::new(bus));
    let events = m.events();
    let dir = env!("CARGO_MANIFEST_DIR");
    let mut child = Command::new("python3")
        .arg(format!("{dir}/../../tests/python/master_localnode.py"))
        .args([
            "--port",
            &hub.local_addr().port().to_string(),
            "--eds",
            &format!("{dir}/tests/data/drive402.eds"),
        ])
        .args(["--node", "5", "--lifetime", "30"])
        .stdout(Stdio::piped())
        .spawn()
        .expect("python3 must be installed");

    // Boot-up, then heartbeats in pre-operational.
    next_event(&events, Duration::from_secs(15), |e| *e == MasterEvent::Booted { node: 5 });
    m.wait_state(5, NmtState::PreOperational, Duration::from_secs(2)).unwrap();

    // Expedited uploads (values from drive402.eds).
    assert_eq!(m.read_u32(5, 0x1000, 0).unwrap(), 0x0002_0192);
    assert_eq!(m.read_u32(5, 0x1018, 4).unwrap(), 0xCAFE);
    // Segmented upload: 19-byte VISIBLE_STRING.
    assert_eq!(m.read_string(5, 0x1008, 0).unwrap(), "SimDrive402 example");
    assert_eq!(m.read_string(5, 0x2000, 0).unwrap(), "initial text of the scratch string");
    // Expedited downloads, read back.
    m.write_u16(5, 0x6040, 0, 0x000F).unwrap();
    assert_eq!(m.read_u16(5, 0x6040, 0).unwrap(), 0x000F);
    m.write_i32(5, 0x607A, 0, -123_456).unwrap();
    assert_eq!(m.read_i32(5, 0x607A, 0).unwrap(), -123_456);
    // Segmented downloads, read back (python also reports what it stored, below).
    let text = "Motus wrote this string through segmented SDO";
    m.sdo_download(5, 0x2000, 0, text.as_bytes()).unwrap();
    assert_eq!(m.read_string(5, 0x2000, 0).unwrap(), text);
    let blob: Vec<u8> = (0..100u32).map(|i| (i * 7 + 3) as u8).collect();
    m.sdo_download(5, 0x2001, 0, &blob).unwrap();
    assert_eq!(m.sdo_upload(5, 0x2001, 0).unwrap(), blob);
    // Device aborts: missing object; wrong length for UNSIGNED16 (python: 0x06070010).
    let e = m.sdo_upload(5, 0x6042, 0).unwrap_err();
    assert_eq!(e.abort_code(), Some(SdoAbortCode::ObjectDoesNotExist), "{e}");
    assert!(e.to_string().starts_with("SDO abort from node 5 on 0x6042:00"), "{e}");
    let e = m.sdo_download(5, 0x6040, 0, &[1, 2, 3, 4]).unwrap_err();
    assert_eq!(e.abort_code(), Some(SdoAbortCode::TypeLengthMismatch), "{e}");

    // NMT: start / stop / pre-operational, seen in the heartbeats.
    m.nmt(5, NmtCommand::Start).unwrap();
    m.wait_state(5, NmtState::Operational, Duration::from_secs(1)).unwrap();
    m.nmt(5, NmtCommand::Stop).unwrap();
    m.wait_state(5, NmtState::Stopped, Duration::from_secs(1)).unwrap();
    m.nmt(0, NmtCommand::EnterPreOperational).unwrap();
    m.wait_state(5, NmtState::PreOperational, Duration::from_secs(1)).unwrap();

    // EMCY produced by python-canopen on command.
    m.write_u8(5, 0x2002, 0, 1).unwrap();
    let MasterEvent::Emergency(emcy) =
        next_event(&events, Duration::from_secs(2), |e| matches!(e, MasterEvent::Emergency(_)))
    else {
        unreachable!()
    };
    assert_eq!(
        (emcy.node, emcy.code, emcy.register.0, emcy.manufacturer),
        (5, 0x2310, 0x03, [1, 2, 3, 4, 5])
    );
    assert_eq!(emcy.register.names(), vec!["generic", "current"]);

    // Heartbeat consumer: fine while beating, lost once after python stops them.
    m.monitor_heartbeat(5, Duration::from_millis(150));
    std::thread::sleep(Duration::from_millis(300));
    assert!(!events.try_iter().any(|e| matches!(e, MasterEvent::HeartbeatLost { .. })));
    m.write_u8(5, 0x2002, 0, 2).unwrap();
    let t0 = Instant::now();
    next_event(&events, Duration::from_secs(2), |e| matches!(e, MasterEvent::HeartbeatLost { node: 5, .. }));
    eprintln!("heartbeat loss detected {:?} after the stop command", t0.elapsed());
    std::thread::sleep(Duration::from_millis(400));
    assert!(
        !events.try_iter().any(|e| matches!(e, MasterEvent::HeartbeatLost { .. })),
        "lost reported twice"
    );

    // Quit: python prints what it stored.
    m.write_u8(5, 0x2002, 0, 3).unwrap();
    let deadline = Instant::now() + Duration::from_secs(10);
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if Instant::now() > deadline {
            child.kill().unwrap();
            panic!("python did not exit");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let mut out = String::new();
    child.stdout.take().unwrap().read_to_string(&mut out).unwrap();
    assert!(status.success(), "python failed: {status} {out}");
    let hex = |b: &[u8]| b.iter().map(|x| format!("{x:02x}")).collect::<String>();
    assert!(out.contains(&format!("\"2000\": \"{}\"", hex(text.as_bytes()))), "{out}");
    assert!(out.contains(&format!("\"2001\": \"{}\"", hex(&blob))), "{out}");
    assert!(out.contains("\"6040\": \"0f00\""), "{out}"); // 0x000F LE
    assert!(out.contains("\"607A\": \"c01dfeff\""), "{out}"); // -123456 = 0xFFFE1DC0 LE
    assert_eq!(m.stats().frames_malformed, 0);
}
