//! The three wheel drives over CANopen / CiA 402. Every wait (boot-up, set-point
//! acknowledge, target reached) and the watchdog run on the master's clock
//! ([`Master::clock`]): the system clock, or a threaded virtual clock in tests
//! ([`Master::with_threaded_clock`]), where the watchdog takes part in the clock and reacts
//! at the virtual instant of the event.

use motus_canopen::{Master, MasterEvent, NmtState};
use motus_cia402::group::{self, GroupMove};
use motus_cia402::{CanopenDrive, Drive, DriveError, DriveIo, DriveSettings, MasterSync, Profile};
use motus_cia402_protocol::sw;
use motus_omni::controller::WheelDrives;
use motus_omni::sync_profile::WheelProfile;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// Why a wheel operation failed.
#[derive(Debug, thiserror::Error)]
pub enum WheelError {
    /// A drive operation failed.
    #[error("wheel {wheel} (node {node}): {source}")]
    Drive {
        /// Wheel 1..=3.
        wheel: usize,
        /// Node id.
        node: u8,
        /// The failure.
        #[source]
        source: DriveError,
    },
    /// A drive was lost or signalled an emergency; every wheel was quick-stopped.
    #[error("robot stopped: {0}")]
    Stopped(String),
    /// A node did not boot or answer during bring-up.
    #[error("node {node}: {reason}")]
    BringUp {
        /// Node id.
        node: u8,
        /// What went wrong.
        reason: String,
    },
}

/// Bring-up and supervision settings.
#[derive(Debug, Clone, PartialEq)]
pub struct WheelSettings {
    /// Node ids of wheels 1, 2, 3 (the seed: 2, 3, 4).
    pub nodes: [u8; 3],
    /// Heartbeat consumer time per drive (a drive silent longer is lost).
    pub heartbeat_timeout: Duration,
    /// How long to wait for each drive's boot-up or first heartbeat.
    pub boot_timeout: Duration,
    /// Driver settings.
    pub drive: DriveSettings,
}

impl Default for WheelSettings {
    fn default() -> Self {
        Self {
            nodes: [2, 3, 4],
            heartbeat_timeout: Duration::from_millis(300),
            boot_timeout: Duration::from_secs(10),
            drive: DriveSettings::default(),
        }
    }
}

/// The robot's three wheel drives.
pub struct CanopenWheels {
    master: Arc<Master>,
    drives: Vec<Drive<CanopenDrive>>,
    nodes: [u8; 3],
    /// Set by the watchdog when a drive is lost or faulted: why the robot stopped.
    stopped: Arc<Mutex<Option<String>>>,
    watchdog_run: Arc<AtomicBool>,
    last_moves: Vec<GroupMove>,
}

/// Quick stop (controlword 0x0002) to every node by RPDO1, as fast as the bus allows.
fn quick_stop_all(master: &Master, nodes: &[u8]) -> Result<(), String> {
    let mut first_err = None;
    for n in nodes {
        if let Err(e) = master.send_pdo(0x200 + u32::from(*n), &0x0002u16.to_le_bytes()) {
            first_err.get_or_insert(e.to_string());
        }
    }
    first_err.map_or(Ok(()), Err)
}

impl CanopenWheels {
    /// Brings the three drives up: waits for each to be heard (boot-up or heartbeat),
    /// starts heartbeat monitoring, configures the PDO set, clears a fault whose cause is
    /// gone, enables, and selects profile position. Starts the watchdog.
    pub fn bring_up(master: Arc<Master>, settings: &WheelSettings) -> Result<Self, WheelError> {
        let nodes = settings.nodes;
        let clock = Arc::clone(master.clock());
        let mut drives = Vec::new();
        for node in nodes {
            let deadline = clock.now() + settings.boot_timeout;
            while master.node_state(node).is_none() {
                if clock.now() > deadline {
                    return Err(WheelError::BringUp {
                        node,
                        reason: format!("no boot-up or heartbeat within {:?}", settings.boot_timeout),
                    });
                }
                clock.sleep(Duration::from_millis(5));
            }
            // Heartbeat every third of the consumer time, so one lost frame is tolerated.
            let period =
                u16::try_from((settings.heartbeat_timeout / 3).as_millis()).unwrap_or(u16::MAX).max(1);
            master.sdo_download(node, 0x1017, 0, &period.to_le_bytes()).map_err(|e| WheelError::BringUp {
                node,
                reason: format!("setting the heartbeat (0x1017): {e}"),
            })?;
            master.monitor_heartbeat(node, settings.heartbeat_timeout);
            let mut io = CanopenDrive::new(Arc::clone(&master), node);
            io.use_pdos().map_err(|e| WheelError::BringUp { node, reason: e.to_string() })?;
            drives.push(Drive::new(io, settings.drive.clone()));
        }
        let stopped = Arc::new(Mutex::new(None));
        let watchdog_run = Arc::new(AtomicBool::new(true));
        spawn_watchdog(Arc::clone(&master), nodes, Arc::clone(&stopped), Arc::clone(&watchdog_run));
        let mut wheels = Self { master, drives, nodes, stopped, watchdog_run, last_moves: Vec::new() };
        wheels.enable()?;
        Ok(wheels)
    }

    fn each<T>(
        &mut self,
        mut f: impl FnMut(&mut Drive<CanopenDrive>) -> Result<T, DriveError>,
    ) -> Result<Vec<T>, WheelError> {
        let mut out = Vec::new();
        for (i, d) in self.drives.iter_mut().enumerate() {
            let node = d.node();
            out.push(f(d).map_err(|source| WheelError::Drive { wheel: i + 1, node, source })?);
        }
        Ok(out)
    }

    /// Clears faults whose cause is gone, enables every drive and selects profile position.
    pub fn enable(&mut self) -> Result<(), WheelError> {
        self.each(|d| {
            d.fault_reset()?;
            d.enable()?;
            d.set_mode(motus_cia402_protocol::Mode::ProfilePosition)
        })?;
        if let Ok(mut s) = self.stopped.lock() {
            *s = None;
        }
        Ok(())
    }

    /// Zeroes every wheel's position by homing on the current position (method 35).
    pub fn home(&mut self) -> Result<(), WheelError> {
        self.check()?;
        self.each(|d| d.home(35, Duration::from_secs(10)))?;
        Ok(())
    }

    /// The node ids.
    pub fn nodes(&self) -> [u8; 3] {
        self.nodes
    }

    /// The master.
    pub fn master(&self) -> &Arc<Master> {
        &self.master
    }

    /// Why the watchdog stopped the robot, if it did.
    pub fn stop_reason(&self) -> Option<String> {
        self.stopped.lock().ok().and_then(|s| s.clone())
    }

    fn check(&self) -> Result<(), WheelError> {
        match self.stop_reason() {
            Some(r) => Err(WheelError::Stopped(r)),
            None => Ok(()),
        }
    }

    /// Statuswords of the three drives.
    pub fn statuswords(&mut self) -> Result<[u16; 3], WheelError> {
        let v = self.each(|d| Ok(d.io().statusword()?))?;
        Ok([v.first().copied().unwrap_or(0), v.get(1).copied().unwrap_or(0), v.get(2).copied().unwrap_or(0)])
    }
}

impl Drop for CanopenWheels {
    fn drop(&mut self) {
        self.watchdog_run.store(false, Ordering::Relaxed);
    }
}

/// Watches the master's events: a lost heartbeat or an emergency from a wheel
/// quick-stops every wheel at once and records why.
fn spawn_watchdog(
    master: Arc<Master>,
    nodes: [u8; 3],
    stopped: Arc<Mutex<Option<String>>>,
    run: Arc<AtomicBool>,
) {
    let events = master.events_on_clock();
    let clock = Arc::clone(master.clock());
    let builder = std::thread::Builder::new().name("robot-watchdog".into());
    let spawned = motus_clock::spawn(&clock, builder, move || {
        // Quick-stops every wheel on a lost heartbeat or an EMCY: a device thread.
        motus_realtime::promote_current_thread(motus_realtime::ThreadClass::Device);
        while run.load(Ordering::Relaxed) {
            let Ok(event) = events.recv_timeout(Duration::from_millis(50)) else { continue };
            let reason = match event {
                MasterEvent::HeartbeatLost { node, last_seen } if nodes.contains(&node) => {
                    let ago = master.clock().elapsed(last_seen);
                    Some(format!("node {node} heartbeat lost (last seen {ago:?} ago)"))
                }
                MasterEvent::StateChanged { node, to, .. }
                    if nodes.contains(&node) && !matches!(to, NmtState::Operational) =>
                {
                    Some(format!("node {node} left OPERATIONAL (now {to})"))
                }
                MasterEvent::Emergency(e) if nodes.contains(&e.node) && e.code != 0 => {
                    Some(format!("emergency from node {}: {e}", e.node))
                }
                _ => None,
            };
            if let Some(reason) = reason {
                tracing::error!(%reason, "quick-stopping every wheel");
                if let Err(e) = quick_stop_all(&master, &nodes) {
                    tracing::error!(error = %e, "quick stop failed");
                }
                if let Ok(mut s) = stopped.lock() {
                    s.get_or_insert(reason);
                }
            }
        }
    });
    if let Err(e) = spawned {
        tracing::error!(error = %e, "cannot spawn the robot watchdog");
    }
}

impl WheelDrives for CanopenWheels {
    type Error = WheelError;

    fn positions(&mut self) -> Result<[i32; 3], WheelError> {
        self.check()?;
        let v = self.each(|d| d.position())?;
        Ok([v.first().copied().unwrap_or(0), v.get(1).copied().unwrap_or(0), v.get(2).copied().unwrap_or(0)])
    }

    fn move_relative(&mut self, travel: [i32; 3], profiles: [WheelProfile; 3]) -> Result<(), WheelError> {
        self.check()?;
        for (i, p) in profiles.iter().enumerate() {
            let Some(d) = self.drives.get_mut(i) else { continue };
            let node = d.node();
            d.set_profile(&Profile {
                velocity: p.velocity,
                acceleration: p.acceleration,
                deceleration: p.deceleration,
            })
            .map_err(|source| WheelError::Drive { wheel: i + 1, node, source })?;
        }
        let moves: Vec<GroupMove> = self
            .nodes
            .iter()
            .zip(travel)
            .map(|(n, t)| GroupMove { rpdo_cob_id: 0x300 + u16::from(*n), target: t, relative: true })
            .collect();
        let bus = MasterSync(Arc::clone(&self.master));
        let io_err = |wheel: usize, node: u8, e| WheelError::Drive { wheel, node, source: DriveError::Io(e) };
        group::start_together(&bus, &moves).map_err(|e| io_err(1, self.nodes[0], e))?;
        // Every drive must acknowledge the set-point (statusword bit 12) before bit 4 drops.
        let clock = Arc::clone(self.master.clock());
        let deadline = clock.now() + Duration::from_secs(2);
        loop {
            let words = self.statuswords()?;
            if words.iter().all(|w| w & sw::SET_POINT_ACKNOWLEDGE != 0) {
                break;
            }
            if let Some(i) = words.iter().position(|w| w & sw::FAULT != 0) {
                let _ = quick_stop_all(&self.master, &self.nodes);
                let node = self.nodes.get(i).copied().unwrap_or(0);
                return Err(WheelError::Drive {
                    wheel: i + 1,
                    node,
                    source: DriveError::Fault { node, code: None },
                });
            }
            if clock.now() > deadline {
                let _ = quick_stop_all(&self.master, &self.nodes);
                let i = words.iter().position(|w| w & sw::SET_POINT_ACKNOWLEDGE == 0).unwrap_or(0);
                let node = self.nodes.get(i).copied().unwrap_or(0);
                return Err(WheelError::Drive {
                    wheel: i + 1,
                    node,
                    source: DriveError::SetPointNotAcknowledged {
                        node,
                        statusword: words.get(i).copied().unwrap_or(0),
                        waited: Duration::from_secs(2),
                    },
                });
            }
            clock.sleep(Duration::from_millis(2));
        }
        group::finish(&bus, &moves).map_err(|e| io_err(1, self.nodes[0], e))?;
        self.last_moves = moves;
        Ok(())
    }

    fn wait_reached(&mut self, timeout: Duration) -> Result<bool, WheelError> {
        let clock = Arc::clone(self.master.clock());
        let deadline = clock.now() + timeout;
        loop {
            self.check()?;
            let words = self.statuswords()?;
            for (i, w) in words.iter().enumerate() {
                let node = self.nodes.get(i).copied().unwrap_or(0);
                if w & sw::FAULT != 0 {
                    let _ = quick_stop_all(&self.master, &self.nodes);
                    let code = self.drives.get(i).and_then(|d| d.error_code());
                    return Err(WheelError::Drive {
                        wheel: i + 1,
                        node,
                        source: DriveError::Fault { node, code },
                    });
                }
                if w & sw::FOLLOWING_ERROR != 0 {
                    let _ = quick_stop_all(&self.master, &self.nodes);
                    return Err(WheelError::Drive {
                        wheel: i + 1,
                        node,
                        source: DriveError::FollowingError { node, statusword: *w },
                    });
                }
            }
            if words
                .iter()
                .all(|w| w & (sw::TARGET_REACHED | sw::SET_POINT_ACKNOWLEDGE) == sw::TARGET_REACHED)
            {
                return Ok(true);
            }
            if clock.now() > deadline {
                return Ok(false);
            }
            clock.sleep(Duration::from_millis(5));
        }
    }

    fn quick_stop(&mut self) -> Result<(), WheelError> {
        quick_stop_all(&self.master, &self.nodes).map_err(WheelError::Stopped)
    }
}
