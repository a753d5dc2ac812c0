//! The driver against a small CiA 402 device model (state machine per spec 2.4 via the
//! shared `next_state`, set-point handshake per spec 2.7, homing per 2.9). The full
//! simulator (motus-icla-sim) is exercised over a real bus in the CLI tests.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_axis::{Axis, AxisCommand, AxisError, MotionProfile, Scale, UnitKind};
use motus_canopen_protocol::SdoAbortCode;
use motus_cia402::{Cia402Axis, Drive, DriveError, DriveIo, DriveSettings, IoError, MoveKind, Profile};
use motus_cia402_protocol::{next_state, DeviceCommand, PowerState};
use std::sync::{Arc, Mutex};

#[derive(Default)]
struct Dev {
    state: Option<PowerState>,
    cw: u16,
    mode: i8,
    target: i32,
    pos: i32,
    ack: bool,
    reached: bool,
    fault_cause: bool,
    homing_steps: u32,
    ignore_set_points: bool,
    writes: Vec<(u16, u8, Vec<u8>)>,
}

#[derive(Clone, Default)]
struct Model(Arc<Mutex<Dev>>);

impl Model {
    fn dev(&self) -> std::sync::MutexGuard<'_, Dev> {
        self.0.lock().unwrap()
    }
    fn fault(&self) {
        let mut d = self.dev();
        d.state = Some(PowerState::Fault);
        d.fault_cause = true;
    }
}

impl DriveIo for Model {
    fn node(&self) -> u8 {
        2
    }
    fn read(&self, index: u16, sub: u8) -> Result<Vec<u8>, IoError> {
        let d = self.dev();
        Ok(match (index, sub) {
            (0x6041, 0) => return Err(IoError::Bus { node: 2, reason: "use statusword()".into() }),
            (0x6061, 0) => vec![d.mode as u8],
            (0x6502, 0) => 0x25u32.to_le_bytes().to_vec(), // pp, pv, hm
            (0x6064, 0) => d.pos.to_le_bytes().to_vec(),
            (0x606C, 0) => 0i32.to_le_bytes().to_vec(),
            (0x603F, 0) => {
                (if d.state == Some(PowerState::Fault) { 0x4310u16 } else { 0 }).to_le_bytes().to_vec()
            }
            _ => {
                return Err(IoError::Refused {
                    node: 2,
                    index,
                    sub,
                    code: SdoAbortCode::from_raw(0x0602_0000),
                })
            }
        })
    }
    fn write(&self, index: u16, sub: u8, data: &[u8]) -> Result<(), IoError> {
        let mut d = self.dev();
        d.writes.push((index, sub, data.to_vec()));
        match index {
            0x6060 => {
                if data[0] as i8 == 4 {
                    return Err(IoError::Refused {
                        node: 2,
                        index,
                        sub,
                        code: SdoAbortCode::from_raw(0x0609_0030),
                    });
                }
                d.mode = data[0] as i8
            }
            0x607A => d.target = i32::from_le_bytes(data.try_into().unwrap()),
            _ => {}
        }
        Ok(())
    }
    fn write_controlword(&self, cw: u16) -> Result<(), IoError> {
        let mut d = self.dev();
        let prev = d.cw;
        d.cw = cw;
        let state = d.state.unwrap_or(PowerState::SwitchOnDisabled);
        if state == PowerState::Fault {
            if prev & 0x80 == 0 && cw & 0x80 != 0 && !d.fault_cause {
                d.state = Some(PowerState::SwitchOnDisabled);
            }
            return Ok(());
        }
        if let Some(c) = DeviceCommand::from_controlword(cw) {
            if let Some((next, _)) = next_state(state, c, 2) {
                d.state = Some(next);
            }
        }
        let rising = prev & 0x10 == 0 && cw & 0x10 != 0;
        if d.state == Some(PowerState::OperationEnabled) && rising && !d.ignore_set_points {
            if d.mode == 1 {
                let t = d.target;
                d.target = if cw & 0x40 != 0 { d.pos + t } else { t };
                d.ack = true;
                d.reached = false;
            } else if d.mode == 6 {
                d.homing_steps = 3;
            }
        }
        if cw & 0x10 == 0 {
            d.ack = false;
        }
        if d.state == Some(PowerState::QuickStopActive) {
            // Option code 2: stop, then switch on disabled (transition 12).
            d.state = Some(PowerState::SwitchOnDisabled);
        }
        Ok(())
    }
    fn statusword(&self) -> Result<u16, IoError> {
        let mut d = self.dev();
        let state = d.state.unwrap_or(PowerState::SwitchOnDisabled);
        let mut sw = state.statusword_bits() | 0x0200;
        if d.mode == 1 && state == PowerState::OperationEnabled {
            if !d.reached && !d.ack {
                let step = (d.target - d.pos).clamp(-100, 100);
                d.pos += step;
                d.reached = d.pos == d.target;
            }
            if d.reached {
                sw |= 0x0400;
            }
            if d.ack {
                sw |= 0x1000;
            }
        }
        if d.mode == 6 {
            if d.homing_steps > 0 {
                d.homing_steps -= 1;
                if d.homing_steps == 0 {
                    d.pos = 0;
                }
            } else if d.cw & 0x10 != 0 {
                sw |= 0x1400;
            } else {
                sw |= 0x0400;
            }
        }
        Ok(sw)
    }
}

fn fast() -> DriveSettings {
    DriveSettings { poll_interval: std::time::Duration::from_micros(100), ..DriveSettings::default() }
}

#[test]
fn enable_walks_the_standard_path_and_disable_comes_back() {
    let m = Model::default();
    let mut d = Drive::new(m.clone(), fast());
    d.enable().unwrap();
    assert_eq!(m.dev().state, Some(PowerState::OperationEnabled));
    d.disable().unwrap();
    assert_eq!(m.dev().state, Some(PowerState::ReadyToSwitchOn));
}

#[test]
fn a_fault_is_reported_with_its_code_and_reset_only_when_the_cause_is_gone() {
    let m = Model::default();
    let mut d = Drive::new(m.clone(), fast());
    m.fault();
    let e = d.enable().unwrap_err();
    assert_eq!(e, DriveError::Fault { node: 2, code: Some(0x4310) });
    assert!(e.to_string().contains("0x4310"), "{e}");
    assert!(matches!(d.fault_reset(), Err(DriveError::FaultPersists { .. })));
    m.dev().fault_cause = false;
    d.fault_reset().unwrap();
    d.enable().unwrap();
}

#[test]
fn profile_position_handshake_reaches_absolute_and_relative_targets() {
    let m = Model::default();
    let mut d = Drive::new(m.clone(), fast());
    d.enable().unwrap();
    d.start_move(1000, MoveKind::Absolute, true).unwrap();
    assert_eq!(d.wait_target_reached(std::time::Duration::from_secs(2)).unwrap(), 1000);
    d.start_move(-250, MoveKind::Relative, true).unwrap();
    assert_eq!(d.wait_target_reached(std::time::Duration::from_secs(2)).unwrap(), 750);
    // Bit 4 was lowered after each acknowledge.
    assert_eq!(d.last_controlword() & 0x10, 0);
}

#[test]
fn a_drive_that_never_acknowledges_is_reported() {
    let m = Model::default();
    let mut d = Drive::new(
        m.clone(),
        DriveSettings { set_point_timeout: std::time::Duration::from_millis(50), ..fast() },
    );
    d.enable().unwrap();
    m.dev().ignore_set_points = true;
    let e = d.start_move(10, MoveKind::Absolute, true).unwrap_err();
    assert!(matches!(e, DriveError::SetPointNotAcknowledged { .. }), "{e}");
}

#[test]
fn limits_and_modes_are_checked_before_anything_moves() {
    let m = Model::default();
    let mut d = Drive::new(m.clone(), fast());
    d.enable().unwrap();
    d.set_software_limits(-100, 100).unwrap();
    let writes_before = m.dev().writes.len();
    assert!(matches!(d.start_move(101, MoveKind::Absolute, true), Err(DriveError::BeyondLimit { .. })));
    assert_eq!(m.dev().writes.len(), writes_before, "nothing written for a refused target");
    use motus_cia402_protocol::Mode;
    assert!(matches!(d.set_mode(Mode::CyclicSyncPosition), Err(DriveError::ModeUnsupported { .. })));
}

#[test]
fn axis_homes_moves_and_refuses_unhomed_absolute_moves() {
    let m = Model::default();
    m.dev().pos = 123;
    let scale = Scale::new(UnitKind::Rotary, std::f64::consts::TAU / 213.333).unwrap();
    let mut axis = Cia402Axis::new(Drive::new(m.clone(), fast()), "wheel 1", scale, Profile::ICLA_SEED);
    axis.execute(&AxisCommand::Enable).unwrap();
    let e = axis
        .execute(&AxisCommand::MoveAbsolute { target: 1.0, profile: MotionProfile::default() })
        .unwrap_err();
    assert!(matches!(e, AxisError::NotHomed { .. }));
    axis.execute(&AxisCommand::Home).unwrap();
    assert_eq!(m.dev().pos, 0);
    axis.execute(&AxisCommand::MoveAbsolute {
        target: std::f64::consts::TAU,
        profile: MotionProfile::default(),
    })
    .unwrap();
    axis.drive().wait_target_reached(std::time::Duration::from_secs(2)).unwrap();
    let s = axis.read_state().unwrap();
    assert_eq!(s.position_raw, 213);
    assert!(s.flags.enabled && s.flags.homed && s.flags.target_reached);
    m.fault();
    let s = axis.read_state().unwrap();
    assert!(s.faults[0].reason.contains("0x4310"), "{:?}", s.faults);
    let e = axis
        .execute(&AxisCommand::MoveRelative { distance: 1.0, profile: MotionProfile::default() })
        .unwrap_err();
    assert!(matches!(e, AxisError::DeviceFault { .. }), "{e}");
}
