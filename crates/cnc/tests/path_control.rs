#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
//! G61, G61.1 and G64 P Q from the program to the executed set-points: the corner of an L
//! at (50, 0) is cut within G64's P (in program units), passed exactly under G61, and the
//! path stops at every move under G61.1.

use motus_cnc::{Limits3, NoTechnology, ProgramRun};
use motus_gcode::InterpreterConfig;

/// Closest approach of the executed path to the corner (50, 0), and the path speed there.
fn at_corner(src: &str) -> (f64, f64, u32) {
    let cfg = InterpreterConfig { require_program_end: false, ..InterpreterConfig::default() };
    let mut run = ProgramRun::new(src, cfg, Limits3::default(), [0.0; 3]).unwrap();
    let mut best = (f64::INFINITY, 0.0);
    let mut stops = 0;
    let mut moving = false;
    run.run_to_end(0.0005, &mut NoTechnology::default(), 60.0, |sp, _, _| {
        let d = (sp.positions[0] - 50.0).hypot(sp.positions[1]);
        if d < best.0 {
            best = (d, sp.path_speed);
        }
        if moving && sp.path_speed == 0.0 {
            stops += 1;
        }
        moving = sp.path_speed > 0.0;
    })
    .unwrap();
    (best.0, best.1, stops)
}

#[test]
fn g64_p_sets_the_corner_tolerance_and_g61_passes_the_corner_exactly() {
    let l = "G1 X25\nG1 X50\nG1 Y50\nM2\n";
    // The machine's default (0.05 mm) under G64 without P.
    let (d, v, _) = at_corner(&format!("G21 G90 G64 F3000\n{l}"));
    assert!((d - 0.05).abs() < 0.005 && v > 0.0, "G64: {d} mm at {v} mm/s");
    let (d, v, _) = at_corner(&format!("G21 G90 G64 P0.4 F3000\n{l}"));
    assert!((d - 0.4).abs() < 0.01 && v > 0.0, "G64 P0.4: {d} mm at {v} mm/s");
    // P in inches under G20: 0.01 in = 0.254 mm.
    let (d, _, _) = at_corner(&format!(
        "G20 G90 G64 P0.01 F118.11\n{}",
        "G1 X0.984252\nG1 X1.968504\nG1 Y1.968504\nM2\n"
    ));
    assert!((d - 0.254).abs() < 0.01, "G20 G64 P0.01: {d} mm");
    let (d, v, stops) = at_corner(&format!("G21 G90 G61 F3000\n{l}"));
    assert!(d < 1e-6 && v < 1.0, "G61: {d} mm at {v} mm/s");
    assert_eq!(stops, 2, "G61: the corner and the end; the collinear join runs on");
    let (_, _, stops) = at_corner(&format!("G21 G90 G61.1 F3000\n{l}"));
    assert_eq!(stops, 3, "G61.1: a stop after every move, the collinear one too");
}
