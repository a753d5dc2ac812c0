#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
//! An E-stop reset answers once the juggler's supervisor has applied it and decided: right
//! after `POST /api/reset` the demo station never shows the supervisor's hold without the
//! E-stop (which reads as a trip, raises the `safe_to_run_false` alarm and shows the last
//! trip's stale reason).

mod common;

use std::time::Duration;

use common::{safety, station, wait_safe, Client};
use serde_json::Value;

#[test]
fn after_an_estop_reset_the_juggler_is_safe_again_at_once() {
    let st = station();
    let admin = Client::login(&st.addr, "admin", "admin-password-1");
    wait_safe(&admin, Duration::from_secs(30));
    for press in 0..10 {
        admin.ok("POST", "/api/estop", Value::Null);
        let held = safety(&admin);
        assert_eq!(
            (held["estop"].as_bool(), held["safe_to_run"].as_bool()),
            (Some(true), Some(false)),
            "{held}"
        );
        admin.ok("POST", "/api/reset", Value::Null);
        let s = safety(&admin);
        assert_eq!(s["estop"], false, "press {press}: {s}");
        assert_eq!(s["safe_to_run"], true, "press {press}: the supervisor's hold outlived the reset: {s}");
    }
}
