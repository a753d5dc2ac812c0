//! The SQLite store in a real file: round trip of every record kind across a reopen,
//! migrations, WAL, permissions, config defaults.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use std::net::{IpAddr, Ipv4Addr};
use std::path::Path;
use std::sync::Arc;

use common::*;
use motus_lab::store::{default_db_path, BookOutcome, SCHEMA_VERSION};
use motus_lab::{
    Actor, AlarmQuery, AuditEntry, AuditOutcome, AuditQuery, Lab, LabConfig, ProgramKind, ProgramMeta,
    ReservationFilter, Role, Severity, SqliteStore, StoreError,
};

#[test]
fn round_trip_across_reopen() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("station.lab.sqlite");
    let ip = IpAddr::V4(Ipv4Addr::LOCALHOST);
    let (token, res_id, alarm_id) = {
        let lab = lab_with_users(Arc::new(SqliteStore::open(&path).unwrap()));
        let token = lab.login("alice", "password-alice", ip, T0).unwrap().session.token;
        let res = lab
            .reservations()
            .book(&Actor::new("alice", Role::Student), "st1", "alice", at(HOUR), at(2 * HOUR), T0)
            .unwrap();
        lab.programs()
            .register(&ProgramMeta {
                station: "st1".into(),
                owner: "alice".into(),
                kind: ProgramKind::Trace,
                name: "t.csv".into(),
                exported: true,
                size_bytes: 1 << 40,
                created: at(5),
            })
            .unwrap();
        let alarm_id =
            lab.alarms().raise("axis_config_wrong", "st1/axis2", "boot", Severity::Error, at(7)).unwrap();
        lab.alarms().acknowledge(alarm_id, "admin", at(8)).unwrap();
        lab.record(
            &Actor::new("alice", Role::Student),
            &motus_lab::Action::View { station: "st1".into() },
            Ok(()),
            at(9),
        )
        .unwrap();
        (token, res.id, alarm_id)
    };
    let store = SqliteStore::open(&path).unwrap();
    assert_eq!(store.schema_version().unwrap(), SCHEMA_VERSION);
    let lab = Lab::new(Arc::new(store), config());
    let users: Vec<(String, Role)> =
        lab.users().list().unwrap().into_iter().map(|u| (u.name, u.role)).collect();
    assert_eq!(
        users,
        [
            ("admin".into(), Role::Admin),
            ("alice".into(), Role::Student),
            ("bob".into(), Role::Student),
            ("vera".into(), Role::Viewer)
        ]
    );
    assert!(lab.users().verify("alice", "password-alice", at(1)).is_ok());
    assert_eq!(lab.sessions().lookup(&token, at(10)).unwrap().user, "alice");
    let r = lab.reservations().get(res_id).unwrap().unwrap();
    assert_eq!(
        (r.station.as_str(), r.user.as_str(), r.start, r.end, r.created, r.cleaned),
        ("st1", "alice", at(HOUR), at(2 * HOUR), T0, false)
    );
    let p = lab.programs().list(Some("st1"), Some("alice")).unwrap();
    assert_eq!(p.len(), 1);
    assert_eq!(
        (p[0].kind, p[0].exported, p[0].size_bytes, p[0].created),
        (ProgramKind::Trace, true, 1 << 40, at(5))
    );
    let a = lab.alarms().get(alarm_id).unwrap().unwrap();
    assert_eq!(
        (a.code.as_str(), a.source.as_str(), a.severity, a.raised_at),
        ("axis_config_wrong", "st1/axis2", Severity::Error, at(7))
    );
    assert_eq!(a.acknowledged.unwrap().by, "admin");
    let log = lab.audit().query(&AuditQuery::default()).unwrap();
    assert_eq!(log[0].entry.action, "view");
    assert_eq!(log[1].entry.action, "login");
    // Journal mode is WAL and the file is private.
    let conn = rusqlite_mode(&path);
    assert_eq!(conn, "wal");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt as _;
        let mode = std::fs::metadata(&path).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o600);
    }
}

/// Reads the journal mode through a second, independent connection (the sqlite3 CLI may be
/// missing; Python's sqlite3 module is always there).
fn rusqlite_mode(path: &Path) -> String {
    let out = std::process::Command::new("python3")
        .args(["-c", "import sqlite3,sys; print(sqlite3.connect(sys.argv[1]).execute('pragma journal_mode').fetchone()[0])"])
        .arg(path)
        .output()
        .expect("python3 is required");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout).unwrap().trim().to_string()
}

#[test]
fn newer_schema_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("x.sqlite");
    drop(SqliteStore::open(&path).unwrap());
    let st = std::process::Command::new("python3")
        .args(["-c", "import sqlite3,sys; c=sqlite3.connect(sys.argv[1]); c.execute('pragma user_version=99'); c.commit()"])
        .arg(&path)
        .status()
        .unwrap();
    assert!(st.success());
    match SqliteStore::open(&path) {
        Err(StoreError::SchemaTooNew { found: 99, supported }) => assert_eq!(supported, SCHEMA_VERSION),
        Err(e) => panic!("{e}"),
        Ok(_) => panic!("opened a newer schema"),
    }
}

#[test]
fn schema_matches_independent_reader() {
    // Python's sqlite3 sees the tables and the user_version we wrote.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("x.sqlite");
    drop(SqliteStore::open(&path).unwrap());
    let out = std::process::Command::new("python3")
        .args(["-c", "import sqlite3,sys; c=sqlite3.connect(sys.argv[1]); print(c.execute('pragma user_version').fetchone()[0], ' '.join(r[0] for r in c.execute(\"select name from sqlite_master where type='table' and name not like 'sqlite_%' order by name\")))"])
        .arg(&path)
        .output()
        .unwrap();
    assert_eq!(
        String::from_utf8(out.stdout).unwrap().trim(),
        "1 alarms audit programs reservations sessions users"
    );
}

#[test]
fn default_path_is_beside_the_config() {
    assert_eq!(
        default_db_path(Path::new("/etc/motus/station.toml")),
        Path::new("/etc/motus/station.lab.sqlite")
    );
    assert_eq!(default_db_path(Path::new("juggler.toml")), Path::new("juggler.lab.sqlite"));
}

#[test]
fn store_level_semantics_on_both_backends() {
    for (name, store) in stores() {
        let u = motus_lab::User {
            name: "u".into(),
            role: Role::Admin,
            password_hash: "h".into(),
            created: T0,
            updated: T0,
        };
        store.insert_user(&u).unwrap();
        assert!(matches!(store.insert_user(&u), Err(StoreError::Conflict { what: "user", .. })), "{name}");
        let ghost = motus_lab::User { name: "ghost".into(), ..u.clone() };
        assert!(matches!(store.update_user(&ghost), Err(StoreError::NotFound { .. })), "{name}");
        // A session for a missing user is refused.
        let s = motus_lab::session::SessionRecord {
            token_hash: "h1".into(),
            user: "ghost".into(),
            csrf_token: "c".into(),
            created: T0,
            last_seen: T0,
            source: None,
        };
        assert!(store.insert_session(&s).is_err(), "{name}");
        // Booking is atomic against overlap, half-open intervals.
        let nr = |s: i64, e: i64| motus_lab::reservation::NewReservation {
            station: "st".into(),
            user: "u".into(),
            start: at(s),
            end: at(e),
            created: T0,
        };
        let BookOutcome::Booked(id) = store.insert_reservation_if_free(&nr(0, 10)).unwrap() else { panic!() };
        assert!(
            matches!(store.insert_reservation_if_free(&nr(9, 20)).unwrap(), BookOutcome::Overlaps(ref o) if o.id == id)
        );
        assert!(matches!(store.insert_reservation_if_free(&nr(10, 20)).unwrap(), BookOutcome::Booked(_)));
        assert!(matches!(store.insert_reservation_if_free(&nr(-5, 0)).unwrap(), BookOutcome::Booked(_)));
        let w = store
            .list_reservations(&ReservationFilter {
                window: Some((at(5), at(12))),
                ..ReservationFilter::default()
            })
            .unwrap();
        assert_eq!(w.len(), 2, "{name}");
        assert_eq!(
            store
                .list_reservations(&ReservationFilter {
                    pending_cleanup_at: Some(at(10)),
                    ..ReservationFilter::default()
                })
                .unwrap()
                .len(),
            2
        );
        assert!(store.delete_reservation(id).unwrap());
        assert!(!store.delete_reservation(id).unwrap());
    }
}

#[test]
fn audit_query_filters_and_limit() {
    for (name, store) in stores() {
        let entries = [
            (1, "alice", "command.axis.move", AuditOutcome::Ok),
            (2, "alice", "command.estop", AuditOutcome::Ok),
            (3, "bob", "command.axis.move", AuditOutcome::Denied("not holder".into())),
            (4, "alice", "change_safety_config", AuditOutcome::Denied("needs admin".into())),
            (5, "admin", "change_safety_config", AuditOutcome::Error("supervisor offline".into())),
            (6, "alice", "command%", AuditOutcome::Ok),
        ];
        for (t, user, action, outcome) in entries {
            store
                .append_audit(&AuditEntry {
                    time: at(t),
                    user: user.into(),
                    action: action.into(),
                    target: "st1".into(),
                    outcome,
                })
                .unwrap();
        }
        let q = |q: AuditQuery| {
            store.query_audit(&q).unwrap().into_iter().map(|r| r.entry.time.0 - T0.0).collect::<Vec<_>>()
        };
        assert_eq!(q(AuditQuery::default()), [6, 5, 4, 3, 2, 1], "{name}");
        assert_eq!(q(AuditQuery { user: Some("alice".into()), ..AuditQuery::default() }), [6, 4, 2, 1]);
        assert_eq!(
            q(AuditQuery { action_prefix: Some("command.".into()), ..AuditQuery::default() }),
            [3, 2, 1],
            "{name}"
        );
        // '%' and '_' are not wildcards.
        assert_eq!(q(AuditQuery { action_prefix: Some("command%".into()), ..AuditQuery::default() }), [6]);
        assert_eq!(
            q(AuditQuery { action_prefix: Some("c_mmand".into()), ..AuditQuery::default() }),
            Vec::<i64>::new()
        );
        assert_eq!(q(AuditQuery { outcome: Some("denied".into()), ..AuditQuery::default() }), [4, 3]);
        assert_eq!(
            q(AuditQuery { since: Some(at(2)), until: Some(at(5)), ..AuditQuery::default() }),
            [4, 3, 2]
        );
        assert_eq!(q(AuditQuery { limit: 2, ..AuditQuery::default() }), [6, 5]);
        let r =
            store.query_audit(&AuditQuery { user: Some("admin".into()), ..AuditQuery::default() }).unwrap();
        assert_eq!(r[0].entry.outcome, AuditOutcome::Error("supervisor offline".into()));
    }
}

#[test]
fn alarms_raise_ack_clear_history() {
    for (name, lab) in labs() {
        let al = lab.alarms();
        let a = al.raise("axis_config_wrong", "st1", "amplifiers booting", Severity::Error, at(1)).unwrap();
        // Raising the same uncleared alarm again does not duplicate it.
        assert_eq!(al.raise("axis_config_wrong", "st1", "again", Severity::Error, at(2)).unwrap(), a);
        let b = al.raise("safe_to_run_false", "st1", "rule r3", Severity::Critical, at(3)).unwrap();
        assert_ne!(a, b);
        let ids = |v: Vec<motus_lab::Alarm>| v.into_iter().map(|x| x.id).collect::<Vec<_>>();
        assert_eq!(ids(al.active().unwrap()), [b, a], "{name}");
        // Cleared but not acknowledged: still active.
        assert_eq!(al.clear("axis_config_wrong", "st1", at(4)).unwrap(), 1);
        assert_eq!(ids(al.active().unwrap()), [b, a]);
        match al.acknowledge(a, "admin", at(5)).unwrap() {
            motus_lab::AckOutcome::Acknowledged(x) => assert_eq!(x.acknowledged.unwrap().at, at(5)),
            other => panic!("{other:?}"),
        }
        assert!(
            matches!(al.acknowledge(a, "bob", at(6)).unwrap(), motus_lab::AckOutcome::AlreadyAcknowledged(ref x) if x.acknowledged.as_ref().unwrap().by == "admin")
        );
        assert!(matches!(al.acknowledge(9999, "bob", at(6)).unwrap(), motus_lab::AckOutcome::NotFound));
        assert_eq!(ids(al.active().unwrap()), [b], "{name}");
        // Acknowledged but not cleared: active; a new occurrence after clearing is a new alarm.
        al.acknowledge(b, "alice", at(7)).unwrap();
        assert_eq!(ids(al.active().unwrap()), [b]);
        let a2 = al.raise("axis_config_wrong", "st1", "again", Severity::Error, at(8)).unwrap();
        assert_ne!(a2, a);
        assert_eq!(ids(al.history(10).unwrap()), [a2, b, a]);
        assert_eq!(ids(al.history(1).unwrap()), [a2]);
        let since =
            lab.store().list_alarms(&AlarmQuery { since: Some(at(3)), ..AlarmQuery::default() }).unwrap();
        assert_eq!(ids(since), [a2, b]);
        let full = al.get(a).unwrap().unwrap();
        assert_eq!((full.cleared_at, full.message.as_str()), (Some(at(4)), "amplifiers booting"));
    }
}

#[test]
fn config_from_toml_with_defaults() {
    let c: LabConfig = toml::from_str(
        r#"
        [password]
        min_length = 12
        [sessions]
        idle_timeout_secs = 600
        cookie = { secure = false }
        [reservations]
        max_slot_secs = 3600
        [student_limits.axes.arm_left]
        max_speed = 87.266
        max_acceleration = 872.66
        "#,
    )
    .unwrap();
    assert_eq!(c.password.min_length, 12);
    assert_eq!(c.password.max_length, 256);
    assert_eq!(c.sessions.idle_timeout_secs, 600);
    assert_eq!(c.sessions.absolute_timeout_secs, 12 * 3600);
    assert!(!c.sessions.cookie.secure);
    assert_eq!(c.sessions.cookie.name, "motus_session");
    assert_eq!(c.reservations.max_slot_secs, 3600);
    assert_eq!(c.limiter.user_max_failures, 5);
    assert_eq!(c.student_limits.for_axis("arm_left").unwrap().max_speed, 87.266);
    assert!(c.student_limits.for_axis("other").is_none());
    assert!(toml::from_str::<LabConfig>("[sessions]\nidle = 5").is_err(), "unknown keys are refused");
}
