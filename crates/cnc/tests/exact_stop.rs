//! A rapid move followed by an external-parameter write and a synchronous M-function must
//! decelerate to an exact stop within the acceleration limit (regression: the marker between
//! them once let the path arrive at full speed).
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
use motus_cnc_planner::*;
#[test]
fn rapid_then_sync_m_decelerates() {
    for with_ext in [false, true] {
        let l = AxisLimits { velocity: 200.0, acceleration: 2000.0 };
        let mut ex = Executor::<3>::new(Config::new([l, l, l]), [0.0; 3]).unwrap();
        ex.push(1, PathItem::Motion(Segment::Line { end: [100.0, 100.0, 0.0], feed: 5.0, rapid: true }))
            .unwrap();
        if with_ext {
            ex.push(2, PathItem::ExternalParameter { array: ExArray::W, index: 60, value: 3600.0 }).unwrap();
        }
        ex.push(3, PathItem::MFunction { number: 60, sync: true }).unwrap();
        ex.finish();
        let mut prev = [0.0; 3];
        let mut worst: f64 = 0.0;
        for _ in 0..5000 {
            let sp = ex.tick(0.001);
            worst = worst.max((sp.velocities[0] - prev[0]).abs() / 0.001);
            prev = sp.velocities;
            while let Some(e) = ex.poll_event() {
                if let Event::MFunction { number, .. } = e {
                    ex.acknowledge(number);
                }
            }
        }
        eprintln!("with_ext {with_ext}: worst acceleration {worst}");
        assert!(worst <= 2000.0 * 1.001, "with_ext {with_ext}: {worst}");
    }
}
