//! CPU part of the reaction: a PRes that makes the juggler unsafe, from its bytes to the
//! encoded revoke handed to the link (a link that drops frames, so no syscall is timed), and a
//! PRes that keeps it safe (evaluation plus a rate-limited renewal). Target: well below the
//! 1 ms reaction budget (and the 5 us evaluation target of the supervisor bench).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, missing_docs)]

use std::hint::black_box;
use std::io;
use std::sync::Arc;
use std::time::{Duration, Instant};

use criterion::{criterion_group, criterion_main, Criterion};
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

fn bench(c: &mut Criterion) {
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
}

criterion_group!(benches, bench);
criterion_main!(benches);
