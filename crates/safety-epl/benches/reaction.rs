//! The supervisor's reaction to an unsafe PRes.
//!
//! * CPU part (criterion, then 20,000 timed events): a PRes that makes the juggler unsafe,
//!   from its bytes to the encoded revoke handed to the link (a link that drops frames, so no
//!   syscall is timed), and a PRes that keeps it safe (evaluation plus a rate-limited
//!   renewal). Target: well below the 1 ms reaction budget (and the 5 us evaluation target of
//!   the supervisor bench).
//! * On a real kernel data path (veth in network namespaces; needs root, skipped otherwise):
//!   10,000 unsafe events (`MOTUS_REACTION_EVENTS`), the scenario of `tests/veth_reaction.rs`
//!   (`tests/common/mod.rs`): p99 inside Motus, from the PRes received to the revoke's `send`
//!   returned, against the 1 ms target.
//!
//! The figures are printed as `REALTIME <name> <value> <unit>` lines (`REALTIME-SKIP <name>
//! <reason>` for a measurement that cannot run here) for `scripts/realtime.sh`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic, missing_docs)]

#[path = "../tests/common/mod.rs"]
mod common;

use std::hint::black_box;
use std::io;
use std::sync::Arc;
use std::time::{Duration, Instant};

use criterion::Criterion;
use motus_epl::sim::Percentiles;
use motus_epl::EthLink;
use motus_epl_protocol::{EplFrame, Flags, MacAddr, Message, NmtState, PRes, PrRs, Soc, ValueMap};
use motus_safety::{RuleSet, JUGGLER_TOML};
use motus_safety_epl::{EplLeaseTarget, InputMap, OnlineConfig, OnlineSupervisor};

struct NullLink;
impl EthLink for NullLink {
    fn send(&self, _frame: &[u8]) -> io::Result<()> {
        Ok(())
    }
    fn recv(&self, _buf: &mut [u8], _timeout: Duration) -> io::Result<Option<(usize, Instant)>> {
        Ok(None)
    }
    fn mac(&self) -> MacAddr {
        MacAddr([2, 0, 0, 0, 0, 1])
    }
    fn describe(&self) -> String {
        "null".into()
    }
}

fn pres(node: u8, position: i32) -> Vec<u8> {
    let mut payload = vec![0u8; 24];
    payload[0] = 0x11;
    payload[16..20].copy_from_slice(&position.to_le_bytes());
    let m = Message::PRes(PRes {
        nmt_state: NmtState::Operational,
        flags: Flags::RD,
        pr_rs: PrRs::default(),
        pdo_version: 0,
        payload,
        reserved: 0,
    });
    EplFrame::new(MacAddr([2, 0, 0, 0, 0, node]), MacAddr::BROADCAST, 255, node, m).encode().unwrap()
}

fn cpu_part(c: &mut Criterion) {
    let rules = RuleSet::from_toml(JUGGLER_TOML).unwrap();
    let mut text = String::new();
    for n in 1..=5 {
        text.push_str(&format!("[[node]]\nnode = {n}\nvalues = [{{ name = \"status\", offset = 0, type = \"u16\" }}, {{ name = \"position\", offset = 16, type = \"i32\" }}, {{ name = \"speed\", offset = 20, type = \"i32\" }}]\n"));
    }
    let inputs = InputMap::new(&rules, ValueMap::from_toml(&text).unwrap(), 0x10).unwrap();
    let origin = Instant::now();
    let link: Arc<dyn EthLink> = Arc::new(NullLink);
    let target =
        EplLeaseTarget::new(link, origin, Duration::from_millis(5), Duration::from_micros(400), [0; 8]);
    let mut sup = OnlineSupervisor::new(
        rules,
        inputs,
        vec![Box::new(target)],
        origin,
        OnlineConfig { restart: motus_safety::Restart::Automatic, ..OnlineConfig::default() },
    );
    sup.set_integrity(Ok(()));
    let safe_positions = [-500, 1000, -500, 10_000, -71_000];
    let soc = EplFrame::new(
        MacAddr([2, 0, 0, 0, 0, 0xf0]),
        MacAddr::BROADCAST,
        255,
        240,
        Message::Soc(Soc {
            flags: Flags::empty(),
            net_time: Default::default(),
            relative_time: 0,
            reserved1: 0,
            reserved2: 0,
        }),
    )
    .encode()
    .unwrap();
    let safe: Vec<Vec<u8>> = (1..=5u8).zip(safe_positions).map(|(n, p)| pres(n, p)).collect();
    let unsafe_thrower = pres(5, 35_000); // 3500 units: beyond the thrower's 3400 limit
    let feed_safe = |sup: &mut OnlineSupervisor| {
        sup.on_frame(&soc, Instant::now());
        for f in &safe {
            sup.on_frame(f, Instant::now());
        }
    };
    feed_safe(&mut sup);
    c.bench_function("online: PRes -> unsafe -> revoke sent (juggler)", |b| {
        b.iter_custom(|iters| {
            let mut total = Duration::ZERO;
            for _ in 0..iters {
                feed_safe(&mut sup);
                let t = Instant::now();
                black_box(sup.on_frame(black_box(&unsafe_thrower), t));
                total += t.elapsed();
            }
            total
        })
    });
    feed_safe(&mut sup);
    let f = &safe[4];
    c.bench_function("online: PRes -> still safe (juggler)", |b| {
        b.iter(|| black_box(sup.on_frame(black_box(f), Instant::now())))
    });

    // The same unsafe event timed one by one: its percentiles.
    let mut samples = Vec::with_capacity(20_000);
    for _ in 0..20_000 {
        feed_safe(&mut sup);
        let t = Instant::now();
        black_box(sup.on_frame(black_box(&unsafe_thrower), t));
        samples.push(u64::try_from(t.elapsed().as_nanos()).unwrap_or(u64::MAX));
    }
    let p = Percentiles::of(&samples);
    println!(
        "CPU part, PRes -> unsafe -> revoke handed to the link, {} events: p50 {} ns, p99 {} ns, max {} ns",
        p.count, p.p50, p.p99, p.max
    );
    println!("REALTIME reaction.cpu.p50 {} ns", p.p50);
    println!("REALTIME reaction.cpu.p99 {} ns", p.p99);
}

/// The reaction on veth (root only): 10,000 unsafe events by default.
fn on_veth() {
    if !motus_epl::netns::is_root() {
        println!("reaction on veth: skipped, network namespaces and veth need root");
        println!("REALTIME-SKIP reaction.veth not root");
        return;
    }
    let events = std::env::var("MOTUS_REACTION_EVENTS").ok().and_then(|s| s.parse().ok()).unwrap_or(10_000);
    let r = common::run(events);
    println!("{}", r.summary());
    // A run whose events were not all answered one by one measured nothing: fail loudly.
    r.check();
    let us = |ns: u64| ns as f64 / 1000.0;
    println!("REALTIME reaction.veth.inside.p50 {:.1} us", us(r.inside.p50));
    println!("REALTIME reaction.veth.inside.p99 {:.1} us", us(r.inside.p99));
    println!("REALTIME reaction.veth.inside.max {:.1} us", us(r.inside.max));
    println!("REALTIME reaction.veth.e2e.p99 {:.1} us", us(r.end_to_end.p99));
    println!("REALTIME reaction.veth.expiries {} events", r.expiries);
}

fn main() {
    // Scheduling as the binary's `--realtime` sets it: MOTUS_REALTIME (auto, nice, off).
    if let Some(obtained) = motus_realtime::set_policy_from_env().unwrap() {
        println!("real-time: {obtained}; {}", motus_realtime::wake_latency::hold_if_fifo());
    }
    let mut c = Criterion::default().configure_from_args();
    cpu_part(&mut c);
    c.final_summary();
    on_veth();
}
