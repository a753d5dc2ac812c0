//! Pinning a thread to one CPU (`sched_setaffinity`).
//!
//! A node's cyclic thread answers fastest on the CPU where its frames arrive: there the
//! frame's reception wakes it without crossing CPUs. openPOWERLINK's Linux demos bind all
//! their threads to CPU 1; on the 2-core development VM a Motus CN woken across CPUs was
//! sometimes not running for 4-8 ms (the idle virtual CPU did not run the woken thread until
//! its next timer tick), and openPOWERLINK's 1 ms MN reset it for the lost PRes; on the MN's
//! CPU it was not (`docs/decisions.md`, issue 20).

use nix::sched::{sched_getaffinity, sched_setaffinity, CpuSet};
use nix::unistd::Pid;

/// Why a thread could not be pinned.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum AffinityError {
    /// The CPU is not one this process may run on.
    #[error("CPU {cpu} is not available to this process (it may run on CPUs {allowed})")]
    NotAllowed {
        /// The CPU asked for.
        cpu: usize,
        /// The CPUs allowed, as a list (`0-1`, `0,2`).
        allowed: String,
    },
    /// The kernel refused.
    #[error("cannot pin the thread to CPU {cpu}: {errno}")]
    Kernel {
        /// The CPU asked for.
        cpu: usize,
        /// The error.
        errno: nix::Error,
    },
}

/// The CPUs this process may run on, in order.
pub fn allowed_cpus() -> Vec<usize> {
    let Ok(set) = sched_getaffinity(Pid::from_raw(0)) else { return Vec::new() };
    (0..CpuSet::count()).filter(|&c| set.is_set(c).unwrap_or(false)).collect()
}

/// `cpus` as a list with ranges (`0-3,6`).
pub fn format_cpus(cpus: &[usize]) -> String {
    let mut out = Vec::new();
    let mut i = 0;
    while let Some(&start) = cpus.get(i) {
        let mut end = start;
        while cpus.get(i + 1) == Some(&(end + 1)) {
            end += 1;
            i += 1;
        }
        out.push(if end == start { start.to_string() } else { format!("{start}-{end}") });
        i += 1;
    }
    if out.is_empty() {
        "none".to_owned()
    } else {
        out.join(",")
    }
}

/// Checks that this process may run on `cpu`.
///
/// # Errors
/// [`AffinityError::NotAllowed`] naming the CPUs it may run on.
pub fn check_cpu(cpu: usize) -> Result<(), AffinityError> {
    let allowed = allowed_cpus();
    if allowed.contains(&cpu) {
        Ok(())
    } else {
        Err(AffinityError::NotAllowed { cpu, allowed: format_cpus(&allowed) })
    }
}

/// Pins the calling thread to `cpu`.
///
/// # Errors
/// The CPU is not allowed to the process, or the kernel refused.
pub fn pin_current_thread(cpu: usize) -> Result<(), AffinityError> {
    check_cpu(cpu)?;
    let mut set = CpuSet::new();
    set.set(cpu).map_err(|errno| AffinityError::Kernel { cpu, errno })?;
    sched_setaffinity(Pid::from_raw(0), &set).map_err(|errno| AffinityError::Kernel { cpu, errno })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;

    #[test]
    fn lists_cpus_with_ranges() {
        assert_eq!(format_cpus(&[0, 1, 2, 3, 6]), "0-3,6");
        assert_eq!(format_cpus(&[1]), "1");
        assert_eq!(format_cpus(&[0, 2]), "0,2");
        assert_eq!(format_cpus(&[]), "none");
    }

    #[test]
    fn a_cpu_the_process_may_not_use_is_refused_by_name() {
        let err = check_cpu(100_000).unwrap_err();
        assert!(err.to_string().starts_with("CPU 100000 is not available to this process"), "{err}");
    }

    #[test]
    fn pins_a_thread_to_an_allowed_cpu() {
        let cpu = *allowed_cpus().last().expect("some CPU");
        std::thread::spawn(move || {
            pin_current_thread(cpu).unwrap();
            let set = sched_getaffinity(Pid::from_raw(0)).unwrap();
            assert!(set.is_set(cpu).unwrap());
            assert_eq!((0..CpuSet::count()).filter(|&c| set.is_set(c).unwrap_or(false)).count(), 1);
        })
        .join()
        .unwrap();
    }
}
