//! The bus master over a real pseudo-terminal against a tiny responder thread: bytes
//! cross the kernel's pty, time-outs and retries happen in real time. Smoke tests of the
//! real transport, with generous liveness bounds only; the exact timing of exchanges,
//! time-outs and retries is tested on virtual time in `sim_link.rs`.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_serial::*;
use motus_wire::{Scan, Scanner};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// A toy protocol: request `[addr, x]`, reply `[addr, x+1, sum]`.
struct Toy;

impl Scanner for Toy {
    type Frame = (u8, u8);
    type Error = ();
    fn scan(&self, buf: &[u8]) -> Scan<(u8, u8), ()> {
        if buf.len() < 3 {
            return Scan::Incomplete;
        }
        if buf[0].wrapping_add(buf[1]) == buf[2] {
            Scan::Frame { frame: (buf[0], buf[1]), len: 3 }
        } else {
            Scan::Corrupt(())
        }
    }
}

fn responder(mut pty: PtyLink, present: &'static [u8], garbage_first: bool, stop: Arc<AtomicBool>) {
    std::thread::spawn(move || {
        let mut buf = [0u8; 64];
        let mut n_req = 0u32;
        while !stop.load(Ordering::Relaxed) {
            let n = pty.read(&mut buf, Duration::from_millis(20)).unwrap();
            if n >= 2 && present.contains(&buf[0]) {
                n_req += 1;
                let (a, x) = (buf[0], buf[1].wrapping_add(1));
                if garbage_first && n_req == 1 {
                    pty.write_all(&[0x55, 0x66]).unwrap();
                    pty.write_all(&[a, x, 0]).unwrap(); // corrupt
                    continue;
                }
                pty.write_all(&[0x00, a, x, a.wrapping_add(x)]).unwrap(); // leading garbage byte
            }
        }
    });
}

fn setup(present: &'static [u8], garbage_first: bool) -> (tempfile::TempDir, BusMaster, Arc<AtomicBool>) {
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("line");
    let pty = PtyLink::create(Some(&link), LineSettings::n81(115_200)).unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    responder(pty, present, garbage_first, stop.clone());
    let port = SerialLink::open(link.to_str().unwrap(), 115_200).unwrap();
    // A liveness margin: on a loaded host a reply can come well after the line's own
    // time-out (the time-outs are tested on virtual time).
    let bus = BusMaster::new(Box::new(port), BusConfig { margin: Duration::from_millis(200), retries: 2 });
    (dir, bus, stop)
}

#[test]
fn transaction_over_a_pty_with_garbage_and_retry() {
    let (_dir, bus, stop) = setup(&[1, 2], true);
    let req = Request { device: 1, bytes: &[1, 41], reply_len: 3, idempotent: true };
    let reply = bus.transact(&req, &Toy, |f| f.0 == 1).unwrap();
    assert_eq!(reply, (1, 42));
    let d = bus.device_stats(1);
    assert_eq!((d.ok, d.retries), (1, 1), "{d:?}");
    assert!(d.corrupt_frames >= 1, "{d:?}");
    stop.store(true, Ordering::Relaxed);
}

#[test]
fn missing_device_times_out_in_time_and_line_keeps_serving() {
    let (_dir, bus, stop) = setup(&[1], false);
    let t0 = Instant::now();
    let req = Request { device: 9, bytes: &[9, 1], reply_len: 3, idempotent: true };
    let err = bus.transact(&req, &Toy, |f| f.0 == 9).unwrap_err();
    let took = t0.elapsed();
    let per_attempt = bus.timeout_for(2, 3);
    assert!(matches!(err, BusError::Timeout { attempts: 3, .. }), "{err}");
    println!("3 time-outs of {per_attempt:?} took {took:?}");
    // Real time: never shorter than the time-outs; the upper bound only proves liveness.
    assert!(took >= per_attempt * 3 && took < per_attempt * 3 + Duration::from_secs(5), "{took:?}");
    let ok =
        bus.transact(&Request { device: 1, bytes: &[1, 1], reply_len: 3, idempotent: true }, &Toy, |f| {
            f.0 == 1
        });
    assert_eq!(ok.unwrap(), (1, 2));
    assert_eq!(bus.device_stats(9).failures, 1);
    stop.store(true, Ordering::Relaxed);
}

#[test]
fn non_idempotent_requests_are_not_repeated() {
    let (_dir, bus, stop) = setup(&[], false);
    let req = Request { device: 3, bytes: &[3, 1], reply_len: 3, idempotent: false };
    let err = bus.transact(&req, &Toy, |_| true).unwrap_err();
    assert!(matches!(err, BusError::Timeout { attempts: 1, .. }), "{err}");
    stop.store(true, Ordering::Relaxed);
}

#[test]
fn a_zero_time_out_read_polls_what_has_arrived() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("line");
    let mut pty = PtyLink::create(Some(&path), LineSettings::n81(115_200)).unwrap();
    let mut port = SerialLink::open(path.to_str().unwrap(), 115_200).unwrap();
    let mut buf = [0u8; 16];
    let t0 = Instant::now();
    assert_eq!(port.read(&mut buf, Duration::ZERO).unwrap(), 0, "nothing sent yet");
    let took = t0.elapsed();
    println!("a poll of an empty line took {took:?}");
    assert!(took < Duration::from_secs(2), "a poll does not wait for a time-out: {took:?}");
    pty.write_all(&[1, 2, 3]).unwrap();
    // Polls until the bytes have crossed the pty (a liveness bound, not a figure).
    let mut got = Vec::new();
    let t0 = Instant::now();
    while got.len() < 3 && t0.elapsed() < Duration::from_secs(10) {
        let n = port.read(&mut buf, Duration::ZERO).unwrap();
        got.extend_from_slice(&buf[..n]);
        std::thread::sleep(Duration::from_millis(1));
    }
    assert_eq!(got, [1, 2, 3]);
}
