#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
//! The seed's example program (specs/cnc.md), as G-code text, through the whole chain:
//! interpreter -> block buffer -> planner/executor -> drilling technology on the simulated
//! machine. Expected values by hand (see crates/cnc-tech/tests/seed_program.rs): holes at the
//! program coordinates, 10 mm deep (EXF62's start value) for the first two and 50 mm for the
//! third, at 3600 / 3600 / 1800 rpm and 100 / 100 / 60 mm/min.

use motus_cnc::{DrillingTechnology, Limits3, ProgramRun, RunReport, RunStatus};
use motus_gcode::{parse_tool_table, CycleOutput, InterpreterConfig, Units};

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

/// The same job written as CAM output for the drilling unit: a tool change (which activates
/// the drilling technology), G81 for the two 10 mm holes, G83 with 10 mm pecks for the deep
/// one. Z 0 is the material surface the unit finds; R only clears the plate.
const SEED_IN_GCODE: &str = "%
O1001 (seed drilling job, CAM style)
G21 G17 G90 G94
T1 M6 (6 mm drill)
G0 X100 Y100
S3600
G99 G81 X100 Y100 Z-10 R2 F100
X110 Y110
G80
S1800
G83 X120 Y120 Z-50 R2 Q10 F60
G80
M2
%
";

fn drill(src: &str, config: InterpreterConfig) -> (DrillingTechnology, RunReport) {
    let mut run = ProgramRun::new(src, config, Limits3::default(), [0.0; 3]).unwrap();
    let mut tech = DrillingTechnology::simulated();
    let report = run.run_to_end(0.001, &mut tech, 900.0, |_, _, _| {}).map_err(|e| e.to_string()).unwrap();
    assert!(tech.cell.machine().events().is_empty(), "{:?}", tech.cell.machine().events());
    (tech, report)
}

#[test]
fn the_seed_job_in_g81_g83_with_a_tool_change_drills_the_same_holes() {
    let m_functions = InterpreterConfig { require_program_end: false, ..InterpreterConfig::default() };
    let (by_m, _) = drill(SEED, m_functions);
    let cycles = InterpreterConfig {
        cycles: CycleOutput::DrillingTechnology,
        tools: parse_tool_table("T1 P1 Z0 D6 ;6 mm drill\n", Units::Mm).unwrap(),
        ..InterpreterConfig::default()
    };
    let (by_g, report) = drill(SEED_IN_GCODE, cycles);
    let (a, b) = (by_m.holes(), by_g.holes());
    assert_eq!(a.len(), 3, "{a:?}");
    assert_eq!(b.len(), 3, "{b:?}");
    for (m, g) in a.iter().zip(b) {
        for k in 0..2 {
            assert!((m.tool_xy[k] - g.tool_xy[k]).abs() < 1e-6, "{m:?} {g:?}");
            assert!((m.gantry_xy[k] - g.gantry_xy[k]).abs() < 1e-6, "{m:?} {g:?}");
        }
        assert!((m.depth - g.depth).abs() < 1e-6, "{m:?} {g:?}");
        assert_eq!(m.spindle_rpm, g.spindle_rpm, "{m:?} {g:?}");
        // The feed measured while cutting new material (not the fast return into the hole
        // between pecks).
        assert!((m.feed - g.feed).abs() < 1e-6, "{m:?} {g:?}");
    }
    // The deep hole was pecked: out of it after every 10 mm (G83), 5 entries.
    assert_eq!([b[0].entries, b[1].entries, b[2].entries], [1, 1, 5], "{b:?}");
    assert_eq!(a[2].entries, 1, "{a:?}");
    assert_eq!(report.m_functions, 4, "M63 (from M6) + three M60");
}

#[test]
fn chip_breaking_pecks_stay_in_the_hole() {
    let src = "G21 G90 T1 M6\nS2000 F80\nG73 X50 Y20 Z-12 R2 Q3\nG80\nM2\n";
    let cycles = InterpreterConfig {
        cycles: CycleOutput::DrillingTechnology,
        tools: parse_tool_table("T1 P1 Z0 D6\n", Units::Mm).unwrap(),
        ..InterpreterConfig::default()
    };
    let (tech, _) = drill(src, cycles);
    let h = tech.holes();
    assert_eq!(h.len(), 1, "{h:?}");
    assert!((h[0].depth - 12.0).abs() < 1e-6 && (h[0].feed - 80.0).abs() < 1e-6, "{h:?}");
    assert_eq!(h[0].spindle_rpm, 2000.0);
    assert_eq!(h[0].entries, 1, "G73 retracts a little in the hole: {h:?}");
}

#[test]
fn an_invalid_line_stops_the_run_with_its_line_and_column() {
    let src = "G21 G90\nG1 X10 F100\nG1 X20 Y#\nM2\n";
    let mut run = ProgramRun::new(src, InterpreterConfig::default(), Limits3::default(), [0.0; 3]).unwrap();
    let mut tech = motus_cnc::NoTechnology::default();
    let err = run.run_to_end(0.001, &mut tech, 60.0, |_, _, _| {}).unwrap_err().to_string();
    assert!(err.starts_with("3:"), "{err}");
}
