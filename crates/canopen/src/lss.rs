//! LSS master (CiA 305) as sans-IO pieces: request frames, reply matching, result
//! checks, the bit-timing table and the FASTSCAN search machine.

use std::time::{Duration, Instant};

use motus_canopen_protocol::message::LSS_MASTER_TO_SLAVE;
use motus_canopen_protocol::{CanFrame, EncodeError, LssIdentityField, LssRequest, LssResponse};

/// The 128-bit LSS address (object 0x1018 sub 1–4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct LssIdentity {
    /// Vendor-ID.
    pub vendor: u32,
    /// Product code.
    pub product: u32,
    /// Revision number.
    pub revision: u32,
    /// Serial number.
    pub serial: u32,
}

impl LssIdentity {
    /// The four parts in LSS order (vendor, product, revision, serial).
    pub fn parts(&self) -> [u32; 4] {
        [self.vendor, self.product, self.revision, self.serial]
    }
}

impl std::fmt::Display for LssIdentity {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "vendor 0x{:08X} product 0x{:08X} revision 0x{:08X} serial 0x{:08X}",
            self.vendor, self.product, self.revision, self.serial
        )
    }
}

/// LSS state of the slaves (switch state global).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LssMode {
    /// Waiting state (normal operation).
    Waiting,
    /// Configuration state.
    Configuration,
}

/// LSS failures.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum LssError {
    /// The slave answered with a non-zero error code.
    #[error("LSS {service} refused by the slave: error {error} (manufacturer error {spec_error})")]
    Refused {
        /// The service ("configure node-ID", ...).
        service: &'static str,
        /// Error code (1 = out of range / not supported, 0xFF = manufacturer specific).
        error: u8,
        /// Manufacturer-specific error.
        spec_error: u8,
    },
    /// No slave answered in time.
    #[error("LSS {service}: no answer within {timeout:?}")]
    Timeout {
        /// The service.
        service: &'static str,
        /// The time-out.
        timeout: Duration,
    },
    /// Bit rate not in the CiA 305 standard table.
    #[error("bit rate {0} bit/s is not in the CiA 305 table")]
    UnsupportedBitRate(u32),
    /// Node id outside 1..=127 and not 0xFF.
    #[error("invalid LSS node id {0} (want 1..=127 or 255)")]
    InvalidNodeId(u8),
    /// The request could not be encoded (our own misuse).
    #[error("LSS request cannot be encoded: {0}")]
    Encode(#[from] EncodeError),
}

/// CiA 305 standard bit-timing table: (index, bit/s). Index 5 is reserved.
pub const BIT_TIMING_TABLE: [(u8, u32); 8] = [
    (0, 1_000_000),
    (1, 800_000),
    (2, 500_000),
    (3, 250_000),
    (4, 125_000),
    (6, 50_000),
    (7, 20_000),
    (8, 10_000),
];

/// The table index of a bit rate (`None` if not in the standard table).
pub fn bit_timing_index(bitrate: u32) -> Option<u8> {
    BIT_TIMING_TABLE.iter().find(|(_, b)| *b == bitrate).map(|(i, _)| *i)
}

/// The frame (COB-ID 0x7E5) of a request.
pub fn request_frame(req: &LssRequest) -> Result<CanFrame, LssError> {
    Ok(CanFrame::new(LSS_MASTER_TO_SLAVE, &req.encode()?).map_err(EncodeError::from)?)
}

/// The four switch-state-selective requests (cs 0x40..0x43) for `id`.
pub fn switch_selective(id: &LssIdentity) -> [LssRequest; 4] {
    [
        LssRequest::SwitchStateSelective { field: LssIdentityField::Vendor, value: id.vendor },
        LssRequest::SwitchStateSelective { field: LssIdentityField::Product, value: id.product },
        LssRequest::SwitchStateSelective { field: LssIdentityField::Revision, value: id.revision },
        LssRequest::SwitchStateSelective { field: LssIdentityField::Serial, value: id.serial },
    ]
}

/// The configure-node-ID request, checked (1..=127 or 0xFF).
pub fn configure_node_id(node_id: u8) -> Result<LssRequest, LssError> {
    if (1..=127).contains(&node_id) || node_id == 0xFF {
        Ok(LssRequest::ConfigureNodeId { node_id })
    } else {
        Err(LssError::InvalidNodeId(node_id))
    }
}

/// The configure-bit-timing request for a bit rate (standard table).
pub fn configure_bit_timing(bitrate: u32) -> Result<LssRequest, LssError> {
    let index = bit_timing_index(bitrate).ok_or(LssError::UnsupportedBitRate(bitrate))?;
    Ok(LssRequest::ConfigureBitTiming { table: 0, index })
}

/// Whether `resp` is the answer to `req` (`false` for requests without an answer).
pub fn answers(req: &LssRequest, resp: &LssResponse) -> bool {
    use LssRequest as Q;
    use LssResponse as R;
    match (req, resp) {
        (Q::SwitchStateSelective { field: LssIdentityField::Serial, .. }, R::SwitchStateSelective) => true,
        (Q::ConfigureNodeId { .. }, R::ConfigureNodeId { .. }) => true,
        (Q::ConfigureBitTiming { .. }, R::ConfigureBitTiming { .. }) => true,
        (Q::StoreConfiguration, R::StoreConfiguration { .. }) => true,
        (Q::InquireIdentity { field: a }, R::InquireIdentity { field: b, .. }) => a == b,
        (Q::InquireNodeId, R::InquireNodeId { .. }) => true,
        (Q::Fastscan { .. } | Q::IdentifyRemoteSlave { selector: 5, .. }, R::IdentifySlave) => true,
        (Q::IdentifyNonConfigured, R::IdentifyNonConfiguredSlave) => true,
        _ => false,
    }
}

/// Checks the error byte of a configuration reply (node-ID, bit timing, store).
pub fn check_result(resp: &LssResponse) -> Result<(), LssError> {
    let (service, error, spec_error) = match *resp {
        LssResponse::ConfigureNodeId { error, spec_error } => ("configure node-ID", error, spec_error),
        LssResponse::ConfigureBitTiming { error, spec_error } => ("configure bit timing", error, spec_error),
        LssResponse::StoreConfiguration { error, spec_error } => ("store configuration", error, spec_error),
        _ => return Ok(()),
    };
    if error == 0 {
        Ok(())
    } else {
        Err(LssError::Refused { service, error, spec_error })
    }
}

/// BitCheck value of the first fastscan request ("is any unconfigured slave there?").
pub const FASTSCAN_CONFIRM: u8 = 0x80;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    Probe,
    Bit(u8),
    Confirm,
    Done,
}

/// What the caller must do next in a fastscan.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum FastscanStep {
    /// Keep waiting (for a reply or the step deadline).
    Wait,
    /// Send this frame.
    Send(CanFrame),
    /// Finished: the identity found, or `None` if no unconfigured slave answered
    /// (or the slave stopped answering during the confirmation of a part).
    Done(Option<LssIdentity>),
}

/// The CiA 305 FASTSCAN search: for each part (vendor, product, revision, serial) and each
/// bit from 31 down to 0, a 0x51 request with the bit guessed 0; a 0x4F reply within the
/// step time-out confirms the guess, silence means the bit is 1. Each part is then
/// confirmed with BitCheck 0 and LSSNext = next part; after the serial number the slave
/// is in configuration state.
#[derive(Debug, Clone)]
pub struct Fastscan {
    id: [u32; 4],
    sub: u8,
    phase: Phase,
    step_timeout: Duration,
    deadline: Instant,
}

impl Fastscan {
    /// Starts a scan; returns the machine and the first frame (BitCheck 0x80).
    pub fn start(now: Instant, step_timeout: Duration) -> Result<(Self, CanFrame), LssError> {
        let mut s = Self { id: [0; 4], sub: 0, phase: Phase::Probe, step_timeout, deadline: now };
        let frame = s.frame(0, FASTSCAN_CONFIRM, 0, now)?;
        Ok((s, frame))
    }

    /// The step deadline (None once done).
    pub fn deadline(&self) -> Option<Instant> {
        (self.phase != Phase::Done).then_some(self.deadline)
    }

    fn frame(
        &mut self,
        id_number: u32,
        bit_check: u8,
        lss_next: u8,
        now: Instant,
    ) -> Result<CanFrame, LssError> {
        self.deadline = now + self.step_timeout;
        request_frame(&LssRequest::Fastscan { id_number, bit_check, lss_sub: self.sub, lss_next })
    }

    fn part(&self) -> u32 {
        self.id.get(usize::from(self.sub)).copied().unwrap_or(0)
    }

    fn send(&mut self, bit_check: u8, lss_next: u8, now: Instant) -> FastscanStep {
        match self.frame(self.part(), bit_check, lss_next, now) {
            Ok(f) => FastscanStep::Send(f),
            Err(_) => self.finish(None),
        }
    }

    fn finish(&mut self, id: Option<LssIdentity>) -> FastscanStep {
        self.phase = Phase::Done;
        FastscanStep::Done(id)
    }

    /// Feeds a received LSS response; only "identify slave" (0x4F) counts.
    pub fn on_response(&mut self, resp: &LssResponse, now: Instant) -> FastscanStep {
        if *resp != LssResponse::IdentifySlave || self.phase == Phase::Done {
            return FastscanStep::Wait;
        }
        self.advance(true, now)
    }

    /// Checks the step deadline: silence past it is a "no" for the current step.
    pub fn poll(&mut self, now: Instant) -> FastscanStep {
        if self.phase == Phase::Done || now < self.deadline {
            return FastscanStep::Wait;
        }
        self.advance(false, now)
    }

    fn advance(&mut self, replied: bool, now: Instant) -> FastscanStep {
        match self.phase {
            Phase::Done => FastscanStep::Wait,
            Phase::Probe => {
                if !replied {
                    return self.finish(None);
                }
                self.phase = Phase::Bit(31);
                self.send(31, self.sub, now)
            }
            Phase::Bit(b) => {
                if !replied {
                    if let Some(p) = self.id.get_mut(usize::from(self.sub)) {
                        *p |= 1 << b;
                    }
                }
                if b > 0 {
                    self.phase = Phase::Bit(b - 1);
                    self.send(b - 1, self.sub, now)
                } else {
                    self.phase = Phase::Confirm;
                    self.send(0, (self.sub + 1) & 3, now)
                }
            }
            Phase::Confirm => {
                if !replied {
                    return self.finish(None);
                }
                if self.sub == 3 {
                    let [vendor, product, revision, serial] = self.id;
                    return self.finish(Some(LssIdentity { vendor, product, revision, serial }));
                }
                self.sub += 1;
                self.phase = Phase::Bit(31);
                self.send(31, self.sub, now)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn bit_timing_table() {
        // specs/canopen.md Part 4 table: 20 kbit/s = index 7, 1 Mbit/s = 0; 100 kbit/s not standard.
        assert_eq!(bit_timing_index(20_000), Some(7));
        assert_eq!(bit_timing_index(1_000_000), Some(0));
        assert_eq!(bit_timing_index(100_000), None);
        // The seed's 20 kbit/s sequence: 7E5 13 00 07.
        let f = request_frame(&configure_bit_timing(20_000).unwrap()).unwrap();
        assert_eq!(f.to_string(), "7E5#1300070000000000");
        assert_eq!(configure_node_id(0), Err(LssError::InvalidNodeId(0)));
        assert_eq!(
            request_frame(&configure_node_id(2).unwrap()).unwrap().to_string(),
            "7E5#1102000000000000"
        );
    }

    #[test]
    fn result_checks() {
        assert!(check_result(&LssResponse::StoreConfiguration { error: 0, spec_error: 0 }).is_ok());
        assert_eq!(
            check_result(&LssResponse::ConfigureBitTiming { error: 1, spec_error: 0 }),
            Err(LssError::Refused { service: "configure bit timing", error: 1, spec_error: 0 })
        );
        assert!(answers(&LssRequest::InquireNodeId, &LssResponse::InquireNodeId { node_id: 3 }));
        assert!(!answers(&LssRequest::InquireNodeId, &LssResponse::IdentifySlave));
    }

    /// A fastscan slave per CiA 305 written independently of the master: answers 0x4F when
    /// bits BitCheck..31 of IDNumber equal its part at LSSPos; BitCheck 0x80 resets.
    struct Slave {
        id: [u32; 4],
        pos: u8,
        configured: bool,
    }
    impl Slave {
        fn on(&mut self, f: &CanFrame) -> bool {
            let d = f.data();
            assert_eq!(f.id(), 0x7E5);
            assert_eq!(d[0], 0x51);
            let idn = u32::from_le_bytes([d[1], d[2], d[3], d[4]]);
            let (bit, sub, next) = (d[5], d[6], d[7]);
            if bit == 0x80 {
                self.pos = 0;
                return true;
            }
            if sub != self.pos || (idn ^ self.id[sub as usize]) >> bit != 0 {
                return false;
            }
            if bit == 0 {
                if next < self.pos {
                    self.configured = true;
                }
                self.pos = next;
            }
            true
        }
    }

    #[test]
    fn fastscan_finds_the_identity() {
        let ident = [0x0000_0123, 0x0000_0402, 0x0001_0000, 0xDEAD_CAFE];
        let mut slave = Slave { id: ident, pos: 0, configured: false };
        let step = Duration::from_millis(10);
        let mut now = Instant::now();
        let (mut scan, mut frame) = Fastscan::start(now, step).unwrap();
        // First frame: 51, IDNumber 0, BitCheck 0x80, sub 0, next 0.
        assert_eq!(frame.to_string(), "7E5#5100000000800000");
        let mut frames = 1;
        let result = loop {
            let s = if slave.on(&frame) {
                scan.on_response(&LssResponse::IdentifySlave, now)
            } else {
                now += step;
                scan.poll(now)
            };
            match s {
                FastscanStep::Send(f) => {
                    frame = f;
                    frames += 1;
                }
                FastscanStep::Done(r) => break r,
                FastscanStep::Wait => panic!("stalled"),
            }
        };
        assert_eq!(result.map(|i| i.parts()), Some(ident));
        assert!(slave.configured);
        // 1 probe + 4 parts × (32 bits + 1 confirmation).
        assert_eq!(frames, 1 + 4 * 33);
    }

    #[test]
    fn fastscan_without_slaves_ends_after_the_probe() {
        let t0 = Instant::now();
        let (mut scan, _) = Fastscan::start(t0, Duration::from_millis(10)).unwrap();
        assert_eq!(scan.poll(t0 + Duration::from_millis(5)), FastscanStep::Wait);
        assert_eq!(scan.poll(t0 + Duration::from_millis(10)), FastscanStep::Done(None));
    }
}
