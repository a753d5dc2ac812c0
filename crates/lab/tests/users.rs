//! User management (`motus user add|passwd|role`) and password verification.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use common::*;
use motus_lab::password::{needs_rehash, verify_password};
use motus_lab::{HashParams, Lab, PasswordPolicy, PolicyViolation, Role, UserError, Users};

#[test]
fn add_list_verify() {
    for (name, store) in stores() {
        let users = Users::new(store, PasswordPolicy { hash: FAST, ..PasswordPolicy::default() });
        let u = users.add("alice", "long enough pw", Role::Student, T0).unwrap();
        assert_eq!(u.role, Role::Student);
        assert!(u.password_hash.starts_with("$argon2id$"));
        assert!(!format!("{u:?}").contains("argon2"), "Debug must not show the hash");
        users.add("admin", "long enough pw", Role::Admin, T0).unwrap();
        let names: Vec<String> = users.list().unwrap().into_iter().map(|u| u.name).collect();
        assert_eq!(names, ["admin", "alice"], "{name}");
        assert_eq!(users.verify("alice", "long enough pw", at(1)).unwrap().name, "alice");
        assert!(matches!(users.verify("alice", "long enough pW", at(1)), Err(UserError::BadCredentials)));
        assert!(matches!(users.verify("nobody", "long enough pw", at(1)), Err(UserError::BadCredentials)));
        assert!(matches!(users.add("alice", "long enough pw", Role::Admin, T0), Err(UserError::Exists(_))));
    }
}

#[test]
fn name_and_password_rules() {
    let (_, store) = stores().remove(0);
    let users = Users::new(store, PasswordPolicy { hash: FAST, ..PasswordPolicy::default() });
    for bad in ["", "Alice", "-x", "a b", "a/b", "é", &"a".repeat(65)] {
        assert!(
            matches!(users.add(bad, "long enough pw", Role::Student, T0), Err(UserError::InvalidName { .. })),
            "{bad:?}"
        );
    }
    for good in ["a", "0x", "j.doe", "j_doe-2", &"a".repeat(64)] {
        users.add(good, "long enough pw", Role::Student, T0).unwrap();
    }
    assert!(matches!(
        users.add("carol", "short", Role::Student, T0),
        Err(UserError::WeakPassword(PolicyViolation::TooShort { length: 5, min: 10 }))
    ));
    assert!(matches!(
        users.add("carolcarol", "CarolCarol", Role::Student, T0),
        Err(UserError::WeakPassword(PolicyViolation::EqualsUserName))
    ));
    assert!(matches!(users.passwd("a", "short", T0), Err(UserError::WeakPassword(_))));
    assert!(matches!(users.passwd("ghost", "long enough pw", T0), Err(UserError::NotFound(_))));
}

#[test]
fn passwd_role_delete_and_last_admin() {
    for (name, store) in stores() {
        let users = Users::new(store, PasswordPolicy { hash: FAST, ..PasswordPolicy::default() });
        users.add("root", "root password", Role::Admin, T0).unwrap();
        users.add("bob", "bob password", Role::Student, T0).unwrap();
        users.passwd("bob", "new bob password", at(5)).unwrap();
        assert!(matches!(users.verify("bob", "bob password", at(6)), Err(UserError::BadCredentials)));
        let bob = users.verify("bob", "new bob password", at(6)).unwrap();
        assert_eq!(bob.updated, at(5), "{name}");
        assert!(matches!(users.set_role("root", Role::Student, at(7)), Err(UserError::LastAdmin(_))));
        assert!(matches!(users.delete("root"), Err(UserError::LastAdmin(_))));
        users.set_role("bob", Role::Admin, at(8)).unwrap();
        assert_eq!(users.get("bob").unwrap().unwrap().role, Role::Admin);
        users.set_role("root", Role::Viewer, at(9)).unwrap();
        users.delete("root").unwrap();
        assert!(users.get("root").unwrap().is_none());
        assert!(matches!(users.delete("root"), Err(UserError::NotFound(_))));
        assert!(matches!(users.set_role("ghost", Role::Admin, at(9)), Err(UserError::NotFound(_))));
    }
}

#[test]
fn hash_upgraded_on_login_when_parameters_change() {
    for (name, store) in stores() {
        let old = Users::new(store.clone(), PasswordPolicy { hash: FAST, ..PasswordPolicy::default() });
        old.add("alice", "long enough pw", Role::Student, T0).unwrap();
        let newer = HashParams { memory_kib: 128, iterations: 2, parallelism: 1 };
        let users = Users::new(store, PasswordPolicy { hash: newer, ..PasswordPolicy::default() });
        let before = users.get("alice").unwrap().unwrap().password_hash;
        assert!(needs_rehash(&before, newer));
        users.verify("alice", "long enough pw", at(1)).unwrap();
        let after = users.get("alice").unwrap().unwrap().password_hash;
        assert!(after.starts_with("$argon2id$v=19$m=128,t=2,p=1$"), "{name}: {after}");
        assert!(verify_password("long enough pw", &after).unwrap());
        // A wrong password never rewrites the hash.
        assert!(users.verify("alice", "nope nope nope", at(2)).is_err());
        assert_eq!(users.get("alice").unwrap().unwrap().password_hash, after);
    }
}

#[test]
fn lab_exposes_the_same_users() {
    let (_, store) = stores().remove(1);
    let lab = Lab::new(store, config());
    lab.users().add("admin", "admin password", Role::Admin, T0).unwrap();
    assert_eq!(lab.users().list().unwrap().len(), 1);
}

#[test]
fn lab_is_shareable_between_request_threads() {
    fn assert_send_sync<T: Send + Sync>() {}
    assert_send_sync::<Lab>();
    assert_send_sync::<motus_lab::SqliteStore>();
    assert_send_sync::<motus_lab::MemoryStore>();
}
