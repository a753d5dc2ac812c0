//! KV-01 transactions on a shared bus master, with the module's own refusals typed.

use motus_clock::Clock;
use motus_kv01_protocol::{
    Address, Command, CrcMode, Decoded, EncodeError, Message, MessageScanner, Reply, ReplyBody, ShortCode,
};
use motus_serial::{BusError, BusMaster, Request};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

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
         the arm's communication modules, then enable the joint again"
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

/// How often a thread waiting for its turn on the line looks again.
const TURN_POLL: Duration = Duration::from_micros(250);

/// Turns on the line, first come first served: the control thread's cycle and the calls
/// of the arm's API (EN, D1, D4...) take turns.
///
/// A thread waits for its turn by sleeping on the bus master's clock in short steps
/// ([`TURN_POLL`]) instead of blocking on a lock: on a threaded virtual clock a thread
/// blocked on another one must be marked so ([`motus_clock::while_blocked`]), and that
/// mark is lifted only once the woken thread runs again, so the clock could move time
/// meanwhile for a thread that is about to run (the control thread's keep-alive would
/// then miss whole cycles of virtual time). A sleeping waiter always holds time back.
#[derive(Debug, Default)]
struct Turns {
    /// The next ticket to hand out.
    next: AtomicU64,
    /// The ticket whose turn it is.
    serving: AtomicU64,
}

/// A turn on the line, given back when dropped.
struct Turn<'a>(&'a Turns);

impl Turns {
    /// Waits (on `clock`) for a turn on the line.
    fn take(&self, clock: &dyn Clock) -> Turn<'_> {
        let ticket = self.next.fetch_add(1, Ordering::AcqRel);
        while self.serving.load(Ordering::Acquire) != ticket {
            clock.sleep(TURN_POLL);
        }
        Turn(self)
    }
}

impl Drop for Turn<'_> {
    fn drop(&mut self) {
        self.0.serving.fetch_add(1, Ordering::AcqRel);
    }
}

/// The KV-01 protocol on one line.
#[derive(Clone)]
pub struct Kv01Bus {
    master: Arc<BusMaster>,
    crc: CrcMode,
    turns: Arc<Turns>,
}

impl Kv01Bus {
    /// KV-01 on `master`, checking reply CRCs in `crc` mode (strict by default; lenient
    /// accepts and logs a mismatch, for arms whose firmware differs from the publication).
    /// Transactions (of every clone) take turns on the line, waiting on the master's clock.
    pub fn new(master: Arc<BusMaster>, crc: CrcMode) -> Self {
        Kv01Bus { master, crc, turns: Arc::default() }
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
        let turn = self.turns.take(&**self.master.clock());
        let decoded = self.master.transact(
            &request,
            &MessageScanner::replies(self.crc),
            |d: &Decoded| matches!(&d.message, Message::Reply(Reply { address, .. }) if *address == addr),
        );
        drop(turn);
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
