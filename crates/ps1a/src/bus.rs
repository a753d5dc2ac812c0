//! PS1A transactions on a shared bus master.

use motus_ps1a_protocol::{
    Command, CommandFrame, LowStatus, Parameters, ReplyScanner, StatusReply, REPLY_LEN,
};
use motus_serial::{BusError, BusMaster, Request};
use std::sync::Arc;
use std::time::Duration;

/// A PS1A transaction failed.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum Ps1aError {
    /// The line failed or the module did not answer.
    #[error(transparent)]
    Bus(#[from] BusError),
    /// The module kept reporting a checksum error in our command (line noise).
    #[error(
        "module {addr} reported a checksum error in the command {attempts} time(s): the line is too noisy"
    )]
    CommandCorrupted {
        /// Module address.
        addr: u8,
        /// Attempts made.
        attempts: u32,
    },
}

/// The PS1A protocol on one line, shared by all modules on it.
#[derive(Clone)]
pub struct Ps1aBus {
    master: Arc<BusMaster>,
}

impl Ps1aBus {
    /// PS1A on `master`.
    pub fn new(master: Arc<BusMaster>) -> Self {
        Ps1aBus { master }
    }

    /// The bus master (statistics, line settings).
    pub fn master(&self) -> &Arc<BusMaster> {
        &self.master
    }

    /// Sends `command` to module `addr` and returns its status reply. A reply with the
    /// checksum-error bit means the module did not execute the command: it is sent again
    /// (this is safe for every command, relative moves included).
    pub fn transact(&self, addr: u8, command: Command) -> Result<StatusReply, Ps1aError> {
        let mut buf = [0u8; motus_ps1a_protocol::MAX_COMMAND_LEN];
        let frame = CommandFrame::new(addr, command);
        let len = frame.encode_into(&mut buf).unwrap_or(0);
        let bytes = buf.get(..len).unwrap_or(&[]);
        let request = Request {
            device: u32::from(addr),
            bytes,
            reply_len: REPLY_LEN,
            idempotent: command.is_idempotent(),
        };
        let attempts = 1 + self.master.config().retries;
        for _ in 0..attempts {
            let reply = self.master.transact(&request, &ReplyScanner, |r: &StatusReply| r.addr == addr)?;
            if !reply.low.has(LowStatus::CHECKSUM_ERROR) {
                return Ok(reply);
            }
            tracing::debug!(addr, "module reported a checksum error in our command; sending again");
        }
        Err(Ps1aError::CommandCorrupted { addr, attempts })
    }

    /// Asks every address in `addresses` for its status with one short attempt each and
    /// returns those that answered.
    pub fn scan(&self, addresses: impl IntoIterator<Item = u8>) -> Vec<(u8, StatusReply)> {
        let mut found = Vec::new();
        for addr in addresses {
            let frame = CommandFrame::new(addr, Command::StatusRequest).encode();
            let request =
                Request { device: u32::from(addr), bytes: &frame, reply_len: REPLY_LEN, idempotent: false };
            if let Ok(reply) = self.master.transact(&request, &ReplyScanner, |r: &StatusReply| r.addr == addr)
            {
                found.push((addr, reply));
            }
        }
        found
    }

    /// Writes the parameter block (command 1) to module `addr`. The module stores it in
    /// EEPROM; a new address applies from the next command.
    pub fn write_parameters(&self, addr: u8, parameters: Parameters) -> Result<StatusReply, Ps1aError> {
        self.transact(addr, Command::SetParameters { parameters })
    }

    /// The time-out of one status transaction.
    pub fn status_timeout(&self) -> Duration {
        self.master.timeout_for(4, REPLY_LEN)
    }
}
