//! The shipped demo cell loads and describes every machine of the laboratory.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use std::path::Path;
use std::time::Duration;

use motus_station::config::{load, DeviceKind, GroupKind, LinkKind};

fn demo_path() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/demo-cell.toml")
}

#[test]
fn demo_cell_loads() {
    let cell = load(&demo_path()).unwrap_or_else(|e| panic!("{e}"));
    // Groups and their sizes, counted from the list of machines.
    let g = |n: &str| cell.group(n).unwrap();
    assert_eq!(g("omni").kind, GroupKind::Omni);
    assert_eq!(g("omni").axes.len(), 3);
    assert_eq!(g("head").axes, vec!["pan", "tilt"]);
    assert_eq!(g("arm").axes.len(), 6);
    assert_eq!(g("juggler").axes.len(), 5);
    assert_eq!(g("cnc").axes, vec!["x", "y", "z"]);
    // The wheels are CiA 402 nodes 2-4 on the virtual CAN bus.
    let can = cell.link("vcan").unwrap();
    assert_eq!(can.kind, LinkKind::Can);
    let wheels: Vec<u32> = cell.devices_on_link("vcan").iter().filter_map(|d| d.address).collect();
    assert_eq!(wheels, vec![2, 3, 4]);
    // Four PS1A modules on one pty, addresses 1-4.
    let ps1a = cell.devices_on_link("ps1a-line");
    assert_eq!(ps1a.len(), 4);
    assert!(ps1a.iter().all(|d| d.kind == DeviceKind::Ps1a && d.simulate));
    // The arm is one device with six joints 0..5.
    let joints: Vec<u32> = cell.axes_of_device("kv01").iter().map(|a| a.index).collect();
    assert_eq!(joints, vec![0, 1, 2, 3, 4, 5]);
    // The juggler's supervisor rules exist (checked by load) and point at the safety crate.
    let sup = cell.supervisor.as_ref().unwrap();
    assert!(sup.rules.ends_with("safety/examples/juggler.toml"));
    assert!(sup.rules.exists());
    // ... and so do the juggler's drive parameters, approved and watched with them.
    let drives = sup.drives.as_ref().unwrap();
    assert!(drives.ends_with("safety/examples/juggler-drives.toml"));
    assert_eq!(drive_tables(drives), 5);
    // Task classes: 1 ms, 10 ms, 20 ms, 100 ms.
    let periods: Vec<Duration> = cell.task_classes().iter().map(|c| c.period).collect();
    assert_eq!(
        periods,
        vec![
            Duration::from_millis(1),
            Duration::from_millis(10),
            Duration::from_millis(20),
            Duration::from_millis(100)
        ]
    );
    assert_eq!(cell.task_classes()[3].overrun_limit, 3);
}

/// `[[drive]]` tables in a drive-parameter file (this crate does not depend on the safety
/// crate: counted in the text).
fn drive_tables(path: &Path) -> usize {
    std::fs::read_to_string(path).unwrap().lines().filter(|l| l.trim() == "[[drive]]").count()
}

#[test]
fn a_broken_copy_of_the_demo_cell_names_line_and_key() {
    let text = std::fs::read_to_string(demo_path()).unwrap();
    // Make the tilt axis's student range leave its machine range.
    let broken = text.replace(
        "student = { min = -1.0, max = 1.0, max_velocity = 2.0 }",
        "student = { min = -1.5, max = 1.0, max_velocity = 2.0 }",
    );
    assert_ne!(broken, text);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cell.toml");
    std::fs::write(&path, &broken).unwrap();
    let errs = load(&path).unwrap_err();
    let line = broken.lines().position(|l| l.contains("min = -1.5")).unwrap() + 1;
    // In the temporary folder the rules and program files are missing too.
    let e = errs.errors().iter().find(|e| e.key.ends_with("student.min")).unwrap();
    assert_eq!(e.line, line);
    assert!(
        e.to_string()
            .contains("axis \"tilt\": student.min (-1.5) must be within the machine limits -1.2 ..= 1.2"),
        "{e}"
    );
    assert!(errs.errors().iter().any(|e| e.key == "supervisor.rules"));
    assert!(errs.errors().iter().any(|e| e.key == "program[0].file"));
}
