//! A smoke test of the real transport: the simulated sensor served on a real
//! pseudo-terminal; a host opens the pty like a serial port, decodes the stream with the
//! resynchronising decoder and sums the counts: they equal the fed displacement times 8500
//! counts/m within one count. Real time: liveness bounds only. The exact timing, garbage
//! and seeds are tested on virtual time in `on_virtual_time.rs`.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use motus_mouse_protocol::{ConverterStream, DeviceType};
use motus_mouse_sim::{serve, MouseSensor, SensorConfig};
use motus_serial::{LineSettings, Link, PtyLink, SerialLink};

struct Run {
    sum: (i64, i64),
    fed: (f64, f64),
    packets: u64,
    garbage: u64,
    elapsed: Duration,
}

fn run(config: SensorConfig, steps: u32, step_m: (f64, f64)) -> Run {
    let pty = PtyLink::create(None, LineSettings::n81(9600)).unwrap();
    let path = pty.host_path().to_str().unwrap().to_string();
    let mut host = SerialLink::open(&path, 9600).unwrap();
    let mut sensor = MouseSensor::new(config).unwrap();
    let motion = sensor.motion();
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    let server = std::thread::spawn(move || {
        let mut pty = pty;
        let stats = serve(&mut pty, &mut sensor, &flag).unwrap();
        (stats, pty)
    });
    let feeder = {
        let motion = motion.clone();
        let stop = stop.clone();
        std::thread::spawn(move || {
            for i in 0..steps {
                // A wavy path: the x step varies, so the remainders are exercised.
                let k = 1.0 + 0.5 * (f64::from(i) * 0.1).sin();
                motion.add_displacement(step_m.0 * k, step_m.1);
                std::thread::sleep(Duration::from_millis(3));
            }
            std::thread::sleep(Duration::from_millis(30));
            stop.store(true, Ordering::Relaxed);
        })
    };
    let start = Instant::now();
    let mut dec = ConverterStream::default();
    let mut sum = (0i64, 0i64);
    let mut buf = [0u8; 256];
    let mut quiet_since: Option<Instant> = None;
    loop {
        let n = host.read(&mut buf, Duration::from_millis(20)).unwrap();
        dec.push(&buf[..n]);
        while let Some(p) = dec.next_frame() {
            assert_eq!(p.device, DeviceType::Microsoft);
            sum.0 += i64::from(p.dx);
            sum.1 += i64::from(p.dy);
        }
        if n == 0 && stop.load(Ordering::Relaxed) {
            let t = *quiet_since.get_or_insert_with(Instant::now);
            if t.elapsed() > Duration::from_millis(100) {
                break;
            }
        } else {
            quiet_since = None;
        }
        assert!(start.elapsed() < Duration::from_secs(60), "test ran away");
    }
    feeder.join().unwrap();
    // The pty (returned by the server thread) stays open until the host has read all.
    let (stats, _pty) = server.join().unwrap();
    assert_eq!(dec.stats().frames, stats.packets);
    Run {
        sum,
        fed: motion.total(),
        packets: stats.packets,
        garbage: dec.stats().garbage_bytes,
        elapsed: start.elapsed(),
    }
}

fn check_counts(r: &Run) {
    // Independent expectation: 850 counts per 10 cm (specs/omni-robot.md).
    let ex = r.fed.0 * 8500.0;
    let ey = r.fed.1 * 8500.0;
    assert!((r.sum.0 as f64 - ex).abs() <= 1.0, "x: sum {} expected {ex}", r.sum.0);
    assert!((r.sum.1 as f64 - ey).abs() <= 1.0, "y: sum {} expected {ey}", r.sum.1);
}

#[test]
fn counts_over_pty_equal_fed_displacement() {
    // 100 steps of ~1.3 mm x and -0.7 mm y: ~0.13 m, ~1100 counts.
    let r = run(SensorConfig::default(), 100, (0.0013, -0.0007));
    check_counts(&r);
    assert!(r.sum.0 > 750 && r.sum.1 < -500, "{:?}", r.sum);
    assert_eq!(r.garbage, 0);
    // The sensor never sends early: at most one packet per 10 ms (+1 final) over the run.
    let max = r.elapsed.as_millis() as u64 / 10 + 2;
    println!("{} packets in {:?}", r.packets, r.elapsed);
    assert!(r.packets >= 2 && r.packets <= max, "{} packets in {:?}", r.packets, r.elapsed);
}
