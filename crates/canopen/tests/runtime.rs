//! Runtime tests of `Master` on an in-process `MemoryHub` with scripted fake nodes
//! (tests/common) that implement the SDO server / NMT slave from the spec's byte tables.
//!
//! On the wall clock: every time-out here is liveness (or a protocol time-out far beyond the
//! answers' microseconds); durations are asserted only from below, which load cannot break.
//! The SYNC period is printed; the 1 kHz SYNC jitter and the SDO rates are measured by
//! `cargo bench -p motus-robot --bench sync_jitter` and `--bench canopen_rates`
//! (`scripts/realtime.sh`).
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::{Duration, Instant};

use motus_can::{CanBus, CanFrame, MemoryHub};
use motus_canopen::lss::LssMode;
use motus_canopen::{Master, MasterEvent, NmtCommand, NmtState, PdoConfig, SdoAbortCode, Value};

fn setup() -> (MemoryHub, Master) {
    let hub = MemoryHub::new();
    let master = Master::new(Arc::new(hub.connect()));
    (hub, master)
}

fn bus(hub: &MemoryHub) -> Arc<dyn CanBus> {
    Arc::new(hub.connect())
}

fn f(s: &str) -> CanFrame {
    s.parse().unwrap()
}

#[test]
fn sdo_expedited_segmented_abort_and_typed() {
    let (hub, m) = setup();
    let _n = common::spawn_node(bus(&hub), 5, None);
    assert_eq!(m.read_u16(5, 0x6041, 0).unwrap(), 0x0237);
    assert_eq!(m.read_u32(5, 0x1000, 0).unwrap(), 0x0002_0192);
    assert_eq!(m.read_string(5, 0x1008, 0).unwrap(), "Fake node 5");
    m.write_i32(5, 0x607A, 0, -1000).unwrap();
    assert_eq!(m.read_i32(5, 0x607A, 0).unwrap(), -1000);
    m.write_i8(5, 0x6060, 0, -3).unwrap();
    assert_eq!(m.read_i8(5, 0x6060, 0).unwrap(), -3);
    // Segmented both ways: 100 bytes.
    let blob: Vec<u8> = (0..100u8).map(|i| i.wrapping_mul(37)).collect();
    m.sdo_download(5, 0x2000, 1, &blob).unwrap();
    assert_eq!(m.sdo_upload(5, 0x2000, 1).unwrap(), blob);
    // Abort by the device names node, object and code.
    let e = m.sdo_upload(5, 0x6042, 0).unwrap_err();
    assert_eq!(e.abort_code(), Some(SdoAbortCode::ObjectDoesNotExist));
    assert_eq!(
        e.to_string(),
        "SDO abort from node 5 on 0x6042:00: Object does not exist in the object dictionary (0x06020000)"
    );
    // Wrong length for a typed read.
    assert!(m.read_u8(5, 0x1008, 0).is_err());
}

#[test]
fn sdo_timeout_sends_abort() {
    let (hub, m) = setup();
    let sniffer = hub.connect();
    let node = common::spawn_node(bus(&hub), 7, None);
    node.controls.mute_sdo.store(true, Ordering::SeqCst);
    m.set_sdo_timeout(Duration::from_millis(50));
    let t0 = Instant::now();
    let e = m.sdo_upload(7, 0x6041, 0).unwrap_err();
    assert!(e.is_timeout(), "{e}");
    assert!(t0.elapsed() >= Duration::from_millis(50));
    assert!(e.to_string().contains("node 7") && e.to_string().contains("0x6041:00"), "{e}");
    // The sniffer sees boot-up, the request, then the abort 0x05040000.
    let mut seen = Vec::new();
    while let Ok(Some(r)) = sniffer.recv(Duration::from_millis(50)) {
        seen.push(r.frame.to_string());
    }
    assert!(seen.contains(&"607#4041600000000000".to_string()), "{seen:?}");
    assert!(seen.contains(&"607#8041600000000405".to_string()), "{seen:?}");
}

#[test]
fn different_nodes_in_parallel_same_node_serialised() {
    let (hub, m) = setup();
    let a = common::spawn_node(bus(&hub), 5, None);
    let _b = common::spawn_node(bus(&hub), 6, None);
    // Node 5 answers after 1 s (within the master's SDO time-out), node 6 at once: a transfer
    // to node 6 completes while node 5's is still outstanding, whatever the host's load (the
    // order is checked, not a duration).
    m.set_sdo_timeout(Duration::from_secs(10));
    a.controls.sdo_delay_us.store(1_000_000, Ordering::SeqCst);
    std::thread::scope(|s| {
        let h1 = s.spawn(|| m.read_u16(5, 0x6041, 0).unwrap());
        // Node 5 has the request (and sleeps on its answer).
        let t0 = Instant::now();
        while a.controls.requests.load(Ordering::SeqCst) == 0 {
            assert!(t0.elapsed() < Duration::from_secs(10), "node 5 got no request");
            std::thread::sleep(Duration::from_millis(1));
        }
        let t0 = Instant::now();
        assert_eq!(m.read_u16(6, 0x6041, 0).unwrap(), 0x0237);
        eprintln!("node 6 answered {:?} while node 5's transfer was outstanding", t0.elapsed());
        assert!(!h1.is_finished(), "node 6's transfer waited for node 5's");
        assert_eq!(h1.join().unwrap(), 0x0237);
    });
    a.controls.sdo_delay_us.store(100_000, Ordering::SeqCst);
    let t0 = Instant::now();
    std::thread::scope(|s| {
        let h1 = s.spawn(|| m.read_u16(5, 0x6041, 0).unwrap());
        let h2 = s.spawn(|| m.read_u32(5, 0x1000, 0).unwrap());
        assert_eq!(h1.join().unwrap(), 0x0237);
        assert_eq!(h2.join().unwrap(), 0x0002_0192);
    });
    let serial = t0.elapsed();
    assert!(serial >= Duration::from_millis(200), "same node took {serial:?}");
}

#[test]
fn nmt_heartbeat_lost_and_recovered() {
    let (hub, m) = setup();
    let events = m.events();
    let node = common::spawn_node(bus(&hub), 5, Some(Duration::from_millis(10)));
    m.wait_state(5, NmtState::PreOperational, Duration::from_secs(2)).unwrap();
    m.nmt(5, NmtCommand::Start).unwrap();
    m.wait_state(5, NmtState::Operational, Duration::from_secs(2)).unwrap();
    m.nmt(0, NmtCommand::Stop).unwrap();
    m.wait_state(5, NmtState::Stopped, Duration::from_secs(2)).unwrap();
    // Heartbeat every 10 ms, consumer time 250 ms (a node thread held off the CPU that long
    // would be a false loss), silent for 1 s.
    m.monitor_heartbeat(5, Duration::from_millis(250));
    node.controls.silent.store(true, Ordering::SeqCst);
    std::thread::sleep(Duration::from_millis(1000));
    node.controls.silent.store(false, Ordering::SeqCst);
    std::thread::sleep(Duration::from_millis(50));
    // Reset node -> boot-up seen by wait_boot.
    let waiter = std::thread::scope(|s| {
        let h = s.spawn(|| m.wait_boot(5, Duration::from_secs(2)));
        std::thread::sleep(Duration::from_millis(20));
        m.nmt(5, NmtCommand::ResetNode).unwrap();
        h.join().unwrap()
    });
    waiter.unwrap();
    // The events so far (liveness: until the recovery and the second boot-up are in).
    let count = |got: &[MasterEvent], f: &dyn Fn(&MasterEvent) -> bool| got.iter().filter(|e| f(e)).count();
    let is_lost = |e: &MasterEvent| matches!(e, MasterEvent::HeartbeatLost { node: 5, .. });
    let is_recovered = |e: &MasterEvent| matches!(e, MasterEvent::HeartbeatRecovered { node: 5, .. });
    let is_booted = |e: &MasterEvent| matches!(e, MasterEvent::Booted { node: 5 });
    let mut got: Vec<MasterEvent> = Vec::new();
    let t0 = Instant::now();
    while count(&got, &is_recovered) < 1 || count(&got, &is_booted) < 2 {
        assert!(t0.elapsed() < Duration::from_secs(10), "{got:?}");
        std::thread::sleep(Duration::from_millis(10));
        got.extend(events.try_iter());
    }
    std::thread::sleep(Duration::from_millis(30));
    got.extend(events.try_iter());
    let lost = count(&got, &is_lost);
    let recovered = count(&got, &is_recovered);
    let booted = count(&got, &is_booted);
    assert_eq!(lost, 1, "{got:?}");
    assert_eq!(recovered, 1, "{got:?}");
    assert_eq!(booted, 2, "{got:?}");
    let to_states: Vec<NmtState> = got
        .iter()
        .filter_map(|e| match e {
            MasterEvent::StateChanged { node: 5, to, .. } => Some(*to),
            _ => None,
        })
        .collect();
    assert!(
        to_states.starts_with(&[NmtState::PreOperational, NmtState::Operational, NmtState::Stopped]),
        "{to_states:?}"
    );
    assert!(m.wait_boot(5, Duration::from_millis(30)).unwrap_err().is_timeout());
}

#[test]
fn emcy_and_malformed_frames() {
    let (hub, m) = setup();
    let events = m.events();
    let peer = hub.connect();
    // EMCY node 5: code 0x2310, register 0x03, manufacturer 01..05.
    peer.send(&f("085#1023030102030405")).unwrap();
    // Malformed: SDO response of 7 bytes, heartbeat with DLC 2, EMCY with DLC 3, LSS cs 0x99.
    for s in ["585#4B416000370200", "705#0500", "085#102303", "7E4#9900000000000000"] {
        peer.send(&f(s)).unwrap();
    }
    // Liveness: the receive thread has taken all five frames.
    let t0 = Instant::now();
    while m.stats().frames_received < 5 {
        assert!(t0.elapsed() < Duration::from_secs(10), "{:?}", m.stats());
        std::thread::sleep(Duration::from_millis(5));
    }
    std::thread::sleep(Duration::from_millis(20));
    let got: Vec<MasterEvent> = events.try_iter().collect();
    assert_eq!(got.len(), 1, "{got:?}");
    let MasterEvent::Emergency(e) = &got[0] else { panic!("{got:?}") };
    assert_eq!((e.node, e.code, e.register.0), (5, 0x2310, 0x03));
    let st = m.stats();
    assert_eq!(st.frames_received, 5);
    assert_eq!(st.frames_malformed, 4);
    assert_eq!(m.node_state(5), None);
}

#[test]
fn pdo_configuration_sequence_and_subscription() {
    let (hub, m) = setup();
    let node = common::spawn_node(bus(&hub), 5, None);
    let cfg = PdoConfig {
        cob_id: 0x185,
        transmission_type: 1,
        inhibit_100us: None,
        event_timer_ms: Some(20),
        sync_start: None,
        mapping: vec![(0x6041, 0, 16), (0x6064, 0, 32)],
    };
    m.configure_tpdo(5, 1, &cfg).unwrap();
    let writes = node.writes.lock().unwrap().clone();
    let want: Vec<(u16, u8, Vec<u8>)> = vec![
        (0x1800, 1, vec![0x85, 0x01, 0x00, 0x80]),
        (0x1800, 2, vec![1]),
        (0x1800, 5, vec![20, 0]),
        (0x1A00, 0, vec![0]),
        (0x1A00, 1, vec![0x10, 0x00, 0x41, 0x60]),
        (0x1A00, 2, vec![0x20, 0x00, 0x64, 0x60]),
        (0x1A00, 0, vec![2]),
        (0x1800, 1, vec![0x85, 0x01, 0x00, 0x00]),
    ];
    assert_eq!(writes, want);
    let rx = m.subscribe(0x181..=0x1FF);
    let peer = hub.connect();
    peer.send(&f("185#37020000E803")).unwrap();
    peer.send(&f("285#01")).unwrap();
    let r = rx.recv_timeout(Duration::from_secs(1)).unwrap();
    assert_eq!(r.frame.to_string(), "185#37020000E803");
    let vals = motus_canopen::pdo::unpack(&cfg.mapping, r.frame.data()).unwrap();
    assert_eq!(vals, vec![0x0237, 0x03E8_0000]);
    assert!(rx.recv_timeout(Duration::from_millis(50)).is_err());
    // send_pdo reaches the bus.
    m.send_pdo(0x205, &[0x0F, 0x00]).unwrap();
    assert_eq!(peer.recv(Duration::from_secs(1)).unwrap().unwrap().frame.to_string(), "205#0F00");
}

#[test]
fn sync_producer_counter_and_period() {
    let (hub, m) = setup();
    let sniffer = hub.connect();
    let mut p = m.start_sync(Duration::from_millis(5), Some(4)).unwrap();
    // Liveness: at least 10 SYNC (about 50 ms) within 10 s.
    let t0 = Instant::now();
    while p.send_instants().len() < 10 {
        assert!(t0.elapsed() < Duration::from_secs(10), "{} SYNC sent", p.send_instants().len());
        std::thread::sleep(Duration::from_millis(20));
    }
    p.stop();
    let mut counters = Vec::new();
    while let Ok(Some(r)) = sniffer.recv(Duration::from_millis(20)) {
        assert_eq!(r.frame.id(), 0x080);
        counters.push(r.frame.data()[0]);
    }
    // Every SYNC the producer sent reached the bus, with the counter 1..=4 wrapping.
    assert_eq!(counters.len(), p.send_instants().len());
    assert_eq!(&counters[..6], &[1, 2, 3, 4, 1, 2]);
    // The period: printed (the host's scheduling); the 1 kHz SYNC jitter is measured by
    // `cargo bench -p motus-robot --bench sync_jitter` (`scripts/realtime.sh`).
    let periods = p.periods();
    let mean = periods.iter().sum::<Duration>() / periods.len() as u32;
    let worst = periods.iter().map(|d| d.as_secs_f64() * 1e3 - 5.0).map(f64::abs).fold(0.0, f64::max);
    eprintln!("SYNC 5 ms: {} periods, mean {mean:?}, worst deviation {worst:.3} ms", periods.len());
    m.send_sync().unwrap();
    assert_eq!(sniffer.recv(Duration::from_secs(1)).unwrap().unwrap().frame.to_string(), "080#");
}

#[test]
fn scan_and_dump() {
    let (hub, m) = setup();
    let _a = common::spawn_node(bus(&hub), 5, None);
    let _b = common::spawn_node(bus(&hub), 9, None);
    let t0 = Instant::now();
    let found = m.scan(1..=20);
    eprintln!("scan 1..=20 took {:?}", t0.elapsed());
    assert_eq!(found.iter().map(|n| n.node).collect::<Vec<_>>(), vec![5, 9]);
    assert_eq!(found[0].device_type, 0x0002_0192);
    assert_eq!(found[1].name.as_deref(), Some("Fake node 9"));
    assert_eq!(found[1].identity.unwrap().serial, 0xCAFE_0009);
    m.load_eds(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/drive402.eds")).unwrap();
    let rows = m.dump(5).unwrap();
    let row = |name: &str| rows.iter().find(|r| r.name == name).unwrap();
    assert_eq!(row("Statusword").value, Ok(Value::Uint(0x0237)));
    assert_eq!(row("Manufacturer device name").value, Ok(Value::Text("Fake node 5".into())));
    assert_eq!(row("Identity object.Vendor-ID").value, Ok(Value::Uint(0x123)));
    assert!(row("Controlword").value.as_ref().unwrap_err().contains("0x06020000"));
}

/// Scripted LSS slave (CiA 305, specs/canopen.md Part 4) on its own thread.
fn spawn_lss_slave(
    bus: Arc<dyn CanBus>,
    id: [u32; 4],
    stop: Arc<std::sync::atomic::AtomicBool>,
) -> std::thread::JoinHandle<(u8, u8)> {
    std::thread::spawn(move || {
        let (mut config, mut pos, mut node_id, mut bit_index, mut selective) = (false, 0u8, 0xFFu8, 0u8, 0u8);
        let reply = |d: [u8; 8]| bus.send(&CanFrame::new(0x7E4, &d).unwrap()).unwrap();
        while !stop.load(Ordering::SeqCst) {
            let Ok(Some(r)) = bus.recv(Duration::from_millis(1)) else { continue };
            let d = r.frame.data().to_vec();
            if r.frame.id() != 0x7E5 || d.len() != 8 {
                continue;
            }
            let v = u32::from_le_bytes([d[1], d[2], d[3], d[4]]);
            match d[0] {
                0x04 => config = d[1] == 1,
                0x40..=0x43 => {
                    let k = d[0] - 0x40;
                    selective = if v == id[usize::from(k)] && k == selective { k + 1 } else { 0 };
                    if selective == 4 {
                        config = true;
                        reply([0x44, 0, 0, 0, 0, 0, 0, 0]);
                    }
                }
                0x11 if config => {
                    let ok = (1..=127).contains(&d[1]) || d[1] == 0xFF;
                    if ok {
                        node_id = d[1];
                    }
                    reply([0x11, u8::from(!ok), 0, 0, 0, 0, 0, 0]);
                }
                0x13 if config => {
                    let ok = d[1] == 0 && d[2] <= 8 && d[2] != 5;
                    if ok {
                        bit_index = d[2];
                    }
                    reply([0x13, u8::from(!ok), 0, 0, 0, 0, 0, 0]);
                }
                0x17 if config => reply([0x17, 0, 0, 0, 0, 0, 0, 0]),
                0x5A..=0x5D if config => {
                    let b = id[usize::from(d[0] - 0x5A)].to_le_bytes();
                    reply([d[0], b[0], b[1], b[2], b[3], 0, 0, 0]);
                }
                0x5E if config => reply([0x5E, node_id, 0, 0, 0, 0, 0, 0]),
                0x51 if node_id == 0xFF => {
                    let (bit, sub, next) = (d[5], d[6], d[7]);
                    if bit == 0x80 {
                        pos = 0;
                        reply([0x4F, 0, 0, 0, 0, 0, 0, 0]);
                    } else if sub == pos && bit < 32 && (v ^ id[usize::from(sub)]) >> bit == 0 {
                        if bit == 0 {
                            if next < pos {
                                config = true;
                            }
                            pos = next;
                        }
                        reply([0x4F, 0, 0, 0, 0, 0, 0, 0]);
                    }
                }
                _ => {}
            }
        }
        (node_id, bit_index)
    })
}

#[test]
fn lss_fastscan_and_configuration() {
    let (hub, m) = setup();
    let stop = Arc::new(std::sync::atomic::AtomicBool::new(false));
    let ident = [0x0000_0123, 0x0000_0402, 0x0001_0002, 0x1234_5678];
    let slave = spawn_lss_slave(bus(&hub), ident, stop.clone());
    m.set_lss_timeout(Duration::from_millis(200));
    // A step without an answer within the step time-out reads as a 0 bit: 40 ms, generous
    // against the scripted slave's thread held off the CPU (answers take microseconds).
    let t0 = Instant::now();
    let found = m.lss_fastscan(Duration::from_millis(40)).unwrap().unwrap();
    eprintln!("fastscan took {:?}", t0.elapsed());
    assert_eq!(found.parts(), ident);
    assert_eq!(m.lss_inquire_identity().unwrap(), found);
    assert_eq!(m.lss_inquire_node_id().unwrap(), 0xFF);
    m.lss_configure_node_id(2).unwrap();
    m.lss_configure_bit_timing(20_000).unwrap();
    m.lss_store().unwrap();
    assert!(m.lss_configure_bit_timing(100_000).is_err()); // not in the table: refused locally
    m.lss_activate_bit_timing(1000).unwrap();
    m.lss_switch_global(LssMode::Waiting).unwrap();
    // Not in configuration any more: inquiries time out.
    assert!(m.lss_inquire_node_id().unwrap_err().is_timeout());
    m.lss_switch_selective(&found).unwrap();
    assert_eq!(m.lss_inquire_node_id().unwrap(), 2);
    // Configured slaves do not answer fastscan.
    assert_eq!(m.lss_fastscan(Duration::from_millis(40)).unwrap(), None);
    stop.store(true, Ordering::SeqCst);
    assert_eq!(slave.join().unwrap(), (2, 7));
}
