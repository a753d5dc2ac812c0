//! Serving several modules on one serial link, with the serial simulators' one loop
//! ([`SimServer`]).
//!
//! The line decodes every command with the codec's resynchronising [`CommandStream`]
//! (a quiet line ends a command: a half-received one is dropped); the module whose address
//! matches answers, the others stay silent (as on a real multi-drop line); a command with
//! a bad checksum is answered by its module with the checksum-error bit. Options model the
//! real line: **pacing** (a command takes its wire time to arrive and the reply leaves byte
//! by byte at the baud rate) and **faults** (dropped replies, corrupted bytes in both
//! directions).
//!
//! Simulated time is on a [`motus_clock::Clock`]: the system clock for [`SimLine::new`],
//! any clock for [`SimLine::with_clock`]. On a virtual clock the line is served **in
//! process** by [`SimLine::into_sim_link`]: a [`SimLink`] is the host's link, and the
//! same serve step answers in the host's thread, on virtual time.
//!
//! [`CommandStream`]: motus_ps1a_protocol::CommandStream

use crate::machine::MachineConfig;
use crate::module::Module;
use crate::state_file::{ModuleState, StateFile, StateFileError};
use crate::state_writer::StateWriter;
use motus_clock::{SharedClock, SystemClock};
use motus_ps1a_protocol::{ChecksumError, CommandFrame, CommandScanner, Parameters};
use motus_serial::{Answer, FaultConfig, Link, Responder, ServeOptions, SimLink, SimServer};
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// How often a moving machine's position is written to the state file, in simulated time.
const SAVE_PERIOD: Duration = Duration::from_millis(200);

/// Options of a simulated line.
#[derive(Debug, Clone, Default)]
pub struct LineOptions {
    /// Factory addresses of the modules, one per slot (at most 16).
    pub addresses: Vec<u8>,
    /// State file (EEPROM + machine position); `None` keeps state in memory only.
    pub state_file: Option<PathBuf>,
    /// Bytes take their real wire time at the link's baud rate.
    pub baud_pacing: bool,
    /// Fault injection on the replies (drop, corrupt) and on received bytes (corrupt).
    pub faults: FaultConfig,
    /// The simulated machine of every module.
    pub machine: MachineConfig,
}

/// Errors starting a simulated line.
pub type LineError = motus_serial::LineError<StateFileError>;

/// Up to 16 simulated modules serving one link.
pub struct SimLine {
    server: SimServer<CommandScanner>,
    modules: Modules,
}

/// The modules of the line and their state file: the line's [`Responder`], what answers
/// the host.
pub struct Modules {
    modules: Vec<Module>,
    /// The latest simulated time the modules were brought to.
    now: Duration,
    /// When the state was last handed to the state file's writer (simulated time).
    last_save: Duration,
    saved_positions: Vec<f64>,
    /// Writes the state file off the serving loop (`None`: no state file).
    writer: Option<StateWriter>,
}

impl SimLine {
    /// Powers the modules on (from the state file if it exists) on `link`, on the system
    /// clock.
    ///
    /// # Errors
    /// [`LineError::Options`] for bad options, [`LineError::Model`] for an unreadable
    /// state file.
    pub fn new(link: Box<dyn Link>, options: LineOptions) -> Result<SimLine, LineError> {
        Self::with_clock(link, options, SystemClock::shared())
    }

    /// Powers the modules on (from the state file if it exists) on `link`, with simulated
    /// time on `clock` (for an in-process line, see [`SimLine::into_sim_link`]).
    ///
    /// # Errors
    /// As [`SimLine::new`].
    pub fn with_clock(
        link: Box<dyn Link>,
        options: LineOptions,
        clock: SharedClock,
    ) -> Result<SimLine, LineError> {
        if options.addresses.is_empty() || options.addresses.len() > motus_ps1a_protocol::MAX_MODULES_PER_LINE
        {
            return Err(LineError::Options(format!(
                "between 1 and 16 module addresses are needed, got {}",
                options.addresses.len()
            )));
        }
        let mut seen = std::collections::BTreeSet::new();
        if let Some(dup) = options.addresses.iter().find(|a| !seen.insert(**a)) {
            return Err(LineError::Options(format!("address {dup} is given twice")));
        }
        let stored = match &options.state_file {
            Some(p) => StateFile::load(p)?,
            None => StateFile::default(),
        };
        let modules = options
            .addresses
            .iter()
            .enumerate()
            .map(|(i, &addr)| match stored.modules.get(i) {
                Some(s) => Module::power_on(
                    s.parameters,
                    s.programmed,
                    options.machine,
                    s.machine_position,
                    Duration::ZERO,
                ),
                None => {
                    let p = Parameters { address: addr, ..Parameters::default() };
                    Module::power_on(
                        p,
                        false,
                        options.machine,
                        options.machine.initial_position,
                        Duration::ZERO,
                    )
                }
            })
            .collect();
        let serve = ServeOptions {
            baud_pacing: options.baud_pacing,
            faults: options.faults,
            poll: Duration::from_millis(10),
            flush_when_idle: true,
        };
        let server = SimServer::with_clock(link, CommandScanner, serve, clock)
            .map_err(|e| LineError::Options(e.to_string()))?;
        let writer = options.state_file.clone().map(StateWriter::spawn).transpose()?;
        let mut line = SimLine {
            server,
            modules: Modules {
                modules,
                now: Duration::ZERO,
                last_save: Duration::ZERO,
                saved_positions: Vec::new(),
                writer,
            },
        };
        line.save()?;
        Ok(line)
    }

    /// The modules (for tests and status displays).
    pub fn modules(&self) -> &[Module] {
        &self.modules.modules
    }

    /// Mutable access to the modules (fault injection in tests).
    pub fn modules_mut(&mut self) -> &mut [Module] {
        &mut self.modules.modules
    }

    /// The serve loop (answers sent, the command decoder's statistics, simulated time).
    pub fn server(&self) -> &SimServer<CommandScanner> {
        &self.server
    }

    /// Writes the state file (if any) and returns once it is on disk.
    pub fn save(&mut self) -> Result<(), StateFileError> {
        self.modules.save()
    }

    /// Serves the line until `stop` is set.
    ///
    /// # Errors
    /// An IO error of the link, or of the state file.
    pub fn run(&mut self, stop: &AtomicBool) -> std::io::Result<()> {
        self.server.run(&mut self.modules, stop)?;
        self.save().map_err(std::io::Error::other)
    }

    /// The line served in process, for a host on the same (virtual) clock: the host's
    /// link, and the modules it serves (shared with the link: lock them to inspect or
    /// change the simulated modules, or to [save](Modules::save) the state file). The
    /// link given when the line was made is not used (e.g. a
    /// [`motus_serial::NullLink`] of the line's settings).
    pub fn into_sim_link(self) -> (SimLink<CommandScanner, Modules>, Arc<Mutex<Modules>>) {
        let line = self.server.line();
        let modules = Arc::new(Mutex::new(self.modules));
        (SimLink::new(self.server, Arc::clone(&modules), line), modules)
    }
}

impl Modules {
    /// The modules.
    pub fn modules(&self) -> &[Module] {
        &self.modules
    }

    /// Mutable access to the modules (fault injection, power cycles in tests).
    pub fn modules_mut(&mut self) -> &mut [Module] {
        &mut self.modules
    }

    /// The latest simulated time the modules were brought to.
    pub fn now(&self) -> Duration {
        self.now
    }

    /// Writes the state file (if any) and returns once it is on disk.
    ///
    /// # Errors
    /// The state file could not be written.
    pub fn save(&mut self) -> Result<(), StateFileError> {
        self.save_in_background()?;
        self.writer.as_ref().map_or(Ok(()), StateWriter::flush)
    }

    /// Hands the state to the state file's writer and returns at once, so that a slow
    /// disk never delays a reply (see `state_writer`). Fails with an earlier write's error.
    fn save_in_background(&mut self) -> Result<(), StateFileError> {
        self.last_save = self.now;
        self.saved_positions = self.modules.iter().map(Module::machine_position).collect();
        let Some(writer) = &self.writer else { return Ok(()) };
        let state = StateFile {
            version: StateFile::VERSION,
            modules: self
                .modules
                .iter()
                .map(|m| ModuleState {
                    parameters: m.parameters(),
                    programmed: m.programmed(),
                    machine_position: m.machine_position(),
                })
                .collect(),
        };
        writer.submit(state)
    }

    fn module(&mut self, addr: u8) -> Option<&mut Module> {
        self.modules.iter_mut().find(|m| m.address() == addr)
    }
}

impl Responder for Modules {
    type Frame = CommandFrame;
    type Error = ChecksumError;

    fn respond(&mut self, frame: CommandFrame, now: Duration) -> Option<Answer> {
        let reply = self.module(frame.addr)?.handle(&frame.command, now);
        Some(Answer { bytes: reply.to_bytes().to_vec(), delay: Duration::ZERO })
    }

    /// The addressed module answers with the checksum-error bit.
    fn corrupt(&mut self, error: ChecksumError, now: Duration) -> Option<Answer> {
        let reply = self.module(error.addr)?.checksum_error(now);
        Some(Answer { bytes: reply.to_bytes().to_vec(), delay: Duration::ZERO })
    }

    fn tick(&mut self, now: Duration) -> std::io::Result<()> {
        self.now = self.now.max(now);
        for m in &mut self.modules {
            m.advance_to(now);
        }
        let moved =
            self.modules.iter().map(Module::machine_position).ne(self.saved_positions.iter().copied());
        let eeprom = self.modules.iter_mut().any(|m| m.take_eeprom_dirty());
        if eeprom || (moved && self.now.saturating_sub(self.last_save) > SAVE_PERIOD) {
            self.save_in_background().map_err(std::io::Error::other)?;
        }
        Ok(())
    }
}
