//! Canned cycles as the seed drilling technology's jobs (`CycleOutput::DrillingTechnology`):
//! the calls each hole becomes, worked out by hand from the module documentation of
//! `interp/drilling_technology.rs` and specs/cnc.md (EXW60 rpm, EXF61 mm/min, EXF62 mm).
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_gcode::{
    format_canon, interpret_with, parse_tool_table, CycleOutput, ErrorKind, InterpreterConfig, Precision,
    Units,
};

fn config() -> InterpreterConfig {
    InterpreterConfig {
        cycles: CycleOutput::DrillingTechnology,
        tools: parse_tool_table("T1 P1 Z0 D6 ;drill 6 mm\nT2 P2 Z0 D10 ;drill 10 mm\n", Units::Mm).unwrap(),
        ..InterpreterConfig::default()
    }
}

/// The calls after the set-up, as text.
fn calls(src: &str) -> Vec<String> {
    interpret_with(src, config())
        .unwrap()
        .iter()
        .skip(5)
        .map(|c| format_canon(&c.canon, Precision::Full))
        .collect()
}

/// The calls of one hole at `[x, y, z]` with `[rpm, feed, depth, peck, chip break]`.
fn hole([x, y, z]: [&str; 3], [rpm, feed, depth, peck, chip]: [&str; 5]) -> Vec<String> {
    vec![
        format!("STRAIGHT_TRAVERSE({x}, {y}, {z}, 0, 0, 0)"),
        format!("EXTERNAL_PARAMETER(W, 60, {rpm})"),
        format!("EXTERNAL_PARAMETER(F, 61, {feed})"),
        format!("EXTERNAL_PARAMETER(F, 62, {depth})"),
        format!("EXTERNAL_PARAMETER(F, 63, {peck})"),
        format!("EXTERNAL_PARAMETER(B, 64, {chip})"),
        "M_FUNCTION(60, SYNC)".to_owned(),
    ]
}

#[test]
fn each_hole_is_one_m60_job_with_its_speed_feed_and_depth() {
    let c = calls("G21 G90\nS3600\nG0 Z5\nG81 X100 Y100 Z-10 R2 F100\nX110 Y110\nG80\nM2\n");
    let at = c.iter().position(|l| l.starts_with("STRAIGHT_TRAVERSE(100")).unwrap();
    let mut want = hole(["100", "100", "5"], ["3600", "100", "10", "0", "0"]);
    want.extend(hole(["110", "110", "5"], ["3600", "100", "10", "0", "0"]));
    assert_eq!(&c[at..at + 14], &want[..], "{c:#?}");
    // No Z move: the unit owns its Z.
    assert!(!c.iter().any(|l| l.starts_with("STRAIGHT_FEED")), "{c:#?}");
}

#[test]
fn pecks_go_to_the_technology_as_its_increment() {
    let c = calls("G21 G90 S1800 F60\nG0 Z5\nG83 X120 Y120 Z-50 R2 Q10\nG73 X130 Z-20 R2 Q4\nG80\nM2\n");
    let at = c.iter().position(|l| l.starts_with("STRAIGHT_TRAVERSE(120")).unwrap();
    let mut want = hole(["120", "120", "5"], ["1800", "60", "50", "10", "0"]);
    want.extend(hole(["130", "120", "5"], ["1800", "60", "20", "4", "1"]));
    assert_eq!(&c[at..at + 14], &want[..], "{c:#?}");
}

#[test]
fn the_surface_is_z0_of_the_coordinate_system_and_g91_and_inches_convert() {
    // G91: R from the initial level (Z5 -> R at 3), Z from R (bottom at -7); L repeats.
    let c = calls("G21 G90 S1000 F50\nG0 X0 Y0 Z5\nG91 G81 X10 Z-10 R-2 L2\nG80 G90\nM2\n");
    let holes: Vec<&String> = c.iter().filter(|l| l.contains("(F, 62,")).collect();
    assert_eq!(holes, ["EXTERNAL_PARAMETER(F, 62, 7)", "EXTERNAL_PARAMETER(F, 62, 7)"], "{c:#?}");
    assert!(c.iter().any(|l| l == "STRAIGHT_TRAVERSE(20, 0, 5, 0, 0, 0)"), "{c:#?}");
    // G20: depth and feed in mm for the unit.
    let c = calls("G20 G90 S1000 F2\nG0 Z0.2\nG81 X1 Y1 Z-0.5 R0.1\nG80\nM2\n");
    assert!(c.contains(&"EXTERNAL_PARAMETER(F, 62, 12.7)".to_owned()), "{c:#?}");
    assert!(c.contains(&"EXTERNAL_PARAMETER(F, 61, 50.8)".to_owned()), "{c:#?}");
    // A G54 Z offset moves the surface with it: the depth stays -Z.
    let c = calls("G21 G90 S1000 F50\nG10 L2 P1 Z-30\nG54 G0 Z5\nG81 X1 Y1 Z-3 R1\nG80\nM2\n");
    assert!(c.contains(&"EXTERNAL_PARAMETER(F, 62, 3)".to_owned()), "{c:#?}");
}

#[test]
fn a_tool_change_activates_the_drilling_technology() {
    let c = calls("G21 G90\nT1 M6\nT0 M6\nM2\n");
    let m63: Vec<_> = c.iter().filter(|l| *l == "M_FUNCTION(63, SYNC)").collect();
    assert_eq!(m63.len(), 1, "T0 changes nothing: {c:#?}");
    let change = c.iter().position(|l| l == "CHANGE_TOOL(1)").unwrap();
    assert_eq!(c[change + 1], "M_FUNCTION(63, SYNC)", "{c:#?}");
    // In LinuxCNC's motion mode, M6 is only the tool change.
    let motion = InterpreterConfig { cycles: CycleOutput::Motion, ..config() };
    let calls = interpret_with("T1 M6\nM2\n", motion).unwrap();
    assert!(!calls.iter().any(|c| format_canon(&c.canon, Precision::Full).starts_with("M_FUNCTION")));
}

#[test]
fn what_the_unit_cannot_do_is_refused_at_its_line() {
    for (src, kind) in [
        ("S1000 F50\nG0 Z5\nG82 X1 Z-2 R1 P0.5\nM2\n", ErrorKind::CycleNotOnTechnology(82)),
        ("S1000 F50\nG0 Z5\nG85 X1 Z-2 R1\nM2\n", ErrorKind::CycleNotOnTechnology(85)),
        ("S1000 F50\nG0 Z5\nG89 X1 Z-2 R1 P1\nM2\n", ErrorKind::CycleNotOnTechnology(89)),
        ("F50\nG0 Z5\nG81 X1 Z-2 R1\nM2\n", ErrorKind::TechnologySpindleSpeed(0.0)),
        ("S40000 F50\nG0 Z5\nG81 X1 Z-2 R1\nM2\n", ErrorKind::TechnologySpindleSpeed(40000.0)),
        ("S1000 F50\nG0 Z5\nG81 X1 Z1 R2\nM2\n", ErrorKind::HoleNotBelowSurface(1.0)),
    ] {
        let e = interpret_with(src, config()).unwrap_err();
        assert_eq!((e.line, &e.kind), (3, &kind), "{src}: {e}");
    }
    // The message names what is wrong.
    let e = interpret_with("S1000 F50\nG0 Z5\nG82 X1 Z-2 R1 P0.5\nM2\n", config()).unwrap_err();
    assert!(e.to_string().contains("G82 cannot run on the drilling technology"), "{e}");
    // LinuxCNC's own checks come first and read the same.
    let e = interpret_with("S1000 F50\nG0 Z5\nG81 X1 Z-2\nM2\n", config()).unwrap_err();
    assert_eq!(e.kind, ErrorKind::CycleWithoutR);
}
