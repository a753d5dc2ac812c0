//! Tests of the drilling task, organised by job and state: the pure task with hand-made
//! inputs, and the task in a [`DrillingCell`] on the simulated machine. Expected numbers
//! are computed by hand from the defaults (surface 20 mm, switch at z = 20 + 88 - 3 =
//! 105, tool tip 5 mm above the material there, start position 400 - 20 = 380).
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use super::*;
use crate::cell::{CellCycle, DrillingCell, MDisposition, RunConfig, Step};
use crate::machine::{MachineConfig, MachineEvent, Surface};
use crate::plc_interface::{ExtType, MFunctionError, MKind};
use crate::setpoint::ZCommand;
use crate::spindle::SpindlePara;
use crate::task::Task;
use crate::CellError;

const DT: f64 = 0.001;

fn cell_with(para: DrillingPara, spindle: SpindlePara, machine: MachineConfig) -> DrillingCell {
    DrillingCell::new(para, spindle, machine)
}

fn cell() -> DrillingCell {
    cell_with(DrillingPara::default(), SpindlePara::default(), MachineConfig::default())
}

/// Cycles until `done` says so (panics after `max_s` simulated seconds).
fn run_until(
    c: &mut DrillingCell,
    xy: [f64; 2],
    max_s: f64,
    mut done: impl FnMut(&CellCycle, &DrillingCell) -> bool,
) -> CellCycle {
    let n = (max_s / DT) as u64;
    for _ in 0..n {
        let out = c.cycle(DT, xy);
        if done(&out, c) {
            return out;
        }
    }
    panic!("not done after {max_s} s; info {:?}", c.drilling().info());
}

/// Sets M`n` and cycles until it is acknowledged; returns the cycles waited.
fn m_wait(c: &mut DrillingCell, n: u16, xy: [f64; 2]) -> u64 {
    assert_eq!(c.on_m_function(n).unwrap(), MDisposition::Wait);
    let mut cycles = 0;
    run_until(c, xy, 400.0, |out, _| {
        cycles += 1;
        assert!(out.error.is_none(), "{:?}", out.error);
        out.acknowledged.contains(&n)
    });
    cycles
}

/// Sets M`n` and cycles until the technology reports an error.
fn m_error(c: &mut DrillingCell, n: u16, xy: [f64; 2]) -> ErrorRecord {
    c.on_m_function(n).unwrap();
    let out = run_until(c, xy, 400.0, |out, _| {
        assert!(!out.acknowledged.contains(&n), "acknowledged instead of failing");
        out.error.is_some()
    });
    out.error.unwrap()
}

fn activated() -> DrillingCell {
    let mut c = cell();
    m_wait(&mut c, 63, [0.0, 0.0]);
    c
}

// ---- M-function handshake -------------------------------------------------------------

#[test]
fn m_functions_synchronous_and_refusals() {
    let mut c = cell();
    assert_eq!(c.mfunctions().kind(60).unwrap(), MKind::Synchronous);
    assert_eq!(c.on_m_function(63).unwrap(), MDisposition::Wait);
    assert_eq!(
        c.on_m_function(63),
        Err(CellError::MFunction(MFunctionError::StillSet { number: 63, kind: MKind::Synchronous }))
    );
    assert_eq!(c.on_m_function(7), Err(CellError::NotHandled(7)));
    assert!(matches!(c.set_external(ExtType::W, 60, 1e6), Err(CellError::External(_))));
    // The PLC defaults are in the external parameters at start.
    assert_eq!(c.external().get_w(60).unwrap(), 3000);
    assert_eq!(c.external().get_f(62).unwrap(), 10.0);
}

// ---- M63 / M64: decouple, shift, recouple -----------------------------------------------

#[test]
fn m63_shifts_by_the_tool_offset_then_m64_shifts_back() {
    let mut c = cell();
    let cycles = m_wait(&mut c, 63, [10.0, 20.0]);
    // The shift is |(-120, 45)| = 128.16 mm at 3000 mm/min = 2.56 s.
    assert!((2500..2700).contains(&cycles), "{cycles}");
    let fb = c.machine().feedback();
    assert_eq!(fb.xy_offset, [-120.0, 45.0]);
    assert!(fb.xy_coupled);
    assert_eq!(fb.tool_xy, [10.0, 20.0]);
    let info = *c.drilling().info();
    assert!(info.technology_active);
    assert_eq!(info.technology, Technology::Drilling);
    // A second M63 is acknowledged at once, without moving.
    assert!(m_wait(&mut c, 63, [10.0, 20.0]) <= 2);
    assert_eq!(c.machine().feedback().xy_offset, [-120.0, 45.0]);

    // Spindle on, then M64: spindle off, Z at start, shift back, cutting active.
    m_wait(&mut c, 61, [10.0, 20.0]);
    assert!(c.spindle().info().running);
    m_wait(&mut c, 64, [10.0, 20.0]);
    let fb = c.machine().feedback();
    assert_eq!(fb.xy_offset, [0.0, 0.0]);
    assert!(c.spindle().info().standstill);
    assert_eq!(c.drilling().info().technology, Technology::Cutting);
    let states: Vec<State> = c.state_trace().iter().rev().take(6).map(|s| s.state).collect();
    assert_eq!(
        states,
        vec![
            State::Idle,
            State::Recouple,
            State::ShiftMove,
            State::Decouple,
            State::ReturnToStart,
            State::SpindleStop
        ]
    );
    // Drilling is locked out again.
    let e = m_error(&mut c, 60, [10.0, 20.0]);
    assert_eq!(e.error, DrillingError::TechnologyNotActive { job: Job::Drill });
}

// ---- M61 / M62 ------------------------------------------------------------------------

#[test]
fn m61_acknowledged_at_speed_m62_at_standstill() {
    let mut c = activated();
    c.set_external(ExtType::W, 60, 2400.0).unwrap();
    // Ramp 3000 rpm/s: 2400 rpm after 0.8 s.
    let cycles = m_wait(&mut c, 61, [0.0, 0.0]);
    assert!((790..=820).contains(&cycles), "{cycles}");
    assert_eq!(c.spindle().info().actual_rpm, 2400.0);
    assert!(c.spindle().info().ready);
    let cycles = m_wait(&mut c, 62, [0.0, 0.0]);
    assert!((790..=820).contains(&cycles), "{cycles}");
    assert!(c.spindle().info().standstill);
}

#[test]
fn m61_needs_drilling_active_and_a_valid_rpm() {
    let mut c = cell();
    assert_eq!(
        m_error(&mut c, 61, [0.0, 0.0]).error,
        DrillingError::TechnologyNotActive { job: Job::SpindleOn }
    );
    let mut c = activated();
    c.set_external(ExtType::W, 60, -5.0).unwrap();
    let e = m_error(&mut c, 61, [0.0, 0.0]);
    assert_eq!(e.error, DrillingError::InvalidParameter { name: "EXW60 spindle rpm", value: -5.0 });
}

// ---- M60 and its states -----------------------------------------------------------------

#[test]
fn m60_without_m63_is_an_error_until_stop_technology() {
    let mut c = cell();
    let e = m_error(&mut c, 60, [0.0, 0.0]);
    assert_eq!(e.error, DrillingError::TechnologyNotActive { job: Job::Drill });
    assert_eq!(e.m, Some(60));
    assert_eq!(e.error.to_string(), "Drill needs the drilling technology active (M63)");
    // The program stays paused: the bit stays set, no acknowledgement.
    for _ in 0..100 {
        let out = c.cycle(DT, [0.0, 0.0]);
        assert!(out.acknowledged.is_empty());
    }
    assert!(c.mfunctions().is_set(60));
    assert_eq!(c.drilling().state(), State::Error);
    // Stop technology: Stopping, then Idle with the M aborted (bit cleared).
    c.drilling_mut().cmd_mut().stop_technology.request();
    let out = c.cycle(DT, [0.0, 0.0]);
    assert_eq!(c.drilling().state(), State::Stopping);
    assert!(c.drilling().info().stopping);
    assert!(out.aborted.is_empty());
    let out = run_until(&mut c, [0.0, 0.0], 10.0, |o, _| !o.aborted.is_empty());
    assert_eq!(out.aborted, vec![60]);
    assert!(!c.mfunctions().is_set(60));
    assert_eq!(c.drilling().state(), State::Idle);
    // The context stays for diagnosis.
    assert_eq!(c.drilling().info().last_error.unwrap().error, e.error);
}

#[test]
fn m60_depth_and_feed_checked() {
    let mut c = activated();
    c.set_external(ExtType::F, 62, 80.0).unwrap(); // not shorter than the 80 mm tool
    let e = m_error(&mut c, 60, [0.0, 0.0]);
    assert_eq!(e.error, DrillingError::InvalidParameter { name: "EXF62 drilling depth", value: 80.0 });
    assert_eq!(c.machine().feedback().z, 380.0, "nothing moved");

    let mut c = activated();
    c.set_external(ExtType::F, 61, 0.0).unwrap();
    let e = m_error(&mut c, 60, [0.0, 0.0]);
    assert_eq!(e.error, DrillingError::InvalidParameter { name: "EXF61 drilling speed", value: 0.0 });
}

#[test]
fn switch_never_closes_is_an_error() {
    // Material far below the table (no material): the search reaches the lower limit.
    let machine = MachineConfig { surface: Surface::Flat(-500.0), ..MachineConfig::default() };
    let mut c = cell_with(DrillingPara::default(), SpindlePara::default(), machine);
    m_wait(&mut c, 63, [0.0, 0.0]);
    let e = m_error(&mut c, 60, [0.0, 0.0]);
    assert_eq!(e.state, State::SearchDescend);
    assert!(matches!(e.error, DrillingError::SwitchNotFound { travel } if (travel - 380.0).abs() < 1e-6));
    assert!(c.machine().feedback().z.abs() < 1e-6);
    assert!(c.machine().events().is_empty(), "no limit hit: the search stops at lower_limit");
    assert!(!c.spindle().info().running, "spindle stopped on the error");

    // A shorter search travel.
    let para = DrillingPara { max_search_travel: 50.0, ..DrillingPara::default() };
    let mut c = cell_with(para, SpindlePara::default(), MachineConfig::default());
    m_wait(&mut c, 63, [0.0, 0.0]);
    let e = m_error(&mut c, 60, [0.0, 0.0]);
    assert!(matches!(e.error, DrillingError::SwitchNotFound { travel } if (travel - 50.0).abs() < 1e-6));
    assert!((c.machine().feedback().z - 330.0).abs() < 1e-6);
}

#[test]
fn spindle_not_ready_in_time() {
    let spindle = SpindlePara { ramp_rpm_per_s: 100.0, ..SpindlePara::default() };
    let mut c = cell_with(DrillingPara::default(), spindle, MachineConfig::default());
    m_wait(&mut c, 63, [0.0, 0.0]);
    let t0 = c.time();
    let e = m_error(&mut c, 60, [0.0, 0.0]);
    assert_eq!(e.error, DrillingError::SpindleNotReady { rpm: 3000, timeout_s: 5.0 });
    assert!(((c.time() - t0) - 5.0).abs() < 0.01);
    assert_eq!(c.machine().feedback().z, 380.0, "Z did not move");
    assert!(!c.spindle().info().running);
}

#[test]
fn sequence_off_returns_to_start() {
    let para = DrillingPara { hole_sequence: false, ..DrillingPara::default() };
    let mut c = cell_with(para, SpindlePara::default(), MachineConfig::default());
    m_wait(&mut c, 63, [0.0, 0.0]);
    m_wait(&mut c, 60, [0.0, 0.0]);
    assert!((c.machine().feedback().z - 380.0).abs() < 1e-9);
    assert_eq!(c.machine().holes().len(), 1);
    let last: Vec<State> = c.state_trace().iter().rev().take(3).map(|s| s.state).collect();
    assert_eq!(last, vec![State::Idle, State::ReturnToStart, State::Unclamp]);
}

/// Surface 20 mm for x < 105 and `HIGH` beyond (program x = drill x after M63).
fn two_levels<const HIGH_TENTHS: i32>(xy: [f64; 2]) -> f64 {
    if xy[0] < 105.0 {
        20.0
    } else {
        f64::from(HIGH_TENTHS) / 10.0
    }
}

fn two_holes(surface: fn([f64; 2]) -> f64) -> DrillingCell {
    let machine = MachineConfig { surface: Surface::Custom(surface), ..MachineConfig::default() };
    let mut c = cell_with(DrillingPara::default(), SpindlePara::default(), machine);
    let steps = [
        Step::M(63),
        Step::Rapid { x: 100.0, y: 100.0 },
        Step::M(60),
        Step::MoveXY { x: 110.0, y: 110.0, feed: 300.0 },
        Step::M(60),
    ];
    c.run_program(&steps, &RunConfig::default()).unwrap();
    assert!(
        c.machine().events().is_empty(),
        "{} events, first {:?}",
        c.machine().events().len(),
        c.machine().events().first()
    );
    c
}

#[test]
fn height_change_within_tolerance_keeps_the_working_height() {
    // 0.5 mm higher (tolerance 1 mm): no re-measuring; the depth is counted from the old
    // working height, so the hole is 10 + 0.5 deep.
    let c = two_holes(two_levels::<205>);
    assert_eq!(c.drilling().info().remeasurements, 0);
    assert_eq!(c.drilling().info().working_height, Some(105.0));
    let h = c.machine().holes();
    assert!((h[0].depth - 10.0).abs() < 1e-9);
    assert!((h[1].depth - 10.5).abs() < 1e-9);
}

#[test]
fn height_change_beyond_tolerance_remeasures() {
    // 3 mm higher: the switch closes 3 mm early in the tool approach -> search again; the
    // new working height is 23 + 85 = 108 and the hole is 10 deep again.
    let c = two_holes(two_levels::<230>);
    assert_eq!(c.drilling().info().remeasurements, 1);
    assert_eq!(c.drilling().info().working_height, Some(108.0));
    assert!((c.machine().holes()[1].depth - 10.0).abs() < 1e-9);
    // 3 mm lower: the switch is still open 1 mm below the known height -> search again.
    let c = two_holes(two_levels::<170>);
    assert_eq!(c.drilling().info().remeasurements, 1);
    assert_eq!(c.drilling().info().working_height, Some(102.0));
    assert!((c.machine().holes()[1].depth - 10.0).abs() < 1e-9);
    // 8 mm higher: the switch closes early in the tool approach -> lift until it opens,
    // search again; working height 28 + 85 = 113.
    let c = two_holes(two_levels::<280>);
    assert_eq!(c.drilling().info().remeasurements, 1);
    assert_eq!(c.drilling().info().working_height, Some(113.0));
    assert!((c.machine().holes()[1].depth - 10.0).abs() < 1e-9);
    assert!(c.state_trace().iter().any(|s| s.state == State::SearchLift));
    // 14 mm higher: the plate waiting at z = 118 (bottom at 30) is already pressed 4 mm
    // by the 34 mm material, so the switch is closed in the plate approach -> measure
    // again; working height 34 + 85 = 119.
    let c = two_holes(two_levels::<340>);
    assert_eq!(c.drilling().info().remeasurements, 1);
    assert_eq!(c.drilling().info().working_height, Some(119.0));
    assert!((c.machine().holes()[1].depth - 10.0).abs() < 1e-9);
    let trace: Vec<State> = c.state_trace().iter().map(|s| s.state).collect();
    let i = trace.iter().rposition(|&s| s == State::PlateApproach).unwrap();
    assert_eq!(&trace[i..i + 3], &[State::PlateApproach, State::SearchLift, State::SearchDescend]);
}

// ---- Commands ---------------------------------------------------------------------------

#[test]
fn find_working_height_command() {
    let mut c = activated();
    c.drilling_mut().cmd_mut().find_working_height.request();
    let mut saw_search = false;
    c.cycle(DT, [0.0, 0.0]);
    run_until(&mut c, [0.0, 0.0], 60.0, |_, c| {
        saw_search |= c.drilling().info().height_search_active;
        c.drilling().state() == State::Idle
    });
    assert!(saw_search);
    let info = c.drilling().info();
    assert!(info.zero_point_found);
    assert_eq!(info.working_height, Some(105.0));
    // Ends with the plate 10 mm above the material: 105 + 3 + 10.
    assert!((c.machine().feedback().z - 118.0).abs() < 1e-9);
    assert!(c.machine().holes().is_empty());
}

#[test]
fn plate_to_switch_and_lift_spindle_commands() {
    let mut c = activated();
    c.drilling_mut().cmd_mut().plate_to_switch.request();
    let mut saw_flag = false;
    c.cycle(DT, [0.0, 0.0]);
    run_until(&mut c, [0.0, 0.0], 60.0, |_, c| {
        saw_flag |= c.drilling().info().plate_moving_to_switch;
        assert!(!c.drilling().info().height_search_active);
        c.drilling().state() == State::Idle
    });
    assert!(saw_flag);
    // The switch is just closed: exactly at its threshold.
    let fb = c.machine().feedback();
    assert!(fb.plate_switch);
    assert_eq!(fb.z, 105.0);
    assert!((fb.plate_compression - 3.0).abs() < 1e-9);

    c.drilling_mut().cmd_mut().lift_spindle.request();
    c.cycle(DT, [0.0, 0.0]);
    assert_eq!(c.drilling().state(), State::ReturnToStart);
    run_until(&mut c, [0.0, 0.0], 60.0, |_, c| c.drilling().state() == State::Idle);
    assert!((c.machine().feedback().z - 380.0).abs() < 1e-9);
}

#[test]
fn start_drilling_command_uses_para_and_ignores_commands_while_busy() {
    let para = DrillingPara {
        spindle_rpm: 2000,
        drilling_speed: 150.0,
        drilling_depth: 7.5,
        ..DrillingPara::default()
    };
    let mut c = cell_with(para, SpindlePara::default(), MachineConfig::default());
    m_wait(&mut c, 63, [50.0, 0.0]);
    c.drilling_mut().cmd_mut().start_drilling.request();
    c.cycle(DT, [50.0, 0.0]);
    assert_eq!(c.drilling().state(), State::SpindleStart);
    assert_eq!(c.drilling().info().job, Some(Job::Drill));
    assert_eq!(c.drilling().info().pending_m, None);
    // A command while busy is taken (reset) and ignored.
    c.drilling_mut().cmd_mut().lift_spindle.request();
    c.cycle(DT, [50.0, 0.0]);
    assert!(!c.drilling_mut().cmd_mut().lift_spindle.is_requested());
    run_until(&mut c, [50.0, 0.0], 120.0, |_, c| c.drilling().state() == State::Idle);
    let h = c.machine().holes()[0];
    assert!((h.depth - 7.5).abs() < 1e-9);
    assert_eq!(h.spindle_rpm, 2000.0);
    assert!((h.feed - 150.0).abs() < 1e-6);
    assert_eq!(h.tool_xy, [50.0, 0.0]);
    // Sequence on: the plate waits above the material, not at the start position.
    assert!((c.machine().feedback().z - 118.0).abs() < 1e-9);
}

#[test]
fn stop_technology_while_drilling_aborts_the_m() {
    let mut c = activated();
    c.on_m_function(60).unwrap();
    run_until(&mut c, [0.0, 0.0], 60.0, |_, c| c.drilling().state() == State::Drill);
    // 2 s into the 10 mm hole at 100 mm/min.
    for _ in 0..2000 {
        c.cycle(DT, [0.0, 0.0]);
    }
    c.drilling_mut().cmd_mut().stop_technology.request();
    let out = run_until(&mut c, [0.0, 0.0], 60.0, |o, _| !o.aborted.is_empty());
    assert_eq!(out.aborted, vec![60]);
    assert!((c.machine().feedback().z - 380.0).abs() < 1e-9);
    assert!(c.spindle().info().standstill);
    let h = c.machine().holes()[0];
    // Drilling started 2 mm above the surface: 2 s at 100 mm/min = 3.33 mm -> 1.33 deep.
    assert!((h.depth - (200.0 / 60.0 - 2.0)).abs() < 0.01, "{h:?}");
    // Stop turns the spindle off while the tool leaves the hole; the hole is recorded
    // and nothing else happened.
    assert!(c.machine().events().iter().all(|e| !matches!(e, MachineEvent::MovedInMaterial { .. })));
    assert!(!c.drilling().info().drilling_active);
    // The M can be given again and completes.
    m_wait(&mut c, 60, [0.0, 0.0]);
}

#[test]
fn simulation_mode_moves_only_x_y() {
    let para = DrillingPara { simulation: true, ..DrillingPara::default() };
    let mut c = cell_with(para, SpindlePara::default(), MachineConfig::default());
    let report = c
        .run_program(
            &[Step::M(63), Step::Rapid { x: 100.0, y: 100.0 }, Step::M(61), Step::M(60), Step::M(62)],
            &RunConfig::default(),
        )
        .unwrap();
    assert!(report.holes.is_empty());
    assert_eq!(c.machine().feedback().z, 380.0);
    assert_eq!(c.machine().feedback().xy_offset, [-120.0, 45.0]);
    assert!(c.spindle().info().standstill);
    // M61, M60, M62 each acknowledged after the Simulated state's cycle.
    assert!(report.waits.iter().skip(1).all(|w| w.1 <= 2), "{:?}", report.waits);
    assert!(report.states.iter().any(|s| s.state == State::Simulated));
}

// ---- The pure task with hand-made inputs ------------------------------------------------

fn inputs(m: &[u16]) -> DrillingInputs {
    let mut set = MSet::EMPTY;
    for &n in m {
        assert!(set.insert(n));
    }
    DrillingInputs {
        m: set,
        ext_spindle_rpm: 3000,
        ext_drilling_speed: 100.0,
        ext_drilling_depth: 10.0,
        z: 380.0,
        xy_coupled: true,
        ..DrillingInputs::default()
    }
}

/// Runs M63 on the pure task by playing the machine's part by hand.
fn pure_activated() -> DrillingTask {
    let mut t = DrillingTask::new(DrillingPara::default());
    let mut i = inputs(&[63]);
    let out = t.cycle(&i, DT);
    assert_eq!(t.state(), State::Decouple);
    assert!(!out.coupling.coupled);
    i.xy_coupled = false;
    let out = t.cycle(&i, DT);
    assert_eq!(t.state(), State::ShiftMove);
    assert_eq!(out.coupling.offset_target, [-120.0, 45.0]);
    t.cycle(&i, DT);
    assert_eq!(t.state(), State::ShiftMove, "waits for the offset");
    i.xy_offset = [-120.0, 45.0];
    let out = t.cycle(&i, DT);
    assert_eq!(t.state(), State::Recouple);
    assert!(out.coupling.coupled);
    assert!(out.acknowledge.is_empty());
    i.xy_coupled = true;
    let out = t.cycle(&i, DT);
    assert_eq!(t.state(), State::Idle);
    assert_eq!(out.acknowledge.iter().collect::<Vec<_>>(), vec![63]);
    assert_eq!(t.info().technology, Technology::Drilling);
    t
}

#[test]
fn pure_m60_transitions_and_spindle_lost() {
    let mut t = pure_activated();
    let mut i = inputs(&[60]);
    i.xy_offset = [-120.0, 45.0];
    let out = t.cycle(&i, DT);
    assert_eq!(t.state(), State::SpindleStart);
    assert!(out.spindle_start && out.spindle_rpm == 3000);
    i.spindle_ready = true;
    i.spindle_rpm = 3000.0;
    let out = t.cycle(&i, DT);
    assert_eq!(t.state(), State::SearchDescend);
    // Search: down by the whole travel, limited to the lower limit 0, at search speed.
    assert_eq!(out.z, ZCommand::Move { target: 0.0, speed: 1200.0 });
    i.z = 105.2;
    i.plate_switch = true;
    i.switch_latch = Some(105.0);
    let out = t.cycle(&i, DT);
    assert_eq!(t.state(), State::ToolApproach);
    // Tool approach to 2 mm above the material: 105 - 5 + 2.
    assert_eq!(out.z, ZCommand::Move { target: 102.0, speed: 300.0 });
    assert_eq!(t.info().working_height, Some(105.0));
    // Still at the switch point: within tolerance of the working height.
    i.switch_latch = None;
    i.z = 105.0;
    t.cycle(&i, DT);
    assert_eq!(t.state(), State::ToolApproach);
    i.z = 102.0;
    t.cycle(&i, DT);
    assert_eq!(t.state(), State::Clamp);
    let out = t.cycle(&i, DT);
    assert_eq!(t.state(), State::Drill);
    assert!(out.clamp);
    // Drill to 10 below the surface contact (z = 100): 90, at 100 mm/min.
    assert_eq!(out.z, ZCommand::Move { target: 90.0, speed: 100.0 });
    i.z = 95.0;
    i.spindle_ready = false;
    let out = t.cycle(&i, DT);
    assert_eq!(t.state(), State::Error);
    assert!(out.spindle_stop);
    assert_eq!(out.z, ZCommand::Hold);
    let e = t.info().last_error.unwrap();
    assert_eq!(e.error, DrillingError::SpindleLost { state: State::Drill });
    assert_eq!((e.state, e.job, e.m, e.z), (State::Drill, Some(Job::Drill), Some(60), 95.0));
    assert!(out.acknowledge.is_empty());
}

#[test]
fn pure_z_limit_and_move_timeout() {
    let mut t = pure_activated();
    let mut i = inputs(&[]);
    i.xy_offset = [-120.0, 45.0];
    t.cmd_mut().lift_spindle.request();
    t.cycle(&i, DT);
    // Already at the start position: done next cycle.
    t.cycle(&i, DT);
    assert_eq!(t.state(), State::Idle);
    i.z = 200.0;
    t.cmd_mut().lift_spindle.request();
    t.cycle(&i, DT);
    assert_eq!(t.state(), State::ReturnToStart);
    // 180 mm at 3000 mm/min = 3.6 s expected; time-out after 1.5 * 3.6 + 5 = 10.4 s.
    for _ in 0..10_300 {
        t.cycle(&i, DT);
    }
    assert_eq!(t.state(), State::ReturnToStart);
    for _ in 0..200 {
        t.cycle(&i, DT);
    }
    assert_eq!(t.state(), State::Error);
    assert!(matches!(
        t.info().last_error.unwrap().error,
        DrillingError::MoveTimeout { state: State::ReturnToStart, after_s } if (after_s - 10.4).abs() < 0.01
    ));

    let mut t = pure_activated();
    i.z = 200.0;
    t.cmd_mut().find_working_height.request();
    t.cycle(&i, DT);
    assert_eq!(t.state(), State::SearchDescend);
    i.z_limit = true;
    t.cycle(&i, DT);
    assert_eq!(
        t.info().last_error.unwrap().error,
        DrillingError::ZLimit { z: 200.0, state: State::SearchDescend }
    );
}

#[test]
fn invalid_geometry_refused() {
    // The tool would reach the material before the plate presses it.
    let para = DrillingPara { tool_approach_height: 6.0, ..DrillingPara::default() };
    let mut c = cell_with(para, SpindlePara::default(), MachineConfig::default());
    m_wait(&mut c, 63, [0.0, 0.0]);
    let e = m_error(&mut c, 60, [0.0, 0.0]);
    assert!(matches!(e.error, DrillingError::InvalidParameter { value, .. } if value == 6.0));
}

#[test]
fn mset_basics() {
    let mut s = MSet::EMPTY;
    assert!(s.is_empty());
    assert!(!s.insert(59));
    assert!(!s.insert(65));
    assert!(s.insert(64) && s.insert(60));
    assert_eq!(s.iter().collect::<Vec<_>>(), vec![60, 64]);
    s.remove(60);
    assert!(!s.contains(60) && s.contains(64));
}
