//! External parameters: four arrays of 100 values shared by the program and the PLC
//! (specs/cnc.md, "External parameters"; program syntax `EX<type><index>=<value>`).

use std::fmt;
use std::str::FromStr;

/// Number of values in each of the four arrays.
pub const EXT_PARAM_COUNT: usize = 100;

/// The type letter of an external parameter.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ExtType {
    /// `EXB`: int8.
    B,
    /// `EXW`: int16.
    W,
    /// `EXL`: int32.
    L,
    /// `EXF`: float32.
    F,
}

impl ExtType {
    /// The letter used in the program (`B`, `W`, `L`, `F`).
    pub fn letter(self) -> char {
        match self {
            Self::B => 'B',
            Self::W => 'W',
            Self::L => 'L',
            Self::F => 'F',
        }
    }

    /// The type from its letter (case-insensitive).
    pub fn from_letter(c: char) -> Option<Self> {
        match c.to_ascii_uppercase() {
            'B' => Some(Self::B),
            'W' => Some(Self::W),
            'L' => Some(Self::L),
            'F' => Some(Self::F),
            _ => None,
        }
    }

    /// The C-like name of the stored type.
    pub fn type_name(self) -> &'static str {
        match self {
            Self::B => "int8",
            Self::W => "int16",
            Self::L => "int32",
            Self::F => "float32",
        }
    }
}

impl fmt::Display for ExtType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.letter())
    }
}

/// A typed value read from or written to an external parameter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ExtValue {
    /// int8 (`EXB`).
    B(i8),
    /// int16 (`EXW`).
    W(i16),
    /// int32 (`EXL`).
    L(i32),
    /// float32 (`EXF`).
    F(f32),
}

impl ExtValue {
    /// The value as f64 (exact for every stored type).
    pub fn as_f64(self) -> f64 {
        match self {
            Self::B(v) => f64::from(v),
            Self::W(v) => f64::from(v),
            Self::L(v) => f64::from(v),
            Self::F(v) => f64::from(v),
        }
    }

    /// The type of the value.
    pub fn ty(self) -> ExtType {
        match self {
            Self::B(_) => ExtType::B,
            Self::W(_) => ExtType::W,
            Self::L(_) => ExtType::L,
            Self::F(_) => ExtType::F,
        }
    }
}

/// The address of one external parameter, written `EXW60` in a program.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ExtParamRef {
    /// The array.
    pub ty: ExtType,
    /// The index in the array (0..100).
    pub index: usize,
}

impl fmt::Display for ExtParamRef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "EX{}{}", self.ty.letter(), self.index)
    }
}

impl FromStr for ExtParamRef {
    type Err = ExtParamError;

    /// Parses `EXW60` (case-insensitive); the index must be in 0..100.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let bad = || ExtParamError::BadName(s.to_string());
        let rest =
            s.get(..2).filter(|p| p.eq_ignore_ascii_case("EX")).and_then(|_| s.get(2..)).ok_or_else(bad)?;
        let mut chars = rest.chars();
        let ty = chars.next().and_then(ExtType::from_letter).ok_or_else(bad)?;
        let digits = chars.as_str();
        if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
            return Err(bad());
        }
        let index: usize = digits.parse().map_err(|_| bad())?;
        if index >= EXT_PARAM_COUNT {
            return Err(ExtParamError::IndexOutOfRange { ty, index });
        }
        Ok(Self { ty, index })
    }
}

/// A refused access to an external parameter.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ExtParamError {
    /// The index is not in 0..100.
    #[error("EX{ty}{index}: index out of range (0..{EXT_PARAM_COUNT})")]
    IndexOutOfRange {
        /// The array.
        ty: ExtType,
        /// The index asked for.
        index: usize,
    },
    /// The value does not fit the array's type.
    #[error("EX{ty}{index}={value}: out of the {} range", ty.type_name())]
    ValueOutOfRange {
        /// The array.
        ty: ExtType,
        /// The index.
        index: usize,
        /// The value refused.
        value: f64,
    },
    /// An integer array was given a value with a fraction.
    #[error("EX{ty}{index}={value}: {} needs an integer", ty.type_name())]
    NotInteger {
        /// The array.
        ty: ExtType,
        /// The index.
        index: usize,
        /// The value refused.
        value: f64,
    },
    /// A parameter name that is not `EX<B|W|L|F><index>`.
    #[error("{0:?} is not an external parameter name (EX<B|W|L|F><index>)")]
    BadName(String),
}

/// The four arrays of external parameters, all zero at start.
#[derive(Debug, Clone, PartialEq)]
pub struct ExternalParameters {
    b: [i8; EXT_PARAM_COUNT],
    w: [i16; EXT_PARAM_COUNT],
    l: [i32; EXT_PARAM_COUNT],
    f: [f32; EXT_PARAM_COUNT],
}

impl Default for ExternalParameters {
    fn default() -> Self {
        Self::new()
    }
}

fn slot<T>(arr: &mut [T], ty: ExtType, index: usize) -> Result<&mut T, ExtParamError> {
    arr.get_mut(index).ok_or(ExtParamError::IndexOutOfRange { ty, index })
}

fn read<T: Copy>(arr: &[T], ty: ExtType, index: usize) -> Result<T, ExtParamError> {
    arr.get(index).copied().ok_or(ExtParamError::IndexOutOfRange { ty, index })
}

impl ExternalParameters {
    /// Every value zero.
    pub fn new() -> Self {
        Self {
            b: [0; EXT_PARAM_COUNT],
            w: [0; EXT_PARAM_COUNT],
            l: [0; EXT_PARAM_COUNT],
            f: [0.0; EXT_PARAM_COUNT],
        }
    }

    /// Program side: `EX<ty><index>=<value>`, with the value as the program computed it.
    /// Integer arrays need an integer in their type's range; `F` needs a finite value in
    /// the f32 range (rounded to the nearest f32). Returns the stored value.
    pub fn set(&mut self, ty: ExtType, index: usize, value: f64) -> Result<ExtValue, ExtParamError> {
        if index >= EXT_PARAM_COUNT {
            return Err(ExtParamError::IndexOutOfRange { ty, index });
        }
        let out_of_range = ExtParamError::ValueOutOfRange { ty, index, value };
        if !value.is_finite() {
            return Err(out_of_range);
        }
        if ty != ExtType::F && value.fract() != 0.0 {
            return Err(ExtParamError::NotInteger { ty, index, value });
        }
        let (lo, hi) = match ty {
            ExtType::B => (f64::from(i8::MIN), f64::from(i8::MAX)),
            ExtType::W => (f64::from(i16::MIN), f64::from(i16::MAX)),
            ExtType::L => (f64::from(i32::MIN), f64::from(i32::MAX)),
            ExtType::F => (f64::from(f32::MIN), f64::from(f32::MAX)),
        };
        if value < lo || value > hi {
            return Err(out_of_range);
        }
        // The range checks above make every cast below exact (integers) or a rounding to
        // the nearest f32 inside its range.
        let stored = match ty {
            ExtType::B => ExtValue::B(value as i8),
            ExtType::W => ExtValue::W(value as i16),
            ExtType::L => ExtValue::L(value as i32),
            ExtType::F => ExtValue::F(value as f32),
        };
        self.store(index, stored)?;
        Ok(stored)
    }

    /// Stores a typed value.
    pub fn store(&mut self, index: usize, value: ExtValue) -> Result<(), ExtParamError> {
        match value {
            ExtValue::B(v) => *slot(&mut self.b, ExtType::B, index)? = v,
            ExtValue::W(v) => *slot(&mut self.w, ExtType::W, index)? = v,
            ExtValue::L(v) => *slot(&mut self.l, ExtType::L, index)? = v,
            ExtValue::F(v) => *slot(&mut self.f, ExtType::F, index)? = v,
        }
        Ok(())
    }

    /// Reads one value, typed.
    pub fn get(&self, ty: ExtType, index: usize) -> Result<ExtValue, ExtParamError> {
        Ok(match ty {
            ExtType::B => ExtValue::B(self.get_b(index)?),
            ExtType::W => ExtValue::W(self.get_w(index)?),
            ExtType::L => ExtValue::L(self.get_l(index)?),
            ExtType::F => ExtValue::F(self.get_f(index)?),
        })
    }

    /// `EXB[index]`.
    pub fn get_b(&self, index: usize) -> Result<i8, ExtParamError> {
        read(&self.b, ExtType::B, index)
    }
    /// `EXW[index]`.
    pub fn get_w(&self, index: usize) -> Result<i16, ExtParamError> {
        read(&self.w, ExtType::W, index)
    }
    /// `EXL[index]`.
    pub fn get_l(&self, index: usize) -> Result<i32, ExtParamError> {
        read(&self.l, ExtType::L, index)
    }
    /// `EXF[index]`.
    pub fn get_f(&self, index: usize) -> Result<f32, ExtParamError> {
        read(&self.f, ExtType::F, index)
    }
    /// Sets `EXB[index]`.
    pub fn set_b(&mut self, index: usize, v: i8) -> Result<(), ExtParamError> {
        self.store(index, ExtValue::B(v))
    }
    /// Sets `EXW[index]`.
    pub fn set_w(&mut self, index: usize, v: i16) -> Result<(), ExtParamError> {
        self.store(index, ExtValue::W(v))
    }
    /// Sets `EXL[index]`.
    pub fn set_l(&mut self, index: usize, v: i32) -> Result<(), ExtParamError> {
        self.store(index, ExtValue::L(v))
    }
    /// Sets `EXF[index]`.
    pub fn set_f(&mut self, index: usize, v: f32) -> Result<(), ExtParamError> {
        self.store(index, ExtValue::F(v))
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn seed_program_values() {
        // The seed's block N010: EXW60=3600 EXF61=100; N060: EXF62=50.
        let mut e = ExternalParameters::new();
        assert_eq!(e.set(ExtType::W, 60, 3600.0).unwrap(), ExtValue::W(3600));
        assert_eq!(e.set(ExtType::F, 61, 100.0).unwrap(), ExtValue::F(100.0));
        e.set(ExtType::F, 62, 50.0).unwrap();
        assert_eq!(e.get_w(60).unwrap(), 3600);
        assert_eq!(e.get_f(61).unwrap(), 100.0);
        assert_eq!(e.get(ExtType::F, 62).unwrap(), ExtValue::F(50.0));
        // The other arrays at the same index are separate.
        assert_eq!(e.get_l(60).unwrap(), 0);
        assert_eq!(e.get_b(60).unwrap(), 0);
    }

    #[test]
    fn ranges_per_type() {
        let mut e = ExternalParameters::new();
        // int8: -128..=127
        assert_eq!(e.set(ExtType::B, 1, -128.0).unwrap(), ExtValue::B(-128));
        assert_eq!(
            e.set(ExtType::B, 1, 128.0),
            Err(ExtParamError::ValueOutOfRange { ty: ExtType::B, index: 1, value: 128.0 })
        );
        // int16: 32767 is the top; 40000 rpm would not fit EXW60.
        e.set(ExtType::W, 60, 32767.0).unwrap();
        let err = e.set(ExtType::W, 60, 40000.0).unwrap_err();
        assert_eq!(err.to_string(), "EXW60=40000: out of the int16 range");
        // int32
        e.set(ExtType::L, 99, -2147483648.0).unwrap();
        assert!(e.set(ExtType::L, 99, 2147483648.0).is_err());
        // fraction into an integer array
        assert_eq!(
            e.set(ExtType::W, 60, 3600.5),
            Err(ExtParamError::NotInteger { ty: ExtType::W, index: 60, value: 3600.5 })
        );
        // float: non-finite and beyond f32
        assert!(e.set(ExtType::F, 0, f64::NAN).is_err());
        assert!(e.set(ExtType::F, 0, 1e39).is_err());
        assert_eq!(e.set(ExtType::F, 0, 0.1).unwrap(), ExtValue::F(0.1f32));
        // index
        assert_eq!(
            e.set(ExtType::F, 100, 1.0),
            Err(ExtParamError::IndexOutOfRange { ty: ExtType::F, index: 100 })
        );
        assert!(e.get_w(100).is_err());
        // A refused write leaves the old value.
        assert_eq!(e.get_w(60).unwrap(), 32767);
    }

    #[test]
    fn names() {
        let r: ExtParamRef = "EXW60".parse().unwrap();
        assert_eq!(r, ExtParamRef { ty: ExtType::W, index: 60 });
        assert_eq!(r.to_string(), "EXW60");
        assert_eq!("exf62".parse::<ExtParamRef>().unwrap().ty, ExtType::F);
        assert!(matches!("EXW100".parse::<ExtParamRef>(), Err(ExtParamError::IndexOutOfRange { .. })));
        for bad in ["EXQ1", "EX", "W60", "EXW", "EXW6a", "EXW-1", "ÉXW1"] {
            assert!(matches!(bad.parse::<ExtParamRef>(), Err(ExtParamError::BadName(_))), "{bad}");
        }
    }

    proptest::proptest! {
        /// Every int16 round-trips through EXW; anything beyond is refused and leaves the
        /// old value.
        #[test]
        fn exw_round_trip(index in 0usize..100, v in -40000i32..40000) {
            let mut e = ExternalParameters::new();
            let r = e.set(ExtType::W, index, f64::from(v));
            if i16::try_from(v).is_ok() {
                proptest::prop_assert_eq!(r, Ok(ExtValue::W(v as i16)));
                proptest::prop_assert_eq!(e.get_w(index).unwrap(), v as i16);
            } else {
                proptest::prop_assert!(r.is_err());
                proptest::prop_assert_eq!(e.get_w(index).unwrap(), 0);
            }
        }

        /// Names print and parse back.
        #[test]
        fn name_round_trip(t in 0usize..4, index in 0usize..100) {
            let ty = [ExtType::B, ExtType::W, ExtType::L, ExtType::F][t];
            let r = ExtParamRef { ty, index };
            proptest::prop_assert_eq!(r.to_string().parse::<ExtParamRef>().unwrap(), r);
        }
    }
}
