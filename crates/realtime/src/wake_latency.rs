//! How long an idle CPU may take to wake up, held short while the process runs real-time
//! work (the kernel's PM QoS request, `/dev/cpu_dma_latency`).
//!
//! An idle CPU enters an idle state; the deeper the state, the longer it takes to wake up
//! when a frame arrives or a timer fires. On the 2-core virtual machine this project is
//! developed on, the idle state is a halt of the virtual CPU (the `haltpoll` driver, which
//! claims 1 us): waking it took long enough that the POWERLINK CN's PReq -> PRes turnaround
//! had a median of 19 us on a quiet host against 6 us with the request held, and that
//! openPOWERLINK's MN, on the same host, overran its own 1 ms cycle and reset its nodes
//! (details in `docs/decisions.md`). Real-time Linux practice (cyclictest, LinuxCNC's
//! latency tests) is to hold this request while measuring or running cyclic work.
//!
//! The request is the one documented in the kernel's `Documentation/power/pm_qos_interface`:
//! write the bound in microseconds (a native-endian 32-bit integer) to the device and keep
//! it open; the bound holds for the whole machine until the file is closed (here: when the
//! process ends). Only root may open the device (mode 0600), so the request is made where
//! the process obtained `SCHED_FIFO` ([`crate::Obtained::Fifo`]), by the programs that run a
//! POWERLINK node ([`hold_if_fifo`]).
//!
//! [`WAKE_LATENCY_ENV`] sets another bound (`MOTUS_WAKE_LATENCY_US=20` lets the CPUs use
//! shallow idle states on hardware whose states report honest exit latencies) or none
//! (`off`): a machine that must save power trades cycle-time margins for it.

use std::fmt;
use std::fs::File;
use std::io::Write;
use std::sync::{Mutex, OnceLock};

/// The kernel's PM QoS device for the CPUs' wake-up latency.
pub const DEVICE: &str = "/dev/cpu_dma_latency";

/// The environment variable setting the bound in microseconds (`0` by default) or `off`.
pub const WAKE_LATENCY_ENV: &str = "MOTUS_WAKE_LATENCY_US";

/// The bound held by default: 0 us, no idle state that halts the CPU. An idle CPU then
/// polls (it takes no time from any thread: the scheduler runs whatever is runnable first).
pub const DEFAULT_BOUND_US: u32 = 0;

/// The outcome of [`hold`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum WakeLatency {
    /// Not requested: the process did not obtain `SCHED_FIFO`, or [`WAKE_LATENCY_ENV`] is `off`.
    Off,
    /// The CPUs wake within this many microseconds while the process runs.
    Held(u32),
    /// The request could not be made (no device, not permitted, a bad variable).
    Failed(String),
}

impl fmt::Display for WakeLatency {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            WakeLatency::Off => f.write_str("CPU wake-up latency not requested"),
            WakeLatency::Held(us) => write!(f, "CPU wake-up latency held at {us} us ({DEVICE})"),
            WakeLatency::Failed(why) => write!(f, "CPU wake-up latency not held: {why}"),
        }
    }
}

/// The bound named by `value` (the variable's text): `Ok(None)` for `off`.
///
/// # Errors
/// Neither `off` nor a number of microseconds.
pub fn parse_bound(value: &str) -> Result<Option<u32>, String> {
    let v = value.trim();
    if v.eq_ignore_ascii_case("off") {
        return Ok(None);
    }
    v.parse::<u32>()
        .ok()
        .filter(|us| i32::try_from(*us).is_ok())
        .map(Some)
        .ok_or_else(|| format!("{WAKE_LATENCY_ENV}={value:?} is neither `off` nor a number of microseconds"))
}

/// The open request: the bound holds while this file stays open.
static REQUEST: Mutex<Option<File>> = Mutex::new(None);
static OUTCOME: OnceLock<WakeLatency> = OnceLock::new();

/// Holds the CPUs' wake-up latency at the bound of [`WAKE_LATENCY_ENV`] (default
/// [`DEFAULT_BOUND_US`]) for the rest of the process, if `wanted`. The first call decides;
/// later calls return its outcome.
pub fn hold(wanted: bool) -> WakeLatency {
    OUTCOME
        .get_or_init(|| {
            if !wanted {
                return WakeLatency::Off;
            }
            let bound = match std::env::var(WAKE_LATENCY_ENV) {
                Ok(v) => match parse_bound(&v) {
                    Ok(Some(us)) => us,
                    Ok(None) => return WakeLatency::Off,
                    Err(e) => return WakeLatency::Failed(e),
                },
                Err(_) => DEFAULT_BOUND_US,
            };
            match request(bound) {
                Ok(file) => {
                    *REQUEST.lock().unwrap_or_else(std::sync::PoisonError::into_inner) = Some(file);
                    WakeLatency::Held(bound)
                }
                Err(e) => WakeLatency::Failed(format!("{DEVICE}: {e}")),
            }
        })
        .clone()
}

/// [`hold`] when the process obtained `SCHED_FIFO` ([`crate::set_policy`] first), with the
/// outcome logged once. Called by the programs that run a POWERLINK node and by the
/// real-time benchmarks; not by the station (`motus serve`/`demo`): under web load on the 2-core development VM, one juggler
/// trip was seen with it in CI and two in a loaded local run, none without
/// (`docs/decisions.md`).
pub fn hold_if_fifo() -> WakeLatency {
    let first = OUTCOME.get().is_none();
    let outcome = hold(matches!(crate::obtained(), crate::Obtained::Fifo(_)));
    if first {
        match &outcome {
            WakeLatency::Off => {}
            WakeLatency::Held(_) => tracing::info!("real-time: {outcome}"),
            WakeLatency::Failed(_) => tracing::warn!("real-time: {outcome}"),
        }
    }
    outcome
}

/// What [`hold`] obtained ([`WakeLatency::Off`] before it is called).
pub fn held() -> WakeLatency {
    OUTCOME.get().cloned().unwrap_or(WakeLatency::Off)
}

fn request(bound_us: u32) -> std::io::Result<File> {
    let mut file = std::fs::OpenOptions::new().write(true).open(DEVICE)?;
    let value = i32::try_from(bound_us).unwrap_or(i32::MAX);
    file.write_all(&value.to_ne_bytes())?;
    Ok(file)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounds_are_microseconds_or_off() {
        assert_eq!(parse_bound("0"), Ok(Some(0)));
        assert_eq!(parse_bound(" 20 "), Ok(Some(20)));
        assert_eq!(parse_bound("OFF"), Ok(None));
        assert!(parse_bound("-1").is_err());
        assert!(parse_bound("3000000000").is_err());
        assert!(parse_bound("fast").is_err_and(|e| e.contains("MOTUS_WAKE_LATENCY_US")));
    }
}
