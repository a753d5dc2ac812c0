//! Throughput of the per-request work of the web layer: session lookup and authorisation.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use std::hint::black_box;
use std::net::{IpAddr, Ipv4Addr};
use std::sync::Arc;

use criterion::{criterion_group, criterion_main, Criterion};
use motus_lab::{
    Action, AxisOp, Command, HashParams, Lab, LabConfig, MemoryStore, MotionDemand, MotionLimits, Role,
    SqliteStore, Store, UnixMs,
};

const T0: UnixMs = UnixMs(1_893_456_000_000);

fn lab(store: Arc<dyn Store>) -> (Lab, String) {
    let mut c = LabConfig::default();
    c.password.hash = HashParams { memory_kib: 64, iterations: 1, parallelism: 1 };
    c.student_limits.default = Some(MotionLimits::new(1.0, 10.0));
    let lab = Lab::new(store, c);
    lab.users().add("admin", "admin-password", Role::Admin, T0).unwrap();
    lab.users().add("alice", "alice-password", Role::Student, T0).unwrap();
    let admin = motus_lab::Actor::new("admin", Role::Admin);
    lab.reservations().book(&admin, "st1", "alice", T0, UnixMs(T0.0 + 3_600_000), T0).unwrap();
    let ok = lab.login("alice", "alice-password", IpAddr::V4(Ipv4Addr::LOCALHOST), T0).unwrap();
    (lab, ok.session.token)
}

fn bench(c: &mut Criterion) {
    let action = Action::Command {
        station: "st1".into(),
        command: Command::Axis {
            axis: "x".into(),
            op: AxisOp::Move,
            demand: Some(MotionDemand::new(0.5, 5.0)),
        },
    };
    let stores: [(&str, Arc<dyn Store>); 2] = [
        ("memory", Arc::new(MemoryStore::new())),
        ("sqlite", Arc::new(SqliteStore::open_in_memory().unwrap())),
    ];
    for (name, store) in stores {
        let (lab, token) = lab(store);
        let now = UnixMs(T0.0 + 1_000);
        c.bench_function(&format!("{name}/session_lookup+authorize"), |b| {
            b.iter(|| {
                let s = lab.sessions().lookup(black_box(&token), now).unwrap();
                lab.authorizer().authorize(&s.user, s.role, black_box(&action), now).unwrap();
            });
        });
        c.bench_function(&format!("{name}/authorize_student_command"), |b| {
            b.iter(|| lab.authorizer().authorize("alice", Role::Student, black_box(&action), now).unwrap());
        });
    }
    let admin = motus_lab::Actor::new("admin", Role::Admin);
    let limits = motus_lab::StudentLimits::default();
    c.bench_function("decide_pure_admin", |b| {
        b.iter(|| {
            motus_lab::decide(&admin, black_box(&action), motus_lab::Facts::default(), &limits).unwrap()
        });
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
