//! Dictionary access with the device's rules: reads and writes from the SDO server and
//! RPDOs, the checks that depend on the device (PDO reconfiguration, supported modes and
//! homing methods, "refused in the present device state" 0x08000022) and the side effects
//! of a write (controlword, heartbeat time, error history, set position 0x200B).

use std::time::Instant;

use motus_canopen_protocol::SdoAbortCode;
use motus_cia402_protocol::{index as ix, Mode};

use crate::drive::SimDrive;
use crate::objects::SET_POSITION;
use crate::sdo_server::SdoTarget;

/// Homing methods the simulator implements (spec 2.9).
pub const HOMING_METHODS: [i8; 4] = [17, 18, 35, 37];

/// The drive seen by its SDO server.
pub(crate) struct Target<'a> {
    pub(crate) drive: &'a mut SimDrive,
    pub(crate) now: Instant,
}

impl SdoTarget for Target<'_> {
    fn upload(&mut self, index: u16, sub: u8) -> Result<Vec<u8>, SdoAbortCode> {
        self.drive.read(index, sub)
    }

    fn download(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), SdoAbortCode> {
        self.drive.write(index, sub, data, self.now)
    }

    fn download_size(&self, index: u16, sub: u8) -> Result<Option<usize>, SdoAbortCode> {
        let e = self.drive.od.locate(index, sub)?;
        if !e.access.writable() {
            return Err(SdoAbortCode::ReadOnly);
        }
        Ok(e.data_type.size())
    }
}

impl SimDrive {
    /// Reads an entry as an SDO upload would (with the same abort codes).
    pub fn read(&self, index: u16, sub: u8) -> Result<Vec<u8>, SdoAbortCode> {
        if index == 0x1003 && sub > 0 && usize::from(sub) > self.emcy.history().len() {
            self.od.locate(index, sub)?;
            return Err(SdoAbortCode::NoDataAvailable);
        }
        self.od.read(index, sub)
    }

    /// Writes an entry as an SDO download would: checks, store, side effects.
    pub fn write(&mut self, index: u16, sub: u8, data: &[u8], now: Instant) -> Result<(), SdoAbortCode> {
        let value = self.od.check_write(index, sub, data)?;
        let v = value.unwrap_or(0);
        crate::pdo::check_write(&self.od, index, sub, v)?;
        match index {
            0x1003 if v != 0 => return Err(SdoAbortCode::InvalidValue),
            0x1003 => self.emcy.clear_history(),
            // We consume SYNC only: no producer bit 30, no extended ids (bit 29).
            0x1005 if v & 0x6000_0000 != 0 => return Err(SdoAbortCode::InvalidValue),
            ix::MODES_OF_OPERATION => {
                let mode = Mode::from_i8(v as i8);
                let ok = mode == Mode::NoMode
                    || mode.supported_bit().is_some_and(|b| b & crate::objects::SUPPORTED_MODES != 0);
                if !ok {
                    return Err(SdoAbortCode::InvalidValue);
                }
            }
            ix::HOMING_METHOD => {
                if v != 0 && !HOMING_METHODS.contains(&(v as i8)) {
                    return Err(SdoAbortCode::InvalidValue);
                }
                if self.mode == Mode::Homing && self.motion.busy() {
                    return Err(SdoAbortCode::DeviceState);
                }
            }
            SET_POSITION => {
                if self.motion.busy() {
                    return Err(SdoAbortCode::DeviceState);
                }
                self.motion.set_position(&mut self.motor, v as f64);
            }
            _ => {}
        }
        self.od.set_bytes(index, sub, data);
        match index {
            ix::CONTROLWORD => self.on_controlword(v as u16),
            0x1017 => self.nmt.schedule(now, v as u16),
            _ => {}
        }
        self.sync_live();
        Ok(())
    }

    fn on_controlword(&mut self, word: u16) {
        let prev = self.controlword;
        self.controlword = word;
        let o = self.options();
        let taken = self.power.on_controlword(prev, word, &o, self.inject.fault_cause.is_some());
        if taken.contains(&15) {
            self.motion.clear_following_error();
            let e = self.emcy.reset();
            self.send_emcy(e);
        }
        if !taken.is_empty() {
            tracing::debug!(node = ?self.node_id(), ?taken, state = %self.power.state(), "CiA 402 transition");
        }
        let enabled = self.power.state() == motus_cia402_protocol::PowerState::OperationEnabled;
        let p = self.params();
        self.motion.on_controlword(word, self.mode, &p, &mut self.motor, enabled);
    }

    /// Fault injection: a drive fault with this EMCY code (e.g. 0x4310 overtemperature)
    /// whose cause stays active until [`SimDrive::clear_fault_cause`].
    pub fn inject_fault(&mut self, code: u16) {
        self.inject.fault_cause = Some(code);
        self.raise_fault(code);
    }

    /// Fault injection: the cause of an injected fault is gone (a fault reset now works).
    pub fn clear_fault_cause(&mut self) {
        self.inject.fault_cause = None;
    }

    /// Fault injection: the load blocks the motor (following error, then fault 0x8611).
    pub fn set_load_blocked(&mut self, blocked: bool) {
        self.motor.set_blocked(blocked);
    }

    /// Fault injection: the node sends nothing at all (heartbeats, replies, PDOs).
    pub fn set_silent(&mut self, silent: bool) {
        self.inject.silent = silent;
    }

    /// Fault injection: the node stops sending heartbeats (all else continues).
    pub fn set_heartbeat_stopped(&mut self, stopped: bool) {
        self.inject.no_heartbeat = stopped;
    }

    /// Fault injection: SDO requests are processed but their replies are dropped.
    pub fn set_drop_sdo_replies(&mut self, drop: bool) {
        self.inject.drop_sdo = drop;
    }
}
