//! The segment scenario over UDP on 127.0.0.1 (unprivileged): boot-up to OPERATIONAL, the
//! monitor reads all five drives every cycle, quick stop. MOTUS_EPL_SECONDS lengthens the run.
//!
//! Function only: the cycles with a missed node (target 0.1 % at 1 ms; 0.05-0.2 % measured on
//! the 2-core dev machine, more on a loaded host), the MN's jitter and its PReq -> PRes round
//! trips are printed here and measured by `cargo bench -p motus-epl --bench monitor`
//! (`scripts/realtime.sh`), never asserted: a miss is a simulated drive's user-space thread
//! held off the CPU past the PRes time-out, which follows the host's load.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use std::sync::Arc;
use std::time::Duration;

use motus_epl::sim::MnConfig;
use motus_epl::{EthLink, UdpHub};

fn run(label: &str, cycle: Duration, pres_timeout: Duration) {
    let hub = UdpHub::new();
    let mn: Arc<dyn EthLink> = Arc::new(hub.connect().unwrap());
    let cns: Vec<Arc<dyn EthLink>> =
        (0..5).map(|_| Arc::new(hub.connect().unwrap()) as Arc<dyn EthLink>).collect();
    let mon: Arc<dyn EthLink> = Arc::new(hub.connect().unwrap());
    let config = MnConfig { cycle, pres_timeout, ..MnConfig::default() };
    let out = common::run_scenario(label, mn, cns, mon, config, common::seconds(2.0));
    // The MN's own view: PReq unanswered within the time-out (printed, the host's load).
    let polls = out.mn.operational_cycles * 5;
    eprintln!("{label}: MN misses {} of {polls} polls: {:?}", out.mn.total_missed(), out.mn.pres_missed);
    assert!(out.monitored_cycles > 0);
}

#[test]
fn udp_segment_1ms() {
    let _one_at_a_time = common::exclusive();
    // Acceptance: every cycle read, or each miss reported (printed, and listed in a file).
    run("udp 1 ms", Duration::from_millis(1), Duration::from_micros(300));
}

#[test]
fn udp_segment_400us() {
    let _one_at_a_time = common::exclusive();
    // Five sequential PReq/PRes round trips of ~80 us (p99 ~250 us) between user-space threads
    // (specs/powerlink.md §5: expect 100 us-class latency) fill a 400 us cycle: misses and
    // overruns are counted and reported.
    run("udp 400 us", Duration::from_micros(400), Duration::from_micros(150));
}
