//! KV-01 transactions on a shared bus master, with the module's own refusals typed.

use motus_kv01_protocol::{
    Address, Command, CrcMode, Decoded, EncodeError, Message, MessageScanner, Reply, ReplyBody, ShortCode,
};
use motus_serial::{BusError, BusMaster, Request};
use std::sync::Arc;

/// A KV-01 transaction failed.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum Kv01Error {
    /// The line failed or the module did not answer.
    #[error(transparent)]
    Bus(#[from] BusError),
    /// The module answers "TO": its 700 ms safety time-out tripped.
    #[error(
        "module 0x{addr:02X} (joint {joint}) answers \"TO\": its 700 ms safety communication time-out tripped, \
         so it disabled the drive and engaged the brake. It stays latched: check the joint is safe, power-cycle \
         the arm's communication modules (a simulated arm: restart `motus sim kv01`), then enable the joint again"
    )]
    SafetyTimeout {
        /// Module address.
        addr: u8,
        /// Joint number 1..=6.
        joint: u8,
    },
    /// The module answers "UC" (unknown command).
    #[error("module 0x{addr:02X} answers \"UC\": it did not understand the command")]
    UnknownCommand {
        /// Module address.
        addr: u8,
    },
    /// Our request could not be built (e.g. 0xF0 inside its data).
    #[error("request not sent: {0}")]
    Encode(#[from] EncodeError),
}

/// The KV-01 protocol on one line.
#[derive(Clone)]
pub struct Kv01Bus {
    master: Arc<BusMaster>,
    crc: CrcMode,
}

impl Kv01Bus {
    /// KV-01 on `master`, checking reply CRCs in `crc` mode (strict by default; lenient
    /// accepts and logs a mismatch, for arms whose firmware differs from the publication).
    /// Transactions (of every clone) take the line in turn through the bus master, whose
    /// lock waits on its clock ([`motus_clock::ClockMutex`]): a thread waiting for the line
    /// never holds it up for the others (a queue of tickets did, when a starved web thread's
    /// ticket came up: the control thread waited behind it past the arm's 700 ms time-out).
    pub fn new(master: Arc<BusMaster>, crc: CrcMode) -> Self {
        Kv01Bus { master, crc }
    }

    /// The bus master.
    pub fn master(&self) -> &Arc<BusMaster> {
        &self.master
    }

    /// Sends `command` to `addr` and returns the reply body. "TO" and "UC" become errors.
    /// The encoder refuses any data containing 0xF0, so the host never sends it.
    pub fn transact(&self, addr: Address, command: Command) -> Result<ReplyBody, Kv01Error> {
        let msg = Message::request(addr, command);
        let mut buf = [0u8; motus_kv01_protocol::MAX_FRAME_LEN];
        let len = msg.encode_into(&mut buf)?;
        let bytes = buf.get(..len).unwrap_or(&[]);
        let request = Request { device: u32::from(addr.raw()), bytes, reply_len: 8, idempotent: true };
        let decoded = self.master.transact(
            &request,
            &MessageScanner::replies(self.crc),
            |d: &Decoded| matches!(&d.message, Message::Reply(Reply { address, .. }) if *address == addr),
        );
        let decoded: Decoded = decoded?;
        if let Some(m) = decoded.crc_mismatch {
            tracing::warn!(
                addr = addr.raw(),
                expected = m.expected,
                received = m.received,
                "reply accepted with a bad CRC (lenient mode)"
            );
        }
        let Message::Reply(reply) = decoded.message else {
            return Err(Kv01Error::UnknownCommand { addr: addr.raw() });
        };
        match reply.body {
            ReplyBody::Short { text: ShortCode::Timeout } => {
                Err(Kv01Error::SafetyTimeout { addr: addr.raw(), joint: addr.joint_number() })
            }
            ReplyBody::Short { text: ShortCode::UnknownCommand } => {
                Err(Kv01Error::UnknownCommand { addr: addr.raw() })
            }
            body => Ok(body),
        }
    }
}
