//! Compares Motus's canonical stream with LinuxCNC's, call by call, on tests/corpus/*.ngc:
//! * `rs274 -g -n 2` (text, 4 decimals): names and every argument within 5e-5;
//! * LinuxCNC's Python `gcode` module (tests/oracle/gcode_oracle.py, full doubles):
//!   every end point, arc centre, offset and XY rotation within 1e-6 mm (degree).
//!
//! Ignored on both sides: `COMMENT(...)` lines (LinuxCNC adds "interpreter: ..." ones)
//! and `ON_RESET()` (printed by the rs274 driver, not by the interpreter); Motus's M66
//! `WAIT(...)`, which the standalone rs274 does not print, is checked to come from an M66
//! line and left out. Motus runs in the LinuxCNC M-code dialect (M60-M68 as LinuxCNC).
//! tests/corpus/errors/*.ngc must fail in both, at the same line.
//! These tests FAIL when rs274 or /usr/bin/python3 with the `gcode` module are missing.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use motus_gcode::{
    format_canon, interpret_with, parse_tool_table, Canon, InterpreterConfig, MCodeDialect, Precision, Units,
};

/// The tool table `rs274` and Motus run with: `rs274` reads it in inches (its configured
/// units); Motus reads the same file in inches and keeps it in millimetres.
const TOOL_TABLE: &str = "T1 P1 D0.125 Z0.5 ;drill\nT2 P2 D0.25 Z1.25 X0.01 ;\nT7 P5 D0.5 Z-0.2 ;\n";

/// Programs the Python `gcode` module cannot run: outside a running LinuxCNC it has no tool
/// data, and a T word, M61 Q or a G41/G42 D word (the radius of a tool in the table)
/// crashes it (segmentation fault, LinuxCNC 2.9). They are compared with `rs274` only.
const WITHOUT_GCODE_MODULE: &[&str] = &[
    "27_tools_and_length_offsets.ngc",
    "30_fusion_2d_contour_mm.ngc",
    "31_mastercam_pocket_helix.ngc",
    "49_g53_tool_change_with_length_offsets.ngc",
    "61_g92_g52_with_tool_offset_inch.ngc",
    "66_cam_contour_finish_g41_mm.ngc",
    "67_g42_outside_profile_inch.ngc",
    "72_g18_lathe_profile_comp_inch.ngc",
    "83_rotated_inch_with_tool_x_offset.ngc",
    // M61 Q crashes it as a T word does.
    "87_m61_tool_in_spindle_and_pallet_m60.ngc",
];

/// Motus's interpretation with the oracles' tool table, M60-M68 read as LinuxCNC does.
fn interpret(src: &str) -> Result<Vec<motus_gcode::CanonCall>, motus_gcode::GcodeError> {
    let tools = parse_tool_table(TOOL_TABLE, Units::Inch).unwrap();
    interpret_with(
        src,
        InterpreterConfig { tools, m_codes: MCodeDialect::LinuxCnc, ..InterpreterConfig::default() },
    )
}

fn corpus(sub: &str) -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/corpus").join(sub);
    let mut v: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "ngc"))
        .collect();
    v.sort();
    v
}

/// Runs rs274 in a private HOME with a fresh var file; returns (stdout, stderr, success).
fn run_rs274(prog: &Path) -> (String, String, bool) {
    let tmp = tempfile::tempdir().unwrap();
    let tbl = tmp.path().join("tool.tbl");
    std::fs::write(&tbl, TOOL_TABLE).unwrap();
    let var = tmp.path().join("fresh.var");
    std::fs::write(&var, "").unwrap();
    let out = Command::new("rs274")
        .args(["-g", "-n", "2", "-t"])
        .arg(&tbl)
        .arg("-v")
        .arg(&var)
        .arg(prog)
        .env("HOME", tmp.path())
        .stdin(Stdio::null())
        .output()
        .expect("rs274 must be installed (apt-get install linuxcnc-uspace)");
    (
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
        out.status.success(),
    )
}

fn run_python(prog: &Path) -> String {
    let tmp = tempfile::tempdir().unwrap();
    let var = tmp.path().join("p.var");
    std::fs::write(&var, "").unwrap();
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/oracle/gcode_oracle.py");
    let out = Command::new("/usr/bin/python3")
        .arg(script)
        .arg(prog)
        .arg(&var)
        .env("HOME", tmp.path())
        .stdin(Stdio::null())
        .output()
        .expect("/usr/bin/python3 must exist");
    assert!(
        out.status.success(),
        "gcode oracle failed (LinuxCNC's python3 `gcode` module missing?): {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// `NAME(a, b, ...)` -> (name, args); `SET_SPINDLE_MODE(0 0.0000)` splits on spaces too.
fn split_call(s: &str) -> (String, Vec<String>) {
    let open = s.find('(').unwrap();
    let name = s[..open].to_owned();
    let inner = &s[open + 1..s.len() - 1];
    let args = inner.split([',', ' ']).map(str::trim).filter(|a| !a.is_empty()).map(str::to_owned).collect();
    (name, args)
}

fn keep(name: &str) -> bool {
    name != "COMMENT" && name != "ON_RESET"
}

/// rs274's standalone canon prints nothing for M66's `WAIT` (LinuxCNC's interpreter calls
/// it all the same): Motus's `WAIT(...)` calls are left out of the text comparison, after
/// checking that each comes from a line with M66.
fn without_waits(prog: &Path, src: &str, calls: &[motus_gcode::CanonCall]) -> Vec<(String, Vec<String>)> {
    let mut v = Vec::new();
    for c in calls {
        if let Canon::WaitInput { .. } = c.canon {
            let line = src.lines().nth(c.line as usize - 1).unwrap_or("").to_ascii_uppercase();
            assert!(line.contains("M66"), "{}: WAIT from line {}: {line}", prog.display(), c.line);
            continue;
        }
        v.push(split_call(&format_canon(&c.canon, Precision::Full)));
    }
    v
}

fn rs274_calls(stdout: &str) -> Vec<(String, Vec<String>)> {
    stdout
        .lines()
        // Canonical calls only: a program's (PRINT,...) text is printed between them.
        .filter(|l| l.len() > 13 && l.get(5..7) == Some(" N") && l.ends_with(')'))
        .map(|l| split_call(l[13..].trim()))
        .filter(|(n, _)| keep(n))
        .collect()
}

fn args_match(a: &[String], b: &[String], tol: f64) -> bool {
    a.len() == b.len()
        && a.iter().zip(b).all(|(x, y)| match (x.parse::<f64>(), y.parse::<f64>()) {
            (Ok(x), Ok(y)) => (x - y).abs() <= tol,
            _ => x == y,
        })
}

#[test]
fn canon_matches_rs274_text() {
    let progs = corpus("");
    assert!(progs.len() >= 15);
    for prog in progs {
        let (stdout, stderr, ok) = run_rs274(&prog);
        assert!(ok, "{}: rs274 failed: {stderr}", prog.display());
        let theirs = rs274_calls(&stdout);
        let src = std::fs::read_to_string(&prog).unwrap();
        let calls = interpret(&src).unwrap_or_else(|e| panic!("{}: {e}", prog.display()));
        let ours: Vec<(String, Vec<String>)> =
            without_waits(&prog, &src, &calls).into_iter().filter(|(n, _)| keep(n)).collect();
        for (k, (t, o)) in theirs.iter().zip(&ours).enumerate() {
            assert!(
                t.0 == o.0 && args_match(&t.1, &o.1, 5e-5),
                "{}: call {k} differs: rs274 {t:?} vs motus {o:?}",
                prog.display()
            );
        }
        assert_eq!(theirs.len(), ours.len(), "{}: call count", prog.display());
    }
}

/// Our calls in the Python oracle's vocabulary, lengths in mm.
fn ours_full(src: &str) -> Vec<(String, Vec<f64>)> {
    let mut units = Units::Mm;
    let mut v = Vec::new();
    for c in interpret(src).unwrap() {
        let f = units.mm_per_unit();
        let mm = |p: &[f64; 6]| vec![p[0] * f, p[1] * f, p[2] * f, p[3], p[4], p[5]];
        match c.canon {
            Canon::UseLengthUnits { units: u } => units = u,
            Canon::StraightTraverse { end } => v.push(("traverse".into(), mm(&end))),
            Canon::StraightFeed { end } => v.push(("feed".into(), mm(&end))),
            Canon::ArcFeed(a) => v.push((
                "arc".into(),
                vec![
                    a.first_end * f,
                    a.second_end * f,
                    a.first_centre * f,
                    a.second_centre * f,
                    f64::from(a.rotation),
                    a.axis_end * f,
                    a.a,
                    a.b,
                    a.c,
                ],
            )),
            Canon::SetG5xOffset { index, offset } => {
                let mut x = vec![f64::from(index)];
                x.extend(mm(&offset));
                v.push(("g5x".into(), x));
            }
            Canon::SetG92Offset { offset } => v.push(("g92".into(), mm(&offset))),
            Canon::Dwell { seconds } => v.push(("dwell".into(), vec![seconds])),
            Canon::SetXyRotation { degrees } => v.push(("rot".into(), vec![degrees])),
            _ => {}
        }
    }
    v
}

#[test]
fn canon_matches_gcode_module_within_1e6_mm() {
    for prog in corpus("") {
        let name = prog.file_name().unwrap().to_string_lossy().into_owned();
        if WITHOUT_GCODE_MODULE.contains(&name.as_str()) {
            eprintln!("{name}: rs274 only (the gcode module has no tool table outside LinuxCNC)");
            continue;
        }
        let out = run_python(&prog);
        let theirs: Vec<(String, Vec<f64>)> = out
            .lines()
            // Motion and offset calls only (not result/message/plane, nor a program's
            // (PRINT,...) text, which the module prints on the same output).
            .filter(|l| {
                l.split_whitespace()
                    .next()
                    .is_some_and(|n| ["traverse", "feed", "arc", "g5x", "g92", "dwell", "rot"].contains(&n))
            })
            .map(|l| {
                let mut it = l.split_whitespace();
                let name = it.next().unwrap().to_owned();
                (name, it.map(|x| x.parse::<f64>().unwrap()).collect())
            })
            .collect();
        let res = out.lines().find(|l| l.starts_with("result")).unwrap();
        assert!(res.ends_with(" 0"), "{}: gcode module error: {out}", prog.display());
        let src = std::fs::read_to_string(&prog).unwrap();
        let ours = ours_full(&src);
        let mut worst = 0.0f64;
        for (k, (t, o)) in theirs.iter().zip(&ours).enumerate() {
            assert_eq!(t.0, o.0, "{}: call {k}: {t:?} vs {o:?}", prog.display());
            assert_eq!(t.1.len(), o.1.len(), "{}: call {k}", prog.display());
            for (x, y) in t.1.iter().zip(&o.1) {
                worst = worst.max((x - y).abs());
                assert!(
                    (x - y).abs() <= 1e-6,
                    "{}: call {k}: gcode module {t:?} vs motus {o:?}",
                    prog.display()
                );
            }
        }
        assert_eq!(theirs.len(), ours.len(), "{}: call count", prog.display());
        eprintln!("{}: {} calls, worst |diff| {worst:e} mm", prog.display(), ours.len());
    }
}

#[test]
fn errors_at_the_same_line_as_rs274() {
    let progs = corpus("errors");
    assert!(progs.len() >= 5);
    for prog in progs {
        let (_, stderr, ok) = run_rs274(&prog);
        assert!(!ok, "{}: rs274 accepted it", prog.display());
        // rs274 -n 2 prints the message, then the offending line's text.
        let their_text = stderr.lines().last().unwrap().trim().to_owned();
        let src = std::fs::read_to_string(&prog).unwrap();
        let err = interpret(&src).expect_err(&prog.display().to_string());
        let our_text = src.lines().nth(err.line as usize - 1).unwrap().trim();
        assert_eq!(our_text, their_text, "{}: motus error {err}; rs274: {stderr}", prog.display());
    }
}
