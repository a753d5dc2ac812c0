//! `SimDrive`: one simulated IclA node, sans-IO. `handle(frame, now)` and `poll(now)` return
//! the frames the node sends; time only moves through the `now` arguments (motion is
//! integrated in fixed 1 ms steps up to `now`).

use std::time::{Duration, Instant};

use motus_canopen_protocol::message::{LSS_MASTER_TO_SLAVE, LSS_SLAVE_TO_MASTER};
use motus_canopen_protocol::{CanFrame, LssRequest, NmtCommand, NmtState};
use motus_cia402_protocol::{index as ix, sw, Mode, PowerState};

use crate::cia402::{Options, Power};
use crate::config::{SimConfig, UNCONFIGURED};
use crate::emcy::Emcy;
use crate::heartbeat_consumer::HeartbeatConsumer;
use crate::lss::{LssEvent, LssSlave};
use crate::motion::{Motion, Params};
use crate::motor::Motor;
use crate::nmt::{Nmt, NmtAction};
use crate::od::ObjectDictionary;
use crate::pdo::{PdoEngine, RpdoResult};
use crate::sdo_server::SdoServer;

/// EMCY code of a consumed heartbeat that stopped (CiA 301 "life guard / heartbeat error").
pub const HEARTBEAT_ERROR: u16 = 0x8130;

/// Integration step of the motion model.
pub const STEP: Duration = Duration::from_millis(1);
/// Longest stretch of time integrated in one call (a paused simulation does not replay hours).
const MAX_CATCH_UP: Duration = Duration::from_secs(60);

/// Fault injection switches.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(crate) struct Injection {
    pub(crate) fault_cause: Option<u16>,
    pub(crate) silent: bool,
    pub(crate) no_heartbeat: bool,
    pub(crate) drop_sdo: bool,
}

/// One simulated drive (one CANopen node).
#[derive(Debug, Clone)]
pub struct SimDrive {
    pub(crate) cfg: SimConfig,
    pub(crate) od: ObjectDictionary,
    pub(crate) nmt: Nmt,
    pub(crate) sdo: SdoServer,
    pub(crate) pdo: PdoEngine,
    pub(crate) emcy: Emcy,
    pub(crate) lss: LssSlave,
    pub(crate) power: Power,
    pub(crate) motion: Motion,
    pub(crate) motor: Motor,
    pub(crate) mode: Mode,
    pub(crate) controlword: u16,
    pub(crate) inject: Injection,
    heartbeat_consumer: HeartbeatConsumer,
    clock: Option<Instant>,
    boot_at: Option<Instant>,
    booted: bool,
    pub(crate) out: Vec<CanFrame>,
}

impl SimDrive {
    /// A drive as configured, powered on; it boots at the first `poll` / `handle` plus the
    /// configured boot delay.
    pub fn new(cfg: SimConfig) -> Self {
        let od = crate::objects::build(&cfg);
        let pos = f64::from(cfg.initial_position);
        let mode = Mode::from_i8(od.int(ix::MODES_OF_OPERATION, 0) as i8);
        Self {
            lss: LssSlave::new(cfg.node_id, cfg.bit_timing),
            motor: Motor::new(pos, cfg.lag_time),
            motion: Motion::new(pos),
            cfg,
            od,
            nmt: Nmt::new(),
            sdo: SdoServer::new(),
            pdo: PdoEngine::default(),
            emcy: Emcy::default(),
            power: Power::new(),
            mode,
            controlword: 0,
            inject: Injection::default(),
            heartbeat_consumer: HeartbeatConsumer::default(),
            clock: None,
            boot_at: None,
            booted: false,
            out: Vec::new(),
        }
    }

    /// The active node id (`None` while LSS-unconfigured).
    pub fn node_id(&self) -> Option<u8> {
        Some(self.lss.active_id()).filter(|&id| id != UNCONFIGURED)
    }

    /// The configuration.
    pub fn config(&self) -> &SimConfig {
        &self.cfg
    }

    /// The object dictionary (current values).
    pub fn od(&self) -> &ObjectDictionary {
        &self.od
    }

    /// The NMT state (`BootUp` = initialising or LSS-unconfigured).
    pub fn nmt_state(&self) -> NmtState {
        self.nmt.state()
    }

    /// The CiA 402 power state.
    pub fn power_state(&self) -> PowerState {
        self.power.state()
    }

    /// The mode of operation in effect (0x6061).
    pub fn mode(&self) -> Mode {
        self.mode
    }

    /// The statusword 0x6041.
    pub fn statusword(&self) -> u16 {
        self.power.state().statusword_bits()
            | sw::VOLTAGE_ENABLED
            | sw::REMOTE
            | self.motion.statusword_bits(self.mode, &self.motor)
    }

    /// Actual position 0x6064 (Inc).
    pub fn position(&self) -> i32 {
        self.motor.position().round() as i32
    }

    /// Actual velocity 0x606C (Inc/s).
    pub fn velocity(&self) -> i32 {
        self.motor.velocity().round() as i32
    }

    /// The physical shaft position (Inc, world frame, unaffected by homing) for a world model.
    pub fn world_position(&self) -> f64 {
        self.motor.world()
    }

    /// The LSS slave (bit rate, stored values...).
    pub fn lss(&self) -> &LssSlave {
        &self.lss
    }

    /// The error state (register, history, last code).
    pub fn emcy(&self) -> &Emcy {
        &self.emcy
    }

    /// The EDS text describing this drive's dictionary.
    pub fn eds(&self) -> String {
        crate::eds::export(&self.od, &self.cfg.identity)
    }

    /// Handles one received frame; returns the frames sent in reaction.
    pub fn handle(&mut self, frame: &CanFrame, now: Instant) -> Vec<CanFrame> {
        self.advance(now);
        if self.is_other_nodes_sdo(frame) {
            return self.take(now);
        }
        if self.booted && !self.lss.muted(now) && !frame.is_extended() && !frame.is_remote() {
            self.dispatch(frame, now);
            if self.nmt.pdo_allowed() {
                let f = self.pdo.events(&self.od, now, false);
                self.out.extend(f);
            }
        }
        self.take(now)
    }

    /// Runs the timers up to `now` (boot-up, heartbeat, event timers, SDO time-out, motion);
    /// returns the frames sent.
    pub fn poll(&mut self, now: Instant) -> Vec<CanFrame> {
        self.advance(now);
        let boot_at = *self.boot_at.get_or_insert(now + self.cfg.boot_delay);
        if !self.booted && now >= boot_at {
            self.booted = true;
            self.boot(now);
        }
        if self.booted {
            let hb = self.od.int(0x1017, 0) as u16;
            if let Some(state) = self.nmt.heartbeat(now, hb) {
                if let (Some(id), false) = (self.node_id(), self.inject.no_heartbeat) {
                    self.push(0x700 + u32::from(id), &[state]);
                }
            }
            if let Some(resp) = self.sdo.poll(now) {
                self.sdo_reply(&resp);
            }
            self.heartbeat_consumer.configure(self.od.u32(0x1016, 1));
            if self.heartbeat_consumer.expired(now)
                && matches!(self.nmt.state(), NmtState::PreOperational | NmtState::Operational)
            {
                let producer = self.heartbeat_consumer.watched().map_or(0, |(n, _)| n);
                tracing::warn!(node = ?self.node_id(), producer, "heartbeat of the master lost: fault reaction");
                self.raise_fault(HEARTBEAT_ERROR);
            }
            if self.nmt.pdo_allowed() {
                let f = self.pdo.events(&self.od, now, false);
                self.out.extend(f);
            }
        }
        self.take(now)
    }

    /// Another node's SDO request or response. CiA 301 reserves 0x581..=0x5FF and
    /// 0x601..=0x67F for the default SDO channels (no PDO, SYNC or EMCY may use them), so
    /// such a frame concerns this drive in no way and costs it no dictionary look-up (on a
    /// bus of many drives every drive sees every transfer).
    fn is_other_nodes_sdo(&self, frame: &CanFrame) -> bool {
        let id = frame.id();
        let sdo = (0x581..=0x5FF).contains(&id) || (0x601..=0x67F).contains(&id);
        sdo && !frame.is_extended() && self.node_id().map_or(true, |n| id != 0x600 + u32::from(n))
    }

    fn take(&mut self, now: Instant) -> Vec<CanFrame> {
        if self.inject.silent || self.lss.muted(now) {
            self.out.clear();
        }
        std::mem::take(&mut self.out)
    }

    pub(crate) fn push(&mut self, id: u32, data: &[u8]) {
        if let Ok(f) = CanFrame::new(id, data) {
            self.out.push(f);
        }
    }

    pub(crate) fn sdo_reply(&mut self, data: &[u8; 8]) {
        if let (Some(id), false) = (self.node_id(), self.inject.drop_sdo) {
            self.push(0x580 + u32::from(id), data);
        }
    }

    /// Sends an EMCY if the NMT state allows it.
    pub(crate) fn send_emcy(&mut self, data: [u8; 8]) {
        if self.node_id().is_some()
            && matches!(self.nmt.state(), NmtState::PreOperational | NmtState::Operational)
        {
            let cob = self.od.u32(0x1014, 0) & 0x7FF;
            self.push(cob, &data);
        }
    }

    fn dispatch(&mut self, frame: &CanFrame, now: Instant) {
        let id = frame.id();
        if id == LSS_MASTER_TO_SLAVE {
            if let Some(req) = LssRequest::decode(frame.data()) {
                let (resp, event) = self.lss.handle(&req, &self.cfg.identity, now);
                if let Some(r) = resp {
                    self.push(LSS_SLAVE_TO_MASTER, &r.encode());
                }
                if event == LssEvent::ResetCommunication {
                    self.reset_communication(now);
                }
            }
            return;
        }
        let Some(node) = self.node_id() else { return };
        if (0x701..=0x77F).contains(&id) {
            if let [_state] = frame.data() {
                self.heartbeat_consumer.on_heartbeat((id - 0x700) as u8, now);
            }
            return;
        }
        if id == 0x000 {
            if let [cs, target] = frame.data() {
                if *target == 0 || *target == node {
                    self.nmt_command(NmtCommand::from_raw(*cs), now);
                }
            }
            return;
        }
        let sync_id = self.od.u32(0x1005, 0) & 0x7FF;
        if id == sync_id && self.nmt.pdo_allowed() {
            let counter = frame.data().first().copied();
            let (frames, writes) = self.pdo.on_sync(&self.od, counter, now);
            self.out.extend(frames);
            self.apply_pdo(writes, now);
            return;
        }
        if id == 0x600 + u32::from(node) {
            if self.nmt.sdo_allowed() {
                let mut server = std::mem::take(&mut self.sdo);
                let resp = server.handle(frame.data(), now, &mut crate::access::Target { drive: self, now });
                self.sdo = server;
                if let Some(r) = resp {
                    self.sdo_reply(&r);
                }
            }
            return;
        }
        if self.nmt.pdo_allowed() {
            match self.pdo.on_frame(&self.od, frame) {
                RpdoResult::Apply(writes) => self.apply_pdo(writes, now),
                RpdoResult::TooShort => {
                    let e = self.emcy.transient(0x8210);
                    self.send_emcy(e);
                }
                RpdoResult::Buffered | RpdoResult::NotOurs => {}
            }
        }
    }

    /// Writes the objects of a received PDO; the controlword last, so that a set-point
    /// edge sees the target position that came in the same PDO (the seed's RPDO2).
    fn apply_pdo(&mut self, mut writes: Vec<crate::pdo::PdoWrite>, now: Instant) {
        writes.sort_by_key(|w| w.0 == ix::CONTROLWORD);
        for (index, sub, data) in writes {
            if let Err(code) = self.write(index, sub, &data, now) {
                tracing::debug!(index, sub, %code, "RPDO write refused");
            }
        }
    }

    fn nmt_command(&mut self, command: NmtCommand, now: Instant) {
        match self.nmt.command(command) {
            NmtAction::None => {}
            NmtAction::EnteredOperational => {
                self.pdo.reset();
                self.sync_live();
                let f = self.pdo.events(&self.od, now, true);
                self.out.extend(f);
            }
            NmtAction::ResetNode => self.reset_node(now),
            NmtAction::ResetCommunication => self.reset_communication(now),
        }
    }

    /// Application reset: every object back to its default, power state machine restarted,
    /// stored LSS values reloaded; the position counter is kept (absolute encoder).
    pub(crate) fn reset_node(&mut self, now: Instant) {
        self.lss.reset_node();
        let pos = self.motor.position();
        self.motion = Motion::new(pos);
        self.power = Power::new();
        self.controlword = 0;
        self.emcy = Emcy::default();
        self.od.reset(0x0000..=0xFFFF, self.lss.pending_id());
        self.mode = Mode::from_i8(self.od.int(ix::MODES_OF_OPERATION, 0) as i8);
        self.reset_communication(now);
        if let Some(code) = self.inject.fault_cause {
            self.raise_fault(code);
        }
    }

    /// Communication reset: 0x1000-0x1FFF back to defaults, pending node id activated, boot-up.
    pub(crate) fn reset_communication(&mut self, now: Instant) {
        self.lss.reset_communication();
        self.od.reset(0x1000..=0x1FFF, self.lss.active_id());
        self.sdo.reset();
        self.pdo.reset();
        self.nmt.initialise();
        self.boot(now);
    }

    fn boot(&mut self, now: Instant) {
        self.sync_live();
        if let Some(id) = self.node_id() {
            self.push(0x700 + u32::from(id), &[0x00]);
            self.nmt.boot(now, self.od.int(0x1017, 0) as u16);
        } else {
            self.nmt.initialise();
        }
    }

    /// Profile parameters from the dictionary.
    pub(crate) fn params(&self) -> Params {
        let od = &self.od;
        let f = |i: u16, s: u8| od.int(i, s) as f64;
        let (lo, hi) = (f(0x607D, 1), f(0x607D, 2));
        let window = od.u32(ix::FOLLOWING_ERROR_WINDOW, 0);
        Params {
            target_position: f(ix::TARGET_POSITION, 0),
            target_velocity: f(ix::TARGET_VELOCITY, 0),
            velocity: f(ix::PROFILE_VELOCITY, 0),
            acceleration: f(ix::PROFILE_ACCELERATION, 0),
            deceleration: f(ix::PROFILE_DECELERATION, 0),
            position_window: f(ix::POSITION_WINDOW, 0),
            position_window_time: f(ix::POSITION_WINDOW_TIME, 0) / 1000.0,
            following_window: (window != u32::MAX).then_some(f64::from(window)),
            following_timeout: f(ix::FOLLOWING_ERROR_TIMEOUT, 0) / 1000.0,
            limits: (lo < hi).then_some((lo, hi)),
            homing_method: od.int(ix::HOMING_METHOD, 0) as i8,
            homing_speeds: (f(ix::HOMING_SPEEDS, 1), f(ix::HOMING_SPEEDS, 2)),
            homing_acceleration: f(ix::HOMING_ACCELERATION, 0),
            home_offset: f(ix::HOME_OFFSET, 0),
            switches: (self.cfg.negative_limit_switch, self.cfg.positive_limit_switch),
        }
    }

    pub(crate) fn options(&self) -> Options {
        let od = &self.od;
        Options {
            quick_stop: od.int(ix::QUICK_STOP_OPTION, 0) as i16,
            shutdown: od.int(0x605B, 0) as i16,
            disable_operation: od.int(0x605C, 0) as i16,
            fault_reaction: od.int(0x605E, 0) as i16,
            profile_deceleration: od.int(ix::PROFILE_DECELERATION, 0) as f64,
            quick_stop_deceleration: od.int(ix::QUICK_STOP_DECELERATION, 0) as f64,
        }
    }

    /// Integrates the motion up to `now` in fixed steps.
    fn advance(&mut self, now: Instant) {
        let last = *self.clock.get_or_insert(now);
        if now <= last {
            return;
        }
        let mut t = if now - last > MAX_CATCH_UP { now - MAX_CATCH_UP } else { last };
        if t + STEP > now {
            // No regulator step due: the live values in the dictionary are current (every
            // write and fault updates them at once).
            return;
        }
        let (p, o) = (self.params(), self.options());
        let dt = STEP.as_secs_f64();
        while t + STEP <= now {
            t += STEP;
            let requested = Mode::from_i8(self.od.int(ix::MODES_OF_OPERATION, 0) as i8);
            if requested != self.mode && !self.motion.busy() {
                self.mode = requested;
            }
            let regime = self.power.regime(&o);
            let outcome = self.motion.step(regime, self.mode, &p, &mut self.motor, dt);
            self.power.after_step(outcome.standstill, &o);
            if outcome.following_error_fault {
                self.raise_fault(0x8611);
            }
        }
        self.clock = Some(t);
        self.sync_live();
    }

    /// A fault (transition 13) with EMCY.
    pub(crate) fn raise_fault(&mut self, code: u16) {
        let o = self.options();
        self.power.fault(&o);
        let e = self.emcy.raise(code, [0; 5]);
        self.send_emcy(e);
        self.sync_live();
    }

    /// Copies the live values into the dictionary (statusword, position...).
    pub(crate) fn sync_live(&mut self) {
        let sw = self.statusword();
        let od = &mut self.od;
        od.set_int(ix::STATUSWORD, 0, i64::from(sw));
        od.set_int(ix::MODES_DISPLAY, 0, i64::from(self.mode.to_i8()));
        od.set_int(0x6062, 0, self.motion.demand().round() as i64);
        od.set_int(ix::POSITION_ACTUAL, 0, self.motor.position().round() as i64);
        od.set_int(ix::VELOCITY_ACTUAL, 0, self.motor.velocity().round() as i64);
        od.set_int(0x60F4, 0, (self.motion.demand() - self.motor.position()).round() as i64);
        od.set_int(ix::ERROR_CODE, 0, i64::from(self.emcy.code()));
        od.set_int(0x1001, 0, i64::from(self.emcy.register()));
        let hist = self.emcy.history();
        od.set_int(0x1003, 0, hist.len() as i64);
        for sub in 1..=8u8 {
            let v = hist.get(usize::from(sub) - 1).copied().unwrap_or(0);
            od.set_int(0x1003, sub, i64::from(v));
        }
    }
}
