#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
//! Offline trace evaluation of the shipped example (figures in the CSV's comments,
//! computed by hand: reach of an arm at 20 000 units/s with H = 10.4 ms is
//! 208 + 27.04 + 25200^2/3.2e6 = 433.49 above its position).

use motus_safety::trace::{evaluate, format_rows, TraceError};
use motus_safety::*;

const TRACE: &str = include_str!("../examples/juggler-stop.csv");

#[test]
fn example_trace_stops_at_the_expected_row() {
    let rules = RuleSet::from_toml(JUGGLER_TOML).unwrap();
    let rows = evaluate(&rules, TRACE).unwrap();
    assert_eq!(rows.len(), 14);
    let first_stop = rows.iter().position(|r| !r.safe_to_run).unwrap();
    assert_eq!(first_stop, 9);
    assert_eq!(rows[9].time, 0.0036);
    assert!(rows[..9].iter().all(|r| r.safe_to_run && r.interlocks == vec![true]));
    let d = rows[9].diagnosis.as_deref().unwrap();
    assert!(
        d.starts_with("rule arms_pass failed: collision(vertical_left, vertical_right) margin -691.4"),
        "{d}"
    );
    assert!(
        d.contains("region(arm_left, 380.0, 1000.0) margin -5.5 [arm_left at -48.0, reach -48.0..385.5]"),
        "{d}"
    );
    // Deterministic output.
    let a = format_rows(&rules, &rows);
    assert_eq!(a, format_rows(&rules, &evaluate(&rules, TRACE).unwrap()));
    assert!(a.starts_with("time,safe_to_run,feeder_enable,diagnosis\n0,1,1,\"\"\n"), "{a}");
}

#[test]
fn trace_errors() {
    let rules = RuleSet::from_toml(JUGGLER_TOML).unwrap();
    assert_eq!(evaluate(&rules, "# only a comment\n"), Err(TraceError::NoHeader));
    let hdr = TRACE.lines().find(|l| l.starts_with("time")).unwrap();
    assert_eq!(
        evaluate(&rules, &hdr.replace(",thrower.speed", "")),
        Err(TraceError::MissingColumn("thrower.speed".into()))
    );
    assert_eq!(
        evaluate(&rules, &format!("{hdr},arm_left.torque")),
        Err(TraceError::Column("arm_left.torque".into()))
    );
    let bad = format!("{hdr}\n0,x,0,0,0,0,0,0,0,0,0\n");
    assert!(matches!(evaluate(&rules, &bad), Err(TraceError::Value { line: 2, .. })));
    let back = format!("{hdr}\n0.1,0,0,0,0,0,0,0,0,0,0\n0.1,0,0,0,0,0,0,0,0,0,0\n");
    assert!(matches!(evaluate(&rules, &back), Err(TraceError::Time { line: 3, .. })));
    // Stale: a sample that is not renewed for 4 cycles.
    let stale = format!(
        "{hdr},arm_left.homed\n0,-500,0,1000,0,-500,0,10000,0,-7100,0,1\n0.0016,,,1000,0,-500,0,10000,0,-7100,0,1\n"
    );
    let rows = evaluate(&rules, &stale).unwrap();
    assert!(rows[0].safe_to_run);
    assert_eq!(rows[1].diagnosis.as_deref(), Some("axis arm_left: data 4 cycles old (max 3)"));
}
