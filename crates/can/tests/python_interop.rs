//! Interoperability with python-can 4.6.1's socketcand client (an independent
//! implementation): tests/python/can_echo_peer.py joins the hub, echoes transformed
//! frames (id + 1, bytes XOR 0xFF) and prints what it parsed. Fails when python3 or
//! python-can is missing (CI installs them).
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_can::socketcand::{Hub, HubConfig, SocketcandBus};
use motus_can::{CanBus, CanFrame};
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn peer_script() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../tests/python/can_echo_peer.py")
}

#[test]
fn python_can_peer_exchanges_frames_both_ways() {
    let hub = Hub::start(HubConfig {
        listen: "127.0.0.1:0".parse().unwrap(),
        bitrate: None,
        channel: "can0".into(),
    })
    .unwrap();
    let rust = SocketcandBus::connect(hub.local_addr(), "can0").unwrap();
    let child = Command::new("python3")
        .arg(peer_script())
        .args(["--port", &hub.local_addr().port().to_string(), "--timeout", "10"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("python3 must be installed (with python-can 4.6.1)");

    // The peer says hello once it is on the bus (its RTR request before is dropped).
    let hello = rust.recv(Duration::from_secs(10)).unwrap().expect("hello from the python peer");
    assert_eq!(hello.frame, CanFrame::new(0x7F0, b"hi").unwrap());

    let sent = vec![
        CanFrame::new(0x080, &[]).unwrap(), // SYNC, zero length
        CanFrame::new(0x605, &[0x40, 0x00, 0x10, 0x00, 0x00, 0x00, 0x00, 0x00]).unwrap(), // SDO upload 0x1000
        CanFrame::with_format(0x1ABC_DEF0, true, &[0x01, 0x02, 0x03]).unwrap(), // extended id
        CanFrame::new(0x00A, &[0xFF]).unwrap(), // low standard id
        CanFrame::new(0x7FF, &[0xEE]).unwrap(), // end marker
    ];
    for f in &sent {
        rust.send(f).unwrap();
    }
    // Expected replies computed by hand: id + 1, every byte XOR 0xFF.
    let expected = vec![
        CanFrame::new(0x081, &[]).unwrap(),
        CanFrame::new(0x606, &[0xBF, 0xFF, 0xEF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF]).unwrap(),
        CanFrame::with_format(0x1ABC_DEF1, true, &[0xFE, 0xFD, 0xFC]).unwrap(),
        CanFrame::new(0x00B, &[0x00]).unwrap(),
        CanFrame::new(0x000, &[0x11]).unwrap(), // 0x7FF + 1 wraps within 11 bits
    ];
    let mut got = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(10);
    while got.len() < expected.len() && Instant::now() < deadline {
        if let Some(r) = rust.recv(Duration::from_millis(200)).unwrap() {
            got.push(r.frame);
        }
    }
    let out = child.wait_with_output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "python peer failed: {:?}\nstdout:\n{stdout}\nstderr:\n{stderr}",
        out.status
    );
    assert_eq!(got, expected, "replies from python-can");

    // What python-can parsed from our `< frame ... >` text.
    let lines: Vec<&str> = stdout.lines().collect();
    assert_eq!(lines.len(), sent.len(), "{stdout}");
    let wanted = [
        (0x080, false, ""),
        (0x605, false, "4000100000000000"),
        (0x1ABC_DEF0, true, "010203"),
        (0x00A, false, "ff"),
        (0x7FF, false, "ee"),
    ];
    let now = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap().as_secs_f64();
    for (line, (id, ext, data)) in lines.iter().zip(wanted) {
        assert!(line.contains(&format!("\"id\": {id},")), "{line}");
        assert!(line.contains(&format!("\"extended\": {},", if ext { "true" } else { "false" })), "{line}");
        assert!(line.contains(&format!("\"data\": \"{data}\"")), "{line}");
        let ts: f64 = line.rsplit_once("\"timestamp\": ").unwrap().1.trim_end_matches('}').parse().unwrap();
        assert!((now - ts).abs() < 30.0, "timestamp {ts} is wall-clock time");
    }
    assert_eq!(hub.stats().remote_dropped, 1, "python-can's RTR request was counted and dropped");
}
