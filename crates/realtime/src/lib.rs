//! Real-time scheduling of a Motus process's threads, decided in one place.
//!
//! The station runs device threads (bus masters, receive loops, the virtual CAN hub),
//! cyclic threads (scheduler classes, SYNC and heartbeat producers, the POWERLINK cycle, the
//! KV-01 keep-alive loop) and simulators beside a web server that any number of browsers can
//! load. Web work must never delay the machine, so:
//!
//! * the binary sets a process-wide [`RealtimePolicy`] once, before it starts any thread
//!   ([`set_policy`]), and locks the process's memory ([`lock_memory`]);
//! * every layer that spawns a device, cyclic or simulator thread calls
//!   [`promote_current_thread`] first thing in that thread, with its [`ThreadClass`];
//! * the web server's threads call [`demote_current_thread_for_web`];
//! * transparent huge pages are off for the process (a 2 MiB page zeroed on first touch
//!   stalls the thread that touched it for milliseconds);
//! * a process that runs a POWERLINK node (`motus epl cn`, `motus epl mn`) or a real-time
//!   benchmark keeps idle CPUs out of idle states that are slow to wake up, for as long as
//!   it runs, when it obtained `SCHED_FIFO` ([`wake_latency::hold_if_fifo`]).
//!
//! What each call does depends on what the process obtained ([`Obtained`]):
//!
//! | obtained | cyclic | device | simulator | web |
//! |---|---|---|---|---|
//! | [`Obtained::Fifo`] (root, `CAP_SYS_NICE` or `RLIMIT_RTPRIO`) | `SCHED_FIFO` 80 | `SCHED_FIFO` 70 | `SCHED_FIFO` 60 | nice +10 |
//! | [`Obtained::Nice`] (`--realtime nice`, or `auto` not permitted) | nice 0, 0.1 ms slice | nice 0 | nice 0 | nice +10 |
//! | [`Obtained::Off`] (`--realtime off`, or never set: libraries, tests) | unchanged | unchanged | unchanged | unchanged |
//!
//! A thread inherits its creator's policy and nice value: a thread spawned by a promoted
//! thread is promoted too unless it sets its own class, and a device thread spawned from a
//! web thread without permission to lower its nice value keeps the web's +10 (logged once).
//!
//! Under nice levels the cyclic threads also ask the fair scheduler for its shortest time
//! slice ([`mod@slice`]): a thread that wakes every millisecond then runs first when it wakes
//! instead of waiting for the slice of a busy device, web or client thread to end.
//!
//! Everything goes through maintained crates (`thread-priority` for the scheduling policy
//! and nice values, `nix` for `mlockall` and resource limits) except the slice, which no
//! crate sets: [`mod@slice`] is the one module with `unsafe`.
#![deny(unsafe_code)]

pub mod affinity;
pub mod ceiling;
pub mod mailbox;
pub mod slice;
pub mod wake_latency;

pub use affinity::{pin_current_thread, AffinityError};
pub use mailbox::{mailbox, MailboxReceiver, MailboxSender};

use std::fmt;
use std::str::FromStr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::OnceLock;

use thread_priority::{
    set_thread_priority_and_policy, thread_native_id, NormalThreadSchedulePolicy,
    RealtimeThreadSchedulePolicy, ThreadPriority, ThreadPriorityValue, ThreadSchedulePolicy,
};

/// The nice value of the web server's threads (workers, blocking pool).
pub const WEB_NICE: i8 = 10;

/// What the binary asks for (`--realtime <auto|off>`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum RealtimePolicy {
    /// Leave every thread at the scheduler's default.
    Off,
    /// Nice levels only: web work at nice +10, device, cyclic and simulator threads at the
    /// default priority (no `SCHED_FIFO`, whatever the permissions). The binary's default:
    /// `SCHED_FIFO` threads that poll (the POWERLINK simulation, spinning waits for fast
    /// answers) can take whole cores from everything else on a small host.
    #[default]
    Nice,
    /// `SCHED_FIFO` for device and cyclic threads when the process may use it, else nice
    /// levels (web work at nice +10).
    Auto,
}

impl fmt::Display for RealtimePolicy {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            RealtimePolicy::Off => "off",
            RealtimePolicy::Nice => "nice",
            RealtimePolicy::Auto => "auto",
        })
    }
}

/// A policy name that is not `nice`, `auto` or `off`.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown real-time policy {0:?} (expected nice, auto or off)")]
pub struct UnknownPolicy(pub String);

impl FromStr for RealtimePolicy {
    type Err = UnknownPolicy;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "auto" => Ok(RealtimePolicy::Auto),
            "nice" => Ok(RealtimePolicy::Nice),
            "off" => Ok(RealtimePolicy::Off),
            other => Err(UnknownPolicy(other.to_owned())),
        }
    }
}

/// What a thread does for the machine; decides its priority.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ThreadClass {
    /// Runs on a period that the machine depends on (scheduler classes, SYNC, the master's
    /// heartbeat, the POWERLINK cycle, the KV-01 keep-alive, the safety supervisor).
    Cyclic,
    /// Talks to a device or carries its traffic (bus masters, receive loops, the virtual CAN
    /// hub, the axis poller, watchdogs).
    Device,
    /// A simulated device (its model and its end of the link).
    Simulator,
}

impl fmt::Display for ThreadClass {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ThreadClass::Cyclic => "cyclic",
            ThreadClass::Device => "device",
            ThreadClass::Simulator => "simulator",
        })
    }
}

/// The `SCHED_FIFO` priority of each class (1..=99, higher runs first).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FifoLevels {
    /// Priority of [`ThreadClass::Cyclic`] threads.
    pub cyclic: u8,
    /// Priority of [`ThreadClass::Device`] threads.
    pub device: u8,
    /// Priority of [`ThreadClass::Simulator`] threads.
    pub simulator: u8,
}

impl FifoLevels {
    /// The levels used when the process may use any priority: cyclic 80 > device 70 >
    /// simulator 60 (below the kernel's own threads at 99 and under 50's usual IRQ threads
    /// on PREEMPT_RT: above them).
    pub const DEFAULT: FifoLevels = FifoLevels { cyclic: 80, device: 70, simulator: 60 };

    /// The levels within a ceiling (an unprivileged process's `RLIMIT_RTPRIO`): the default
    /// levels when they fit, else `cap`, `cap - 1`, `cap - 2` (never below 1). `None` for a
    /// ceiling of 0 (no real-time priority allowed).
    pub fn within(cap: u64) -> Option<FifoLevels> {
        let cap = u8::try_from(cap.min(99)).ok()?;
        if cap == 0 {
            return None;
        }
        if cap >= Self::DEFAULT.cyclic {
            return Some(Self::DEFAULT);
        }
        Some(FifoLevels {
            cyclic: cap,
            device: cap.saturating_sub(1).max(1),
            simulator: cap.saturating_sub(2).max(1),
        })
    }

    /// The priority of `class`.
    pub fn of(&self, class: ThreadClass) -> u8 {
        match class {
            ThreadClass::Cyclic => self.cyclic,
            ThreadClass::Device => self.device,
            ThreadClass::Simulator => self.simulator,
        }
    }
}

/// What the process obtained from [`set_policy`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Obtained {
    /// Nothing is changed (`--realtime off`, or no policy was set).
    Off,
    /// Device, cyclic and simulator threads run under `SCHED_FIFO` at these levels; web
    /// threads at nice [`WEB_NICE`].
    Fifo(FifoLevels),
    /// `SCHED_FIFO` is not permitted: device, cyclic and simulator threads at nice 0 (cyclic
    /// ones with the fair scheduler's shortest slice, [`slice::MIN_SLICE`]), web threads at
    /// nice [`WEB_NICE`].
    Nice,
}

impl fmt::Display for Obtained {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Obtained::Off => f.write_str("off: every thread at the default priority"),
            Obtained::Fifo(l) => write!(
                f,
                "SCHED_FIFO (cyclic {}, device {}, simulator {}), web threads at nice +{WEB_NICE}",
                l.cyclic, l.device, l.simulator
            ),
            Obtained::Nice => write!(
                f,
                "nice levels: cyclic, device and simulator threads at nice 0 (cyclic with a 0.1 ms slice), web threads at nice +{WEB_NICE}"
            ),
        }
    }
}

static OBTAINED: OnceLock<Obtained> = OnceLock::new();

/// Sets the process-wide policy (the first call decides; later calls return what the first
/// obtained) and logs once what was obtained. Call it before starting any device thread.
pub fn set_policy(policy: RealtimePolicy) -> Obtained {
    *OBTAINED.get_or_init(|| {
        let obtained = decide(policy);
        if obtained != Obtained::Off {
            disable_huge_pages();
        }
        obtained
    })
}

/// Turns transparent huge pages off for the process (`PR_SET_THP_DISABLE`): the first touch
/// of a huge page zeroes 2 MiB inside whichever thread touched it, and a cyclic thread whose
/// buffer grew into fresh memory was measured stalled 6 ms there. Pages are then 4 KiB, each
/// faulted in microseconds. Logged when it fails.
fn disable_huge_pages() {
    if let Err(e) = nix::sys::prctl::set_thp_disable(true) {
        tracing::warn!("real-time: transparent huge pages stay on ({e})");
    }
}

/// The environment variable naming a policy for programs without a `--realtime` flag (the
/// benchmarks that measure real-time figures): `auto`, `nice` or `off`.
pub const POLICY_ENV: &str = "MOTUS_REALTIME";

/// Sets the policy named by [`POLICY_ENV`], if set ([`set_policy`]); `Ok(None)` when unset.
///
/// # Errors
/// The variable names no policy.
pub fn set_policy_from_env() -> Result<Option<Obtained>, UnknownPolicy> {
    match std::env::var(POLICY_ENV) {
        Ok(name) => Ok(Some(set_policy(name.parse()?))),
        Err(_) => Ok(None),
    }
}

/// What the process obtained ([`Obtained::Off`] until [`set_policy`] is called).
pub fn obtained() -> Obtained {
    OBTAINED.get().copied().unwrap_or(Obtained::Off)
}

fn decide(policy: RealtimePolicy) -> Obtained {
    match policy {
        RealtimePolicy::Off => {
            tracing::info!("real-time: off (--realtime off): every thread at the default priority");
            Obtained::Off
        }
        RealtimePolicy::Nice => {
            tracing::info!(
                "real-time: nice levels only (--realtime nice): web threads at nice +{WEB_NICE}; \
                 `--realtime auto` asks for SCHED_FIFO"
            );
            Obtained::Nice
        }
        RealtimePolicy::Auto => match probe_fifo() {
            Ok(levels) => {
                tracing::info!(
                    cyclic = levels.cyclic,
                    device = levels.device,
                    simulator = levels.simulator,
                    web_nice = WEB_NICE,
                    "real-time: SCHED_FIFO for cyclic, device and simulator threads; web threads at nice +{WEB_NICE}"
                );
                Obtained::Fifo(levels)
            }
            Err(why) => {
                tracing::warn!(
                    "real-time: SCHED_FIFO not permitted ({why}; run as root, with CAP_SYS_NICE or a \
                     RLIMIT_RTPRIO): cyclic, device and simulator threads at nice 0, web threads at nice +{WEB_NICE}"
                );
                Obtained::Nice
            }
        },
    }
}

/// Tries `SCHED_FIFO` on a short-lived thread (the caller's own scheduling is untouched):
/// the default levels, else the levels within `RLIMIT_RTPRIO`.
fn probe_fifo() -> Result<FifoLevels, String> {
    let probe = |priority: u8| -> Result<(), String> {
        std::thread::Builder::new()
            .name("motus-rt-probe".into())
            .spawn(move || set_fifo(priority).map_err(|e| e.to_string()))
            .map_err(|e| format!("probe thread: {e}"))?
            .join()
            .map_err(|_| "probe thread panicked".to_owned())?
    };
    let first = match probe(FifoLevels::DEFAULT.cyclic) {
        Ok(()) => return Ok(FifoLevels::DEFAULT),
        Err(e) => e,
    };
    let rtprio = nix::sys::resource::getrlimit(nix::sys::resource::Resource::RLIMIT_RTPRIO)
        .map(|(soft, _)| soft)
        .unwrap_or(0);
    match FifoLevels::within(rtprio) {
        Some(levels) if levels != FifoLevels::DEFAULT => {
            probe(levels.cyclic).map(|()| levels).map_err(|e| format!("{e}; RLIMIT_RTPRIO {rtprio}"))
        }
        _ => Err(format!("{first}; RLIMIT_RTPRIO {rtprio}")),
    }
}

/// An error from the operating system's scheduler.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct SchedError(String);

fn set_fifo(priority: u8) -> Result<(), SchedError> {
    let value = ThreadPriorityValue::try_from(priority).map_err(SchedError)?;
    set_thread_priority_and_policy(
        thread_native_id(),
        ThreadPriority::Crossplatform(value),
        ThreadSchedulePolicy::Realtime(RealtimeThreadSchedulePolicy::Fifo),
    )
    .map_err(|e| SchedError(os_error(e)))
}

/// The `thread-priority` cross-platform value that maps to each nice value used here under
/// the normal policy on Linux (`nice = (39 * (1 - p / 99)) as i8 - 20`).
fn crossplatform_for_nice(nice: i8) -> Option<u8> {
    match nice {
        0 => Some(48),
        WEB_NICE => Some(22),
        _ => None,
    }
}

/// Sets the calling thread to the normal policy (`SCHED_OTHER`) at `nice` (0 or
/// [`WEB_NICE`]). Raising the nice value is always permitted; lowering it needs
/// `CAP_SYS_NICE` or `RLIMIT_NICE`.
fn set_nice(nice: i8) -> Result<(), SchedError> {
    let p = crossplatform_for_nice(nice).ok_or_else(|| SchedError(format!("nice {nice} not supported")))?;
    let value = ThreadPriorityValue::try_from(p).map_err(SchedError)?;
    set_thread_priority_and_policy(
        thread_native_id(),
        ThreadPriority::Crossplatform(value),
        ThreadSchedulePolicy::Normal(NormalThreadSchedulePolicy::Other),
    )
    .map_err(|e| SchedError(os_error(e)))
}

fn os_error(e: thread_priority::Error) -> String {
    match e {
        thread_priority::Error::OS(code) => std::io::Error::from_raw_os_error(code).to_string(),
        other => other.to_string(),
    }
}

/// Gives the calling thread the priority of `class` under the process's policy (see the
/// crate documentation). Failures are logged once per kind and leave the thread as it was.
pub fn promote_current_thread(class: ThreadClass) {
    if let Err(e) = apply_class(obtained(), class) {
        static WARNED: AtomicBool = AtomicBool::new(false);
        if !WARNED.swap(true, Ordering::Relaxed) {
            tracing::warn!(
                thread = std::thread::current().name().unwrap_or("?"),
                %class,
                error = %e,
                "real-time: cannot promote a thread (logged once)"
            );
        }
    }
}

/// Lowers the calling thread to nice [`WEB_NICE`] unless the policy is off: for the web
/// server's workers and blocking threads, so that web work yields to every other thread of
/// the station. Failures are logged once.
pub fn demote_current_thread_for_web() {
    if let Err(e) = apply_web(obtained()) {
        static WARNED: AtomicBool = AtomicBool::new(false);
        if !WARNED.swap(true, Ordering::Relaxed) {
            tracing::warn!(error = %e, "real-time: cannot lower a web thread's priority (logged once)");
        }
    }
}

fn apply_class(obtained: Obtained, class: ThreadClass) -> Result<(), SchedError> {
    let applied = apply_class_policy(obtained, class);
    if applied.is_ok() {
        ceiling::record(ceiling::Role::Class(class));
    }
    applied
}

fn apply_class_policy(obtained: Obtained, class: ThreadClass) -> Result<(), SchedError> {
    match obtained {
        Obtained::Off => Ok(()),
        // On failure, fall back to the normal policy at nice 0 (what `Nice` gives), and report.
        Obtained::Fifo(levels) => set_fifo(levels.of(class)).inspect_err(|_| {
            let _ = set_nice(0);
        }),
        Obtained::Nice => {
            let at_nice_0 =
                current_thread_scheduling().is_some_and(|s| s.nice == 0 && s.policy == Policy::Normal);
            let niced = if at_nice_0 {
                Ok(())
            } else {
                set_nice(0).map_err(|e| {
                    SchedError(format!(
                        "{e} (a thread started by a web thread keeps nice +{WEB_NICE} without CAP_SYS_NICE)"
                    ))
                })
            };
            // Cyclic threads only: a short slice puts a thread ahead of those with the default
            // slice, and a cycle is what must not wait. Asked for even when the nice value
            // could not be lowered.
            let sliced =
                if class == ThreadClass::Cyclic { slice::request_slice(slice::MIN_SLICE) } else { Ok(()) };
            niced.and(sliced)
        }
    }
}

fn apply_web(obtained: Obtained) -> Result<(), SchedError> {
    match obtained {
        Obtained::Off => Ok(()),
        Obtained::Fifo(_) | Obtained::Nice => {
            set_nice(WEB_NICE).inspect(|()| ceiling::record(ceiling::Role::Web))
        }
    }
}

/// The outcome of [`lock_memory`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum MemoryLock {
    /// Not attempted: the process did not obtain `SCHED_FIFO` (policy off or nice levels).
    Off,
    /// Every page of the process, present and future, stays in RAM once touched.
    Locked,
    /// Not attempted: the process may not lock unbounded memory (a locked `MCL_FUTURE` under
    /// a finite `RLIMIT_MEMLOCK` would make later allocations fail).
    NotPermitted(String),
    /// `mlockall` failed.
    Failed(String),
}

impl fmt::Display for MemoryLock {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MemoryLock::Off => f.write_str("memory not locked (only with SCHED_FIFO)"),
            MemoryLock::Locked => f.write_str("memory locked"),
            MemoryLock::NotPermitted(why) => write!(f, "memory not locked ({why})"),
            MemoryLock::Failed(why) => write!(f, "memory not locked: mlockall failed ({why})"),
        }
    }
}

/// Locks the process's memory (`mlockall(MCL_CURRENT | MCL_FUTURE | MCL_ONFAULT)`) when the
/// process obtained `SCHED_FIFO` ([`Obtained::Fifo`]) and may lock unbounded memory (`CAP_IPC_LOCK`, root, or an
/// unlimited `RLIMIT_MEMLOCK`), so that no page a device thread touches is ever paged out.
/// `MCL_ONFAULT` (Linux 4.4+, retried without it on older kernels) locks pages as they are
/// first touched instead of populating every mapping at once: thread stacks and allocator
/// reserves do not all become resident. Logs the outcome once; call once, early.
pub fn lock_memory() -> MemoryLock {
    let outcome = lock_memory_for(obtained());
    match &outcome {
        MemoryLock::Off => {}
        MemoryLock::Locked => tracing::info!("real-time: memory locked (mlockall current|future, on fault)"),
        MemoryLock::NotPermitted(why) => tracing::warn!("real-time: memory not locked ({why})"),
        MemoryLock::Failed(why) => tracing::warn!("real-time: memory not locked: mlockall failed ({why})"),
    }
    outcome
}

fn lock_memory_for(obtained: Obtained) -> MemoryLock {
    use nix::sys::mman::{mlockall, MlockAllFlags};
    use nix::sys::resource::{getrlimit, Resource, RLIM_INFINITY};
    // Only with SCHED_FIFO: locked pages are never given back (freed memory stays resident),
    // a price worth paying only where the device threads are real-time.
    if !matches!(obtained, Obtained::Fifo(_)) {
        return MemoryLock::Off;
    }
    let unlimited = getrlimit(Resource::RLIMIT_MEMLOCK).is_ok_and(|(soft, _)| soft == RLIM_INFINITY);
    if !unlimited && !has_effective_capability(CAP_IPC_LOCK) {
        return MemoryLock::NotPermitted("needs CAP_IPC_LOCK (root) or an unlimited RLIMIT_MEMLOCK".into());
    }
    let base = MlockAllFlags::MCL_CURRENT | MlockAllFlags::MCL_FUTURE;
    let on_fault = base | MlockAllFlags::from_bits_retain(libc::MCL_ONFAULT);
    match mlockall(on_fault) {
        Ok(()) => MemoryLock::Locked,
        Err(nix::errno::Errno::EINVAL) => match mlockall(base) {
            Ok(()) => MemoryLock::Locked,
            Err(e) => MemoryLock::Failed(e.to_string()),
        },
        Err(e) => MemoryLock::Failed(e.to_string()),
    }
}

/// `CAP_IPC_LOCK` (linux/capability.h).
const CAP_IPC_LOCK: u32 = 14;

/// Whether the process has `capability` in its effective set (`CapEff` of
/// `/proc/self/status`).
fn has_effective_capability(capability: u32) -> bool {
    let Ok(status) = std::fs::read_to_string("/proc/self/status") else { return false };
    status
        .lines()
        .find_map(|l| l.strip_prefix("CapEff:"))
        .and_then(|hex| u64::from_str_radix(hex.trim(), 16).ok())
        .is_some_and(|caps| caps.checked_shr(capability).is_some_and(|c| c & 1 == 1))
}

/// A thread's scheduling policy, as the kernel reports it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Policy {
    /// `SCHED_OTHER` (the default, time-shared by nice value).
    Normal,
    /// `SCHED_FIFO`.
    Fifo,
    /// `SCHED_RR`.
    RoundRobin,
    /// Another policy (batch, idle, deadline), by number.
    Other(u32),
}

/// A thread's scheduling, read from `/proc`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Scheduling {
    /// The policy.
    pub policy: Policy,
    /// The real-time priority (0 under the normal policies).
    pub rt_priority: u32,
    /// The nice value (meaningful under the normal policies).
    pub nice: i32,
}

impl fmt::Display for Scheduling {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.policy {
            Policy::Fifo => write!(f, "SCHED_FIFO {}", self.rt_priority),
            Policy::RoundRobin => write!(f, "SCHED_RR {}", self.rt_priority),
            Policy::Normal => write!(f, "nice {}", self.nice),
            Policy::Other(n) => write!(f, "policy {n}, nice {}", self.nice),
        }
    }
}

/// Parses the contents of `/proc/<pid>/task/<tid>/stat`: the thread's name and scheduling.
/// `None` when the text is not in that format.
pub fn parse_stat(stat: &str) -> Option<(String, Scheduling)> {
    // "tid (comm) state ..." where comm may hold spaces and parentheses: split at the last ')'.
    let open = stat.find('(')?;
    let close = stat.rfind(')')?;
    let name = stat.get(open + 1..close)?.to_owned();
    let fields: Vec<&str> = stat.get(close + 1..)?.split_whitespace().collect();
    // Field numbers of proc(5), counted from 1 with `state` as field 3.
    let field = |n: usize| fields.get(n.checked_sub(3)?).copied();
    let nice: i32 = field(19)?.parse().ok()?;
    let rt_priority: u32 = field(40)?.parse().ok()?;
    let policy = match field(41)?.parse::<u32>().ok()? {
        0 => Policy::Normal,
        1 => Policy::Fifo,
        2 => Policy::RoundRobin,
        n => Policy::Other(n),
    };
    Some((name, Scheduling { policy, rt_priority, nice }))
}

/// The calling thread's scheduling (from `/proc/thread-self/stat`).
pub fn current_thread_scheduling() -> Option<Scheduling> {
    let stat = std::fs::read_to_string("/proc/thread-self/stat").ok()?;
    parse_stat(&stat).map(|(_, s)| s)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]
    use super::*;

    fn in_thread<T: Send + 'static>(f: impl FnOnce() -> T + Send + 'static) -> T {
        std::thread::spawn(f).join().unwrap()
    }

    #[test]
    fn policy_names() {
        assert_eq!("auto".parse::<RealtimePolicy>(), Ok(RealtimePolicy::Auto));
        assert_eq!("off".parse::<RealtimePolicy>(), Ok(RealtimePolicy::Off));
        assert_eq!("nice".parse::<RealtimePolicy>(), Ok(RealtimePolicy::Nice));
        assert!("fifo".parse::<RealtimePolicy>().is_err());
        assert_eq!(RealtimePolicy::default().to_string(), "nice");
    }

    #[test]
    fn levels_keep_their_order_within_a_ceiling() {
        assert_eq!(FifoLevels::within(99), Some(FifoLevels::DEFAULT));
        assert_eq!(FifoLevels::within(1000), Some(FifoLevels::DEFAULT));
        assert_eq!(FifoLevels::within(80), Some(FifoLevels::DEFAULT));
        assert_eq!(FifoLevels::within(50), Some(FifoLevels { cyclic: 50, device: 49, simulator: 48 }));
        assert_eq!(FifoLevels::within(1), Some(FifoLevels { cyclic: 1, device: 1, simulator: 1 }));
        assert_eq!(FifoLevels::within(0), None);
        let d = FifoLevels::DEFAULT;
        assert!(d.of(ThreadClass::Cyclic) > d.of(ThreadClass::Device));
        assert!(d.of(ThreadClass::Device) > d.of(ThreadClass::Simulator));
    }

    #[test]
    fn stat_lines_parse_with_odd_names() {
        // Fields 3 (state) to 44 as proc(5) numbers them: nice is 19, rt_priority 40, policy 41.
        let fields: Vec<String> = (3..=44)
            .map(|n| match n {
                3 => "S".to_owned(),
                19 => "10".to_owned(),
                40 => "70".to_owned(),
                41 => "1".to_owned(),
                n => (n * 100).to_string(),
            })
            .collect();
        let line = format!("1234 (kv01 (arm) x) {}", fields.join(" "));
        let line = line.as_str();
        let (name, s) = parse_stat(line).unwrap();
        assert_eq!(name, "kv01 (arm) x");
        assert_eq!(s, Scheduling { policy: Policy::Fifo, rt_priority: 70, nice: 10 });
        assert_eq!(s.to_string(), "SCHED_FIFO 70");
        assert!(parse_stat("garbage").is_none());
        assert!(parse_stat("1 (x) S 1 2").is_none());
    }

    #[test]
    fn off_changes_nothing() {
        let before = in_thread(current_thread_scheduling).unwrap();
        let after = in_thread(|| {
            apply_class(Obtained::Off, ThreadClass::Cyclic).unwrap();
            apply_web(Obtained::Off).unwrap();
            current_thread_scheduling().unwrap()
        });
        assert_eq!(before, after);
        assert_eq!(lock_memory_for(Obtained::Off), MemoryLock::Off);
        assert_eq!(lock_memory_for(Obtained::Nice), MemoryLock::Off);
    }

    /// Raising the nice value is always permitted: a web thread ends at nice +10 under both
    /// modes that are not off (the crate's value mapping is checked against the kernel).
    #[test]
    fn web_threads_run_at_nice_10() {
        for obtained in [Obtained::Nice, Obtained::Fifo(FifoLevels::DEFAULT)] {
            let s = in_thread(move || {
                apply_web(obtained).unwrap();
                current_thread_scheduling().unwrap()
            });
            assert_eq!(s, Scheduling { policy: Policy::Normal, rt_priority: 0, nice: i32::from(WEB_NICE) });
        }
    }

    /// Without permission, a device thread is at nice 0 (the default): promoting it is a
    /// no-op that succeeds. From a web thread it can only get back to 0 with CAP_SYS_NICE.
    #[test]
    fn nice_mode_puts_device_threads_at_nice_0() {
        let (s, before, after) = in_thread(|| {
            let before = slice::current_slice();
            apply_class(Obtained::Nice, ThreadClass::Cyclic).unwrap();
            (current_thread_scheduling().unwrap(), before, slice::current_slice())
        });
        assert_eq!(s.nice, 0);
        assert_eq!(s.policy, Policy::Normal);
        // The shortest slice, where the kernel has slices (EEVDF, Linux 6.6+).
        if before.is_some() {
            assert_eq!(after, Some(slice::MIN_SLICE));
        }
        let privileged = has_effective_capability(23); // CAP_SYS_NICE
        let (r, s) = in_thread(|| {
            apply_web(Obtained::Nice).unwrap();
            let r = apply_class(Obtained::Nice, ThreadClass::Device);
            (r, current_thread_scheduling().unwrap())
        });
        if privileged {
            r.unwrap();
            assert_eq!(s.nice, 0);
        } else {
            assert!(r.is_err());
            assert_eq!(s.nice, i32::from(WEB_NICE));
        }
    }

    /// Where SCHED_FIFO is permitted (CI runs as root), each class gets its level, and a web
    /// thread started from a promoted thread leaves SCHED_FIFO; where it is not, promotion
    /// fails and leaves the thread at nice 0.
    #[test]
    fn fifo_levels_per_class_when_permitted() {
        let probe = probe_fifo();
        let fifo = Obtained::Fifo(FifoLevels::DEFAULT);
        for class in [ThreadClass::Cyclic, ThreadClass::Device, ThreadClass::Simulator] {
            let (r, s) = in_thread(move || {
                let r = apply_class(fifo, class);
                (r, current_thread_scheduling().unwrap())
            });
            match &probe {
                Ok(levels) if *levels == FifoLevels::DEFAULT => {
                    r.unwrap();
                    assert_eq!(s.policy, Policy::Fifo);
                    assert_eq!(s.rt_priority, u32::from(FifoLevels::DEFAULT.of(class)));
                }
                _ => {
                    assert!(r.is_err());
                    assert_eq!((s.policy, s.nice), (Policy::Normal, 0));
                }
            }
        }
        if probe.is_ok() {
            let s = in_thread(move || {
                apply_class(fifo, ThreadClass::Device).unwrap();
                in_thread(move || {
                    apply_web(fifo).unwrap();
                    current_thread_scheduling().unwrap()
                })
            });
            assert_eq!(s.policy, Policy::Normal);
            assert_eq!(s.nice, i32::from(WEB_NICE));
        }
    }

    #[test]
    fn capabilities_are_read_from_proc() {
        // Bit 63 is no capability: never set.
        assert!(!has_effective_capability(63));
        assert!(!has_effective_capability(200));
    }
}
