//! `motus gcode check | canon | plan | run` through the binary.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use common::MOTUS;
use std::process::{Command, Output};

fn motus(args: &[&str]) -> Output {
    Command::new(MOTUS).args(args).output().unwrap()
}

fn write(dir: &std::path::Path, name: &str, text: &str) -> String {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p.to_str().unwrap().to_owned()
}

#[test]
fn check_names_the_line_and_column_of_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let ok = write(dir.path(), "ok.ngc", "G21 G90\nG1 X10 F100\nM2\n");
    let o = motus(&["gcode", "check", &ok]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let bad = write(dir.path(), "bad.ngc", "G21 G90\nG0 X1\nG1 X10\nM2\n");
    let o = motus(&["gcode", "check", &bad]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("bad.ngc:3:"), "{err}");
    assert!(err.to_lowercase().contains("zero feed rate"), "{err}");
}

#[test]
fn canon_matches_rs274_line_for_line() {
    // rs274 (LinuxCNC's standalone interpreter) is installed by scripts/install-oracles.sh.
    let dir = tempfile::tempdir().unwrap();
    let prog =
        write(dir.path(), "p.ngc", "G21 G90\nG0 X1 Y2\nG1 X10 F100\nG2 X20 Y2 I5 J0\nG18 G3 X0 Z5 R12\nM2\n");
    let o = motus(&["gcode", "canon", "--rs274", &prog]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let ours = String::from_utf8_lossy(&o.stdout).to_string();
    let var = write(dir.path(), "p.var", "");
    let tbl = write(dir.path(), "tool.tbl", "");
    let r = Command::new("rs274")
        .args(["-g", "-n", "2", "-t", &tbl, "-v", &var, &prog])
        .env("HOME", dir.path())
        .stdin(std::process::Stdio::null())
        .output()
        .expect("rs274 is needed (apt-get install linuxcnc-uspace)");
    let theirs = String::from_utf8_lossy(&r.stdout).to_string();
    // Compare the motion calls (rs274 adds interpreter comments and resets).
    let motion = |s: &str| -> Vec<String> {
        s.lines()
            .filter_map(|l| l.get(13..))
            .filter(|c| {
                c.starts_with("STRAIGHT_") || c.starts_with("ARC_FEED") || c.starts_with("SET_FEED_RATE")
            })
            .map(|c| c.replace("-0.0000", "0.0000"))
            .collect()
    };
    assert_eq!(motion(&ours), motion(&theirs), "ours:\n{ours}\nrs274:\n{theirs}");
    assert_eq!(motion(&ours).len(), 6, "traverse, 2 feed rates, feed, 2 arcs");
}

#[test]
fn plan_reports_limits_held_and_run_drills_the_seed_program() {
    let dir = tempfile::tempdir().unwrap();
    let square = write(dir.path(), "sq.ngc", "G21 G90 F6000\nG1 X100\nG1 Y100\nG1 X0\nG1 Y0\nM2\n");
    let o = motus(&["gcode", "plan", &square, "--limits", "200,2000"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    // 400 mm at 100 mm/s with 4 stops at 2000 mm/s²: 4 x (100/2000 + 50/100) ... > 4 s.
    let d = v["duration_s"].as_f64().unwrap();
    assert!(d > 4.0 && d < 5.0, "{v}");
    for (p, l) in v["peak_acceleration_mm_s2"].as_array().unwrap().iter().zip([2000.0, 2000.0, 2000.0]) {
        assert!(p.as_f64().unwrap() <= l * 1.001, "{v}");
    }
    let seed = write(
        dir.path(),
        "seed.ngc",
        "N001 M63\nN005 G00 X100 Y100 F300\nN010 EXW60=3600 EXF61=100\nN020 M60\nN030 G01 X110 Y110\nN040 M60\nN050 G01 X120 Y120 A35\nN060 EXW60=1800 EXF61=60 EXF62=50\nN070 M60\n",
    );
    let o = motus(&["gcode", "run", &seed, "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = String::from_utf8_lossy(&o.stdout);
    let holes: Vec<serde_json::Value> =
        out.lines().filter(|l| l.contains("\"hole\"")).map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(holes.len(), 3, "{out}");
    assert_eq!(holes[2]["rpm"].as_f64(), Some(1800.0));
    assert!((holes[2]["depth_mm"].as_f64().unwrap() - 50.0).abs() < 1e-6);
    assert!(out.contains("\"technology\":\"Drill\""), "the drilling state is visible");
}

#[test]
fn run_drills_canned_cycles_through_the_drilling_technology() {
    let dir = tempfile::tempdir().unwrap();
    let tools = write(dir.path(), "tools.tbl", "T1 P1 Z0 D6 ;6 mm drill\n");
    let prog = write(
        dir.path(),
        "holes.ngc",
        "G21 G90\nT1 M6\nS1800 F60\nG0 Z5\nG83 X120 Y120 Z-30 R2 Q10\nG80\nM2\n",
    );
    let o = motus(&["gcode", "run", &prog, "--tool-table", &tools, "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = String::from_utf8_lossy(&o.stdout);
    let holes: Vec<serde_json::Value> =
        out.lines().filter(|l| l.contains("\"hole\"")).map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(holes.len(), 1, "{out}");
    assert!((holes[0]["depth_mm"].as_f64().unwrap() - 30.0).abs() < 1e-6, "{out}");
    assert!((holes[0]["feed_mm_min"].as_f64().unwrap() - 60.0).abs() < 1e-6, "{out}");
    assert_eq!(holes[0]["entries"].as_u64(), Some(3), "three 10 mm pecks: {out}");
    // A cycle the unit cannot do is refused when checked for it, naming the line and why.
    let dwell = write(dir.path(), "dwell.ngc", "S1000 F50\nG0 Z5\nG82 X1 Z-2 R1 P0.5\nM2\n");
    let o = motus(&["gcode", "check", &dwell, "--cycles", "drilling-technology"]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("dwell.ngc:3:") && err.contains("G82 cannot run on the drilling technology"),
        "{err}"
    );
    // LinuxCNC's motion is the default for check: the same program is valid there.
    assert!(motus(&["gcode", "check", &dwell]).status.success());
}

#[test]
fn run_on_a_cell_moves_its_gantry_axes() {
    let dir = tempfile::tempdir().unwrap();
    let mut cell = String::from("[station]\nname = \"gantry test\"\n");
    for (axis, max) in [("x", 0.6), ("y", 0.4), ("z", 0.15)] {
        cell.push_str(&format!(
            "[[device]]\nname = \"cnc-{axis}\"\nkind = \"sim-axis\"\n\n[[axis]]\nname = \"{axis}\"\ndevice = \"cnc-{axis}\"\nunit = \"m\"\nscale = 1e-6\nlimits = {{ min = 0.0, max = {max} }}\nmax_velocity = 0.1\nmax_acceleration = 1.0\n\n"
        ));
    }
    cell.push_str("[[group]]\nname = \"cnc\"\nkind = \"gantry\"\naxes = [\"x\", \"y\", \"z\"]\n");
    let cell = write(dir.path(), "cell.toml", &cell);
    let prog = write(dir.path(), "p.ngc", "G21 G90 F3000\nG1 X40 Y20 Z5\nG1 X60\nM2\n");
    let o = motus(&["gcode", "run", &prog, "--cell", &cell, "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = String::from_utf8_lossy(&o.stdout);
    let last: serde_json::Value =
        serde_json::from_str(out.lines().rfind(|l| l.contains("\"xyz\"")).unwrap()).unwrap();
    assert_eq!(last["status"], "done", "{out}");
    // The real axes (simulated devices of the cell) followed the set-points to the end.
    let g: serde_json::Value =
        serde_json::from_str(out.lines().find(|l| l.contains("gantry_mm")).unwrap()).unwrap();
    for (axis, want) in [("x", 60.0), ("y", 20.0), ("z", 5.0)] {
        let got = g["gantry_mm"][axis].as_f64().unwrap();
        assert!((got - want).abs() < 0.01, "{axis}: {got} mm, want {want}");
    }
    // Planned within the cell's 100 mm/s: the 60 mm in X take well over 0.6 s.
    assert!(last["t"].as_f64().unwrap() > 0.6, "{last}");
}
