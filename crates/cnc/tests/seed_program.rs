#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
//! The seed's example program (specs/cnc.md), as G-code text, through the whole chain:
//! interpreter -> block buffer -> planner/executor -> drilling technology on the simulated
//! machine. Expected values by hand (see crates/cnc-tech/tests/seed_program.rs): holes at the
//! program coordinates, 10 mm deep (EXF62's start value) for the first two and 50 mm for the
//! third, at 3600 / 3600 / 1800 rpm and 100 / 100 / 60 mm/min.

use motus_cnc::{DrillingTechnology, Limits3, ProgramRun, RunStatus};
use motus_gcode::InterpreterConfig;

const SEED: &str = "N001 M63
N005 G00 X100 Y100 F300
N010 EXW60=3600 EXF61=100
N020 M60
N030 G01 X110 Y110
N040 M60
N050 G01 X120 Y120 A35
N060 EXW60=1800 EXF61=60 EXF62=50
N070 M60
";

#[test]
fn seed_program_drills_its_holes_through_the_whole_chain() {
    let config = InterpreterConfig { require_program_end: false, ..InterpreterConfig::default() };
    let mut run = ProgramRun::new(SEED, config, Limits3::default(), [0.0; 3]).unwrap();
    let mut tech = DrillingTechnology::simulated();
    let mut states = Vec::new();
    let mut waited = 0u64;
    let report = run
        .run_to_end(0.001, &mut tech, 600.0, |sp, status, _| {
            if status == RunStatus::WaitingTechnology {
                waited += 1;
            }
            if std::env::var("DBG").is_ok() && sp.velocities.iter().any(|v| v.abs() > 0.0) {
                eprintln!(
                    "{:.3} {:?} {:?} {:?} {:?}",
                    sp.time, sp.state, sp.coupling, sp.positions, sp.velocities
                );
            }
        })
        .map_err(|e| e.to_string())
        .unwrap();
    // The technology's state machine, visible through its Info after every cycle.
    states.push(tech.info().state);
    let holes = tech.holes();
    assert_eq!(holes.len(), 3, "{holes:?}");
    let expected = [
        (100.0, 100.0, 10.0, 3600.0, 100.0),
        (110.0, 110.0, 10.0, 3600.0, 100.0),
        (120.0, 120.0, 50.0, 1800.0, 60.0),
    ];
    for (h, (x, y, depth, rpm, feed)) in holes.iter().zip(expected) {
        assert!((h.tool_xy[0] - x).abs() < 1e-6 && (h.tool_xy[1] - y).abs() < 1e-6, "{h:?}");
        assert!((h.depth - depth).abs() < 1e-6, "{h:?}");
        assert_eq!(h.spindle_rpm, rpm, "{h:?}");
        assert!((h.feed - feed).abs() < 1e-6, "{h:?}");
    }
    assert!(tech.cell.machine().events().is_empty(), "{:?}", tech.cell.machine().events());
    assert_eq!(report.m_functions, 4, "M63 + three M60");
    assert!(waited > 100, "the path waited for the technology ({waited} cycles)");
    assert!(report.duration > 1.0);
    // The limits held on the executed set-points (X, Y 200 mm/s, 2000 mm/s²; small allowance
    // for the finite-difference measurement).
    for (v, a) in report.peak_velocity.iter().zip(report.peak_acceleration) {
        assert!(*v <= 200.0 * (1.0 + 1e-9), "{report:?}");
        assert!(a <= 2000.0 * 1.001, "{report:?}");
    }
    eprintln!("seed program: {report:?}");
}

#[test]
fn an_invalid_line_stops_the_run_with_its_line_and_column() {
    let src = "G21 G90\nG1 X10 F100\nG1 X20 Y#\nM2\n";
    let mut run = ProgramRun::new(src, InterpreterConfig::default(), Limits3::default(), [0.0; 3]).unwrap();
    let mut tech = motus_cnc::NoTechnology::default();
    let err = run.run_to_end(0.001, &mut tech, 60.0, |_, _, _| {}).unwrap_err().to_string();
    assert!(err.starts_with("3:"), "{err}");
}
