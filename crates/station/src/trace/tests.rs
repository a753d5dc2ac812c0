#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use super::*;
use crate::alarm::NullAlarms;
use crate::scheduler::{Scheduler, TaskClass};

fn ms(n: u64) -> Duration {
    Duration::from_millis(n)
}

#[test]
fn register_rejects_duplicates_and_csv_breaking_names() {
    let mut r = Recorder::new(8);
    let a = r.register("x.position", "m").unwrap();
    assert_eq!(a, SignalId(0));
    assert_eq!(r.register("x.position", "m"), Err(TraceError::DuplicateSignal("x.position".into())));
    assert!(matches!(r.register("a,b", "m"), Err(TraceError::InvalidName { what: "name", .. })));
    assert!(matches!(r.register("", "m"), Err(TraceError::InvalidName { .. })));
    assert!(matches!(r.register("ok", "m\n"), Err(TraceError::InvalidName { what: "unit", .. })));
    assert_eq!(r.find("x.position"), Some(a));
    assert_eq!(r.record(SignalId(7), ms(0), 1.0), Err(TraceError::UnknownSignal(7)));
}

#[test]
fn streaming_cursor_sees_each_sample_once_and_counts_losses() {
    let mut r = Recorder::new(4);
    let a = r.register("a", "").unwrap();
    let b = r.register("b", "").unwrap();
    for i in 0..3 {
        r.record(a, ms(i), i as f64).unwrap();
    }
    let batch = r.samples_since(&Cursor::default());
    assert_eq!(batch.lost, 0);
    assert_eq!(batch.signals.len(), 1); // b has nothing yet
    assert_eq!(batch.signals[0].samples.iter().map(|s| s.value).collect::<Vec<_>>(), vec![0.0, 1.0, 2.0]);
    let cursor = batch.cursor;
    // Nothing new: empty batch.
    assert!(r.samples_since(&cursor).signals.is_empty());
    // Six more for a (ring of 4: samples 5..=8 remain), one for b.
    for i in 3..9 {
        r.record(a, ms(i), i as f64).unwrap();
    }
    r.record(b, ms(8), -1.0).unwrap();
    let batch = r.samples_since(&cursor);
    // The reader expected a from #3; #3 and #4 were overwritten.
    assert_eq!(batch.lost, 2);
    assert_eq!(
        batch.signals[0].samples.iter().map(|s| s.value).collect::<Vec<_>>(),
        vec![5.0, 6.0, 7.0, 8.0]
    );
    assert_eq!(batch.signals[1].signal, b);
    // A cursor taken now sees only later samples.
    let now = r.cursor_now();
    r.record(b, ms(9), -2.0).unwrap();
    let batch = r.samples_since(&now);
    assert_eq!(batch.signals.len(), 1);
    assert_eq!(batch.signals[0].samples, vec![Sample { t: ms(9), value: -2.0 }]);
    assert_eq!(r.latest(a), Some(Sample { t: ms(8), value: 8.0 }));
}

#[test]
fn csv_rows_merge_by_timestamp_with_units_in_the_header() {
    let mut r = Recorder::new(16);
    let pos = r.register("x.position", "m").unwrap();
    let sw = r.register("x.statusword", "").unwrap();
    r.record(pos, ms(0), 0.5).unwrap();
    r.record(sw, ms(0), 567.0).unwrap();
    r.record(pos, ms(1), 0.25).unwrap();
    r.record(sw, Duration::from_micros(1500), 1591.0).unwrap();
    let mut out = Vec::new();
    r.write_csv(&[], &mut out).unwrap();
    // Expected text written by hand: one row per distinct time, empty cell where a signal
    // has no sample at that time.
    let expected = "time_s,x.position (m),x.statusword\n\
                    0.000000000,0.5,567\n\
                    0.001000000,0.25,\n\
                    0.001500000,,1591\n";
    assert_eq!(String::from_utf8(out).unwrap(), expected);
    let mut out = Vec::new();
    r.write_csv(&[sw], &mut out).unwrap();
    assert_eq!(String::from_utf8(out).unwrap(), "time_s,x.statusword\n0.000000000,567\n0.001500000,1591\n");
}

#[test]
fn rising_trigger_captures_pre_and_post_window_of_every_signal() {
    let mut r = Recorder::new(32);
    let v = r.register("v", "m/s").unwrap();
    let s = r.register("safe", "").unwrap();
    let id = r
        .arm(Trigger { signal: v, condition: Condition::Rising(5.0), pre_samples: 3, post_samples: 2 })
        .unwrap();
    // v = 0,1,2,...: crosses 5.0 upwards at sample 5 (t = 5 ms). Window: samples 2..=7.
    for i in 0..12u64 {
        r.record(v, ms(i), i as f64).unwrap();
        r.record(s, ms(i), if i < 6 { 1.0 } else { 0.0 }).unwrap();
        if i == 6 {
            assert_eq!(r.armed(), vec![(id, true)], "fired, waiting for post samples");
            assert!(r.take_captures().is_empty());
        }
    }
    assert!(r.armed().is_empty(), "one-shot");
    let caps = r.take_captures();
    assert_eq!(caps.len(), 1);
    let c = &caps[0];
    assert_eq!(c.id, id);
    assert_eq!((c.fired_at, c.fired_value), (ms(5), 5.0));
    assert_eq!(c.window, (ms(2), ms(7)));
    let values = |i: usize| c.signals[i].samples.iter().map(|x| x.value).collect::<Vec<_>>();
    assert_eq!(values(0), vec![2.0, 3.0, 4.0, 5.0, 6.0, 7.0]);
    // The second signal's samples at t = 2..7 ms (recorded after v in each cycle; the
    // capture completed on v's sample at 7 ms, before safe's sample at 7 ms).
    assert_eq!(values(1), vec![1.0, 1.0, 1.0, 1.0, 0.0]);
    let mut out = Vec::new();
    c.write_csv(&r, &mut out).unwrap();
    let text = String::from_utf8(out).unwrap();
    assert!(text.starts_with("time_s,v (m/s),safe\n0.002000000,2,1\n"), "{text}");
    assert_eq!(text.lines().count(), 7);
}

#[test]
fn level_trigger_with_zero_post_and_limits() {
    let mut r = Recorder::new(8);
    let x = r.register("x", "").unwrap();
    assert_eq!(
        r.arm(Trigger { signal: x, condition: Condition::Below(0.0), pre_samples: 5, post_samples: 3 }),
        Err(TraceError::WindowTooLarge { requested: 8, capacity: 8 })
    );
    let id = r
        .arm(Trigger { signal: x, condition: Condition::Below(0.0), pre_samples: 1, post_samples: 0 })
        .unwrap();
    r.record(x, ms(0), 1.0).unwrap();
    r.record(x, ms(1), -1.0).unwrap();
    let caps = r.take_captures();
    assert_eq!(caps.len(), 1);
    assert_eq!(caps[0].signals[0].samples.len(), 2);
    assert!(!r.disarm(id));
    let id2 = r
        .arm(Trigger { signal: x, condition: Condition::Above(100.0), pre_samples: 0, post_samples: 0 })
        .unwrap();
    assert!(r.disarm(id2));
}

#[test]
fn trace_task_records_at_the_class_cycle() {
    let rec = Arc::new(Mutex::new(Recorder::new(1000)));
    let (sig, cyc) = {
        let mut r = rec.lock().unwrap();
        (r.register("ramp", "").unwrap(), r.register("const", "V").unwrap())
    };
    let mut n = 0.0;
    let task = TraceTask::new("trace", Arc::clone(&rec), Instant::now())
        .probe(
            sig,
            Box::new(move || {
                n += 1.0;
                Some(n)
            }),
        )
        .probe(cyc, Box::new(|| Some(24.0)));
    let sched = Scheduler::start(
        vec![TaskClass::new("t", Duration::from_millis(2)).with_task(Box::new(task))],
        Arc::new(NullAlarms),
    )
    .unwrap();
    std::thread::sleep(Duration::from_millis(100));
    sched.stop();
    let r = rec.lock().unwrap();
    let ramp = r.samples(sig);
    let konst = r.samples(cyc);
    assert!(ramp.len() >= 20, "{}", ramp.len());
    assert_eq!(ramp.len(), konst.len());
    // Values 1, 2, 3... and both signals share each cycle's timestamp.
    for (i, (a, b)) in ramp.iter().zip(&konst).enumerate() {
        assert_eq!(a.value, (i + 1) as f64);
        assert_eq!(a.t, b.t);
        assert_eq!(b.value, 24.0);
    }
    assert!(ramp.windows(2).all(|w| w[1].t > w[0].t));
}
