//! Simulators started in-process, each on its real transport, and the kill / restart switch
//! the chaos test uses.
//!
//! A [`SimThread`] runs a simulator loop on its own thread until its stop flag is set; the
//! serial families ([`serve_pty`]) create their pty (symlink at the link's path, parent
//! folder created, a stale symlink replaced) inside the start function, so a kill closes the
//! pty and removes the symlink exactly as a killed `motus sim` process would.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;

use motus_serial::{LineSettings, Link, PtyLink};

use crate::CellError;

/// A simulator the cell can kill and restart.
pub(crate) trait SimControl: Send {
    /// Stops the simulator (closing its transport). Idempotent.
    fn kill(&mut self);
    /// Starts it again (after a kill); a running simulator is killed first.
    fn restart(&mut self) -> Result<(), CellError>;
    /// True while it runs.
    fn is_running(&self) -> bool;
}

/// What starts a simulator loop: given the stop flag, returns the loop to run on a thread.
pub(crate) type Starter = Box<dyn Fn(Arc<AtomicBool>) -> Result<Box<dyn FnOnce() + Send>, CellError> + Send>;

/// A simulator loop on a thread (see the module documentation).
pub(crate) struct SimThread {
    name: String,
    starter: Starter,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl SimThread {
    /// Starts the simulator `name`.
    pub(crate) fn start(name: &str, starter: Starter) -> Result<Self, CellError> {
        let mut s =
            SimThread { name: name.into(), starter, stop: Arc::new(AtomicBool::new(false)), thread: None };
        s.spawn()?;
        Ok(s)
    }

    fn spawn(&mut self) -> Result<(), CellError> {
        let stop = Arc::new(AtomicBool::new(false));
        let body = (self.starter)(Arc::clone(&stop))?;
        let thread = std::thread::Builder::new()
            .name(format!("sim-{}", self.name))
            .spawn(move || {
                motus_realtime::promote_current_thread(motus_realtime::ThreadClass::Simulator);
                body()
            })
            .map_err(|e| CellError::Simulator { name: self.name.clone(), reason: format!("spawn: {e}") })?;
        self.stop = stop;
        self.thread = Some(thread);
        Ok(())
    }
}

impl SimControl for SimThread {
    fn kill(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            if t.join().is_err() {
                tracing::warn!(simulator = %self.name, "simulator thread panicked");
            }
        }
    }

    fn restart(&mut self) -> Result<(), CellError> {
        self.kill();
        self.spawn()
    }

    fn is_running(&self) -> bool {
        self.thread.as_ref().is_some_and(|t| !t.is_finished())
    }
}

impl Drop for SimThread {
    fn drop(&mut self) {
        self.kill();
    }
}

/// Creates the pty of a simulated serial link at `path` (parent folder created, a stale
/// symlink replaced; a regular file there is an error).
pub(crate) fn create_pty(name: &str, path: &Path, baud: u32) -> Result<Box<dyn Link>, CellError> {
    let err = |reason: String| CellError::Simulator { name: name.into(), reason };
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)
            .map_err(|e| err(format!("cannot create {}: {e}", parent.display())))?;
    }
    let pty = PtyLink::create(Some(path), LineSettings::n81(baud))
        .map_err(|e| err(format!("cannot create the pty link {}: {e}", path.display())))?;
    tracing::info!(simulator = name, link = %path.display(), slave = %pty.slave_path().display(), "simulator pty ready");
    Ok(Box::new(pty))
}

/// A serial simulator on a pty: `make` builds the simulated line on the link and returns its
/// loop (which must return when the flag is set).
pub(crate) fn serve_pty<F>(name: &str, path: PathBuf, baud: u32, make: F) -> Result<SimThread, CellError>
where
    F: Fn(Box<dyn Link>, Arc<AtomicBool>) -> Result<Box<dyn FnOnce() + Send>, CellError> + Send + 'static,
{
    let n = name.to_string();
    SimThread::start(
        name,
        Box::new(move |stop| {
            let link = create_pty(&n, &path, baud)?;
            make(link, stop)
        }),
    )
}
