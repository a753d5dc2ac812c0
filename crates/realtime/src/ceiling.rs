//! Priority ceiling for a shared device line (the immediate priority-ceiling protocol).
//!
//! A serial line is held for a whole transaction, reply included. Any thread may hold it:
//! a device's own threads (`SCHED_FIFO` under [`crate::Obtained::Fifo`]), but also a web
//! thread at nice +10 or a command-line thread at nice 0 sending a command. A holder at
//! normal priority that the real-time threads keep off the CPU keeps the line from the
//! cyclic thread that needs it: a KV-01 arm's modules trip their 700 ms communication
//! time-out when the keep-alive waits that long (seen in the suite, a test's thread holding
//! the arm's line). While it holds the line, a thread therefore runs at the line's
//! ceiling, the device class's priority ([`raise_to`]), and returns to its own scheduling
//! when it lets go.
//!
//! Cheap where nothing is to be done (no `SCHED_FIFO` in the process, or a thread promoted
//! to the class or above: a thread-local look-up); otherwise two `sched_setscheduler`
//! calls per transaction.

use std::cell::Cell;

use crate::{obtained, set_fifo, set_nice, Obtained, Policy, ThreadClass, WEB_NICE};

/// What this thread was set to by [`crate::promote_current_thread`] or
/// [`crate::demote_current_thread_for_web`], or read once from `/proc` ([`Role::Read`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Role {
    Unknown,
    Class(ThreadClass),
    Web,
    /// Read from `/proc` at the first raise: how to give it back, or `None` when it cannot
    /// be restored exactly (the thread is then left alone).
    Read(Option<Restore>),
}

thread_local! {
    static ROLE: Cell<Role> = const { Cell::new(Role::Unknown) };
}

/// Records the calling thread's role (after a successful promotion or demotion).
pub(crate) fn record(role: Role) {
    ROLE.with(|r| r.set(role));
}

/// How to give the ceiling back.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Restore {
    Fifo(u8),
    Nice(i8),
}

/// The raised priority of the calling thread; gives it back on drop. Not `Send`: it
/// belongs to the thread that raised it.
#[derive(Debug)]
#[must_use = "the ceiling is given back when this guard is dropped"]
pub struct Ceiling {
    restore: Option<Restore>,
    _not_send: std::marker::PhantomData<*const ()>,
}

impl Ceiling {
    /// Whether this guard raised the thread (false: nothing to do, or not permitted).
    pub fn raised(&self) -> bool {
        self.restore.is_some()
    }
}

impl Drop for Ceiling {
    fn drop(&mut self) {
        let result = match self.restore {
            None => return,
            Some(Restore::Fifo(p)) => set_fifo(p),
            Some(Restore::Nice(n)) => set_nice(n),
        };
        if let Err(e) = result {
            tracing::warn!(error = %e, "real-time: cannot give back a line's priority ceiling");
        }
    }
}

/// Raises the calling thread to `class`'s `SCHED_FIFO` priority until the guard is dropped,
/// when the process obtained `SCHED_FIFO` and the thread runs below it. A thread whose
/// scheduling cannot be restored exactly (another nice value, another policy) is left as
/// it is.
pub fn raise_to(class: ThreadClass) -> Ceiling {
    raise_within(obtained(), class)
}

fn raise_within(obtained: Obtained, class: ThreadClass) -> Ceiling {
    let none = Ceiling { restore: None, _not_send: std::marker::PhantomData };
    let Obtained::Fifo(levels) = obtained else { return none };
    let ceiling = levels.of(class);
    let restore = match ROLE.with(Cell::get) {
        Role::Class(c) => Restore::Fifo(levels.of(c)),
        Role::Web => Restore::Nice(WEB_NICE),
        Role::Read(r) => match r {
            Some(r) => r,
            None => return none,
        },
        // Read once per thread: the transactions after it take the paths above.
        Role::Unknown => {
            let read = read_restore();
            record(Role::Read(read));
            match read {
                Some(r) => r,
                None => return none,
            }
        }
    };
    if matches!(restore, Restore::Fifo(p) if p >= ceiling) {
        return none;
    }
    match set_fifo(ceiling) {
        Ok(()) => Ceiling { restore: Some(restore), _not_send: std::marker::PhantomData },
        Err(_) => none,
    }
}

/// How to restore the calling thread's scheduling as `/proc` shows it: `SCHED_FIFO` at its
/// priority, or the normal policy at nice 0 or [`WEB_NICE`]; `None` otherwise.
fn read_restore() -> Option<Restore> {
    let s = crate::current_thread_scheduling()?;
    match s.policy {
        Policy::Fifo => u8::try_from(s.rt_priority).ok().map(Restore::Fifo),
        Policy::Normal => i8::try_from(s.nice).ok().filter(|n| *n == 0 || *n == WEB_NICE).map(Restore::Nice),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
    use super::*;
    use crate::{apply_class, apply_web, current_thread_scheduling, probe_fifo, FifoLevels, Scheduling};

    fn in_thread<T: Send + 'static>(f: impl FnOnce() -> T + Send + 'static) -> T {
        std::thread::spawn(f).join().unwrap()
    }

    /// (raised?, scheduling while raised, scheduling after) for a thread set up by `setup`.
    fn raise_in_thread(setup: fn(Obtained)) -> (bool, Scheduling, Scheduling) {
        in_thread(move || {
            let fifo = Obtained::Fifo(FifoLevels::DEFAULT);
            setup(fifo);
            let c = raise_within(fifo, ThreadClass::Device);
            let during = current_thread_scheduling().unwrap();
            let raised = c.raised();
            drop(c);
            (raised, during, current_thread_scheduling().unwrap())
        })
    }

    #[test]
    fn a_thread_below_the_device_class_holds_the_line_at_its_priority_and_gets_its_own_back() {
        if probe_fifo() != Ok(FifoLevels::DEFAULT) {
            eprintln!("skipped: SCHED_FIFO at the default levels is not permitted here (not root)");
            return;
        }
        let fifo_at = |p: u32| (Policy::Fifo, p);
        let of =
            |s: Scheduling| if s.policy == Policy::Fifo { (s.policy, s.rt_priority) } else { (s.policy, 0) };
        // A thread at nice 0 (a command-line or test thread, its role unknown).
        let (raised, during, after) = raise_in_thread(|_| {});
        assert!(raised);
        assert_eq!(of(during), fifo_at(70));
        assert_eq!((after.policy, after.nice), (Policy::Normal, 0));
        // A web thread (nice +10).
        let (raised, during, after) = raise_in_thread(|o| apply_web(o).unwrap());
        assert!(raised);
        assert_eq!(of(during), fifo_at(70));
        assert_eq!((after.policy, after.nice), (Policy::Normal, i32::from(WEB_NICE)));
        // A simulator thread (FIFO 60): raised to 70, back to 60.
        let (raised, during, after) = raise_in_thread(|o| apply_class(o, ThreadClass::Simulator).unwrap());
        assert!(raised);
        assert_eq!(of(during), fifo_at(70));
        assert_eq!(of(after), fifo_at(60));
        // A cyclic thread (FIFO 80) is above the ceiling: left alone.
        let (raised, during, after) = raise_in_thread(|o| apply_class(o, ThreadClass::Cyclic).unwrap());
        assert!(!raised);
        assert_eq!(of(during), fifo_at(80));
        assert_eq!(of(after), fifo_at(80));
    }

    #[test]
    fn without_fifo_in_the_process_nothing_is_raised() {
        // The unit tests never set a policy: obtained() is Off.
        std::thread::spawn(|| {
            let before = crate::current_thread_scheduling();
            let c = raise_to(ThreadClass::Device);
            assert!(!c.raised());
            drop(c);
            assert_eq!(crate::current_thread_scheduling(), before);
        })
        .join()
        .unwrap();
    }
}
