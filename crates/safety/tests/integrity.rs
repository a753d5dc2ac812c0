#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
//! Integrity fingerprint, change report and admin approval.

use motus_safety::*;

fn drives() -> Vec<DriveParameters> {
    ["arm_left", "vertical_left", "arm_right", "vertical_right", "thrower"]
        .iter()
        .enumerate()
        .map(|(i, n)| DriveParameters {
            axis: (*n).into(),
            node_id: i as u32 + 1,
            serial_number: format!("A{}", 1000 + i),
            a_stop: 500_000.0,
            accel_limits: [500_000.0; 4],
            homing_offset: -900.0,
            homing_mode: 1,
            encoder_inverted: false,
            encoder_scaling: 1.0,
            input_levels: 0b1010,
            motion_mode: 0,
        })
        .collect()
}

fn snap(toml: &str, d: &[DriveParameters]) -> Snapshot {
    Snapshot::new(&RuleSet::from_toml(toml).unwrap(), d).with_module("x20safety", b"task v1")
}

#[test]
fn fingerprint_ignores_comments_and_spelling() {
    let a = snap(JUGGLER_TOML, &drives());
    let b = snap(
        &JUGGLER_TOML.replace("# ", "#~ ").replace("expr = \"limits(thrower)\"", "expr = \"  limits( 5 )\""),
        &drives(),
    );
    assert_eq!(a.fingerprint(), b.fingerprint());
    assert_eq!(a.fingerprint().to_string().len(), 64);
    // The fingerprint is the SHA-256 of the canonical text (checked with an independent
    // implementation: Python's hashlib over the same text).
    let text = a.canonical_text();
    assert!(text.contains("axis[arm_left].limits.max=1000.0\n"));
    assert!(text.contains("drive[thrower].serial_number=\"A1004\"\n"));
    let py = std::process::Command::new("python3")
        .args(["-c", "import sys,hashlib;print(hashlib.sha256(sys.stdin.buffer.read()).hexdigest())"])
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    use std::io::Write;
    py.stdin.as_ref().unwrap().write_all(text.as_bytes()).unwrap();
    let out = py.wait_with_output().unwrap();
    assert_eq!(String::from_utf8(out.stdout).unwrap().trim(), a.fingerprint().to_string());
}

#[test]
fn check_names_what_changed_and_only_admin_approves() {
    let secret = b"lab-admin-secret";
    let mut integ = Integrity::new(snap(JUGGLER_TOML, &drives()), integrity::secret_hash(secret));
    assert!(integ.check(&snap(JUGGLER_TOML, &drives())).is_ok());

    // A student-side change: wider arm limit and a swapped amplifier.
    let toml = JUGGLER_TOML.replacen(
        "limits = { min = -1000, max = 1000 }",
        "limits = { min = -1000, max = 1100 }",
        1,
    );
    let mut d = drives();
    d[4].serial_number = "B9999".into();
    let current = snap(&toml, &d);
    let err = integ.check(&current).unwrap_err();
    let IntegrityError::Changed { current: fp, changes } = &err else { panic!("{err:?}") };
    assert_eq!(changes.len(), 2);
    assert_eq!(changes[0].to_string(), "axis[arm_left].limits.max: 1000.0 -> 1100.0");
    assert_eq!(changes[1].to_string(), "drive[thrower].serial_number: \"A1004\" -> \"B9999\"");
    assert!(err.to_string().contains(&fp.to_string()));

    // Module changed / removed.
    let m = Snapshot::new(&RuleSet::from_toml(JUGGLER_TOML).unwrap(), &drives());
    let e = integ.check(&m).unwrap_err().to_string();
    assert!(e.contains("module[x20safety].sha256: ") && e.ends_with("-> (absent)"), "{e}");

    // Re-check the change so it is pending, then approvals.
    let _ = integ.check(&current);
    let fp = current.fingerprint();
    let student = AdminToken::new("student", b"guess".to_vec());
    assert_eq!(integ.approve(fp, &student), Err(IntegrityError::NotAuthorised));
    let admin = AdminToken::new("admin", secret.to_vec());
    let other = snap(JUGGLER_TOML, &drives()).fingerprint();
    assert!(matches!(integ.approve(other, &admin), Err(IntegrityError::NotPending { .. })));
    assert!(integ.check(&current).is_err());
    integ.approve(fp, &admin).unwrap();
    assert_eq!(integ.approved(), fp);
    assert!(integ.check(&current).is_ok());
    assert!(format!("{admin:?}").contains("<secret>"));
}

#[test]
fn approval_file_signed_with_the_admin_key_round_trips_and_rejects_edits() {
    let key = b"0123456789abcdef-admin-key";
    let s = snap(JUGGLER_TOML, &drives());
    let a = Approval::sign(&s, "alice", "2026-11-21T20:00:00Z", key).unwrap();
    let text = a.to_toml().unwrap();
    let back = Approval::from_toml(&text).unwrap();
    assert_eq!(back.verify(key).unwrap(), s);
    // Another key: refused.
    assert_eq!(back.verify(b"another-key-of-16+bytes"), Err(ApprovalError::BadSignature));
    // An edited approved value (a student widening a limit in the file): refused.
    let edited = text.replace("axis[thrower].limits.max=3400.0", "axis[thrower].limits.max=9400.0");
    assert_ne!(edited, text, "the canonical text names the thrower's limit");
    assert_eq!(Approval::from_toml(&edited).unwrap().verify(key), Err(ApprovalError::BadSignature));
    assert_eq!(Approval::sign(&s, "a", "t", b"short").unwrap_err(), ApprovalError::KeyTooShort(5));
}
