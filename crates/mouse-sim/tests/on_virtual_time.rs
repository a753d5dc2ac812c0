//! The simulated sensor served on a threaded virtual clock into an in-memory line: the
//! host decodes the stream with the resynchronising decoder and sums the counts; they
//! equal the fed displacement times 8500 counts/m within one count, with and without
//! garbage on the line. On virtual time the packet timing is exact: one packet per
//! 10 ms period, its bytes one character time (9600 Bd 8N1) apart, and a seed repeats a
//! run byte for byte. `over_pty.rs` serves the same sensor on a real pseudo-terminal.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use motus_clock::{Clock, SharedClock, VirtualClock};
use motus_mouse_protocol::{ConverterStream, DeviceType};
use motus_mouse_sim::{serve_with_clock, MouseSensor, SensorConfig, ServeStats};
use motus_serial::{LineSettings, Link};

const LINE: LineSettings = LineSettings { baud: 9600, bits_per_char: 10 };

/// The host's end of an in-memory line: every byte the sensor sends, with the virtual time
/// (since the start) it completed; the host sends nothing.
struct Line {
    clock: SharedClock,
    start: Instant,
    received: Arc<Mutex<Vec<(Duration, u8)>>>,
}

impl Link for Line {
    fn write_all(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        let at = self.clock.elapsed(self.start);
        self.received.lock().unwrap().extend(bytes.iter().map(|b| (at, *b)));
        Ok(())
    }
    fn read(&mut self, _: &mut [u8], _: Duration) -> std::io::Result<usize> {
        Ok(0)
    }
    fn discard_input(&mut self) -> std::io::Result<()> {
        Ok(())
    }
    fn line(&self) -> LineSettings {
        LINE
    }
    fn describe(&self) -> String {
        "memory".into()
    }
}

#[derive(Debug, PartialEq)]
struct Run {
    sum: (i64, i64),
    fed: (f64, f64),
    stats: ServeStats,
    garbage: u64,
    /// The bytes received, with their virtual times.
    received: Vec<(Duration, u8)>,
}

/// Serves the sensor on its own thread while this one feeds `steps` displacements 3 ms
/// apart (half a millisecond off the sensor's instants), then stops it.
fn run(config: SensorConfig, steps: u32, step_m: (f64, f64)) -> Run {
    let clock = VirtualClock::threaded();
    let shared = clock.shared();
    let mut sensor = MouseSensor::new(config).unwrap();
    let motion = sensor.motion();
    let received = Arc::new(Mutex::new(Vec::new()));
    let stop = Arc::new(AtomicBool::new(false));
    let mut line = Line { clock: shared.clone(), start: clock.now(), received: received.clone() };
    let (flag, server_clock) = (stop.clone(), shared.clone());
    let builder = std::thread::Builder::new().name("mouse-sim".into());
    let server = motus_clock::spawn(&shared, builder, move || {
        serve_with_clock(&mut line, &mut sensor, &flag, &server_clock).unwrap()
    })
    .unwrap();
    clock.sleep(Duration::from_micros(500));
    for i in 0..steps {
        // A wavy path: the x step varies, so the remainders are exercised.
        let k = 1.0 + 0.5 * (f64::from(i) * 0.1).sin();
        motion.add_displacement(step_m.0 * k, step_m.1);
        clock.sleep(Duration::from_millis(3));
    }
    clock.sleep(Duration::from_millis(30));
    stop.store(true, Ordering::Relaxed);
    let stats = motus_clock::while_blocked(&clock, || server.join().unwrap());
    let received = std::mem::take(&mut *received.lock().unwrap());
    let mut dec = ConverterStream::default();
    let bytes: Vec<u8> = received.iter().map(|(_, b)| *b).collect();
    dec.push(&bytes);
    let mut sum = (0i64, 0i64);
    while let Some(p) = dec.next_frame() {
        assert_eq!(p.device, DeviceType::Microsoft);
        sum.0 += i64::from(p.dx);
        sum.1 += i64::from(p.dy);
    }
    assert_eq!(dec.stats().frames, stats.packets);
    assert_eq!(received.len() as u64, stats.bytes);
    Run { sum, fed: motion.total(), stats, garbage: dec.stats().garbage_bytes, received }
}

fn check_counts(r: &Run) {
    // Independent expectation: 850 counts per 10 cm (specs/omni-robot.md).
    let ex = r.fed.0 * 8500.0;
    let ey = r.fed.1 * 8500.0;
    assert!((r.sum.0 as f64 - ex).abs() <= 1.0, "x: sum {} expected {ex}", r.sum.0);
    assert!((r.sum.1 as f64 - ey).abs() <= 1.0, "y: sum {} expected {ey}", r.sum.1);
}

#[test]
fn counts_equal_fed_displacement_and_packets_leave_every_period() {
    // 200 steps of ~1.3 mm x and -0.7 mm y: ~0.26 m, ~2200 counts, over 630.5 ms.
    let wall = Instant::now();
    let r = run(SensorConfig::default(), 200, (0.0013, -0.0007));
    println!("{:?} in {:?} of wall time", r.stats, wall.elapsed());
    check_counts(&r);
    assert!(r.sum.0 > 1500 && r.sum.1 < -1000, "{:?}", r.sum);
    assert_eq!(r.garbage, 0);
    // Packets at 10, 20, ..., 630 ms, and the last one once the stop (at 630.5 ms) is
    // seen: right after the packet of 630 ms has left.
    assert_eq!((r.stats.packets, r.stats.late_periods), (64, 0));
    let ct = LINE.char_time();
    for (k, packet) in r.received.chunks(7).enumerate().take(63) {
        let due = Duration::from_millis(10) * (k as u32 + 1);
        let times: Vec<Duration> = packet.iter().map(|(t, _)| *t).collect();
        let expected: Vec<Duration> = (1..=7).map(|j| due + ct * j).collect();
        assert_eq!(times, expected, "packet {k}");
    }
    let last = r.received.last().unwrap().0;
    assert_eq!(last, Duration::from_millis(630) + ct * 14);
}

#[test]
fn counts_survive_garbage_on_the_line_and_a_seed_repeats_the_run() {
    let cfg = SensorConfig { garbage_rate: 0.3, seed: 42, ..SensorConfig::default() };
    let r = run(cfg.clone(), 150, (-0.002, 0.0011));
    check_counts(&r);
    assert!(r.garbage > 0, "no garbage was injected");
    assert_eq!(run(cfg, 150, (-0.002, 0.0011)), r, "the same seed, the same bytes at the same times");
}
