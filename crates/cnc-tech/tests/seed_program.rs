//! End-to-end: the seed's example program (specs/cnc.md, "Programs") on the simulated
//! machine, without the interpreter:
//!
//! ```text
//! N001 M63
//! N005 G00 X100 Y100 F300
//! N010 EXW60=3600 EXF61=100
//! N020 M60
//! N030 G01 X110 Y110
//! N040 M60
//! N050 G01 X120 Y120 A35        (A, a tangential/rotary axis, is not modelled here)
//! N060 EXW60=1800 EXF61=60 EXF62=50
//! N070 M60
//! ```
//!
//! Expected values by hand from the defaults: drill 120 mm in X and -45 mm in Y from
//! the cutting tool (`DrillingPara::drill_offset` = `MachineConfig::drill_mount`), so M63
//! shifts the real axes by (-120, +45) and the drill lands on the program coordinates;
//! EXF62 keeps its start value, `DrillingPara::drilling_depth` = 10 mm, for the first two
//! holes; the material surface is at 20 mm, the switch closes at z = 20 + 88 - 3 = 105.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_cnc_tech::{
    DrillingCell, DrillingPara, ExtType, Job, MachineConfig, RunConfig, SpindlePara, State, Step, Task,
    Technology,
};

fn seed_program() -> Vec<Step> {
    vec![
        Step::M(63),
        Step::Rapid { x: 100.0, y: 100.0 },
        Step::Ext(ExtType::W, 60, 3600.0),
        Step::Ext(ExtType::F, 61, 100.0),
        Step::M(60),
        Step::MoveXY { x: 110.0, y: 110.0, feed: 300.0 },
        Step::M(60),
        Step::MoveXY { x: 120.0, y: 120.0, feed: 300.0 },
        Step::Ext(ExtType::W, 60, 1800.0),
        Step::Ext(ExtType::F, 61, 60.0),
        Step::Ext(ExtType::F, 62, 50.0),
        Step::M(60),
    ]
}

fn cell() -> DrillingCell {
    DrillingCell::new(DrillingPara::default(), SpindlePara::default(), MachineConfig::default())
}

#[test]
fn seed_program_drills_three_holes() {
    let mut cell = cell();
    let report = cell.run_program(&seed_program(), &RunConfig::default()).unwrap();

    assert_eq!(report.holes.len(), 3, "{:?}", report.holes);
    // (program x, y, depth mm, rpm, feed mm/min)
    let expected = [
        (100.0, 100.0, 10.0, 3600.0, 100.0),
        (110.0, 110.0, 10.0, 3600.0, 100.0),
        (120.0, 120.0, 50.0, 1800.0, 60.0),
    ];
    for (hole, (x, y, depth, rpm, feed)) in report.holes.iter().zip(expected) {
        // Drill position on the material = program coordinates.
        assert!((hole.tool_xy[0] - x).abs() < 1e-9 && (hole.tool_xy[1] - y).abs() < 1e-9, "{hole:?}");
        // Gantry (machine coordinates) = program shifted by the tool offset (-120, +45).
        assert!((hole.gantry_xy[0] - (x - 120.0)).abs() < 1e-9, "{hole:?}");
        assert!((hole.gantry_xy[1] - (y + 45.0)).abs() < 1e-9, "{hole:?}");
        assert!((hole.depth - depth).abs() < 1e-9, "{hole:?}");
        assert_eq!(hole.spindle_rpm, rpm, "{hole:?}");
        assert!((hole.feed - feed).abs() < 1e-6, "{hole:?}");
    }
    assert!(cell.machine().events().is_empty(), "{:?}", cell.machine().events());

    // Every synchronous M paused the program for more than one cycle.
    let ms: Vec<u16> = report.waits.iter().map(|w| w.0).collect();
    assert_eq!(ms, vec![63, 60, 60, 60]);
    assert!(report.waits.iter().all(|w| w.1 > 1), "{:?}", report.waits);
    assert_eq!(cell.mfunctions().pending().count(), 0);

    // The state machine as seen through Info, in order for the first hole: spindle up,
    // search (working height unknown), tool approach, clamp, drill, retract, unclamp,
    // stay above the material (hole sequence), idle.
    let states: Vec<State> = report.states.iter().map(|c| c.state).collect();
    let first_hole = [
        State::SpindleStart,
        State::SearchDescend,
        State::ToolApproach,
        State::Clamp,
        State::Drill,
        State::Retract,
        State::Unclamp,
        State::AboveMaterial,
        State::Idle,
    ];
    let start = states.iter().position(|&s| s == State::SpindleStart).unwrap();
    assert_eq!(&states[start..start + first_hole.len()], &first_hole);
    // M63's shift came before: decouple, shift, recouple.
    assert_eq!(&states[..4], &[State::Decouple, State::ShiftMove, State::Recouple, State::Idle]);
    // Later holes know the working height: fast plate approach instead of a search.
    assert_eq!(states.iter().filter(|&&s| s == State::SearchDescend).count(), 1);
    assert_eq!(states.iter().filter(|&&s| s == State::PlateApproach).count(), 2);
    assert_eq!(states.iter().filter(|&&s| s == State::Drill).count(), 3);
    assert!(report.states.iter().filter(|c| c.state == State::Drill).all(|c| c.job == Some(Job::Drill)));

    let info = cell.drilling().info();
    assert!(info.technology_active);
    assert_eq!(info.technology, Technology::Drilling);
    assert!(info.zero_point_found);
    assert_eq!(info.working_height, Some(105.0));
    assert_eq!(info.holes_done, 3);
    assert_eq!(info.remeasurements, 0);
    assert!(!info.drilling_active);
    assert_eq!(info.state, State::Idle);
    // Hole sequence: the plate waits 10 mm above the material: z = 105 + 3 + 10.
    assert!((cell.machine().feedback().z - 118.0).abs() < 1e-9);
    // Spindle still at the last speed.
    assert!(cell.spindle().info().ready);
    assert_eq!(cell.spindle().info().actual_rpm, 1800.0);
}

#[test]
fn info_flags_during_the_first_hole() {
    // Drive the cell by hand as an executor would: M63, move, M60, and watch Info.
    let mut cell = cell();
    let cfg = RunConfig::default();
    cell.run_program(&[Step::M(63), Step::Rapid { x: 100.0, y: 100.0 }], &cfg).unwrap();
    assert!(cell.drilling().info().technology_active);
    assert!(!cell.drilling().info().zero_point_found);

    use motus_cnc_tech::MDisposition;
    assert_eq!(cell.on_m_function(60).unwrap(), MDisposition::Wait);
    let (mut saw_search, mut saw_drilling, mut cycles) = (false, false, 0u64);
    loop {
        let c = cell.cycle(0.001, [100.0, 100.0]);
        cycles += 1;
        let info = cell.drilling().info();
        if c.acknowledged.contains(&60) {
            break;
        }
        // Until acknowledged, the bit stays set and the program stays paused.
        assert!(cell.mfunctions().is_set(60));
        assert!(info.drilling_active);
        assert_eq!(info.pending_m, Some(60));
        saw_search |= info.height_search_active;
        saw_drilling |= info.state == State::Drill;
        if info.state == State::Drill {
            assert!(info.zero_point_found);
            assert!(!info.height_search_active);
        }
        assert!(cycles < 200_000);
    }
    assert!(saw_search && saw_drilling);
    assert!(!cell.mfunctions().is_set(60));
    let info = cell.drilling().info();
    assert!(!info.drilling_active);
    assert_eq!(info.pending_m, None);
}
