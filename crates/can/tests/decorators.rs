//! Decorators over the in-process MemoryHub.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_can::decorate::{
    candump_line, check_cycle, cycle_load, socketcan_record, BusLoad, CandumpLog, FaultConfig, FaultyBus,
};
use motus_can::{CanBus, CanFrame, MemoryHub};
use std::time::{Duration, Instant};

fn sdo() -> CanFrame {
    CanFrame::new(0x605, &[0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]).unwrap()
}

#[test]
fn candump_lines_match_candump_l() {
    // The example line of can-utils' candump -l format, as in the brief.
    let line = candump_line(&sdo(), Duration::new(1_436_509_052, 249_713_000), "can0");
    assert_eq!(line, "(1436509052.249713) can0 605#4000100000000000\n");
    let sync = candump_line(&CanFrame::new(0x080, &[]).unwrap(), Duration::from_micros(1), "vcan0");
    assert_eq!(sync, "(0.000001) vcan0 080#\n");
}

#[test]
fn candump_log_records_sent_and_received_frames() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bus.log");
    let hub = MemoryHub::new();
    let logged = CandumpLog::create(hub.connect(), &path, "can0").unwrap();
    let other = hub.connect();
    logged.send(&sdo()).unwrap();
    other.send(&CanFrame::new(0x585, &[0x43, 0, 0x10, 0, 0x92, 1, 2, 0]).unwrap()).unwrap();
    logged.recv(Duration::from_secs(1)).unwrap().unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let rest: Vec<&str> = text.lines().map(|l| l.split_once(") ").unwrap().1).collect();
    assert_eq!(rest, ["can0 605#4000100000000000", "can0 585#4300100092010200"]);
    assert!(text.starts_with('('));
}

#[test]
fn socketcan_record_layout() {
    // LINKTYPE_CAN_SOCKETCAN: id big-endian with flags, DLC, 3 zero bytes, 8 data bytes.
    assert_eq!(socketcan_record(&sdo()), [0, 0, 0x06, 0x05, 8, 0, 0, 0, 0x40, 0, 0x10, 0, 0, 0, 0, 0]);
    let ext = CanFrame::with_format(0x1ABC_DEF0, true, &[0xAA]).unwrap();
    assert_eq!(socketcan_record(&ext), [0x9A, 0xBC, 0xDE, 0xF0, 1, 0, 0, 0, 0xAA, 0, 0, 0, 0, 0, 0, 0]);
    let rtr = CanFrame::remote(0x701, false, 1).unwrap();
    assert_eq!(socketcan_record(&rtr), [0x40, 0, 0x07, 0x01, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]);
}

fn drain(bus: &dyn CanBus) -> Vec<CanFrame> {
    let mut out = Vec::new();
    while let Some(r) = bus.recv(Duration::from_millis(30)).unwrap() {
        out.push(r.frame);
    }
    out
}

#[test]
fn corrupted_frames_are_counted_never_delivered() {
    let hub = MemoryHub::new();
    let tx = hub.connect();
    let rx = FaultyBus::new(hub.connect(), FaultConfig { corrupt: 1.0, ..FaultConfig::default() });
    for _ in 0..10 {
        tx.send(&sdo()).unwrap();
    }
    assert!(drain(&rx).is_empty());
    let s = rx.stats();
    assert_eq!((s.corrupted, s.passed, s.dropped), (10, 0, 0));
}

#[test]
fn dropped_and_passed_frames_add_up_and_are_seeded() {
    let run = |seed| {
        let hub = MemoryHub::new();
        let tx = hub.connect();
        let rx = FaultyBus::new(hub.connect(), FaultConfig { drop: 0.3, seed, ..FaultConfig::default() });
        for i in 0..200u8 {
            tx.send(&CanFrame::new(0x181, &[i]).unwrap()).unwrap();
        }
        let got: Vec<u8> = drain(&rx).iter().map(|f| f.data()[0]).collect();
        (got, rx.stats())
    };
    let (got, stats) = run(7);
    assert_eq!(stats.dropped + stats.passed, 200);
    assert_eq!(got.len() as u64, stats.passed);
    assert!((30..=90).contains(&stats.dropped), "{stats:?}");
    assert!(got.windows(2).all(|w| w[0] < w[1]), "order kept");
    assert_eq!(run(7).0, got, "same seed, same faults");
    assert_ne!(run(8).0, got, "another seed, other faults");
}

#[test]
fn mangled_frames_are_delivered_damaged() {
    let hub = MemoryHub::new();
    let tx = hub.connect();
    let rx = FaultyBus::new(hub.connect(), FaultConfig { mangle: 1.0, ..FaultConfig::default() });
    for _ in 0..50 {
        tx.send(&sdo()).unwrap();
    }
    tx.send(&CanFrame::new(0x080, &[]).unwrap()).unwrap();
    let got = drain(&rx);
    assert_eq!(got.len(), 51);
    assert!(got.iter().all(|f| f != &sdo() && f.id() != 0), "{got:?}");
    // One flipped bit or a wrong length.
    for f in &got[..50] {
        let flipped: u32 = f.data().iter().zip(sdo().data()).map(|(a, b)| (a ^ b).count_ones()).sum();
        assert!(f.dlc() != 8 || flipped == 1, "{f}");
    }
    assert_eq!(got[50].dlc(), 1, "a SYNC can only grow");
    assert_eq!(rx.stats().mangled, 51);
}

#[test]
fn delayed_frames_arrive_late_and_in_order() {
    let hub = MemoryHub::new();
    let tx = hub.connect();
    let config =
        FaultConfig { delay: 1.0, max_delay: Duration::from_millis(40), seed: 3, ..FaultConfig::default() };
    let rx = FaultyBus::new(hub.connect(), config);
    let start = Instant::now();
    for i in 0..5u8 {
        tx.send(&CanFrame::new(0x181, &[i]).unwrap()).unwrap();
    }
    let mut latest = Duration::ZERO;
    for i in 0..5u8 {
        let r = rx.recv(Duration::from_secs(1)).unwrap().unwrap();
        assert_eq!(r.frame.data(), [i]);
        latest = start.elapsed();
    }
    assert!(latest >= Duration::from_millis(5), "some delay: {latest:?}");
    assert!(latest < Duration::from_millis(500), "{latest:?}");
    assert_eq!(rx.stats().delayed, 5);
}

#[test]
fn faults_on_send_side() {
    let hub = MemoryHub::new();
    let tx =
        FaultyBus::new(hub.connect(), FaultConfig { drop: 1.0, on_send: true, ..FaultConfig::default() });
    let rx = hub.connect();
    tx.send(&sdo()).unwrap();
    assert!(drain(&rx).is_empty());
    assert_eq!(tx.stats().dropped, 1);
}

#[test]
fn bus_load_counts_worst_case_bits_over_the_window() {
    let hub = MemoryHub::new();
    let bus = BusLoad::new(hub.connect(), 125_000, Duration::from_secs(1), 0.5);
    let other = hub.connect();
    for _ in 0..10 {
        bus.send(&sdo()).unwrap();
    }
    other.send(&CanFrame::new(0x080, &[]).unwrap()).unwrap();
    bus.recv(Duration::from_secs(1)).unwrap().unwrap();
    let load = bus.load();
    // 10 x 135 bits (8-byte standard frame) + 55 bits (SYNC), wire_time.rs unit tests.
    assert_eq!(load.total_bits, 1405);
    assert!((load.bits_per_second - 1405.0).abs() < 1e-6, "{load:?}");
    assert!((load.fraction - 1405.0 / 125_000.0).abs() < 1e-9);
}

#[test]
fn bus_load_window_slides() {
    let hub = MemoryHub::new();
    let bus = BusLoad::new(hub.connect(), 20_000, Duration::from_millis(50), 0.1);
    for _ in 0..20 {
        bus.send(&sdo()).unwrap(); // 2700 bits in 50 ms = 54 kbit/s: over the threshold
    }
    assert!(bus.load().fraction > 1.0);
    std::thread::sleep(Duration::from_millis(80));
    assert_eq!(bus.load().bits_per_second, 0.0);
    assert_eq!(bus.load().total_bits, 2700);
}

#[test]
fn cycle_budget() {
    // 7 eight-byte frames x 135 bits = 945 bits = 47.25 ms at 20 kbit/s.
    let frames = vec![sdo(); 7];
    let load = cycle_load(&frames, Duration::from_millis(100), 20_000);
    assert_eq!(load.bits, 945);
    assert_eq!(load.busy, Duration::from_micros(47_250));
    assert!((load.fraction - 0.4725).abs() < 1e-9);
    assert!(check_cycle(&frames, Duration::from_millis(100), 20_000).is_ok());
    let err = check_cycle(&frames, Duration::from_millis(10), 20_000).unwrap_err();
    assert_eq!(err.to_string(), "a 10 ms cycle of 7 frames needs 47.2 ms at 20 kbit/s");
    // 1 Mbit/s: 0.945 ms, fits in 1 ms.
    assert!(check_cycle(&frames, Duration::from_millis(1), 1_000_000).is_ok());
    let err = check_cycle(&frames, Duration::from_micros(500), 1_000_000).unwrap_err();
    assert_eq!(err.to_string(), "a 0.5 ms cycle of 7 frames needs 0.9 ms at 1000 kbit/s");
}
