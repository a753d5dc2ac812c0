//! Pseudo-terminals for simulators: the simulator holds the master side, and a symlink
//! (e.g. `/tmp/ps1a-line`) points to the slave side that a host opens like any serial
//! port. The simulator also keeps the slave open, so hosts may come and go.

use super::{LineSettings, Link};
use nix::poll::{poll, PollFd, PollFlags, PollTimeout};
use nix::pty::openpty;
use nix::sys::termios::{cfmakeraw, tcgetattr, tcsetattr, SetArg};
use std::fs::File;
use std::io::{self, Read, Write};
use std::os::fd::{AsFd, OwnedFd};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// The master side of a pseudo-terminal, with an optional symlink to its slave.
pub struct PtyLink {
    master: File,
    _slave: OwnedFd,
    slave_path: PathBuf,
    link_path: Option<PathBuf>,
    line: LineSettings,
}

impl PtyLink {
    /// Creates a pty in raw mode. If `link` is given, a symlink at that path points to the
    /// slave device (an existing symlink there is replaced; any other file is an error).
    /// `line` is the nominal line the pty stands for (used for pacing and time-outs).
    pub fn create(link: Option<&Path>, line: LineSettings) -> io::Result<PtyLink> {
        let pty = openpty(None, None).map_err(io::Error::from)?;
        let mut tio = tcgetattr(&pty.slave).map_err(io::Error::from)?;
        cfmakeraw(&mut tio);
        tcsetattr(&pty.slave, SetArg::TCSANOW, &tio).map_err(io::Error::from)?;
        let slave_path = nix::unistd::ttyname(&pty.slave).map_err(io::Error::from)?;
        let link_path = match link {
            Some(path) => {
                if let Ok(meta) = std::fs::symlink_metadata(path) {
                    if meta.file_type().is_symlink() {
                        std::fs::remove_file(path)?;
                    } else {
                        return Err(io::Error::new(
                            io::ErrorKind::AlreadyExists,
                            format!("{} exists and is not a symlink: refusing to replace it", path.display()),
                        ));
                    }
                }
                std::os::unix::fs::symlink(&slave_path, path).map_err(|e| {
                    io::Error::new(e.kind(), format!("cannot create pty link {}: {e}", path.display()))
                })?;
                Some(path.to_path_buf())
            }
            None => None,
        };
        Ok(PtyLink { master: File::from(pty.master), _slave: pty.slave, slave_path, link_path, line })
    }

    /// The slave device path (e.g. `/dev/pts/7`).
    pub fn slave_path(&self) -> &Path {
        &self.slave_path
    }

    /// The symlink path, if one was created.
    pub fn link_path(&self) -> Option<&Path> {
        self.link_path.as_deref()
    }

    /// The path a host should open: the symlink if any, else the slave device.
    pub fn host_path(&self) -> &Path {
        self.link_path.as_deref().unwrap_or(&self.slave_path)
    }
}

impl Drop for PtyLink {
    fn drop(&mut self) {
        if let Some(link) = &self.link_path {
            // Only remove the link if it still points to our slave.
            if std::fs::read_link(link).ok().as_deref() == Some(self.slave_path.as_path()) {
                let _ = std::fs::remove_file(link);
            }
        }
    }
}

impl Link for PtyLink {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.master.write_all(bytes)
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        let ms = timeout.as_millis().min(i32::MAX as u128) as i32;
        // Round sub-millisecond waits up so a short wait still waits.
        let ms = if ms == 0 && !timeout.is_zero() { 1 } else { ms };
        let mut fds = [PollFd::new(self.master.as_fd(), PollFlags::POLLIN)];
        let ready =
            poll(&mut fds, PollTimeout::try_from(ms).unwrap_or(PollTimeout::MAX)).map_err(io::Error::from)?;
        if ready == 0 {
            return Ok(0);
        }
        match self.master.read(buf) {
            Ok(n) => Ok(n),
            Err(e) if e.kind() == io::ErrorKind::WouldBlock || e.kind() == io::ErrorKind::Interrupted => {
                Ok(0)
            }
            Err(e) => Err(e),
        }
    }

    fn discard_input(&mut self) -> io::Result<()> {
        let mut scratch = [0u8; 256];
        while self.read(&mut scratch, Duration::ZERO)? > 0 {}
        Ok(())
    }

    fn line(&self) -> LineSettings {
        self.line
    }

    fn describe(&self) -> String {
        format!("pty:{}", self.host_path().display())
    }
}
