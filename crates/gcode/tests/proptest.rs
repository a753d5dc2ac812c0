//! Property tests: the interpreter never panics on arbitrary text, and the full-precision
//! text of every numeric argument reads back to the same f64.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_gcode::{format_canon, interpret_with, Canon, InterpreterConfig, Precision};
use proptest::prelude::*;

fn cfg() -> InterpreterConfig {
    InterpreterConfig { max_steps: 10_000, ..InterpreterConfig::default() }
}

proptest! {
    #[test]
    fn never_panics_on_arbitrary_text(s in "\\PC{0,200}") {
        let _ = interpret_with(&s, cfg());
    }

    #[test]
    fn never_panics_on_gcode_like_text(s in "([GMXYZIJKRFPSNO#\\[\\]<>=+\\-*/. 0-9a-z()\n]){0,300}") {
        let _ = interpret_with(&s, cfg());
    }

    #[test]
    fn full_precision_round_trips(x in -1e6f64..1e6, y in -1e6f64..1e6) {
        let src = format!("G1 X{x} Y{y} F100\nM2\n");
        let calls = interpret_with(&src, cfg()).unwrap();
        let feed = calls.iter().find(|c| matches!(c.canon, Canon::StraightFeed { .. })).unwrap();
        let t = format_canon(&feed.canon, Precision::Full);
        let inner = &t["STRAIGHT_FEED(".len()..t.len() - 1];
        let v: Vec<f64> = inner.split(", ").map(|a| a.parse().unwrap()).collect();
        prop_assert_eq!(v[0], x);
        prop_assert_eq!(v[1], y);
    }
}
