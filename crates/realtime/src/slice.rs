//! The time slice the kernel's fair scheduler (EEVDF, Linux 6.6+) gives a normal thread.
//!
//! # Why
//! Under the normal policy a thread that wakes every millisecond, such as the POWERLINK cycle
//! or the juggler's supervisor, waits for the running thread's slice to end before it runs
//! (about 1.4 ms on a 2-core host, noticed at the next 4 ms tick on a `HZ=250` kernel), and
//! behind every other runnable thread whose deadline is earlier. With a busy web server and its
//! clients on the same cores, the supervisor was measured runnable but not running for 6 to
//! 44 ms: past its 9 ms lease. A thread that asks for a shorter slice gets an earlier virtual
//! deadline, so it is picked first whenever it is eligible (it has used less than its share),
//! and since Linux 6.12 its wake-up preempts a thread with a longer slice. Its share of the CPU
//! does not change: that is the nice value's job. No privilege is needed.
//!
//! # Safety
//! The only module of the crate with `unsafe`: neither `thread-priority` nor `nix` sets
//! `sched_attr.sched_runtime` for the normal policy, so the two syscalls are made here.
#![allow(unsafe_code)]

use std::time::Duration;

use crate::SchedError;

/// The shortest slice the kernel accepts (it clamps requests to 0.1..100 ms).
pub const MIN_SLICE: Duration = Duration::from_micros(100);

/// `struct sched_attr` (include/uapi/linux/sched/types.h), the `SCHED_ATTR_SIZE_VER1` layout.
#[repr(C)]
#[derive(Debug, Default, Clone, Copy)]
struct SchedAttr {
    size: u32,
    sched_policy: u32,
    sched_flags: u64,
    sched_nice: i32,
    sched_priority: u32,
    sched_runtime: u64,
    sched_deadline: u64,
    sched_period: u64,
    sched_util_min: u32,
    sched_util_max: u32,
}

const SCHED_OTHER: u32 = 0;
const SCHED_BATCH: u32 = 3;

fn attr_size() -> u32 {
    u32::try_from(std::mem::size_of::<SchedAttr>()).unwrap_or(u32::MAX)
}

/// The calling thread's scheduling attributes.
fn get() -> Result<SchedAttr, SchedError> {
    let mut attr = SchedAttr::default();
    // SAFETY: `sched_getattr(0, attr, size, 0)` writes at most `size` bytes into `attr`, a
    // live, properly aligned `#[repr(C)] struct sched_attr` of exactly that size; pid 0 is the
    // calling thread. No pointer outlives the call.
    let r = unsafe { libc::syscall(libc::SYS_sched_getattr, 0, &mut attr as *mut SchedAttr, attr_size(), 0) };
    if r != 0 {
        return Err(SchedError(format!("sched_getattr: {}", std::io::Error::last_os_error())));
    }
    Ok(attr)
}

/// Asks the kernel for a time slice of `slice` (clamped by the kernel to 0.1..100 ms) for
/// the calling thread, keeping its policy and nice value. Only for the normal policies
/// (`SCHED_OTHER`, `SCHED_BATCH`); a real-time thread is left as it is. Kernels before 6.6
/// (no EEVDF) ignore the request; kernels without `sched_setattr` fail it.
pub fn request_slice(slice: Duration) -> Result<(), SchedError> {
    let mut attr = get()?;
    if attr.sched_policy != SCHED_OTHER && attr.sched_policy != SCHED_BATCH {
        return Ok(());
    }
    attr.size = attr_size();
    attr.sched_flags = 0;
    attr.sched_runtime = u64::try_from(slice.as_nanos()).unwrap_or(u64::MAX);
    attr.sched_deadline = 0;
    attr.sched_period = 0;
    // SAFETY: `sched_setattr(0, attr, 0)` only reads `attr.size` bytes from `attr`, a live,
    // initialised `#[repr(C)] struct sched_attr` whose `size` field is its own size; pid 0 is
    // the calling thread. The nice value passed is the thread's own (read above), so the call
    // never asks for more than the thread has.
    let r = unsafe { libc::syscall(libc::SYS_sched_setattr, 0, &attr as *const SchedAttr, 0) };
    if r != 0 {
        return Err(SchedError(format!("sched_setattr (slice): {}", std::io::Error::last_os_error())));
    }
    Ok(())
}

/// The calling thread's slice as the kernel holds it (`se.slice` of `/proc/thread-self/sched`),
/// when the kernel shows it.
pub fn current_slice() -> Option<Duration> {
    let text = std::fs::read_to_string("/proc/thread-self/sched").ok()?;
    let line = text.lines().find(|l| l.trim_start().starts_with("se.slice"))?;
    let ns: u64 = line.split(':').nth(1)?.trim().parse().ok()?;
    Some(Duration::from_nanos(ns))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;

    #[test]
    fn a_normal_thread_gets_the_slice_it_asks_for_without_privilege() {
        std::thread::spawn(|| {
            let before = current_slice();
            request_slice(MIN_SLICE).expect("sched_setattr");
            // Kernels without EEVDF (before 6.6) have no slice to show.
            if before.is_some() {
                assert_eq!(current_slice(), Some(MIN_SLICE));
            }
            // The nice value is kept.
            let attr = get().unwrap();
            assert_eq!(attr.sched_policy, SCHED_OTHER);
        })
        .join()
        .unwrap();
    }
}
