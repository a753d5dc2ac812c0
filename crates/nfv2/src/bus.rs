//! NFv2 exchanges on a shared half-duplex bus master: one frame out, the addressed
//! slave's answer back (if the frame carries a query it answers).
//!
//! The 1209A answers only queries; a frame of set-points alone gets no answer. The
//! [`BusMaster`] has no send-only call, so such a frame is sent as a transaction that
//! waits for nothing and ends at its time-out (wire time + margin); the master counts
//! that as a time-out in its own statistics. The scheduler never sends such frames in
//! packed mode (every frame carries queries).

use std::collections::BTreeMap;
use std::sync::Arc;

use motus_nfv2_protocol::{DeviceProfile, Frame, FrameScanner, Revision};
use motus_serial::{BusConfig, BusError, BusMaster, Request, SerialLink, Traced};

use crate::error::Nfv2Error;
use crate::framing::AnswerShape;

/// Answer length assumed for a raw query the device profile does not know.
const UNKNOWN_ANSWER_LEN: usize = 64;

/// The NFv2 protocol on one line: per-address protocol revisions and the device profile
/// (what each slave answers).
#[derive(Clone)]
pub struct Nfv2Bus {
    master: Arc<BusMaster>,
    default_revision: Revision,
    revisions: BTreeMap<u8, Revision>,
    profile: DeviceProfile,
}

/// One exchange: the answer (if one was expected) and the bytes it put on the wire.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Exchanged {
    /// The answer, `None` if the frame asked for none.
    pub answer: Option<Frame>,
    /// Request bytes.
    pub sent: usize,
    /// Answer bytes (0 without an answer).
    pub received: usize,
}

impl Nfv2Bus {
    /// NFv2 on `master`: latest revision, 1209A slaves.
    #[must_use]
    pub fn new(master: Arc<BusMaster>) -> Self {
        Nfv2Bus {
            master,
            default_revision: Revision::LATEST,
            revisions: BTreeMap::new(),
            profile: DeviceProfile::axis_1209a(),
        }
    }

    /// Opens the serial port at `path` (a real port or a simulator's pty link) at `baud`,
    /// 8N1, with hex tracing at TRACE level.
    ///
    /// # Errors
    /// [`Nfv2Error::Open`] if the port cannot be opened.
    pub fn open(path: &str, baud: u32, config: BusConfig) -> Result<Self, Nfv2Error> {
        let link = SerialLink::open(path, baud)
            .map_err(|e| Nfv2Error::Open { path: path.to_string(), reason: e.to_string() })?;
        Ok(Self::new(Arc::new(BusMaster::new(Box::new(Traced::new(link)), config))))
    }

    /// Uses `rev` for every slave without its own revision.
    #[must_use]
    pub fn with_default_revision(mut self, rev: Revision) -> Self {
        self.default_revision = rev;
        self
    }

    /// Uses `rev` for the slave at `address`.
    #[must_use]
    pub fn with_revision(mut self, address: u8, rev: Revision) -> Self {
        self.revisions.insert(address, rev);
        self
    }

    /// Uses `profile` for what slaves answer (default: the 1209A).
    #[must_use]
    pub fn with_profile(mut self, profile: DeviceProfile) -> Self {
        self.profile = profile;
        self
    }

    /// The revision of the slave at `address`.
    #[must_use]
    pub fn revision(&self, address: u8) -> Revision {
        self.revisions.get(&address).copied().unwrap_or(self.default_revision)
    }

    /// What the slaves answer.
    #[must_use]
    pub fn profile(&self) -> &DeviceProfile {
        &self.profile
    }

    /// The bus master (statistics, line settings).
    #[must_use]
    pub fn master(&self) -> &Arc<BusMaster> {
        &self.master
    }

    /// Sends any frame and returns the slave's answer: `Ok(None)` when the frame carries
    /// no query, after the line time of the frame. A query for a code the profile does
    /// not know is still awaited (any answer from the address carrying only queried codes
    /// is accepted). This is what `motus nfv2 <port> raw '<json>'` uses.
    ///
    /// # Errors
    /// [`Nfv2Error::Encode`] for a frame the slave's revision cannot carry,
    /// [`Nfv2Error::Bus`] when an expected answer does not come.
    pub fn transact(&self, frame: &Frame) -> Result<Option<Frame>, Nfv2Error> {
        self.exchange(frame, true).map(|e| e.answer)
    }

    /// One exchange. Without retries when `idempotent` is false (the scheduler's cyclic
    /// frames: a retry would only delay the next cycle, which carries fresher values).
    pub(crate) fn exchange(&self, frame: &Frame, idempotent: bool) -> Result<Exchanged, Nfv2Error> {
        let rev = self.revision(frame.address);
        let bytes = frame.encode(rev)?;
        let shape = AnswerShape::of(frame, &self.profile, rev);
        let queried: Vec<_> = frame.queries().collect();
        let reply_len = match &shape {
            Some(_) => self.profile.answer_len(frame, rev).unwrap_or(0),
            None if !queried.is_empty() => UNKNOWN_ANSWER_LEN,
            None => 0,
        };
        let request = Request { device: u32::from(frame.address), bytes: &bytes, reply_len, idempotent };
        let address = frame.address;
        let accept = |answer: &Frame| match &shape {
            Some(shape) => shape.matches(answer),
            None => {
                answer.address == address
                    && !answer.commands.is_empty()
                    && answer.commands.iter().all(|c| !c.is_query() && queried.contains(&c.code()))
            }
        };
        match self.master.transact(&request, &FrameScanner::new(rev), accept) {
            Ok(answer) => {
                let received = answer.encoded_len(rev).unwrap_or(reply_len);
                Ok(Exchanged { answer: Some(answer), sent: bytes.len(), received })
            }
            Err(BusError::Timeout { .. }) if queried.is_empty() => {
                Ok(Exchanged { answer: None, sent: bytes.len(), received: 0 })
            }
            Err(e) => Err(Nfv2Error::Bus(e)),
        }
    }
}
