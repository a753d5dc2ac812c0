//! Writing the state file off the serving thread.
//!
//! A module answers within its reply time, but a file system under load can take tens of
//! milliseconds to replace a file: the rename of the atomic write took up to 48 ms on
//! this project's CI machine (ext4) beside a disk-heavy job, longer than a host's whole
//! reply time-out at 9600 Bd (the wire time plus 20 ms). So the serving loop hands the
//! newest state to a writer thread and goes on answering. Only the newest unwritten
//! state is kept: an older one it supersedes would be overwritten at once anyway.

use crate::state_file::{StateFile, StateFileError};
use std::path::PathBuf;
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;

/// What the serving thread and the writer share.
#[derive(Default)]
struct Slot {
    /// The newest state not yet being written.
    pending: Option<StateFile>,
    /// The writer is writing a state now.
    writing: bool,
    /// The first failure not yet reported to the serving thread.
    error: Option<StateFileError>,
    /// The writer should end once nothing is pending.
    stop: bool,
}

type Shared = Arc<(Mutex<Slot>, Condvar)>;

fn lock(shared: &Shared) -> MutexGuard<'_, Slot> {
    shared.0.lock().unwrap_or_else(PoisonError::into_inner)
}

/// A thread that writes the states it is given to one state file, newest first.
pub(crate) struct StateWriter {
    shared: Shared,
    thread: Option<JoinHandle<()>>,
}

impl StateWriter {
    /// Starts the writer of `path`.
    pub fn spawn(path: PathBuf) -> Result<StateWriter, StateFileError> {
        let shared: Shared = Arc::default();
        let theirs = Arc::clone(&shared);
        let name = path.display().to_string();
        let thread = std::thread::Builder::new()
            .name("ps1a-state-writer".into())
            .spawn(move || write_loop(&theirs, &path))
            .map_err(|source| StateFileError::Io { path: name, source })?;
        Ok(StateWriter { shared, thread: Some(thread) })
    }

    /// Hands `state` to the writer and returns at once. Fails with an earlier write's
    /// error, if one has not been reported yet.
    pub fn submit(&self, state: StateFile) -> Result<(), StateFileError> {
        let mut slot = lock(&self.shared);
        slot.pending = Some(state);
        self.shared.1.notify_all();
        slot.error.take().map_or(Ok(()), Err)
    }

    /// Waits until every state handed over is on disk.
    pub fn flush(&self) -> Result<(), StateFileError> {
        let mut slot = lock(&self.shared);
        while slot.pending.is_some() || slot.writing {
            slot = self.shared.1.wait(slot).unwrap_or_else(PoisonError::into_inner);
        }
        slot.error.take().map_or(Ok(()), Err)
    }
}

impl Drop for StateWriter {
    /// Writes what is still pending, then ends the thread.
    fn drop(&mut self) {
        lock(&self.shared).stop = true;
        self.shared.1.notify_all();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

fn write_loop(shared: &Shared, path: &std::path::Path) {
    loop {
        let state = {
            let mut slot = lock(shared);
            loop {
                if let Some(state) = slot.pending.take() {
                    slot.writing = true;
                    break state;
                }
                if slot.stop {
                    return;
                }
                slot = shared.1.wait(slot).unwrap_or_else(PoisonError::into_inner);
            }
        };
        let result = state.save(path);
        let mut slot = lock(shared);
        slot.writing = false;
        if let Err(e) = result {
            tracing::warn!(error = %e, "could not write the simulator's state file");
            slot.error.get_or_insert(e);
        }
        shared.1.notify_all();
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
    use super::*;
    use crate::state_file::ModuleState;
    use motus_ps1a_protocol::Parameters;

    fn state(position: f64) -> StateFile {
        StateFile {
            version: StateFile::VERSION,
            modules: vec![ModuleState {
                parameters: Parameters::default(),
                programmed: false,
                machine_position: position,
            }],
        }
    }

    #[test]
    fn the_newest_state_is_on_disk_after_a_flush_and_after_drop() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.json");
        let w = StateWriter::spawn(path.clone()).unwrap();
        for i in 0..50 {
            w.submit(state(f64::from(i))).unwrap();
        }
        w.flush().unwrap();
        assert_eq!(StateFile::load(&path).unwrap(), state(49.0));
        w.submit(state(7.0)).unwrap();
        drop(w);
        assert_eq!(StateFile::load(&path).unwrap(), state(7.0), "drop writes what is pending");
    }

    #[test]
    fn a_failed_write_is_reported_once() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("missing-dir").join("s.json");
        let w = StateWriter::spawn(path).unwrap();
        w.submit(state(1.0)).unwrap();
        let err = w.flush().unwrap_err();
        assert!(err.to_string().contains("missing-dir"), "{err}");
        assert!(w.flush().is_ok(), "reported once");
    }
}
