//! The segment scenario over UDP on 127.0.0.1 (unprivileged): boot-up to OPERATIONAL, the
//! monitor reads all five drives every cycle, quick stop. MOTUS_EPL_SECONDS lengthens the run.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use std::sync::Arc;
use std::time::Duration;

use motus_epl::sim::MnConfig;
use motus_epl::{EthLink, UdpHub};

fn run(label: &str, cycle: Duration, pres_timeout: Duration, max_miss: f64) {
    let hub = UdpHub::new();
    let mn: Arc<dyn EthLink> = Arc::new(hub.connect().unwrap());
    let cns: Vec<Arc<dyn EthLink>> =
        (0..5).map(|_| Arc::new(hub.connect().unwrap()) as Arc<dyn EthLink>).collect();
    let mon: Arc<dyn EthLink> = Arc::new(hub.connect().unwrap());
    let config = MnConfig { cycle, pres_timeout, ..MnConfig::default() };
    let max_miss = common::max_miss(max_miss);
    let out = common::run_scenario(label, mn, cns, mon, config, max_miss);
    // The MN's own view: PReq unanswered within the time-out stay below the same limit.
    let polls = out.mn.operational_cycles * 5;
    assert!(
        (out.mn.total_missed() as f64) < max_miss * polls as f64,
        "{label}: MN misses {:?}",
        out.mn.pres_missed
    );
    assert!(out.monitored_cycles > 0);
}

#[test]
fn udp_segment_1ms() {
    let _one_at_a_time = common::exclusive();
    // Acceptance: every cycle read, or each miss reported (printed, and listed in a file).
    // A miss here is a simulated drive's user-space thread held off the CPU past the 300 us
    // PRes time-out, so the fraction follows the host's load: 0.05-0.2 % on the 2-core dev
    // machine while other crates compiled, 0.53 % on a shared CI host whose MN thread itself
    // overran 132 times in 4,859 cycles. The assertion (2 %) catches a broken segment (a node
    // that stops answering is 20 % of polls, a stale-age error 100 %), not the host's load;
    // MOTUS_EPL_MAX_MISS=0.001 applies the 0.1 % target on a quiet machine.
    run("udp 1 ms", Duration::from_millis(1), Duration::from_micros(300), 0.02);
}

#[test]
fn udp_segment_400us() {
    let _one_at_a_time = common::exclusive();
    // Five sequential PReq/PRes round trips of ~80 us (p99 ~250 us) between user-space threads
    // (specs/powerlink.md §5: expect 100 us-class latency) fill a 400 us cycle, so the limit
    // here is 5 %; overruns are counted and reported, not asserted.
    run("udp 400 us", Duration::from_micros(400), Duration::from_micros(150), 0.05);
}
