//! Serving several modules on one serial link.
//!
//! The line decodes every command with a resynchronising stream decoder; the module
//! whose address matches answers, the others stay silent (as on a real multi-drop line).
//! Options model the real line: **pacing** (a command takes its wire time to arrive and
//! the reply leaves byte by byte at the baud rate) and **faults** (dropped replies,
//! corrupted bytes in both directions).

use crate::machine::MachineConfig;
use crate::module::Module;
use crate::state_file::{ModuleState, StateFile, StateFileError};
use crate::state_writer::StateWriter;
use motus_ps1a_protocol::{CommandStream, Parameters, StreamEvent, REPLY_LEN};
use motus_serial::{FaultConfig, FaultInjector, Link, Paced};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

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
#[derive(Debug, thiserror::Error)]
pub enum LineError {
    /// Bad options.
    #[error("invalid simulator options: {0}")]
    Options(String),
    /// State file failure.
    #[error(transparent)]
    State(#[from] StateFileError),
}

/// Up to 16 simulated modules serving one link.
pub struct SimLine {
    modules: Vec<Module>,
    link: Box<dyn Link>,
    stream: CommandStream,
    options: LineOptions,
    start: Instant,
    rx_rng: SmallRng,
    last_save: Instant,
    frames_served: u64,
    saved_positions: Vec<f64>,
    /// Writes the state file off the serving loop (`None`: no state file).
    writer: Option<StateWriter>,
}

impl SimLine {
    /// Powers the modules on (from the state file if it exists) on `link`.
    pub fn new(link: Box<dyn Link>, options: LineOptions) -> Result<SimLine, LineError> {
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
        let mut link = link;
        if options.faults.drop_rate > 0.0 || options.faults.corrupt_rate > 0.0 {
            link = Box::new(FaultInjector::new(link, options.faults));
        }
        if options.baud_pacing {
            link = Box::new(Paced::new(link));
        }
        let rx_rng = SmallRng::seed_from_u64(options.faults.seed ^ 0x5eed);
        let writer = options.state_file.clone().map(StateWriter::spawn).transpose()?;
        let mut line = SimLine {
            modules,
            link,
            stream: CommandStream::commands(),
            options,
            start: Instant::now(),
            rx_rng,
            last_save: Instant::now(),
            frames_served: 0,
            saved_positions: Vec::new(),
            writer,
        };
        line.save()?;
        Ok(line)
    }

    /// The modules (for tests and status displays).
    pub fn modules(&self) -> &[Module] {
        &self.modules
    }

    /// Mutable access to the modules (fault injection in tests).
    pub fn modules_mut(&mut self) -> &mut [Module] {
        &mut self.modules
    }

    /// Commands answered so far.
    pub fn frames_served(&self) -> u64 {
        self.frames_served
    }

    fn now(&self) -> Duration {
        self.start.elapsed()
    }

    /// Writes the state file (if any) and returns once it is on disk.
    pub fn save(&mut self) -> Result<(), StateFileError> {
        self.save_in_background()?;
        self.writer.as_ref().map_or(Ok(()), StateWriter::flush)
    }

    /// Hands the state to the state file's writer and returns at once, so that a slow
    /// disk never delays a reply (see `state_writer`). Fails with an earlier write's error.
    fn save_in_background(&mut self) -> Result<(), StateFileError> {
        self.last_save = Instant::now();
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

    /// Serves the line until `stop` is set.
    pub fn run(&mut self, stop: &AtomicBool) -> std::io::Result<()> {
        let line = self.link.line();
        let char_time = line.char_time();
        let idle_gap = (char_time * 3).max(Duration::from_millis(2));
        let mut buf = [0u8; 256];
        let mut first_byte_at: Option<Instant> = None;
        let mut last_byte_at = Instant::now();
        while !stop.load(Ordering::Relaxed) {
            let n = self.link.read(&mut buf, Duration::from_millis(10))?;
            let now_i = Instant::now();
            if n == 0 {
                if self.stream.pending_len() > 0 && now_i - last_byte_at > idle_gap {
                    self.stream.clear();
                    first_byte_at = None;
                }
                self.tick()?;
                continue;
            }
            if self.stream.pending_len() == 0 || now_i - last_byte_at > idle_gap {
                if now_i - last_byte_at > idle_gap {
                    self.stream.clear();
                }
                first_byte_at = Some(now_i);
            }
            last_byte_at = now_i;
            let data = buf.get_mut(..n).unwrap_or(&mut []);
            if self.options.faults.corrupt_rate > 0.0 {
                for b in data.iter_mut() {
                    if self.rx_rng.gen_bool(self.options.faults.corrupt_rate.clamp(0.0, 1.0)) {
                        *b ^= self.rx_rng.gen_range(1..=255u8);
                    }
                }
            }
            self.stream.push(data);
            while let Some(event) = self.stream.next_event() {
                let frame_len;
                let now = self.now();
                let reply = match event {
                    StreamEvent::Frame(f) => {
                        frame_len = f.command.frame_len();
                        self.modules
                            .iter_mut()
                            .find(|m| m.address() == f.addr)
                            .map(|m| m.handle(&f.command, now))
                    }
                    StreamEvent::ChecksumError { addr, .. } => {
                        frame_len = REPLY_LEN;
                        self.modules.iter_mut().find(|m| m.address() == addr).map(|m| m.checksum_error(now))
                    }
                };
                let Some(reply) = reply else { continue };
                if self.options.baud_pacing {
                    // The command's last byte arrives one wire time after its first.
                    if let Some(t0) = first_byte_at {
                        motus_serial::sleep_until(t0 + line.wire_time(frame_len));
                    }
                }
                self.link.write_all(&reply.to_bytes())?;
                self.frames_served += 1;
                first_byte_at = None;
            }
            if self.stream.pending_len() == 0 {
                first_byte_at = None;
            }
            if self.modules.iter_mut().any(|m| m.take_eeprom_dirty()) {
                self.save_in_background().map_err(std::io::Error::other)?;
            }
        }
        self.tick()?;
        self.save().map_err(std::io::Error::other)
    }

    fn tick(&mut self) -> std::io::Result<()> {
        let now = self.now();
        for m in &mut self.modules {
            m.advance_to(now);
        }
        let moved =
            self.modules.iter().map(Module::machine_position).ne(self.saved_positions.iter().copied());
        if moved && self.last_save.elapsed() > Duration::from_millis(200) {
            self.save_in_background().map_err(std::io::Error::other)?;
        }
        Ok(())
    }
}
