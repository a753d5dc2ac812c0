//! Every authorisation rule, allow and deny cases, on the pure decision and through the store.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use common::*;
use motus_lab::{
    decide, Action, Actor, AuditQuery, AuthzError, AxisOp, Command, DenyReason, Facts, MotionDemand,
    MotionLimits, Role, StudentLimits,
};

fn limits() -> StudentLimits {
    let mut l = StudentLimits::default();
    l.axes.insert("x".into(), MotionLimits::new(1.0, 10.0));
    l
}

fn cmd(command: Command) -> Action {
    Action::Command { station: "st1".into(), command }
}

fn mv(axis: &str, speed: f64, acceleration: f64) -> Action {
    cmd(Command::Axis {
        axis: axis.into(),
        op: AxisOp::Move,
        demand: Some(MotionDemand::new(speed, acceleration)),
    })
}

fn admin_only_actions() -> Vec<Action> {
    vec![
        Action::ChangeSafetyConfig { station: "st1".into() },
        Action::ChangeAxisParameters { station: "st1".into(), axis: "x".into() },
        Action::ManageUsers,
        Action::EndSession { user: "bob".into() },
        Action::ViewAudit,
    ]
}

fn holding(user: &str) -> Facts<'_> {
    Facts { holder: Some(user), resetting: false }
}

#[test]
fn viewer_never_commands_not_even_estop() {
    let v = Actor::new("vera", Role::Viewer);
    for c in [Command::EStop, Command::Stop, Command::Trace, Command::ResetFault] {
        let e = decide(&v, &cmd(c), holding("vera"), &limits()).unwrap_err();
        assert_eq!(e.reason, DenyReason::RoleTooLow { required: Role::Student, actual: Role::Viewer });
    }
    assert!(decide(&v, &Action::View { station: "st1".into() }, Facts::default(), &limits()).is_ok());
    let e = decide(
        &v,
        &Action::Reserve { station: "st1".into(), for_user: "vera".into() },
        Facts::default(),
        &limits(),
    );
    assert!(matches!(e.unwrap_err().reason, DenyReason::RoleTooLow { .. }));
}

#[test]
fn student_commands_only_in_own_slot() {
    let a = Actor::new("alice", Role::Student);
    let ok = mv("x", 0.5, 5.0);
    assert!(decide(&a, &ok, holding("alice"), &limits()).is_ok());
    // Someone else's slot.
    let e = decide(&a, &ok, holding("bob"), &limits()).unwrap_err();
    assert_eq!(e.reason, DenyReason::NotSlotHolder { station: "st1".into(), holder: Some("bob".into()) });
    // Nobody's slot.
    let e = decide(&a, &cmd(Command::Stop), Facts::default(), &limits()).unwrap_err();
    assert_eq!(e.reason, DenyReason::NotSlotHolder { station: "st1".into(), holder: None });
    // Own slot but the station is still being reset.
    let e = decide(&a, &ok, Facts { holder: Some("alice"), resetting: true }, &limits()).unwrap_err();
    assert_eq!(e.reason, DenyReason::StationResetting { station: "st1".into() });
}

#[test]
fn estop_is_allowed_to_students_any_time() {
    let a = Actor::new("alice", Role::Student);
    for f in [Facts::default(), holding("bob"), Facts { holder: None, resetting: true }] {
        assert!(decide(&a, &cmd(Command::EStop), f, &limits()).is_ok());
    }
}

#[test]
fn admin_may_do_everything_any_time() {
    let ad = Actor::new("admin", Role::Admin);
    let mut all = admin_only_actions();
    all.push(mv("x", 100.0, 1000.0)); // no student limits for admins
    all.push(mv("unlisted", 1.0, 1.0));
    all.push(cmd(Command::Axis { axis: "x".into(), op: AxisOp::Jog, demand: None }));
    all.push(Action::Reserve { station: "st1".into(), for_user: "alice".into() });
    all.push(Action::CancelReservation { station: "st1".into(), owner: "alice".into() });
    for action in all {
        assert!(decide(&ad, &action, holding("alice"), &limits()).is_ok(), "{action:?}");
        assert!(
            decide(&ad, &action, Facts { holder: None, resetting: true }, &limits()).is_ok(),
            "{action:?}"
        );
    }
}

#[test]
fn only_admin_changes_safety_axis_parameters_users() {
    for role in [Role::Viewer, Role::Student] {
        let actor = Actor::new("alice", role);
        for action in admin_only_actions() {
            let e = decide(&actor, &action, holding("alice"), &limits()).unwrap_err();
            assert_eq!(
                e.reason,
                DenyReason::RoleTooLow { required: Role::Admin, actual: role },
                "{action:?}"
            );
        }
    }
}

#[test]
fn student_motion_limits() {
    let a = Actor::new("alice", Role::Student);
    let f = holding("alice");
    // At the limit is allowed, above is not; signs are ignored.
    assert!(decide(&a, &mv("x", 1.0, 10.0), f, &limits()).is_ok());
    assert!(decide(&a, &mv("x", -1.0, -10.0), f, &limits()).is_ok());
    let e = decide(&a, &mv("x", 1.01, 1.0), f, &limits()).unwrap_err();
    assert!(matches!(e.reason, DenyReason::MotionLimit { quantity: motus_lab::authz::Quantity::Speed, .. }));
    let e = decide(&a, &mv("x", -0.1, -10.5), f, &limits()).unwrap_err();
    assert!(matches!(
        e.reason,
        DenyReason::MotionLimit { quantity: motus_lab::authz::Quantity::Acceleration, .. }
    ));
    for bad in [f64::NAN, f64::INFINITY] {
        assert!(decide(&a, &mv("x", bad, 1.0), f, &limits()).is_err());
        assert!(decide(&a, &mv("x", 0.1, bad), f, &limits()).is_err());
    }
    // An axis without limits cannot be moved by a student (fail closed) ...
    let e = decide(&a, &mv("y", 0.1, 0.1), f, &limits()).unwrap_err();
    assert_eq!(e.reason, DenyReason::NoMotionLimits { axis: "y".into() });
    // ... unless a default is configured.
    let mut with_default = limits();
    with_default.default = Some(MotionLimits::new(0.2, 0.2));
    assert!(decide(&a, &mv("y", 0.1, 0.1), f, &with_default).is_ok());
    assert!(decide(&a, &mv("y", 0.3, 0.1), f, &with_default).is_err());
    // A move or jog must state its demand.
    for op in [AxisOp::Move, AxisOp::Jog] {
        let e =
            decide(&a, &cmd(Command::Axis { axis: "x".into(), op, demand: None }), f, &limits()).unwrap_err();
        assert_eq!(e.reason, DenyReason::MissingMotionDemand { axis: "x".into() });
    }
    // Homing needs none.
    assert!(decide(
        &a,
        &cmd(Command::Axis { axis: "x".into(), op: AxisOp::Home, demand: None }),
        f,
        &limits()
    )
    .is_ok());
    // A program is checked axis by axis.
    let prog = |s| {
        cmd(Command::RunProgram {
            name: "p".into(),
            demands: vec![("x".into(), MotionDemand::new(0.5, 1.0)), ("x".into(), MotionDemand::new(s, 1.0))],
        })
    };
    assert!(decide(&a, &prog(0.9), f, &limits()).is_ok());
    assert!(decide(&a, &prog(1.5), f, &limits()).is_err());
}

#[test]
fn reserve_and_cancel_only_for_self_unless_admin() {
    let a = Actor::new("alice", Role::Student);
    let own = Action::Reserve { station: "st1".into(), for_user: "alice".into() };
    let other = Action::Reserve { station: "st1".into(), for_user: "bob".into() };
    assert!(decide(&a, &own, Facts::default(), &limits()).is_ok());
    assert_eq!(
        decide(&a, &other, Facts::default(), &limits()).unwrap_err().reason,
        DenyReason::NotOwner { owner: "bob".into() }
    );
    let cancel_other = Action::CancelReservation { station: "st1".into(), owner: "bob".into() };
    assert!(decide(&a, &cancel_other, Facts::default(), &limits()).is_err());
}

#[test]
fn no_action_sets_safe_to_run() {
    // The JSON form of actions is closed: no variant or command writes SafeToRun.
    for json in [
        r#"{"action":"set_safe_to_run","station":"st1"}"#,
        r#"{"action":"command","station":"st1","command":{"command":"set_safe_to_run"}}"#,
        r#"{"action":"command","station":"st1","command":{"command":"force_output","name":"SafeToRun"}}"#,
    ] {
        assert!(serde_json::from_str::<Action>(json).is_err(), "{json}");
    }
    // And the names of everything that exists mention no such thing.
    let everything = [
        cmd(Command::EStop),
        cmd(Command::Stop),
        cmd(Command::Trace),
        cmd(Command::ResetFault),
        cmd(Command::AcknowledgeAlarm { id: 1 }),
        cmd(Command::Upload { name: "a".into() }),
        Action::ChangeSafetyConfig { station: "st1".into() },
    ];
    for a in everything {
        assert!(!a.name().contains("safe_to_run"), "{}", a.name());
    }
}

#[test]
fn authorizer_reads_the_slot_from_the_store_and_lab_audits_denials() {
    for (name, lab) in labs() {
        let admin = Actor::new("admin", Role::Admin);
        let alice = Actor::new("alice", Role::Student);
        let bob = Actor::new("bob", Role::Student);
        lab.reservations().book(&admin, "st1", "alice", at(HOUR), at(2 * HOUR), T0).unwrap();
        let action = mv("x", 0.5, 5.0);
        // Before, during (start inclusive), at the end (exclusive).
        assert!(lab.authorize(&alice, &action, at(HOUR - 1)).is_err(), "{name}");
        assert!(lab.authorize(&alice, &action, at(HOUR)).is_ok(), "{name}");
        assert!(lab.authorize(&alice, &action, at(2 * HOUR - 1)).is_ok(), "{name}");
        let e = lab.authorize(&alice, &action, at(2 * HOUR)).unwrap_err();
        // At the end the slot is over and its cleanup pending: not the holder any more.
        assert!(
            matches!(e, AuthzError::Denied(ref d) if matches!(d.reason, DenyReason::NotSlotHolder { holder: None, .. })),
            "{name}: {e:?}"
        );
        // Bob during Alice's slot.
        let e = lab.authorize(&bob, &action, at(HOUR + 5)).unwrap_err();
        assert!(
            matches!(e, AuthzError::Denied(ref d) if d.reason == DenyReason::NotSlotHolder { station: "st1".into(), holder: Some("alice".into()) }),
            "{name}"
        );
        // A student trying a safety change: denied and audited.
        assert!(lab
            .authorize(&alice, &Action::ChangeSafetyConfig { station: "st1".into() }, at(HOUR + 6))
            .is_err());
        let denied = lab
            .audit()
            .query(&AuditQuery { outcome: Some("denied".into()), ..AuditQuery::default() })
            .unwrap();
        assert_eq!(denied.len(), 4, "{name}: {denied:?}");
        assert_eq!(denied[0].entry.action, "change_safety_config");
        assert_eq!(denied[0].entry.user, "alice");
        assert_eq!(denied[0].entry.time, at(HOUR + 6));
        assert!(denied[0].entry.outcome.message().contains("needs admin"), "{:?}", denied[0]);
        assert_eq!(denied[1].entry.user, "bob");
        assert_eq!(denied[1].entry.action, "command.axis.move");
        assert_eq!(denied[1].entry.target, "st1/x move speed=0.5 acc=5");
        // Allowed actions are audited by the caller with their result.
        lab.record(&alice, &action, Err("drive fault".into()), at(HOUR + 7)).unwrap();
        let errors = lab
            .audit()
            .query(&AuditQuery { outcome: Some("error".into()), ..AuditQuery::default() })
            .unwrap();
        assert_eq!(errors.len(), 1);
        assert_eq!(errors[0].entry.outcome.message(), "drive fault");
    }
}

#[test]
fn station_resetting_until_cleanup_completed() {
    for (name, lab) in labs() {
        let admin = Actor::new("admin", Role::Admin);
        let alice = Actor::new("alice", Role::Student);
        let bob = Actor::new("bob", Role::Student);
        lab.reservations().book(&admin, "st1", "alice", at(0), at(HOUR), T0).unwrap();
        lab.reservations().book(&admin, "st1", "bob", at(HOUR), at(2 * HOUR), T0).unwrap();
        let action = mv("x", 0.5, 5.0);
        let e = lab.authorize(&bob, &action, at(HOUR)).unwrap_err();
        assert!(
            matches!(e, AuthzError::Denied(ref d) if matches!(d.reason, DenyReason::StationResetting { .. })),
            "{name}"
        );
        // E-stop still works; the admin still commands.
        assert!(lab.authorize(&bob, &cmd(Command::EStop), at(HOUR)).is_ok());
        assert!(lab.authorize(&admin, &action, at(HOUR)).is_ok());
        let due = lab.reservations().due_cleanups(at(HOUR)).unwrap();
        assert_eq!(due.len(), 1);
        lab.reservations().complete_cleanup(&due[0]).unwrap();
        assert!(lab.authorize(&bob, &action, at(HOUR)).is_ok(), "{name}");
        assert!(lab.authorize(&alice, &action, at(HOUR)).is_err(), "{name}");
    }
}

#[test]
fn audit_targets_carry_the_command_parameters() {
    let axis = |op, demand| cmd(Command::Axis { axis: "x".into(), op, demand });
    let to = MotionDemand::within(0.5, 5.0, 0.25, 0.25);
    assert_eq!(axis(AxisOp::Move, Some(to)).target(), "st1/x move to=0.25 speed=0.5 acc=5");
    assert_eq!(
        axis(AxisOp::Move, Some(MotionDemand::within(0.123_456_789, 1e6, -1.15, -1.15))).target(),
        "st1/x move to=-1.15 speed=0.123457 acc=1000000"
    );
    assert_eq!(axis(AxisOp::Jog, Some(MotionDemand::new(-0.1, 2.0))).target(), "st1/x jog speed=-0.1 acc=2");
    assert_eq!(axis(AxisOp::Home, None).target(), "st1/x home");
    assert_eq!(
        axis(AxisOp::Move, Some(MotionDemand::within(f64::NAN, f64::INFINITY, 1e-7, 2.5e12))).target(),
        "st1/x move range=[1e-7, 2500000000000] speed=NaN acc=inf"
    );
    let program = cmd(Command::RunProgram {
        name: "prog.nc".into(),
        demands: vec![
            ("x".into(), MotionDemand::within(0.5, 5.0, 0.0, 0.5)),
            ("y".into(), MotionDemand::new(1.0, 2.0)),
        ],
    });
    assert_eq!(program.target(), "st1/prog.nc axes: x range=[0, 0.5] speed=0.5 acc=5; y speed=1 acc=2");
    assert_eq!(
        cmd(Command::RunProgram { name: "empty.nc".into(), demands: vec![] }).target(),
        "st1/empty.nc"
    );

    // Refused and accepted moves are audited with their target position and speed.
    for (name, lab) in labs() {
        let admin = Actor::new("admin", Role::Admin);
        let alice = Actor::new("alice", Role::Student);
        let far = axis(AxisOp::Move, Some(MotionDemand::within(0.75, 5.0, 1.15, 1.15)));
        assert!(lab.authorize(&alice, &far, at(0)).is_err(), "{name}");
        lab.authorize(&admin, &far, at(1)).unwrap();
        lab.record(&admin, &far, Ok(()), at(1)).unwrap();
        let log = lab
            .audit()
            .query(&AuditQuery { action_prefix: Some("command.".into()), ..AuditQuery::default() })
            .unwrap();
        let seen: Vec<(&str, &str, &str)> = log
            .iter()
            .map(|r| (r.entry.user.as_str(), r.entry.outcome.kind(), r.entry.target.as_str()))
            .collect();
        assert_eq!(
            seen,
            [
                ("admin", "ok", "st1/x move to=1.15 speed=0.75 acc=5"),
                ("alice", "denied", "st1/x move to=1.15 speed=0.75 acc=5"),
            ],
            "{name}"
        );
    }
}
