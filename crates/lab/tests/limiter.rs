//! The login limiter: per-user and per-address thresholds, growing lock-outs, login flow.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use std::net::{IpAddr, Ipv4Addr, Ipv6Addr};
use std::time::Duration;

use common::*;
use motus_lab::limiter::ip_key;
use motus_lab::{AuditQuery, LimitKey, LimiterPolicy, LoginError, LoginLimiter};

const IP: IpAddr = IpAddr::V4(Ipv4Addr::new(198, 51, 100, 1));

fn ip(n: u8) -> IpAddr {
    IpAddr::V4(Ipv4Addr::new(198, 51, 100, n))
}

#[test]
fn five_failures_lock_the_user_for_five_minutes_then_doubling() {
    let l = LoginLimiter::new(LimiterPolicy::default());
    for k in 0..4 {
        assert!(l.check("alice", IP, at(k * 1000)).is_ok());
        assert_eq!(l.record_failure("alice", IP, at(k * 1000)), None, "failure {k}");
    }
    let locked = l.record_failure("alice", IP, at(4000)).unwrap();
    assert_eq!(locked.key, LimitKey::User("alice".into()));
    assert_eq!(locked.retry_after, Duration::from_secs(300));
    let e = l.check("alice", ip(2), at(4000 + 100_000)).unwrap_err();
    assert_eq!(e.retry_after, Duration::from_secs(200));
    // Other users are not affected.
    assert!(l.check("bob", ip(2), at(5000)).is_ok());
    // Lock-out over at exactly 300 s.
    assert!(l.check("alice", IP, at(4000 + 300_000)).is_ok());
    // Five more failures: 600 s, then 1200 s, 2400 s, 3600 s (cap).
    let mut t = 4000 + 300_000;
    for expected in [600, 1200, 2400, 3600, 3600] {
        let mut last = None;
        for _ in 0..5 {
            last = l.record_failure("alice", IP, at(t));
            t += 1;
        }
        assert_eq!(last.unwrap().retry_after, Duration::from_secs(expected));
        t += i64::try_from(expected).unwrap() * 1000;
    }
}

#[test]
fn failures_outside_the_window_do_not_count() {
    let l = LoginLimiter::new(LimiterPolicy::default());
    for k in 0..4 {
        l.record_failure("alice", ip(k), at(i64::from(k)));
    }
    // The fifth failure comes 300 s after the first ones: the window has slid past them.
    assert_eq!(l.record_failure("alice", IP, at(300_000)), None);
    assert!(l.check("alice", IP, at(300_001)).is_ok());
}

#[test]
fn success_resets_the_user_but_not_the_address() {
    let l = LoginLimiter::new(LimiterPolicy { ip_max_failures: 6, ..LimiterPolicy::default() });
    for k in 0..4 {
        l.record_failure("alice", IP, at(k));
    }
    l.record_success("alice", IP, at(10));
    // Four more user failures are fine again, but the address reaches 6 at the second one.
    assert_eq!(l.record_failure("alice", IP, at(11)), None);
    let locked = l.record_failure("alice", IP, at(12)).unwrap();
    assert_eq!(locked.key, LimitKey::Ip(IP));
}

#[test]
fn address_limit_across_user_names() {
    let l = LoginLimiter::new(LimiterPolicy::default());
    // 20 failures from one address with 20 different names: the address locks.
    let mut locked = None;
    for k in 0..20 {
        locked = l.record_failure(&format!("user{k}"), IP, at(k));
    }
    assert_eq!(locked.unwrap().key, LimitKey::Ip(IP));
    let e = l.check("someone-else", IP, at(100)).unwrap_err();
    assert_eq!(e.key, LimitKey::Ip(IP));
    assert!(l.check("someone-else", ip(9), at(100)).is_ok());
}

#[test]
fn ipv6_grouped_by_64() {
    let a: Ipv6Addr = "2001:db8:1:2:aaaa::1".parse().unwrap();
    let b: Ipv6Addr = "2001:db8:1:2:bbbb::9".parse().unwrap();
    let c: Ipv6Addr = "2001:db8:1:3::1".parse().unwrap();
    assert_eq!(ip_key(IpAddr::V6(a)), ip_key(IpAddr::V6(b)));
    assert_ne!(ip_key(IpAddr::V6(a)), ip_key(IpAddr::V6(c)));
    assert_eq!(ip_key(IpAddr::V6(a)), IpAddr::V6("2001:db8:1:2::".parse().unwrap()));
    let mapped: Ipv6Addr = "::ffff:198.51.100.1".parse().unwrap();
    assert_eq!(ip_key(IpAddr::V6(mapped)), IP);
}

#[test]
fn prune_forgets_stale_keys() {
    let l = LoginLimiter::new(LimiterPolicy::default());
    l.record_failure("alice", IP, at(0));
    assert_eq!(l.prune(at(1000)), 2);
    assert_eq!(l.prune(at(3600 * 1000)), 0);
}

#[test]
fn login_is_rate_limited_and_audited() {
    for (name, lab) in labs() {
        for k in 0..4 {
            assert!(
                matches!(lab.login("alice", "wrong", IP, at(k)), Err(LoginError::BadCredentials)),
                "{name}"
            );
        }
        assert!(matches!(lab.login("alice", "wrong", IP, at(4)), Err(LoginError::BadCredentials)));
        // Now even the right password is refused without being checked.
        match lab.login("alice", "password-alice", IP, at(5)) {
            Err(LoginError::RateLimited(r)) => assert_eq!(r.retry_after, Duration::from_millis(300_000 - 1)),
            other => panic!("{name}: {other:?}"),
        }
        // Unknown names are limited the same way (no hint that the name does not exist).
        assert!(matches!(lab.login("nobody", "x", ip(3), at(6)), Err(LoginError::BadCredentials)));
        assert!(lab.login("alice", "password-alice", IP, at(4 + 300_000)).is_ok());
        let log = lab
            .audit()
            .query(&AuditQuery { action_prefix: Some("login".into()), ..AuditQuery::default() })
            .unwrap();
        let kinds: Vec<&str> = log.iter().rev().map(|r| r.entry.outcome.kind()).collect();
        assert_eq!(
            kinds,
            ["denied", "denied", "denied", "denied", "denied", "denied", "denied", "ok"],
            "{name}"
        );
        assert!(log[2].entry.outcome.message().contains("too many failed logins"), "{:?}", log[2]);
        assert_eq!(log[0].entry.target, "198.51.100.1");
    }
}

#[test]
fn reserved_attempts_count_as_failures_until_settled() {
    let l = LoginLimiter::new(LimiterPolicy::default());
    // Five reservations in flight: the fifth starts the lock-out, the sixth is refused.
    let attempts: Vec<_> = (0..5).map(|k| l.reserve("alice", IP, at(k)).unwrap()).collect();
    assert!(attempts[..4].iter().all(|a| a.lockout().is_none()));
    let lock = attempts[4].lockout().unwrap().clone();
    assert_eq!(lock.key, LimitKey::User("alice".into()));
    assert_eq!(lock.retry_after, Duration::from_secs(300));
    let e = l.reserve("alice", ip(2), at(10)).unwrap_err();
    assert_eq!(e.key, LimitKey::User("alice".into()));
    // The fifth was not checked after all (busy): its failure and lock-out are given back.
    let mut attempts = attempts;
    let fifth = attempts.pop().unwrap();
    l.release(fifth);
    assert!(l.check("alice", IP, at(11)).is_ok());
    // A new attempt takes its place and locks again; failing keeps the lock.
    let again = l.reserve("alice", IP, at(12)).unwrap();
    let locked = l.failed(again).unwrap();
    assert_eq!(locked.retry_after, Duration::from_secs(300));
    for a in attempts {
        assert_eq!(l.failed(a), None);
    }
    assert!(l.reserve("alice", IP, at(13)).is_err());
    assert!(l.reserve("alice", IP, at(12 + 300_000)).is_ok());
}

#[test]
fn a_reserved_success_gives_the_address_failure_back() {
    let l = LoginLimiter::new(LimiterPolicy { ip_max_failures: 3, ..LimiterPolicy::default() });
    // Many successful logins from one address never lock it.
    for k in 0..10 {
        let a = l.reserve(&format!("user{k}"), IP, at(k)).unwrap();
        l.succeeded(a);
    }
    assert!(l.check("anyone", IP, at(20)).is_ok());
    // A success also clears the user name (as record_success).
    for k in 0..2 {
        assert_eq!(l.failed(l.reserve("alice", ip(k), at(30)).unwrap()), None);
    }
    l.succeeded(l.reserve("alice", ip(7), at(31)).unwrap());
    for k in 0..4 {
        assert_eq!(l.failed(l.reserve("alice", ip(10 + k), at(40)).unwrap()), None, "{k}");
    }
    // Three failures from one address lock it.
    let mut last = None;
    for k in 0..3 {
        last = l.failed(l.reserve(&format!("x{k}"), ip(50), at(50)).unwrap());
    }
    assert_eq!(last.unwrap().key, LimitKey::Ip(ip(50)));
    assert_eq!(l.reserve("bob", ip(50), at(51)).unwrap_err().key, LimitKey::Ip(ip(50)));
}
