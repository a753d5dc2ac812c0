#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
//! FaultyLink over a real UDP link on loopback: drops, corruption and delays happen at the
//! configured rates, are counted, and are reproducible with the same seed.

use std::time::{Duration, Instant};

use motus_epl::{EthLink, FaultConfig, FaultyLink, UdpHub};

fn frame(i: u16) -> Vec<u8> {
    let mut f = vec![0u8; 60];
    f[..6].copy_from_slice(&[1, 0x11, 0x1e, 0, 0, 4]);
    f[12..14].copy_from_slice(&[0x88, 0xab]);
    f[14] = 0x04;
    f[20..22].copy_from_slice(&i.to_le_bytes());
    f
}

/// Sends 2000 frames through a faulty sender, each followed by a receive; returns (counters,
/// frames received intact, frames received corrupted).
fn run(config: FaultConfig) -> (motus_epl::FaultCounters, usize, usize) {
    let hub = UdpHub::new();
    let tx = FaultyLink::new(hub.connect().unwrap(), config);
    let rx = hub.connect().unwrap();
    let (mut intact, mut corrupted) = (0, 0);
    let mut buf = [0u8; 1518];
    for i in 0..2000u16 {
        let dropped_before = tx.counters().dropped;
        tx.send(&frame(i)).unwrap();
        // Loopback delivers within the send call, or a little later on a loaded host: a frame
        // not dropped is waited for generously (liveness), a dropped one briefly.
        let dropped = tx.counters().dropped > dropped_before;
        let wait = if dropped { Duration::from_millis(2) } else { Duration::from_secs(5) };
        if let Some((n, _)) = rx.recv(&mut buf, wait).unwrap() {
            if buf[..n] == frame(i)[..] {
                intact += 1;
            } else {
                corrupted += 1;
            }
        }
    }
    assert_eq!(rx.recv(&mut buf, Duration::from_millis(20)).unwrap(), None, "no late frames");
    (tx.counters(), intact, corrupted)
}

#[test]
fn drop_and_corrupt_rates_are_applied_counted_and_reproducible() {
    let config = FaultConfig { seed: 7, drop: 0.1, corrupt: 0.05, ..FaultConfig::default() };
    let (c, intact, corrupted) = run(config);
    assert_eq!(c.sent, 2000);
    // 10 % of 2000 = 200 drops (binomial sd ~13); 5 % of the rest ~ 90 corruptions (sd ~9).
    assert!((140..260).contains(&c.dropped), "{c:?}");
    assert!((50..140).contains(&c.corrupted), "{c:?}");
    assert_eq!(intact + corrupted, (c.sent - c.dropped) as usize, "every frame not dropped arrived");
    assert_eq!(corrupted as u64, c.corrupted, "every corruption changed a byte of the frame");
    let (again, _, _) = run(config);
    assert_eq!(again, c, "same seed, same faults");
}

#[test]
fn delays_hold_the_sender() {
    let config =
        FaultConfig { seed: 1, delay: 1.0, delay_by: Duration::from_millis(2), ..FaultConfig::default() };
    let hub = UdpHub::new();
    let tx = FaultyLink::new(hub.connect().unwrap(), config);
    let t = Instant::now();
    for i in 0..10 {
        tx.send(&frame(i)).unwrap();
    }
    assert!(t.elapsed() >= Duration::from_millis(20));
    assert_eq!(tx.counters().delayed, 10);
    assert!(tx.describe().starts_with("faulty(udp"));
}
