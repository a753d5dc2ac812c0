//! Typed parameters: command 1's parameter block, command 2's control byte, and the
//! acceleration number, DDA cycle and baud-rate codes.

use crate::error::DecodeError;
use crate::values::U24;
use serde::{Deserialize, Serialize};
use std::time::Duration;

/// Acceleration number 1..=10 (commands 1 and 3). See [`crate::units`] for its meaning.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(try_from = "u8", into = "u8")]
pub struct Acceleration(u8);

impl Acceleration {
    /// The smallest acceleration number.
    pub const MIN: Acceleration = Acceleration(1);
    /// The largest acceleration number.
    pub const MAX: Acceleration = Acceleration(10);

    /// `Some` for 1..=10.
    pub const fn new(n: u8) -> Option<Acceleration> {
        if n >= 1 && n <= 10 {
            Some(Acceleration(n))
        } else {
            None
        }
    }

    /// The number.
    pub const fn get(self) -> u8 {
        self.0
    }

    pub(crate) fn decode(name: &'static str, v: u8) -> Result<Acceleration, DecodeError> {
        Acceleration::new(v).ok_or(DecodeError::InvalidParameter {
            name,
            value: u32::from(v),
            reason: "acceleration number must be 1..=10",
        })
    }
}

impl TryFrom<u8> for Acceleration {
    type Error = String;
    fn try_from(v: u8) -> Result<Self, Self::Error> {
        Acceleration::new(v).ok_or_else(|| format!("acceleration number {v} is outside 1..=10"))
    }
}

impl From<Acceleration> for u8 {
    fn from(a: Acceleration) -> u8 {
        a.0
    }
}

/// DDA cycle (parameter TVZ): 0 = 1.54 ms, 1 = 2.1 ms, 2 = 2.66 ms, 3 = 4.2 ms.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(try_from = "u8", into = "u8")]
pub enum DdaCycle {
    /// TVZ 0: 1.54 ms (default).
    #[default]
    Ms1_54,
    /// TVZ 1: 2.1 ms.
    Ms2_10,
    /// TVZ 2: 2.66 ms.
    Ms2_66,
    /// TVZ 3: 4.2 ms.
    Ms4_20,
}

impl DdaCycle {
    /// The TVZ code.
    pub fn code(self) -> u8 {
        match self {
            DdaCycle::Ms1_54 => 0,
            DdaCycle::Ms2_10 => 1,
            DdaCycle::Ms2_66 => 2,
            DdaCycle::Ms4_20 => 3,
        }
    }

    /// The cycle for a TVZ code.
    pub fn from_code(code: u8) -> Option<DdaCycle> {
        match code {
            0 => Some(DdaCycle::Ms1_54),
            1 => Some(DdaCycle::Ms2_10),
            2 => Some(DdaCycle::Ms2_66),
            3 => Some(DdaCycle::Ms4_20),
            _ => None,
        }
    }

    /// The period in seconds.
    pub fn seconds(self) -> f64 {
        match self {
            DdaCycle::Ms1_54 => 1.54e-3,
            DdaCycle::Ms2_10 => 2.10e-3,
            DdaCycle::Ms2_66 => 2.66e-3,
            DdaCycle::Ms4_20 => 4.20e-3,
        }
    }

    /// The period.
    pub fn period(self) -> Duration {
        Duration::from_micros(match self {
            DdaCycle::Ms1_54 => 1540,
            DdaCycle::Ms2_10 => 2100,
            DdaCycle::Ms2_66 => 2660,
            DdaCycle::Ms4_20 => 4200,
        })
    }
}

impl TryFrom<u8> for DdaCycle {
    type Error = String;
    fn try_from(v: u8) -> Result<Self, Self::Error> {
        DdaCycle::from_code(v).ok_or_else(|| format!("TVZ code {v} is outside 0..=3"))
    }
}

impl From<DdaCycle> for u8 {
    fn from(c: DdaCycle) -> u8 {
        c.code()
    }
}

/// Baud-rate code (parameter COMS): 0 = 9600, 1 = 19200, 2 = 29070, 3 = 33784 Bd.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(try_from = "u8", into = "u8")]
pub enum BaudRate {
    /// COMS 0: 9600 Bd (default).
    #[default]
    B9600,
    /// COMS 1: 19200 Bd.
    B19200,
    /// COMS 2: 29070 Bd (non-standard).
    B29070,
    /// COMS 3: 33784 Bd (non-standard).
    B33784,
}

impl BaudRate {
    /// The COMS code.
    pub fn code(self) -> u8 {
        match self {
            BaudRate::B9600 => 0,
            BaudRate::B19200 => 1,
            BaudRate::B29070 => 2,
            BaudRate::B33784 => 3,
        }
    }

    /// The rate for a COMS code.
    pub fn from_code(code: u8) -> Option<BaudRate> {
        match code {
            0 => Some(BaudRate::B9600),
            1 => Some(BaudRate::B19200),
            2 => Some(BaudRate::B29070),
            3 => Some(BaudRate::B33784),
            _ => None,
        }
    }

    /// The code for a rate in Bd, if the module supports it.
    pub fn from_bps(bps: u32) -> Option<BaudRate> {
        [BaudRate::B9600, BaudRate::B19200, BaudRate::B29070, BaudRate::B33784]
            .into_iter()
            .find(|b| b.bps() == bps)
    }

    /// Bits per second.
    pub fn bps(self) -> u32 {
        match self {
            BaudRate::B9600 => 9600,
            BaudRate::B19200 => 19200,
            BaudRate::B29070 => 29070,
            BaudRate::B33784 => 33784,
        }
    }
}

impl TryFrom<u8> for BaudRate {
    type Error = String;
    fn try_from(v: u8) -> Result<Self, Self::Error> {
        BaudRate::from_code(v).ok_or_else(|| format!("COMS code {v} is outside 0..=3"))
    }
}

impl From<BaudRate> for u8 {
    fn from(b: BaudRate) -> u8 {
        b.code()
    }
}

/// The parameter block of command 1, stored in the module's EEPROM.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Parameters {
    /// ADR: the module's new address.
    pub address: u8,
    /// DS: fraction (x/256) of an encoder unit travelled per DDA cycle at unit speed.
    pub ds: u8,
    /// TVZ: DDA cycle.
    pub tvz: DdaCycle,
    /// COMS: baud rate.
    pub coms: BaudRate,
    /// B1MXP..B3MXP: maximum distance from zero, in encoder units.
    pub max_position: U24,
    /// VNRB: reference-switch approach speed (speed units).
    pub vnrb: u8,
    /// ANRB: reference-switch approach acceleration number.
    pub anrb: Acceleration,
    /// VNNB: encoder-zero approach speed (speed units).
    pub vnnb: u8,
    /// ANNB: encoder-zero approach acceleration number.
    pub annb: Acceleration,
}

impl Default for Parameters {
    /// The factory defaults of the spec.
    fn default() -> Self {
        Parameters {
            address: 0,
            ds: 39,
            tvz: DdaCycle::Ms1_54,
            coms: BaudRate::B9600,
            max_position: U24::DEFAULT_MAX_POSITION,
            vnrb: 10,
            anrb: Acceleration(8),
            vnnb: 5,
            annb: Acceleration(8),
        }
    }
}

impl Parameters {
    /// Number of parameter bytes on the wire.
    pub const LEN: usize = 11;

    /// The 11 parameter bytes in wire order.
    pub fn to_bytes(&self) -> [u8; 11] {
        let [m1, m2, m3] = self.max_position.to_le();
        [
            self.address,
            self.ds,
            self.tvz.code(),
            self.coms.code(),
            m1,
            m2,
            m3,
            self.vnrb,
            self.anrb.get(),
            self.vnnb,
            self.annb.get(),
        ]
    }

    /// Parses the 11 parameter bytes, validating every coded field.
    pub fn from_bytes(b: [u8; 11]) -> Result<Parameters, DecodeError> {
        let [address, ds, tvz, coms, m1, m2, m3, vnrb, anrb, vnnb, annb] = b;
        Ok(Parameters {
            address,
            ds,
            tvz: DdaCycle::from_code(tvz).ok_or(DecodeError::InvalidParameter {
                name: "TVZ",
                value: u32::from(tvz),
                reason: "DDA cycle code must be 0..=3",
            })?,
            coms: BaudRate::from_code(coms).ok_or(DecodeError::InvalidParameter {
                name: "COMS",
                value: u32::from(coms),
                reason: "baud-rate code must be 0..=3",
            })?,
            max_position: U24::from_le([m1, m2, m3]),
            vnrb,
            anrb: Acceleration::decode("ANRB", anrb)?,
            vnnb,
            annb: Acceleration::decode("ANNB", annb)?,
        })
    }
}

/// Command 2's byte: D0 power stage on, D1 interpolation blocking on following error,
/// D2 run reference-switch approach, D3 run encoder-zero approach. Bits 4-7 are not
/// defined by the source; they are kept as received.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(try_from = "ControlByteJson", into = "ControlByteJson")]
pub struct ControlByte(pub u8);

impl ControlByte {
    /// D0: binary output OSON (power stage on).
    pub const POWER_STAGE: u8 = 1 << 0;
    /// D1: block interpolation while the following error exceeds +-1024 units.
    pub const INTERPOLATION_BLOCKING: u8 = 1 << 1;
    /// D2: run the reference-switch approach.
    pub const REFERENCE_APPROACH: u8 = 1 << 2;
    /// D3: run the encoder-zero approach.
    pub const ENCODER_ZERO_APPROACH: u8 = 1 << 3;

    /// D0.
    pub fn power_stage(self) -> bool {
        self.0 & Self::POWER_STAGE != 0
    }
    /// D1.
    pub fn interpolation_blocking(self) -> bool {
        self.0 & Self::INTERPOLATION_BLOCKING != 0
    }
    /// D2.
    pub fn reference_approach(self) -> bool {
        self.0 & Self::REFERENCE_APPROACH != 0
    }
    /// D3.
    pub fn encoder_zero_approach(self) -> bool {
        self.0 & Self::ENCODER_ZERO_APPROACH != 0
    }
}

/// JSON form of [`ControlByte`]: the raw byte plus named bits (all optional on input; the
/// named bits, when given, must agree with the raw byte).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ControlByteJson {
    #[serde(default)]
    raw: Option<u8>,
    #[serde(default)]
    power_stage: Option<bool>,
    #[serde(default)]
    interpolation_blocking: Option<bool>,
    #[serde(default)]
    reference_approach: Option<bool>,
    #[serde(default)]
    encoder_zero_approach: Option<bool>,
}

impl From<ControlByte> for ControlByteJson {
    fn from(c: ControlByte) -> Self {
        ControlByteJson {
            raw: Some(c.0),
            power_stage: Some(c.power_stage()),
            interpolation_blocking: Some(c.interpolation_blocking()),
            reference_approach: Some(c.reference_approach()),
            encoder_zero_approach: Some(c.encoder_zero_approach()),
        }
    }
}

impl TryFrom<ControlByteJson> for ControlByte {
    type Error = String;
    fn try_from(j: ControlByteJson) -> Result<Self, Self::Error> {
        let bits = [
            (j.power_stage, ControlByte::POWER_STAGE, "power_stage"),
            (j.interpolation_blocking, ControlByte::INTERPOLATION_BLOCKING, "interpolation_blocking"),
            (j.reference_approach, ControlByte::REFERENCE_APPROACH, "reference_approach"),
            (j.encoder_zero_approach, ControlByte::ENCODER_ZERO_APPROACH, "encoder_zero_approach"),
        ];
        let mut value = j.raw.unwrap_or(0);
        for (flag, mask, name) in bits {
            match (flag, j.raw) {
                (Some(f), Some(raw)) if f != (raw & mask != 0) => {
                    return Err(format!("control byte: {name} = {f} contradicts raw = 0x{raw:02X}"))
                }
                (Some(true), None) => value |= mask,
                _ => {}
            }
        }
        Ok(ControlByte(value))
    }
}
