//! The bus master against a toy simulator served inline by a [`SimLink`], on virtual
//! time: exchanges take exactly their wire times and delays, time-outs take virtual time
//! only, and seeded faults repeat exactly.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_clock::{Clock, VirtualClock};
use motus_serial::*;
use motus_wire::{Scan, Scanner};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// A toy protocol: `[header, addr, x, addr + x]`; requests start with 0xA5, replies with
/// 0x5A.
#[derive(Debug, Clone, Copy)]
struct Toy(u8);

const REQUESTS: Toy = Toy(0xA5);
const REPLIES: Toy = Toy(0x5A);

fn frame(header: u8, addr: u8, x: u8) -> [u8; 4] {
    [header, addr, x, addr.wrapping_add(x)]
}

impl Scanner for Toy {
    type Frame = (u8, u8);
    type Error = u8;
    fn scan(&self, buf: &[u8]) -> Scan<(u8, u8), u8> {
        match buf {
            [h, ..] if *h != self.0 => Scan::Skip,
            [_, a, x, cs, ..] if a.wrapping_add(*x) == *cs => Scan::Frame { frame: (*a, *x), len: 4 },
            [_, a, _, _, ..] => Scan::Corrupt(*a),
            _ => Scan::Incomplete,
        }
    }
}

/// Devices answering `[0x5A, addr, x + 1, ..]` after `delay`; the first `deaf_for`
/// requests go unanswered.
#[derive(Debug, Default)]
struct Devices {
    present: Vec<u8>,
    delay: Duration,
    deaf_for: u32,
    requests: u32,
    /// (address, simulated time) of each request.
    seen: Vec<(u8, Duration)>,
    last_tick: Duration,
}

impl Responder for Devices {
    type Frame = (u8, u8);
    type Error = u8;

    fn respond(&mut self, (addr, x): (u8, u8), now: Duration) -> Option<Answer> {
        if !self.present.contains(&addr) {
            return None;
        }
        self.requests += 1;
        self.seen.push((addr, now));
        if self.requests <= self.deaf_for {
            return None;
        }
        Some(Answer { bytes: frame(0x5A, addr, x.wrapping_add(1)).to_vec(), delay: self.delay })
    }

    fn tick(&mut self, now: Duration) -> std::io::Result<()> {
        assert!(now >= self.last_tick, "time went back");
        self.last_tick = now;
        Ok(())
    }
}

const LINE: LineSettings = LineSettings { baud: 9600, bits_per_char: 10 };
const DELAY: Duration = Duration::from_micros(1500);

fn options(faults: FaultConfig) -> ServeOptions {
    ServeOptions { baud_pacing: true, faults, poll: Duration::from_millis(10), flush_when_idle: true }
}

/// A simulated line on a fresh virtual clock, with the devices shared for inspection.
fn sim_link(
    devices: Devices,
    faults: FaultConfig,
) -> (VirtualClock, Arc<Mutex<Devices>>, SimLink<Toy, Devices>) {
    let clock = VirtualClock::new();
    let server =
        SimServer::with_clock(Box::new(NullLink::new(LINE)), REQUESTS, options(faults), clock.shared())
            .unwrap();
    let devices = Arc::new(Mutex::new(devices));
    let link = SimLink::new(server, Arc::clone(&devices), LINE);
    (clock, devices, link)
}

/// A bus master on a simulated line.
fn pair(
    devices: Devices,
    faults: FaultConfig,
    config: BusConfig,
) -> (VirtualClock, Arc<Mutex<Devices>>, BusMaster) {
    let (clock, devices, link) = sim_link(devices, faults);
    let bus_clock = Arc::clone(link.clock());
    (clock, devices, BusMaster::with_clock(Box::new(link), config, bus_clock))
}

fn device_1() -> Devices {
    Devices { present: vec![1], delay: DELAY, ..Devices::default() }
}

fn ask(bus: &BusMaster, addr: u8, x: u8) -> Result<(u8, u8), BusError> {
    let bytes = frame(0xA5, addr, x);
    let req = Request { device: u32::from(addr), bytes: &bytes, reply_len: 4, idempotent: true };
    bus.transact(&req, &REPLIES, |f| f.0 == addr)
}

#[test]
fn an_exchange_takes_its_wire_times_and_the_answer_delay_exactly() {
    let (clock, devices, bus) = pair(device_1(), FaultConfig::default(), BusConfig::default());
    let t0 = clock.now();
    assert_eq!(ask(&bus, 1, 41).unwrap(), (1, 42));
    let exchange = LINE.wire_time(4) + DELAY + LINE.wire_time(4);
    assert_eq!(clock.elapsed(t0), exchange);
    // The device saw the request once its last byte was on the wire.
    assert_eq!(devices.lock().unwrap().seen, vec![(1, LINE.wire_time(4))]);
    // Ten virtual seconds later, the devices have been brought up to time.
    clock.sleep(Duration::from_secs(10));
    assert_eq!(ask(&bus, 1, 1).unwrap(), (1, 2));
    assert_eq!(clock.elapsed(t0), Duration::from_secs(10) + exchange * 2);
    let d = devices.lock().unwrap();
    assert_eq!(d.seen[1], (1, exchange + Duration::from_secs(10) + LINE.wire_time(4)));
    assert_eq!(d.last_tick, Duration::from_secs(10) + exchange * 2);
    let stats = bus.stats();
    assert_eq!((stats.window, stats.totals.ok, stats.bytes_rx), (clock.elapsed(t0), 2, 8));
}

#[test]
fn a_dropped_answer_times_out_on_virtual_time_and_is_retried() {
    let faults = FaultConfig { drop_rate: 1.0, corrupt_rate: 0.0, seed: 1 };
    // Time-outs of seconds: a real wait would take 15 s of wall time.
    let config = BusConfig { margin: Duration::from_secs(5), retries: 2 };
    let (clock, devices, bus) = pair(device_1(), faults, config);
    let (t0, wall) = (clock.now(), Instant::now());
    let err = ask(&bus, 1, 5).unwrap_err();
    assert!(matches!(err, BusError::Timeout { attempts: 3, .. }), "{err}");
    assert_eq!(clock.elapsed(t0), bus.timeout_for(4, 4) * 3);
    let wall = wall.elapsed();
    println!("15 s of virtual time-outs took {wall:?} of wall time");
    assert!(wall < Duration::from_secs(5), "{wall:?}");
    let d = bus.device_stats(1);
    assert_eq!((d.timeouts, d.retries, d.failures), (3, 2, 1), "{d:?}");
    assert_eq!(devices.lock().unwrap().requests, 3, "every attempt reached the device");
}

#[test]
fn a_request_the_device_missed_is_answered_on_the_retry() {
    let devices = Devices { deaf_for: 1, ..device_1() };
    let (clock, _, bus) = pair(devices, FaultConfig::default(), BusConfig::default());
    let t0 = clock.now();
    assert_eq!(ask(&bus, 1, 9).unwrap(), (1, 10));
    let exchange = LINE.wire_time(4) + DELAY + LINE.wire_time(4);
    assert_eq!(clock.elapsed(t0), bus.timeout_for(4, 4) + exchange);
    let d = bus.device_stats(1);
    assert_eq!((d.ok, d.timeouts, d.retries), (1, 1, 1), "{d:?}");
}

#[test]
fn a_missing_device_times_out_and_the_line_keeps_serving() {
    let (clock, _, bus) =
        pair(device_1(), FaultConfig::default(), BusConfig { retries: 0, ..BusConfig::default() });
    let t0 = clock.now();
    assert!(matches!(ask(&bus, 9, 1), Err(BusError::Timeout { attempts: 1, .. })));
    assert_eq!(clock.elapsed(t0), bus.timeout_for(4, 4));
    assert_eq!(ask(&bus, 1, 1).unwrap(), (1, 2));
}

/// Many transactions on a faulty line: what the bus master, the injector and the
/// decoder counted, and the virtual time it took.
fn faulty_run(seed: u64) -> (BusStats, FaultStats, motus_wire::StreamStats, Duration, u64) {
    let faults = FaultConfig { drop_rate: 0.1, corrupt_rate: 0.02, seed };
    let (clock, devices, link) = sim_link(Devices { present: vec![1, 2], ..device_1() }, faults);
    // The test keeps a handle on the link to read its statistics.
    let link = Arc::new(Mutex::new(link));
    let bus = BusMaster::with_clock(Box::new(Arc::clone(&link)), BusConfig::default(), clock.shared());
    let t0 = clock.now();
    for i in 0..300u32 {
        let _ = ask(&bus, 1 + (i % 2) as u8, i as u8);
    }
    assert!(devices.lock().unwrap().requests > 0);
    let link = link.lock().unwrap();
    (bus.stats(), link.fault_stats(), link.decoder_stats(), clock.elapsed(t0), link.frames_served())
}

#[test]
fn seeded_faults_repeat_exactly() {
    let first = faulty_run(42);
    let (stats, faults, decoder, took, _) = first;
    println!("{stats:?}\n{faults:?}\n{decoder:?}\n{took:?}");
    assert!(
        faults.dropped_writes > 0 && faults.corrupted_bytes > 0 && faults.corrupted_received > 0,
        "{faults:?}"
    );
    assert!(stats.totals.retries > 0 && stats.totals.corrupt_frames > 0, "{stats:?}");
    assert!(decoder.corrupt_frames > 0, "corrupted requests were seen: {decoder:?}");
    assert_eq!(stats.totals.ok + stats.totals.failures, 300);
    assert_eq!(faulty_run(42), first, "same seed, same run");
    assert_ne!(faulty_run(43).1, faults, "another seed, other faults");
}

#[test]
fn answer_bytes_arrive_one_character_time_apart() {
    let (clock, _, mut link) = sim_link(device_1(), FaultConfig::default());
    let t0 = clock.now();
    link.write_all(&frame(0xA5, 1, 3)).unwrap();
    let mut got = Vec::new();
    let mut buf = [0u8; 16];
    while got.len() < 4 {
        let n = link.read(&mut buf, Duration::from_secs(1)).unwrap();
        assert!(n > 0);
        got.extend_from_slice(&buf[..n]);
        let answer_start = LINE.wire_time(4) + DELAY;
        assert_eq!(clock.elapsed(t0), answer_start + LINE.wire_time(got.len()));
    }
    assert_eq!(got, frame(0x5A, 1, 4));
    // Nothing more: a read times out on virtual time.
    let t1 = clock.now();
    assert_eq!(link.read(&mut buf, Duration::from_millis(30)).unwrap(), 0);
    assert_eq!(clock.elapsed(t1), Duration::from_millis(30));
}

#[test]
fn a_quiet_line_ends_a_half_received_request() {
    let (clock, devices, mut link) = sim_link(device_1(), FaultConfig::default());
    let t0 = clock.now();
    let mut buf = [0u8; 16];
    link.write_all(&[0xA5, 1]).unwrap();
    // The two bytes are on the wire until 2 character times, the line quiet 3 later.
    let flush_at = LINE.wire_time(2) + LINE.wire_time(3);
    assert_eq!(link.read(&mut buf, flush_at - Duration::from_nanos(1)).unwrap(), 0);
    assert_eq!(link.decoder_stats().garbage_bytes, 0, "still pending");
    assert_eq!(link.read(&mut buf, Duration::from_millis(1)).unwrap(), 0);
    assert_eq!(link.decoder_stats().garbage_bytes, 2, "dropped by the idle flush");
    // A whole request after the silence is answered as usual.
    let t1 = clock.now();
    link.write_all(&frame(0xA5, 1, 7)).unwrap();
    let mut got = Vec::new();
    while got.len() < 4 {
        let n = link.read(&mut buf, Duration::from_secs(1)).unwrap();
        got.extend_from_slice(&buf[..n]);
    }
    assert_eq!(got, frame(0x5A, 1, 8));
    assert_eq!(clock.elapsed(t1), LINE.wire_time(4) + DELAY + LINE.wire_time(4));
    assert_eq!(devices.lock().unwrap().seen, vec![(1, clock.elapsed(t0) - DELAY - LINE.wire_time(4))]);
}

/// The same devices served by the threaded loop ([`SimServer::run`]) over a real pty, on
/// the system clock: a smoke test of the shared serve step on a real transport (liveness
/// bounds only).
#[test]
fn the_same_devices_answer_over_a_pty_served_by_the_threaded_loop() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("line");
    let pty = PtyLink::create(Some(&path), LINE).unwrap();
    let server = SimServer::new(Box::new(pty), REQUESTS, options(FaultConfig::default())).unwrap();
    let line = (server, device_1());
    let thread =
        ServeThread::spawn("toy-sim", line, |(server, devices), stop| server.run(devices, stop)).unwrap();
    let port = SerialLink::open(path.to_str().unwrap(), LINE.baud).unwrap();
    let bus = BusMaster::new(Box::new(port), BusConfig { margin: Duration::from_millis(500), retries: 0 });
    let t0 = Instant::now();
    assert_eq!(ask(&bus, 1, 41).unwrap(), (1, 42));
    let took = t0.elapsed();
    println!("a paced exchange over a pty took {took:?}");
    assert!(took >= LINE.wire_time(4) + DELAY, "the answer waits for the request's wire time and the delay");
    assert!(matches!(ask(&bus, 9, 1), Err(BusError::Timeout { .. })));
    let (server, devices) = thread.stop().unwrap();
    assert_eq!((server.frames_served(), devices.seen.len()), (1, 1));
}

/// A poller's thread and the test thread share the bus master and the simulated line on a
/// threaded virtual clock: each waits for the line while the other holds it, and time
/// moves when both wait.
#[test]
fn a_poller_and_the_test_thread_share_the_line_on_a_threaded_clock() {
    let clock = VirtualClock::threaded();
    let server = SimServer::with_clock(
        Box::new(NullLink::new(LINE)),
        REQUESTS,
        options(FaultConfig::default()),
        clock.shared(),
    )
    .unwrap();
    let devices = Arc::new(Mutex::new(Devices { present: vec![1, 2], ..device_1() }));
    let link = SimLink::new(server, Arc::clone(&devices), LINE);
    let bus = Arc::new(BusMaster::with_clock(Box::new(link), BusConfig::default(), clock.shared()));
    let polls = Arc::new(Mutex::new(Vec::new()));
    let poller = {
        let (bus, polls) = (Arc::clone(&bus), Arc::clone(&polls));
        Poller::with_clock(clock.shared())
            .every(Duration::from_millis(10), move || polls.lock().unwrap().push(ask(&bus, 2, 0)))
            .spawn()
            .unwrap()
    };
    let (t0, wall) = (clock.now(), Instant::now());
    for x in 0..20u8 {
        assert_eq!(ask(&bus, 1, x).unwrap(), (1, x + 1));
        clock.sleep(Duration::from_millis(7));
    }
    let took = clock.elapsed(t0);
    poller.stop();
    let polls = polls.lock().unwrap();
    println!("{} polls in {took:?} of virtual time, {:?} of wall time", polls.len(), wall.elapsed());
    assert!(polls.iter().all(|p| *p == Ok((2, 1))), "{polls:?}");
    // An exchange takes 9.8 ms: 20 of them and 20 pauses, polls in between. How the two
    // threads interleave at a hand-over of the line is up to the OS (a thread woken from
    // the line's lock marks itself running again only once scheduled), so only bounds.
    assert!(took >= (LINE.wire_time(4) * 2 + DELAY + Duration::from_millis(7)) * 20, "{took:?}");
    assert!(!polls.is_empty());
    assert_eq!(devices.lock().unwrap().seen.iter().filter(|(a, _)| *a == 1).count(), 20);
}

#[test]
fn requests_written_back_to_back_arrive_at_their_wire_times() {
    let (clock, devices, mut link) = sim_link(device_1(), FaultConfig::default());
    let t0 = clock.now();
    // Two bytes of noise, then two requests, in one write.
    let mut bytes = vec![0x00, 0x11];
    bytes.extend_from_slice(&frame(0xA5, 1, 3));
    bytes.extend_from_slice(&frame(0xA5, 1, 5));
    link.write_all(&bytes).unwrap();
    assert_eq!(devices.lock().unwrap().seen, vec![(1, LINE.wire_time(6)), (1, LINE.wire_time(10))]);
    let mut got = Vec::new();
    let mut buf = [0u8; 16];
    while got.len() < 8 {
        let n = link.read(&mut buf, Duration::from_secs(1)).unwrap();
        got.extend_from_slice(&buf[..n]);
    }
    assert_eq!(got[..4], frame(0x5A, 1, 4));
    assert_eq!(got[4..], frame(0x5A, 1, 6));
    // The second answer follows the first on the line.
    assert_eq!(clock.elapsed(t0), LINE.wire_time(6) + DELAY + LINE.wire_time(4) * 2);
    assert_eq!(link.decoder_stats().garbage_bytes, 2);
}
