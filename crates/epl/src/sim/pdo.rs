//! Process-data layout of the simulated drives (our own convention, little-endian).
//!
//! PReq payload (MN -> drive, [`PREQ_PAYLOAD_LEN`] bytes):
//! | offset | type | meaning |
//! |---|---|---|
//! | 0 | u16 | control word: bit 0 [`CONTROL_ENABLE`], bit 1 [`CONTROL_QUICK_STOP`] |
//! | 2 | u16 | reserved |
//! | 4 | i32 | target position (units) |
//!
//! PRes payload (drive -> all, [`PRES_PAYLOAD_LEN`] bytes), matching the juggler's Acopos
//! layout of `specs/powerlink.md` ("position at PRes payload offset 16 and speed at offset 20")
//! and `crates/epl-protocol/examples/acopos-map.toml`:
//! | offset | type | meaning |
//! |---|---|---|
//! | 0 | u16 | status word: bit 0 [`STATUS_ENABLED`], bit 1 [`STATUS_QUICK_STOP`], bit 2 [`STATUS_STANDSTILL`], bit 3 [`STATUS_LEASE_STOP`], bit 4 [`STATUS_HOMED`] |
//! | 2..16 | – | zero |
//! | 16 | i32 | actual position (units) |
//! | 20 | i32 | actual speed (units/s) |

/// PReq payload length.
pub const PREQ_PAYLOAD_LEN: usize = 8;
/// PRes payload length.
pub const PRES_PAYLOAD_LEN: usize = 24;
/// PRes payload offset of the actual position.
pub const PRES_POSITION_OFFSET: usize = 16;
/// PRes payload offset of the actual speed.
pub const PRES_SPEED_OFFSET: usize = 20;

/// Control word bit: follow the target position.
pub const CONTROL_ENABLE: u16 = 0x0001;
/// Control word bit: quick stop (brake at the braking deceleration, ignore targets).
pub const CONTROL_QUICK_STOP: u16 = 0x0002;
/// Status word bit: enabled and following.
pub const STATUS_ENABLED: u16 = 0x0001;
/// Status word bit: quick stop active.
pub const STATUS_QUICK_STOP: u16 = 0x0002;
/// Status word bit: speed is zero.
pub const STATUS_STANDSTILL: u16 = 0x0004;
/// Status word bit: stopped because the safety lease was revoked or expired.
pub const STATUS_LEASE_STOP: u16 = 0x0008;
/// Status word bit: the axis is homed (the simulated drives have absolute encoders).
pub const STATUS_HOMED: u16 = 0x0010;

/// A set-point carried in a PReq.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SetPoint {
    /// Control word.
    pub control: u16,
    /// Target position (units).
    pub target: i32,
}

impl SetPoint {
    /// Encodes the PReq payload.
    pub fn encode(&self) -> [u8; PREQ_PAYLOAD_LEN] {
        let [c0, c1] = self.control.to_le_bytes();
        let [t0, t1, t2, t3] = self.target.to_le_bytes();
        [c0, c1, 0, 0, t0, t1, t2, t3]
    }

    /// Decodes a PReq payload; `None` when it is shorter than [`PREQ_PAYLOAD_LEN`].
    pub fn decode(payload: &[u8]) -> Option<Self> {
        let c: [u8; 2] = payload.get(0..2)?.try_into().ok()?;
        let t: [u8; 4] = payload.get(4..8)?.try_into().ok()?;
        Some(Self { control: u16::from_le_bytes(c), target: i32::from_le_bytes(t) })
    }
}

/// The actual values a drive publishes in its PRes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Actual {
    /// Status word.
    pub status: u16,
    /// Actual position (units).
    pub position: i32,
    /// Actual speed (units/s).
    pub speed: i32,
}

impl Actual {
    /// Encodes the PRes payload.
    pub fn encode(&self) -> Vec<u8> {
        let mut p = vec![0u8; PRES_PAYLOAD_LEN];
        p.splice(0..2, self.status.to_le_bytes());
        p.splice(PRES_POSITION_OFFSET..PRES_POSITION_OFFSET + 4, self.position.to_le_bytes());
        p.splice(PRES_SPEED_OFFSET..PRES_SPEED_OFFSET + 4, self.speed.to_le_bytes());
        p
    }

    /// Decodes a PRes payload; `None` when it is shorter than [`PRES_PAYLOAD_LEN`].
    pub fn decode(payload: &[u8]) -> Option<Self> {
        let s: [u8; 2] = payload.get(0..2)?.try_into().ok()?;
        let p: [u8; 4] = payload.get(PRES_POSITION_OFFSET..PRES_POSITION_OFFSET + 4)?.try_into().ok()?;
        let v: [u8; 4] = payload.get(PRES_SPEED_OFFSET..PRES_SPEED_OFFSET + 4)?.try_into().ok()?;
        Some(Self {
            status: u16::from_le_bytes(s),
            position: i32::from_le_bytes(p),
            speed: i32::from_le_bytes(v),
        })
    }
}
