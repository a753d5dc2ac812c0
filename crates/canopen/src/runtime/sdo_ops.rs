//! SDO services of the runtime: transfers, typed helpers, PDO configuration, node scan
//! and EDS-driven dumps.

use std::collections::HashMap;
use std::ops::RangeInclusive;
use std::path::Path;
use std::sync::mpsc::{channel, RecvTimeoutError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use crate::eds::{ObjectDictionary, Value};
use crate::error::MasterError;
use crate::lss::LssIdentity;
use crate::pdo::{PdoConfig, PdoDirection};
use crate::sdo_client::{SdoError, SdoStep, SdoTransfer};

use super::spin_wait::WaitPlan;
use super::wake::Waiter;
use super::{lock, Inner, Master};

/// What [`Master::scan`] found about one node.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct NodeInfo {
    /// Node id.
    pub node: u8,
    /// 0x1000 device type.
    pub device_type: u32,
    /// 0x1008 manufacturer device name, if the node has it.
    pub name: Option<String>,
    /// 0x1018 identity (vendor required; missing sub-objects read as 0).
    pub identity: Option<LssIdentity>,
}

/// One row of [`Master::dump`].
#[derive(Debug, Clone, PartialEq)]
pub struct DumpRow {
    /// Object index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// `Parent.Name` from the EDS.
    pub name: String,
    /// The value read, or why it could not be read.
    pub value: Result<Value, String>,
}

/// Removes the SDO waiter of a node when the transfer ends, whatever the outcome.
struct WaiterGuard<'a> {
    inner: &'a Inner,
    node: u8,
}

impl Drop for WaiterGuard<'_> {
    fn drop(&mut self) {
        lock(&self.inner.sdo_waiters).remove(&self.node);
    }
}

type Start = dyn FnOnce(Instant) -> Result<(SdoTransfer, motus_can::CanFrame), SdoError>;

impl Inner {
    fn node_lock(&self, node: u8) -> Arc<Mutex<()>> {
        Arc::clone(lock(&self.sdo_locks).entry(node).or_default())
    }

    /// Runs one SDO transfer to completion on the calling thread.
    pub(crate) fn sdo_transfer(&self, node: u8, start: Box<Start>) -> Result<Vec<u8>, MasterError> {
        let node_lock = self.node_lock(node);
        let _serial = lock(&node_lock);
        let (tx, rx) = channel();
        lock(&self.sdo_waiters).insert(node, Waiter::new(tx, self.wake_slot()));
        let _guard = WaiterGuard { inner: self, node };
        let clock = &*self.clock;
        let (mut t, first) = start(clock.now())?;
        let (index, sub) = t.object();
        let ctx = || format!("SDO transfer with node {node} on 0x{index:04X}:{sub:02X}");
        self.send(&first, ctx)?;
        // Each request is answered once: its answer measures the bus and the way of
        // waiting (see `spin_wait`). Only a request still unanswered is spun for. The
        // protocol's times (`sent_at`, the deadline) are the clock's; the way of waiting
        // (`wall_sent`, the spin) is measured on wall time.
        let mut unanswered = Some((clock.now(), Instant::now(), self.sdo_latency.plan()));
        loop {
            let deadline = t.deadline().unwrap_or_else(|| clock.now());
            let wall_deadline = Instant::now() + deadline.saturating_duration_since(clock.now());
            let (sent_at, wall_sent, plan) = unanswered.unwrap_or((deadline, wall_deadline, WaitPlan::SLEEP));
            let answer = if self.threaded {
                // Parked on the clock until the answer is delivered or the deadline.
                self.recv_until(&rx, deadline)
            } else {
                self.sdo_latency.recv(&rx, plan, wall_sent, wall_deadline)
            };
            let step = match answer {
                Ok(r) => {
                    if unanswered.take().is_some() {
                        self.sdo_latency.record_bus(r.at.saturating_duration_since(sent_at));
                        self.sdo_latency.record_exchange(plan, wall_sent.elapsed());
                    }
                    t.on_frame(&r.frame, clock.now())
                }
                Err(RecvTimeoutError::Timeout) => {
                    // On a virtual clock nobody else moves time: jump to the deadline.
                    clock.sleep_until(deadline);
                    t.poll(clock.now())
                }
                Err(RecvTimeoutError::Disconnected) => t.poll(clock.now() + Duration::from_secs(3600)),
            };
            match step {
                SdoStep::Wait => {}
                SdoStep::Send(f) => {
                    self.send(&f, ctx)?;
                    unanswered = Some((clock.now(), Instant::now(), self.sdo_latency.plan()));
                }
                SdoStep::Done(data) => return Ok(data),
                SdoStep::Failed { abort, error } => {
                    if let Some(a) = abort {
                        // The error to report is the SDO one; a failing abort is only logged.
                        if let Err(e) = self.send(&a, ctx) {
                            tracing::warn!(error = %e, "could not send SDO abort");
                        }
                    }
                    return Err(error.into());
                }
            }
        }
    }

    /// Runs upload transfers to distinct nodes concurrently on the calling thread.
    pub(crate) fn upload_many(
        &self,
        requests: &[(u8, u16, u8)],
        timeout: Duration,
    ) -> Vec<Result<Vec<u8>, MasterError>> {
        let mut results: Vec<Option<Result<Vec<u8>, MasterError>>> = requests.iter().map(|_| None).collect();
        // One channel per node, locked in node order (no lock-order inversion with
        // other callers); a node named twice is refused.
        let mut order: Vec<usize> = (0..requests.len()).collect();
        order.sort_by_key(|i| requests.get(*i).map(|r| r.0));
        let mut node_locks = Vec::new();
        let mut seen = std::collections::HashSet::new();
        for &i in &order {
            let Some(&(node, index, sub)) = requests.get(i) else { continue };
            if !seen.insert(node) {
                if let Some(slot) = results.get_mut(i) {
                    *slot = Some(Err(MasterError::InvalidArgument(format!(
                        "node {node} named twice in one batch (0x{index:04X}:{sub:02X})"
                    ))));
                }
                continue;
            }
            node_locks.push((i, self.node_lock(node)));
        }
        let guards: Vec<_> = node_locks.iter().map(|(i, l)| (*i, lock(l))).collect();
        let (tx, rx) = channel();
        let waiter = Waiter::new(tx, self.wake_slot());
        let mut active: HashMap<u8, (usize, SdoTransfer)> = HashMap::new();
        let mut waiter_guards = Vec::new();
        let mut first_frames = Vec::with_capacity(guards.len());
        for (i, _) in &guards {
            let Some(&(node, index, sub)) = requests.get(*i) else { continue };
            lock(&self.sdo_waiters).insert(node, waiter.clone());
            waiter_guards.push(WaiterGuard { inner: self, node });
            match SdoTransfer::upload(node, index, sub, self.clock.now(), timeout) {
                Ok((t, first)) => {
                    active.insert(node, (*i, t));
                    first_frames.push(first);
                }
                Err(e) => {
                    if let Some(slot) = results.get_mut(*i) {
                        *slot = Some(Err(e.into()));
                    }
                }
            }
        }
        // Every request in one batch (one write on socketcand): the nodes answer together.
        if let Err(e) = self.send_batch(&first_frames) {
            for (node, (i, _)) in active.drain() {
                if let Some(slot) = results.get_mut(i) {
                    let context = format!("SDO upload from node {node}");
                    *slot = Some(Err(MasterError::transport(context, duplicate(&e))));
                }
            }
        }
        // On a fast bus the answers may be spun for (see `spin_wait`): the first answer's
        // arrival at the receive thread measures the bus, the last one the way of waiting.
        let clock = &*self.clock;
        let (sent_at, wall_sent) = (clock.now(), Instant::now());
        let plan = self.sdo_latency.plan();
        let mut first_answer = true;
        let mut timed_out = false;
        while !active.is_empty() {
            let next = active.values().filter_map(|(_, t)| t.deadline()).min();
            let deadline = next.unwrap_or_else(|| clock.now());
            let wall_deadline = Instant::now() + deadline.saturating_duration_since(clock.now());
            let answer = if self.threaded {
                self.recv_until(&rx, deadline)
            } else {
                self.sdo_latency.recv(&rx, plan, wall_sent, wall_deadline)
            };
            let (node, step) = match answer {
                Ok(r) => {
                    if std::mem::take(&mut first_answer) {
                        self.sdo_latency.record_bus(r.at.saturating_duration_since(sent_at));
                    }
                    let node = u8::try_from(r.frame.id().wrapping_sub(0x580)).unwrap_or(0);
                    match active.get_mut(&node) {
                        Some((_, t)) => (node, t.on_frame(&r.frame, clock.now())),
                        None => continue,
                    }
                }
                Err(_) => {
                    // Time-out: poll every transfer (the one due fails, the others wait).
                    timed_out = true;
                    clock.sleep_until(deadline);
                    let now = clock.now();
                    let due: Vec<u8> = active
                        .iter()
                        .filter(|(_, (_, t))| t.deadline().is_some_and(|d| d <= now))
                        .map(|(n, _)| *n)
                        .collect();
                    let Some(node) = due.first().copied() else { continue };
                    match active.get_mut(&node) {
                        Some((_, t)) => (node, t.poll(now)),
                        None => continue,
                    }
                }
            };
            let outcome = match step {
                SdoStep::Wait => None,
                SdoStep::Send(f) => match self.send(&f, || format!("SDO upload from node {node}")) {
                    Ok(()) => None,
                    Err(e) => Some(Err(e)),
                },
                SdoStep::Done(data) => Some(Ok(data)),
                SdoStep::Failed { abort, error } => {
                    if let Some(a) = abort {
                        if let Err(e) = self.send(&a, || format!("SDO abort to node {node}")) {
                            tracing::warn!(error = %e, "could not send SDO abort");
                        }
                    }
                    Some(Err(error.into()))
                }
            };
            if let Some(result) = outcome {
                if let Some((i, _)) = active.remove(&node) {
                    if let Some(slot) = results.get_mut(i) {
                        *slot = Some(result);
                    }
                }
            }
        }
        if !timed_out && !first_answer {
            self.sdo_latency.record_exchange(plan, wall_sent.elapsed());
        }
        drop(waiter_guards);
        drop(guards);
        results
            .into_iter()
            .map(|r| {
                r.unwrap_or_else(|| Err(MasterError::InvalidArgument("SDO batch: request not run".into())))
            })
            .collect()
    }

    pub(crate) fn upload(
        &self,
        node: u8,
        index: u16,
        sub: u8,
        timeout: Duration,
    ) -> Result<Vec<u8>, MasterError> {
        self.sdo_transfer(node, Box::new(move |now| SdoTransfer::upload(node, index, sub, now, timeout)))
    }

    pub(crate) fn download(
        &self,
        node: u8,
        index: u16,
        sub: u8,
        data: &[u8],
        timeout: Duration,
    ) -> Result<(), MasterError> {
        let data = data.to_vec();
        self.sdo_transfer(
            node,
            Box::new(move |now| SdoTransfer::download(node, index, sub, &data, now, timeout)),
        )
        .map(|_| ())
    }
}

macro_rules! typed {
    ($($read:ident $write:ident $t:ty;)*) => {$(
        #[doc = concat!("Reads a `", stringify!($t), "` (little-endian) with an SDO upload.")]
        pub fn $read(&self, node: u8, index: u16, sub: u8) -> Result<$t, MasterError> {
            let bytes = self.sdo_upload_exact(node, index, sub, std::mem::size_of::<$t>())?;
            let arr = bytes.try_into().map_err(|_| MasterError::Length {
                node, index, sub, len: 0, want: std::mem::size_of::<$t>(),
            })?;
            Ok(<$t>::from_le_bytes(arr))
        }
        #[doc = concat!("Writes a `", stringify!($t), "` (little-endian) with an expedited SDO download.")]
        pub fn $write(&self, node: u8, index: u16, sub: u8, value: $t) -> Result<(), MasterError> {
            self.sdo_download(node, index, sub, &value.to_le_bytes())
        }
    )*};
}

impl Master {
    /// Sets the SDO time-out (per response; default 500 ms).
    pub fn set_sdo_timeout(&self, timeout: Duration) {
        *lock(&self.inner.sdo_timeout) = timeout;
    }

    /// The SDO time-out.
    pub fn sdo_timeout(&self) -> Duration {
        *lock(&self.inner.sdo_timeout)
    }

    /// Reads `index:sub` of `node` (expedited or segmented).
    pub fn sdo_upload(&self, node: u8, index: u16, sub: u8) -> Result<Vec<u8>, MasterError> {
        self.inner.upload(node, index, sub, self.sdo_timeout())
    }

    /// Writes `data` to `index:sub` of `node` (expedited for 1–4 bytes, else segmented).
    pub fn sdo_download(&self, node: u8, index: u16, sub: u8, data: &[u8]) -> Result<(), MasterError> {
        self.inner.download(node, index, sub, data, self.sdo_timeout())
    }

    /// Uploads several objects from **different** nodes at once: every request is sent,
    /// then the answers are collected as they come (one SDO channel per node, as CiA 301
    /// allows), so the transfers overlap instead of waiting for each other. Results come
    /// back in the order of `requests`. A node named twice is refused for its second
    /// request (its SDO channel is busy) without affecting the others.
    pub fn sdo_upload_many(&self, requests: &[(u8, u16, u8)]) -> Vec<Result<Vec<u8>, MasterError>> {
        self.inner.upload_many(requests, self.sdo_timeout())
    }

    /// Uploads and checks the length: exactly `want` bytes, or 4 bytes from an expedited
    /// transfer without size (then the first `want` are used).
    fn sdo_upload_exact(&self, node: u8, index: u16, sub: u8, want: usize) -> Result<Vec<u8>, MasterError> {
        let mut data = self.sdo_upload(node, index, sub)?;
        if data.len() == want {
            return Ok(data);
        }
        if data.len() == 4 && want < 4 {
            data.truncate(want);
            return Ok(data);
        }
        Err(MasterError::Length { node, index, sub, len: data.len(), want })
    }

    typed! {
        read_u8 write_u8 u8;
        read_u16 write_u16 u16;
        read_u32 write_u32 u32;
        read_i8 write_i8 i8;
        read_i16 write_i16 i16;
        read_i32 write_i32 i32;
    }

    /// Reads a VISIBLE_STRING (trailing NULs removed).
    pub fn read_string(&self, node: u8, index: u16, sub: u8) -> Result<String, MasterError> {
        let data = self.sdo_upload(node, index, sub)?;
        Ok(String::from_utf8_lossy(&data).trim_end_matches('\0').to_owned())
    }

    fn configure_pdo(&self, node: u8, dir: PdoDirection, n: u16, cfg: &PdoConfig) -> Result<(), MasterError> {
        let writes = cfg.sdo_writes(dir, n).map_err(|source| MasterError::Pdo { node, source })?;
        for w in writes {
            self.sdo_download(node, w.index, w.sub, &w.data)?;
        }
        Ok(())
    }

    /// Configures RPDO `n` (1-based) of `node` (the node should be pre-operational).
    pub fn configure_rpdo(&self, node: u8, n: u16, cfg: &PdoConfig) -> Result<(), MasterError> {
        self.configure_pdo(node, PdoDirection::Rpdo, n, cfg)
    }

    /// Configures TPDO `n` (1-based) of `node` (the node should be pre-operational).
    pub fn configure_tpdo(&self, node: u8, n: u16, cfg: &PdoConfig) -> Result<(), MasterError> {
        self.configure_pdo(node, PdoDirection::Tpdo, n, cfg)
    }

    /// Probes `nodes` with uploads of 0x1000 (100 ms time-out, 16 in parallel) and
    /// reads 0x1008 and 0x1018 of those that answer.
    pub fn scan(&self, nodes: RangeInclusive<u8>) -> Vec<NodeInfo> {
        self.scan_with(nodes, Duration::from_millis(100), 16)
    }

    /// [`Self::scan`] with an explicit probe time-out and parallelism.
    pub fn scan_with(
        &self,
        nodes: RangeInclusive<u8>,
        probe_timeout: Duration,
        parallel: usize,
    ) -> Vec<NodeInfo> {
        let ids: Vec<u8> = nodes.filter(|n| (1..=127).contains(n)).collect();
        let mut found = Vec::new();
        // The probing threads take part in the clock from their start (as
        // `motus_clock::spawn` makes them), while this one waits for them.
        let clock = &*self.inner.clock;
        for chunk in ids.chunks(parallel.max(1)) {
            let results: Vec<Option<NodeInfo>> = motus_clock::while_blocked(clock, || {
                std::thread::scope(|s| {
                    let handles: Vec<_> = chunk
                        .iter()
                        .map(|&n| {
                            clock.starting_thread(true);
                            s.spawn(move || {
                                clock.join_thread();
                                clock.starting_thread(false);
                                self.probe(n, probe_timeout)
                            })
                        })
                        .collect();
                    handles.into_iter().map(|h| h.join().ok().flatten()).collect()
                })
            });
            found.extend(results.into_iter().flatten());
        }
        found
    }

    fn probe(&self, node: u8, timeout: Duration) -> Option<NodeInfo> {
        let bytes = self.inner.upload(node, 0x1000, 0, timeout).ok()?;
        let device_type = u32::from_le_bytes(bytes.get(..4)?.try_into().ok()?);
        let t = self.sdo_timeout();
        let name = self
            .inner
            .upload(node, 0x1008, 0, t)
            .ok()
            .map(|d| String::from_utf8_lossy(&d).trim_end_matches('\0').to_owned());
        let part = |sub| {
            self.inner
                .upload(node, 0x1018, sub, t)
                .ok()
                .and_then(|d| d.get(..4).and_then(|b| b.try_into().ok()))
        };
        let identity = part(1).map(|v: [u8; 4]| LssIdentity {
            vendor: u32::from_le_bytes(v),
            product: part(2).map_or(0, u32::from_le_bytes),
            revision: part(3).map_or(0, u32::from_le_bytes),
            serial: part(4).map_or(0, u32::from_le_bytes),
        });
        Some(NodeInfo { node, device_type, name, identity })
    }

    /// Loads an EDS used by [`Self::dump`] to name and decode objects.
    pub fn load_eds(&self, path: impl AsRef<Path>) -> Result<Arc<ObjectDictionary>, MasterError> {
        let od = Arc::new(ObjectDictionary::load(path.as_ref())?);
        *lock(&self.inner.eds) = Some(Arc::clone(&od));
        Ok(od)
    }

    /// Uses an already parsed object dictionary for [`Self::dump`].
    pub fn set_eds(&self, od: ObjectDictionary) {
        *lock(&self.inner.eds) = Some(Arc::new(od));
    }

    /// The loaded EDS.
    pub fn eds(&self) -> Option<Arc<ObjectDictionary>> {
        lock(&self.inner.eds).clone()
    }

    /// Reads every readable object of the loaded EDS from `node`.
    pub fn dump(&self, node: u8) -> Result<Vec<DumpRow>, MasterError> {
        let od = self.eds().ok_or(MasterError::NoEds)?;
        Ok(od
            .iter()
            .filter(|v| v.access.readable())
            .map(|v| DumpRow {
                index: v.index,
                sub: v.sub,
                name: v.full_name(),
                value: self
                    .sdo_upload(node, v.index, v.sub)
                    .map_err(|e| e.to_string())
                    .and_then(|raw| v.data_type.decode(&raw).map_err(|e| e.to_string())),
            })
            .collect())
    }
}

/// The same transport error again (one per transfer of a failed batch; `io::Error` is not
/// `Clone`, so its kind and text are kept).
fn duplicate(e: &motus_can::CanError) -> motus_can::CanError {
    use motus_can::CanError as E;
    match e {
        E::Closed(s) => E::Closed(s.clone()),
        E::Io(io) => E::Io(std::io::Error::new(io.kind(), io.to_string())),
        E::Protocol(s) => E::Protocol(s.clone()),
        E::Address(s) => E::Address(s.clone()),
        E::Unavailable { what, reason } => E::Unavailable { what: what.clone(), reason: reason.clone() },
    }
}
