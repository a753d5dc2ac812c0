//! Concurrent logins: attempts are reserved before the password is checked, and the
//! password checks run on a bounded pool that refuses at once when it is full.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use std::net::{IpAddr, Ipv4Addr};
use std::sync::mpsc;
use std::sync::{Arc, Barrier};
use std::thread;
use std::time::Duration;

use common::*;
use motus_lab::{AuditQuery, Lab, LabConfig, LimitKey, LoginError, Role, Store};

/// Generous: only guards against a hang.
const LIVENESS: Duration = Duration::from_secs(60);

fn ip(n: u8) -> IpAddr {
    IpAddr::V4(Ipv4Addr::new(198, 51, 100, n))
}

fn lab(store: Arc<dyn Store>, tweak: impl FnOnce(&mut LabConfig)) -> Arc<Lab> {
    let mut c = config();
    tweak(&mut c);
    let lab = Lab::new(store, c);
    for (name, role) in [("admin", Role::Admin), ("alice", Role::Student), ("bob", Role::Student)] {
        lab.users().add(name, &format!("password-{name}"), role, T0).unwrap();
    }
    Arc::new(lab)
}

/// `n` logins at once from threads (released together by a barrier), in order of `n`.
fn burst(
    lab: &Arc<Lab>,
    n: usize,
    login: impl Fn(usize) -> (String, String, IpAddr),
) -> Vec<Result<(), LoginError>> {
    let barrier = Arc::new(Barrier::new(n));
    let handles: Vec<_> = (0..n)
        .map(|k| {
            let (user, password, addr) = login(k);
            let (lab, barrier) = (Arc::clone(lab), Arc::clone(&barrier));
            thread::spawn(move || {
                barrier.wait();
                lab.login(&user, &password, addr, at(0)).map(|_| ())
            })
        })
        .collect();
    handles.into_iter().map(|h| h.join().unwrap()).collect()
}

fn count(results: &[Result<(), LoginError>], what: fn(&Result<(), LoginError>) -> bool) -> usize {
    results.iter().filter(|r| what(r)).count()
}

#[test]
fn concurrent_wrong_passwords_for_one_user_check_at_most_the_limit() {
    for (name, store) in stores() {
        let lab = lab(store, |_| {});
        let max = usize::try_from(lab.limiter().policy().user_max_failures).unwrap();
        let results = burst(&lab, 40, |_| ("alice".into(), "wrong password".into(), ip(1)));
        let bad = count(&results, |r| matches!(r, Err(LoginError::BadCredentials)));
        let limited = count(
            &results,
            |r| matches!(r, Err(LoginError::RateLimited(l)) if l.key == LimitKey::User("alice".into())),
        );
        assert_eq!(bad + limited, 40, "{name}: {results:?}");
        // The reservations before the checks let exactly `max` attempts through.
        assert_eq!(bad, max, "{name}");
        assert_eq!(lab.users().verifications(), u64::try_from(max).unwrap(), "{name}");
        let log = lab
            .audit()
            .query(&AuditQuery { action_prefix: Some("login".into()), ..AuditQuery::default() })
            .unwrap();
        assert_eq!(log.len(), 40, "{name}");
        assert!(log.iter().all(|r| r.entry.outcome.kind() == "denied"), "{name}");

        // Another user's right password from the same address still works; alice's does
        // not until her lock-out is over.
        assert!(lab.login("bob", "password-bob", ip(1), at(1)).is_ok(), "{name}");
        assert!(matches!(
            lab.login("alice", "password-alice", ip(1), at(2)),
            Err(LoginError::RateLimited(_))
        ));
        assert!(lab.login("alice", "password-alice", ip(1), at(300_000)).is_ok(), "{name}");
        assert_eq!(lab.users().verifications(), u64::try_from(max).unwrap() + 2, "{name}");
    }
}

#[test]
fn concurrent_wrong_logins_from_one_address_check_at_most_its_limit() {
    let (_, store) = stores().remove(0);
    // Room for every check at once, so that none is refused as busy.
    let lab = lab(store, |c| c.password.hash_queue = 64);
    let max = usize::try_from(lab.limiter().policy().ip_max_failures).unwrap();
    // Unknown names: the dummy hash is checked for them (same time as a known name).
    let results = burst(&lab, 2 * max, |k| (format!("nobody{k}"), "wrong password".into(), ip(9)));
    let bad = count(&results, |r| matches!(r, Err(LoginError::BadCredentials)));
    let limited =
        count(&results, |r| matches!(r, Err(LoginError::RateLimited(l)) if l.key == LimitKey::Ip(ip(9))));
    assert_eq!((bad, limited), (max, max), "{results:?}");
    assert_eq!(lab.users().verifications(), u64::try_from(max).unwrap());
    // Another address is not affected.
    assert!(lab.login("alice", "password-alice", ip(10), at(1)).is_ok());
}

/// Occupies the lab's only hashing worker until the returned sender is dropped or used.
fn occupy_the_worker(lab: &Arc<Lab>) -> (mpsc::Sender<()>, thread::JoinHandle<()>) {
    let (started_tx, started_rx) = mpsc::channel();
    let (release_tx, release_rx) = mpsc::channel::<()>();
    let l = Arc::clone(lab);
    let handle = thread::spawn(move || {
        l.users()
            .hash_pool()
            .try_run(move || {
                started_tx.send(()).unwrap();
                let _ = release_rx.recv();
            })
            .unwrap();
    });
    started_rx.recv_timeout(LIVENESS).unwrap();
    (release_tx, handle)
}

#[test]
fn a_full_pool_answers_busy_at_once_and_everyone_is_answered() {
    for (name, store) in stores() {
        let lab = lab(store, |c| {
            c.password.hash_workers = 1;
            c.password.hash_queue = 1;
        });
        const N: usize = 16;
        for k in 0..N {
            lab.users().add(&format!("user{k}"), &format!("password-user{k}"), Role::Student, T0).unwrap();
        }
        let (release, worker) = occupy_the_worker(&lab);
        // A burst of logins of different users while the worker is busy: one fits in the
        // queue (and waits), every other one is answered busy without waiting for the pool.
        let (done_tx, done_rx) = mpsc::channel();
        let barrier = Arc::new(Barrier::new(N));
        for k in 0..N {
            let (lab, barrier, done) = (Arc::clone(&lab), Arc::clone(&barrier), done_tx.clone());
            thread::spawn(move || {
                barrier.wait();
                let u = format!("user{k}");
                let r = lab.login(&u, &format!("password-{u}"), ip(u8::try_from(k).unwrap()), at(0));
                done.send((k, r.map(|_| ()))).unwrap();
            });
        }
        let mut busy = Vec::new();
        for _ in 0..N - 1 {
            let (k, r) = done_rx.recv_timeout(LIVENESS).expect("busy answers come while the worker is held");
            assert!(matches!(r, Err(LoginError::Busy)), "{name}: user{k}: {r:?}");
            busy.push(k);
        }
        assert_eq!(lab.users().verifications(), 0, "{name}: nothing checked yet");
        // Release the worker: the queued login completes.
        release.send(()).unwrap();
        worker.join().unwrap();
        let (k, r) = done_rx.recv_timeout(LIVENESS).unwrap();
        assert!(r.is_ok(), "{name}: user{k}: {r:?}");
        assert!(!busy.contains(&k));
        assert_eq!(lab.users().verifications(), 1, "{name}");
        assert_eq!(lab.users().hash_pool().rejected(), u64::try_from(N - 1).unwrap(), "{name}");
        // The refused ones were audited and can log in now.
        let log = lab
            .audit()
            .query(&AuditQuery {
                action_prefix: Some("login".into()),
                outcome: Some("denied".into()),
                ..AuditQuery::default()
            })
            .unwrap();
        assert_eq!(log.len(), N - 1, "{name}");
        assert!(log.iter().all(|r| r.entry.outcome.message().contains("busy")), "{name}");
        for k in busy {
            let u = format!("user{k}");
            assert!(lab.login(&u, &format!("password-{u}"), ip(200), at(1)).is_ok(), "{name}: {u}");
        }
    }
}

#[test]
fn busy_logins_are_not_counted_as_failures() {
    let (_, store) = stores().remove(0);
    let lab = lab(store, |c| {
        c.password.hash_workers = 1;
        c.password.hash_queue = 0;
    });
    let (release, worker) = occupy_the_worker(&lab);
    // Twice the user limit, with the wrong password even: refused as busy, nothing checked.
    for k in 0..10 {
        assert!(matches!(lab.login("alice", "wrong password", ip(1), at(k)), Err(LoginError::Busy)), "{k}");
    }
    release.send(()).unwrap();
    worker.join().unwrap();
    assert_eq!(lab.users().verifications(), 0);
    assert!(lab.login("alice", "password-alice", ip(1), at(20)).is_ok());
}
