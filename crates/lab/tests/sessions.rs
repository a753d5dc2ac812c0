//! Sessions: creation, lookup, idle and absolute expiry, logout, admin ending, CSRF, cookies.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use std::net::{IpAddr, Ipv4Addr};
use std::time::Duration;

use common::*;
use motus_lab::session::{constant_time_eq, token_hash, ExpiryKind};
use motus_lab::{Actor, CookieConfig, LoginError, Role, SessionError};

const IP: IpAddr = IpAddr::V4(Ipv4Addr::new(192, 0, 2, 7));

#[test]
fn login_lookup_and_token_format() {
    for (name, lab) in labs() {
        let ok = lab.login("alice", "password-alice", IP, T0).unwrap();
        let s = &ok.session;
        assert_eq!(s.token.len(), 64, "{name}");
        assert!(s.token.chars().all(|c| c.is_ascii_hexdigit()));
        assert_eq!(s.csrf_token.len(), 64);
        assert_ne!(s.token, s.csrf_token);
        // Only the hash is stored.
        let stored = lab.sessions().list(Some("alice")).unwrap();
        assert_eq!(stored.len(), 1);
        assert_eq!(stored[0].token_hash, token_hash(&s.token));
        assert_ne!(stored[0].token_hash, s.token);
        assert_eq!(stored[0].source.as_deref(), Some("192.0.2.7"));
        let info = lab.sessions().lookup(&s.token, at(1000)).unwrap();
        assert_eq!((info.user.as_str(), info.role), ("alice", Role::Student));
        assert_eq!(info.csrf_token, s.csrf_token);
        assert_eq!(info.absolute_expires, at(12 * HOUR));
        assert!(matches!(lab.sessions().lookup("00", at(1000)), Err(SessionError::Unknown)));
        // A second login gives another token.
        let ok2 = lab.login("alice", "password-alice", IP, T0).unwrap();
        assert_ne!(ok2.session.token, s.token);
    }
}

#[test]
fn sha256_of_token_matches_independent_value() {
    // python3 -c "import hashlib; print(hashlib.sha256(b'abc').hexdigest())"
    assert_eq!(token_hash("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
}

#[test]
fn idle_expiry_with_touches() {
    for (name, lab) in labs() {
        let tok = lab.login("alice", "password-alice", IP, T0).unwrap().session.token;
        // Idle timeout 30 min, touch interval 60 s. Use it every 20 min: stays alive.
        for k in 1..=5 {
            let info = lab.sessions().lookup(&tok, at(k * 20 * MIN)).unwrap();
            assert_eq!(info.idle_expires, at(k * 20 * MIN + 30 * MIN), "{name} k={k}");
        }
        // Last write at 100 min; 130 min - 1 ms is still inside the idle timeout, and this
        // use is written (more than the 60 s touch interval later).
        let info = lab.sessions().lookup(&tok, at(130 * MIN - 1)).unwrap();
        assert_eq!(info.idle_expires, at(160 * MIN - 1));
        // Idle 30 min exactly: expired and deleted.
        assert!(
            matches!(
                lab.sessions().lookup(&tok, at(160 * MIN - 1)),
                Err(SessionError::Expired(ExpiryKind::Idle))
            ),
            "{name}"
        );
        assert!(matches!(lab.sessions().lookup(&tok, at(160 * MIN)), Err(SessionError::Unknown)));
    }
}

#[test]
fn touch_interval_limits_writes() {
    for (name, lab) in labs() {
        let tok = lab.login("alice", "password-alice", IP, T0).unwrap().session.token;
        // 59 s after the last write: not written, so idle expiry counts from T0.
        let info = lab.sessions().lookup(&tok, at(59_000)).unwrap();
        assert_eq!(info.idle_expires, at(30 * MIN), "{name}");
        assert_eq!(lab.sessions().list(None).unwrap()[0].last_seen, T0);
        let info = lab.sessions().lookup(&tok, at(60_000)).unwrap();
        assert_eq!(info.idle_expires, at(60_000 + 30 * MIN));
        assert_eq!(lab.sessions().list(None).unwrap()[0].last_seen, at(60_000));
    }
}

#[test]
fn absolute_expiry_even_when_busy() {
    for (name, lab) in labs() {
        let tok = lab.login("alice", "password-alice", IP, T0).unwrap().session.token;
        let mut t = 0;
        while t < 12 * HOUR - 10 * MIN {
            t += 10 * MIN;
            assert!(lab.sessions().lookup(&tok, at(t)).is_ok(), "{name} t={t}");
        }
        assert!(lab.sessions().lookup(&tok, at(12 * HOUR - 1)).is_ok());
        assert!(matches!(
            lab.sessions().lookup(&tok, at(12 * HOUR)),
            Err(SessionError::Expired(ExpiryKind::Absolute))
        ));
    }
}

#[test]
fn logout_end_all_and_deleted_user() {
    for (name, lab) in labs() {
        let a1 = lab.login("alice", "password-alice", IP, T0).unwrap().session.token;
        let a2 = lab.login("alice", "password-alice", IP, T0).unwrap().session.token;
        let b = lab.login("bob", "password-bob", IP, T0).unwrap().session.token;
        let info = lab.sessions().lookup(&a1, at(1)).unwrap();
        assert!(lab.logout(&info, at(2)).unwrap());
        assert!(matches!(lab.sessions().lookup(&a1, at(3)), Err(SessionError::Unknown)), "{name}");
        assert!(lab.sessions().lookup(&a2, at(3)).is_ok());
        // A student cannot end another user's session; an admin can.
        let alice = Actor::new("alice", Role::Student);
        assert!(lab.end_user_session(&alice, "bob", at(4)).is_err());
        assert!(lab.sessions().lookup(&b, at(5)).is_ok());
        let admin = Actor::new("admin", Role::Admin);
        let ended = lab.end_user_session(&admin, "alice", at(6)).unwrap();
        assert_eq!(ended.sessions, 1, "{name}");
        assert!(matches!(lab.sessions().lookup(&a2, at(7)), Err(SessionError::Unknown)));
        // Deleting a user removes their sessions.
        lab.users().delete("bob").unwrap();
        assert!(matches!(lab.sessions().lookup(&b, at(8)), Err(SessionError::Unknown)));
    }
}

#[test]
fn role_change_applies_to_live_sessions_and_passwd_ends_them() {
    for (name, lab) in labs() {
        let tok = lab.login("alice", "password-alice", IP, T0).unwrap().session.token;
        lab.users().set_role("alice", Role::Viewer, at(1)).unwrap();
        assert_eq!(lab.sessions().lookup(&tok, at(2)).unwrap().role, Role::Viewer, "{name}");
        lab.users().passwd("alice", "another-password", at(3)).unwrap();
        assert!(matches!(lab.sessions().lookup(&tok, at(4)), Err(SessionError::Unknown)));
        assert!(matches!(lab.login("alice", "password-alice", IP, at(5)), Err(LoginError::BadCredentials)));
        assert!(lab.login("alice", "another-password", IP, at(6)).is_ok());
    }
}

#[test]
fn purge_expired() {
    for (name, lab) in labs() {
        let _old = lab.login("alice", "password-alice", IP, T0).unwrap();
        let fresh = lab.login("bob", "password-bob", IP, at(20 * MIN)).unwrap().session.token;
        assert_eq!(lab.sessions().purge_expired(at(35 * MIN)).unwrap(), 1, "{name}");
        assert!(lab.sessions().lookup(&fresh, at(35 * MIN)).is_ok());
    }
}

#[test]
fn csrf_check() {
    for (_, lab) in labs() {
        let ok = lab.login("alice", "password-alice", IP, T0).unwrap();
        let info = lab.sessions().lookup(&ok.session.token, at(1)).unwrap();
        assert!(lab.sessions().check_csrf(&info, Some(&ok.session.csrf_token)).is_ok());
        assert!(matches!(lab.sessions().check_csrf(&info, None), Err(SessionError::CsrfMismatch)));
        assert!(matches!(
            lab.sessions().check_csrf(&info, Some(&ok.session.token)),
            Err(SessionError::CsrfMismatch)
        ));
        assert!(matches!(lab.sessions().check_csrf(&info, Some("")), Err(SessionError::CsrfMismatch)));
    }
    assert!(constant_time_eq(b"abc", b"abc"));
    assert!(!constant_time_eq(b"abc", b"abd"));
    assert!(!constant_time_eq(b"abc", b"ab"));
}

#[test]
fn cookie_attributes() {
    let secure = CookieConfig::default();
    assert_eq!(
        secure.set_cookie("t0k", Duration::from_secs(43_200)),
        "__Host-motus_session=t0k; Path=/; Max-Age=43200; HttpOnly; SameSite=Strict; Secure"
    );
    assert_eq!(
        secure.clear_cookie(),
        "__Host-motus_session=; Path=/; Max-Age=0; HttpOnly; SameSite=Strict; Secure"
    );
    let plain = CookieConfig { secure: false, ..CookieConfig::default() };
    assert_eq!(
        plain.set_cookie("t0k", Duration::from_secs(60)),
        "motus_session=t0k; Path=/; Max-Age=60; HttpOnly; SameSite=Strict"
    );
    assert_eq!(secure.token_from_header("a=1; __Host-motus_session=abc; b=2"), Some("abc"));
    assert_eq!(secure.token_from_header("motus_session=abc"), None);
    assert_eq!(plain.token_from_header("motus_session=abc"), Some("abc"));
    assert_eq!(plain.token_from_header("motus_session="), None);
    assert_eq!(plain.token_from_header("xmotus_session=abc"), None);
    // The login flow returns the cookie with the absolute timeout as Max-Age.
    let (_, lab) = labs().remove(0);
    let ok = lab.login("alice", "password-alice", IP, T0).unwrap();
    assert_eq!(ok.session.set_cookie, secure.set_cookie(&ok.session.token, Duration::from_secs(12 * 3600)));
}
