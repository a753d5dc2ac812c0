//! [`DriveIo`] over the CANopen master: SDOs for objects, and — once
//! [`CanopenDrive::use_pdos`] configured them — RPDO1 for the controlword and TPDOs for a
//! fresh statusword and position without SDO traffic.
//!
//! The PDO set is the seed's (specs/omni-robot.md), written to the drive by SDO in the
//! order CiA 301 requires, so it works with any vendor's CiA 402 drive:
//! - RPDO1 (0x200 + node, type 255: applied at once): controlword;
//! - RPDO2 (0x300 + node, type 1: applied at the next SYNC): controlword + 0x607A;
//! - TPDO1 (0x180 + node, type 255: on change, and every 100 ms): statusword + 0x6061;
//! - TPDO2 (0x280 + node, type 1: after every SYNC): statusword + 0x6064.

use crate::group::SyncTransport;
use crate::io::{DriveIo, IoError};
use motus_canopen::{Master, MasterError, NmtCommand, NmtState, PdoConfig, SdoError};
use motus_cia402_protocol::index;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// The latest statusword / position seen in a TPDO.
#[derive(Debug, Clone, Copy, Default)]
struct Cache {
    statusword: Option<(u16, Instant)>,
    position: Option<(i32, Instant)>,
}

/// One drive on a CANopen bus.
pub struct CanopenDrive {
    master: Arc<Master>,
    node: u8,
    pdos: bool,
    cache: Arc<Mutex<Cache>>,
    /// How old a TPDO value may be before an SDO read is used instead.
    max_age: Duration,
    /// A SYNC producer runs, so TPDO2's position is fresh.
    sync_running: bool,
}

fn io_error(node: u8, index: u16, sub: u8, e: MasterError) -> IoError {
    match e {
        MasterError::Sdo(SdoError::Aborted { code, .. }) => IoError::Refused { node, index, sub, code },
        e if e.is_timeout() => IoError::Timeout { node, index, sub, detail: e.to_string() },
        MasterError::Transport { .. } => IoError::Bus { node, reason: e.to_string() },
        e => IoError::Malformed { node, index, sub, reason: e.to_string() },
    }
}

impl CanopenDrive {
    /// A drive reached by SDO only.
    pub fn new(master: Arc<Master>, node: u8) -> Self {
        Self {
            master,
            node,
            pdos: false,
            cache: Arc::default(),
            max_age: Duration::from_millis(250),
            sync_running: false,
        }
    }

    /// The master.
    pub fn master(&self) -> &Arc<Master> {
        &self.master
    }

    /// Configures the seed's PDO set on the drive (in pre-operational), starts the node
    /// (NMT start) and from then on uses the PDOs. The drive must support them (the
    /// configuration is refused with the drive's SDO abort otherwise).
    pub fn use_pdos(&mut self) -> Result<(), IoError> {
        let n = self.node;
        let id = u32::from(n);
        let cfg = |cob: u32, ty: u8, timer: Option<u16>, mapping: Vec<(u16, u8, u8)>| PdoConfig {
            cob_id: cob,
            transmission_type: ty,
            inhibit_100us: None,
            event_timer_ms: timer,
            sync_start: None,
            mapping,
        };
        let err = |e| io_error(n, 0x1400, 0, e);
        self.master.nmt(n, NmtCommand::EnterPreOperational).map_err(err)?;
        self.master
            .configure_rpdo(n, 1, &cfg(0x200 + id, 255, None, vec![(index::CONTROLWORD, 0, 16)]))
            .map_err(err)?;
        self.master
            .configure_rpdo(
                n,
                2,
                &cfg(0x300 + id, 1, None, vec![(index::CONTROLWORD, 0, 16), (index::TARGET_POSITION, 0, 32)]),
            )
            .map_err(err)?;
        self.master
            .configure_tpdo(
                n,
                1,
                &cfg(
                    0x4000_0180 + id,
                    255,
                    Some(100),
                    vec![(index::STATUSWORD, 0, 16), (index::MODES_DISPLAY, 0, 8)],
                ),
            )
            .map_err(err)?;
        self.master
            .configure_tpdo(
                n,
                2,
                &cfg(
                    0x4000_0280 + id,
                    1,
                    None,
                    vec![(index::STATUSWORD, 0, 16), (index::POSITION_ACTUAL, 0, 32)],
                ),
            )
            .map_err(err)?;
        self.listen();
        self.master.nmt(n, NmtCommand::Start).map_err(err)?;
        self.pdos = true;
        Ok(())
    }

    /// Starts the thread that keeps the TPDO cache. It ends (and its subscription with it)
    /// once this driver is dropped, so a drive brought up again and again (after restarts of
    /// the drive) leaves no thread behind. It takes part in the master's clock and waits on
    /// it (on a threaded virtual clock the cache is updated at the instant of the TPDO).
    fn listen(&self) {
        let rx = self.master.subscribe_on_clock(motus_canopen::CobFilter::Range(
            0x180 + u32::from(self.node)..=0x280 + u32::from(self.node),
        ));
        let cache = Arc::downgrade(&self.cache);
        let (t1, t2) = (0x180 + u32::from(self.node), 0x280 + u32::from(self.node));
        let builder = std::thread::Builder::new().name(format!("cia402-tpdo-{}", self.node));
        let spawned = motus_clock::spawn(self.master.clock(), builder, move || {
            motus_realtime::promote_current_thread(motus_realtime::ThreadClass::Device);
            loop {
                let r = match rx.recv_timeout(Duration::from_secs(1)) {
                    Ok(r) => r,
                    Err(std::sync::mpsc::RecvTimeoutError::Timeout) if cache.strong_count() > 0 => continue,
                    Err(_) => break,
                };
                let Some(cache) = cache.upgrade() else { break };
                let id = r.frame.id();
                let d = r.frame.data();
                let mut c = match cache.lock() {
                    Ok(c) => c,
                    Err(p) => p.into_inner(),
                };
                if (id == t1 || id == t2) && d.len() >= 2 {
                    if let Some(sw) = d.get(0..2).and_then(|b| b.try_into().ok()) {
                        c.statusword = Some((u16::from_le_bytes(sw), r.at));
                    }
                }
                if id == t2 {
                    if let Some(p) = d.get(2..6).and_then(|b| b.try_into().ok()) {
                        c.position = Some((i32::from_le_bytes(p), r.at));
                    }
                }
            }
        });
        if let Err(e) = spawned {
            tracing::error!(error = %e, "cannot spawn the TPDO listener");
        }
    }

    fn cached<T: Copy>(&self, pick: impl Fn(&Cache) -> Option<(T, Instant)>) -> Option<T> {
        if !self.pdos {
            return None;
        }
        let c = self.cache.lock().ok()?;
        let clock = self.master.clock();
        pick(&c).filter(|(_, at)| clock.elapsed(*at) <= self.max_age).map(|(v, _)| v)
    }

    /// Declares that a SYNC producer runs (every few ms), so the position TPDO2 carries
    /// is fresh and can replace SDO reads.
    pub fn set_sync_running(&mut self, running: bool) {
        self.sync_running = running;
    }

    /// Whether the node's heartbeat says it is alive and in a state that runs PDOs.
    pub fn nmt_state(&self) -> Option<NmtState> {
        self.master.node_state(self.node)
    }
}

impl DriveIo for CanopenDrive {
    fn node(&self) -> u8 {
        self.node
    }

    fn clock(&self) -> motus_clock::SharedClock {
        std::sync::Arc::clone(self.master.clock())
    }

    fn read(&self, index: u16, sub: u8) -> Result<Vec<u8>, IoError> {
        self.master.sdo_upload(self.node, index, sub).map_err(|e| io_error(self.node, index, sub, e))
    }

    fn write(&self, index: u16, sub: u8, data: &[u8]) -> Result<(), IoError> {
        self.master.sdo_download(self.node, index, sub, data).map_err(|e| io_error(self.node, index, sub, e))
    }

    fn write_controlword(&self, cw: u16) -> Result<(), IoError> {
        if self.pdos {
            self.master
                .send_pdo(0x200 + u32::from(self.node), &cw.to_le_bytes())
                .map_err(|e| io_error(self.node, index::CONTROLWORD, 0, e))
        } else {
            self.write(index::CONTROLWORD, 0, &cw.to_le_bytes())
        }
    }

    fn statusword(&self) -> Result<u16, IoError> {
        match self.cached(|c| c.statusword) {
            Some(sw) => Ok(sw),
            None => {
                let raw = self.read(index::STATUSWORD, 0)?;
                crate::io::fixed::<2>(self.node, index::STATUSWORD, 0, &raw).map(u16::from_le_bytes)
            }
        }
    }

    fn position(&self) -> Result<i32, IoError> {
        // TPDO2 only carries the position of the last SYNC: without a SYNC producer it
        // is stale, so the position is read by SDO unless a SYNC is running.
        match self.cached(|c| c.position).filter(|_| self.sync_running) {
            Some(p) => Ok(p),
            None => {
                let raw = self.read(index::POSITION_ACTUAL, 0)?;
                crate::io::fixed::<4>(self.node, index::POSITION_ACTUAL, 0, &raw).map(i32::from_le_bytes)
            }
        }
    }
}

/// PDOs and SYNC through the master, for [`crate::group`].
pub struct MasterSync(pub Arc<Master>);

impl SyncTransport for MasterSync {
    fn send_pdo(&self, cob_id: u16, data: &[u8]) -> Result<(), IoError> {
        self.0.send_pdo(u32::from(cob_id), data).map_err(|e| IoError::Bus { node: 0, reason: e.to_string() })
    }

    fn send_sync(&self) -> Result<(), IoError> {
        self.0.send_sync().map_err(|e| IoError::Bus { node: 0, reason: e.to_string() })
    }
}
