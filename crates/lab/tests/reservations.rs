//! Booking rules, overlap rejection, cancellation, holder, end-of-slot cleanup.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use common::*;
use motus_lab::{Actor, CleanupAction, ProgramKind, ProgramMeta, ReservationError, ReservationFilter, Role};

fn admin() -> Actor {
    Actor::new("admin", Role::Admin)
}
fn alice() -> Actor {
    Actor::new("alice", Role::Student)
}
fn bob() -> Actor {
    Actor::new("bob", Role::Student)
}

#[test]
fn overlaps_are_rejected_adjacent_slots_are_not() {
    for (name, lab) in labs() {
        let r = lab.reservations();
        let base = r.book(&alice(), "st1", "alice", at(HOUR), at(2 * HOUR), T0).unwrap();
        // [1h,2h) booked. Overlap shapes: inside, around, start inside, end inside, identical.
        for (s, e) in [(70, 80), (30, 150), (90, 150), (30, 61), (60, 120)] {
            match r.book(&bob(), "st1", "bob", at(s * MIN), at(e * MIN), T0) {
                Err(ReservationError::Overlap(o)) => assert_eq!(o.id, base.id, "{name}"),
                other => panic!("{name} [{s},{e}) min: {other:?}"),
            }
        }
        // Touching at either end is fine, and so is another station.
        r.book(&bob(), "st1", "bob", at(2 * HOUR), at(3 * HOUR), T0).unwrap();
        r.book(&bob(), "st1", "bob", at(30 * MIN), at(HOUR), T0).unwrap();
        r.book(&bob(), "st2", "bob", at(HOUR), at(2 * HOUR), T0).unwrap();
        // Admins cannot overlap either.
        assert!(matches!(
            r.book(&admin(), "st1", "admin", at(HOUR), at(HOUR + MIN), T0),
            Err(ReservationError::Overlap(_))
        ));
        let st1 = r
            .list(&ReservationFilter { station: Some("st1".into()), ..ReservationFilter::default() })
            .unwrap();
        let starts: Vec<i64> = st1.iter().map(|x| (x.start.0 - T0.0) / MIN).collect();
        assert_eq!(starts, [30, 60, 120], "{name}");
    }
}

#[test]
fn policy_limits_for_students_not_admins() {
    for (name, lab) in labs() {
        let r = lab.reservations();
        let e = |res: Result<_, ReservationError>| res.unwrap_err();
        assert!(matches!(
            e(r.book(&alice(), "st1", "alice", at(HOUR), at(HOUR), T0)),
            ReservationError::EmptySlot
        ));
        assert!(matches!(
            e(r.book(&alice(), "st1", "alice", at(2 * HOUR), at(HOUR), T0)),
            ReservationError::EmptySlot
        ));
        assert!(matches!(
            e(r.book(&alice(), "st1", "alice", at(HOUR), at(HOUR + 4 * MIN), T0)),
            ReservationError::TooShort { .. }
        ));
        assert!(matches!(
            e(r.book(&alice(), "st1", "alice", at(HOUR), at(3 * HOUR + 1), T0)),
            ReservationError::TooLong { .. }
        ));
        assert!(matches!(
            e(r.book(&alice(), "st1", "alice", at(-6 * MIN), at(HOUR), T0)),
            ReservationError::InPast
        ));
        assert!(matches!(
            e(r.book(&alice(), "st1", "alice", at(15 * 24 * HOUR), at(15 * 24 * HOUR + HOUR), T0)),
            ReservationError::BeyondHorizon { .. }
        ));
        // Start within the 5-minute grace is accepted; exactly 2 h is accepted.
        r.book(&alice(), "st1", "alice", at(-5 * MIN), at(-5 * MIN + 2 * HOUR), T0).unwrap();
        r.book(&alice(), "st2", "alice", at(3 * HOUR), at(4 * HOUR), T0).unwrap();
        r.book(&alice(), "st3", "alice", at(3 * HOUR), at(4 * HOUR), T0).unwrap();
        assert!(
            matches!(
                e(r.book(&alice(), "st4", "alice", at(3 * HOUR), at(4 * HOUR), T0)),
                ReservationError::TooMany { held: 3, max: 3 }
            ),
            "{name}"
        );
        // Students book only for themselves; viewers cannot hold slots; unknown users neither.
        assert!(matches!(
            e(r.book(&alice(), "st5", "bob", at(HOUR), at(2 * HOUR), T0)),
            ReservationError::Denied(_)
        ));
        assert!(matches!(
            e(r.book(&Actor::new("vera", Role::Viewer), "st5", "vera", at(HOUR), at(2 * HOUR), T0)),
            ReservationError::Denied(_)
        ));
        assert!(matches!(
            e(r.book(&admin(), "st5", "vera", at(HOUR), at(2 * HOUR), T0)),
            ReservationError::ViewerCannotHold(_)
        ));
        assert!(matches!(
            e(r.book(&admin(), "st5", "ghost", at(HOUR), at(2 * HOUR), T0)),
            ReservationError::UnknownUser(_)
        ));
        // Admins are exempt from length, horizon and count.
        r.book(&admin(), "st4", "alice", at(30 * 24 * HOUR), at(31 * 24 * HOUR), T0).unwrap();
    }
}

#[test]
fn cancel_own_or_admin_and_holder_at() {
    for (name, lab) in labs() {
        let r = lab.reservations();
        let a = r.book(&alice(), "st1", "alice", at(HOUR), at(2 * HOUR), T0).unwrap();
        let b = r.book(&bob(), "st1", "bob", at(2 * HOUR), at(3 * HOUR), T0).unwrap();
        assert_eq!(r.holder_at("st1", at(HOUR - 1)).unwrap(), None, "{name}");
        assert_eq!(r.holder_at("st1", at(HOUR)).unwrap().as_deref(), Some("alice"));
        assert_eq!(r.holder_at("st1", at(2 * HOUR)).unwrap().as_deref(), Some("bob"));
        assert_eq!(r.holder_at("st2", at(HOUR)).unwrap(), None);
        // Bob cannot cancel Alice's; Alice cancels her own future slot: it is gone.
        assert!(matches!(r.cancel(&bob(), a.id, T0), Err(ReservationError::Denied(_))));
        assert_eq!(r.cancel(&alice(), a.id, T0).unwrap(), None);
        assert!(r.get(a.id).unwrap().is_none());
        assert!(matches!(r.cancel(&alice(), a.id, T0), Err(ReservationError::NotFound(_))));
        // Bob cancels his running slot: it ends now and its cleanup is due.
        let ended = r.cancel(&bob(), b.id, at(2 * HOUR + 10 * MIN)).unwrap().unwrap();
        assert_eq!(ended.end, at(2 * HOUR + 10 * MIN));
        assert_eq!(ended.ended_by.as_deref(), Some("bob"));
        assert_eq!(r.holder_at("st1", at(2 * HOUR + 10 * MIN)).unwrap(), None);
        assert_eq!(r.due_cleanups(at(2 * HOUR + 10 * MIN)).unwrap().len(), 1);
        assert!(matches!(r.cancel(&bob(), b.id, at(3 * HOUR)), Err(ReservationError::AlreadyEnded(_))));
        // An admin ends a running slot; a student cannot.
        let c = r.book(&alice(), "st2", "alice", at(HOUR), at(2 * HOUR), T0).unwrap();
        assert!(matches!(r.end_current(&alice(), "st2", at(HOUR + 1)), Err(ReservationError::Denied(_))));
        let ended = r.end_current(&admin(), "st2", at(HOUR + 1)).unwrap();
        assert_eq!((ended.id, ended.end, ended.ended_by.as_deref()), (c.id, at(HOUR + 1), Some("admin")));
        assert!(matches!(
            r.end_current(&admin(), "st2", at(HOUR + 2)),
            Err(ReservationError::NoActiveSlot(_))
        ));
    }
}

fn prog(station: &str, owner: &str, kind: ProgramKind, name: &str, exported: bool) -> ProgramMeta {
    ProgramMeta {
        station: station.into(),
        owner: owner.into(),
        kind,
        name: name.into(),
        exported,
        size_bytes: 10,
        created: T0,
    }
}

#[test]
fn end_of_slot_cleanup_lists_unexported_files_of_the_holder() {
    for (name, lab) in labs() {
        let r = lab.reservations();
        let p = lab.programs();
        let slot = r.book(&alice(), "st1", "alice", at(0), at(HOUR), T0).unwrap();
        p.register(&prog("st1", "alice", ProgramKind::Program, "juggle.txt", false)).unwrap();
        p.register(&prog("st1", "alice", ProgramKind::Program, "kept.txt", false)).unwrap();
        p.register(&prog("st1", "alice", ProgramKind::Trace, "run1.csv", false)).unwrap();
        p.register(&prog("st1", "bob", ProgramKind::Program, "bobs.txt", false)).unwrap();
        p.register(&prog("st2", "alice", ProgramKind::Program, "other-station.txt", false)).unwrap();
        p.register(&prog("st1", "admin", ProgramKind::Program, "starter.txt", true)).unwrap();
        assert!(p.set_exported("st1", "alice", ProgramKind::Program, "kept.txt", true).unwrap());
        assert!(!p.set_exported("st1", "alice", ProgramKind::Program, "missing.txt", true).unwrap());
        // Nothing is due while the slot runs.
        assert!(r.due_cleanups(at(HOUR - 1)).unwrap().is_empty(), "{name}");
        let due = r.due_cleanups(at(HOUR)).unwrap();
        assert_eq!(due.len(), 1);
        assert_eq!(due[0].reservation.id, slot.id);
        let del = |kind, n: &str| CleanupAction::DeleteFile {
            station: "st1".into(),
            owner: "alice".into(),
            kind,
            name: n.into(),
        };
        assert_eq!(
            due[0].actions,
            vec![
                CleanupAction::MakeSafeAndHome { station: "st1".into() },
                del(ProgramKind::Program, "juggle.txt"),
                del(ProgramKind::Trace, "run1.csv"),
            ],
            "{name}"
        );
        r.complete_cleanup(&due[0]).unwrap();
        assert!(r.due_cleanups(at(2 * HOUR)).unwrap().is_empty());
        assert!(r.get(slot.id).unwrap().unwrap().cleaned);
        let left: Vec<String> = p
            .list(None, None)
            .unwrap()
            .into_iter()
            .map(|m| format!("{}/{}/{}", m.station, m.owner, m.name))
            .collect();
        assert_eq!(
            left,
            [
                "st1/admin/starter.txt",
                "st1/alice/kept.txt",
                "st1/bob/bobs.txt",
                "st2/alice/other-station.txt"
            ],
            "{name}"
        );
    }
}

#[test]
fn several_ended_slots_each_get_a_cleanup() {
    for (name, lab) in labs() {
        let r = lab.reservations();
        r.book(&alice(), "st1", "alice", at(0), at(HOUR), T0).unwrap();
        r.book(&bob(), "st2", "bob", at(0), at(30 * MIN), T0).unwrap();
        r.book(&bob(), "st1", "bob", at(HOUR), at(2 * HOUR), T0).unwrap();
        let due = r.due_cleanups(at(HOUR)).unwrap();
        let who: Vec<(&str, &str)> =
            due.iter().map(|c| (c.reservation.station.as_str(), c.reservation.user.as_str())).collect();
        assert_eq!(who, [("st1", "alice"), ("st2", "bob")], "{name}");
        for c in &due {
            assert_eq!(
                c.actions,
                vec![CleanupAction::MakeSafeAndHome { station: c.reservation.station.clone() }]
            );
        }
    }
}
