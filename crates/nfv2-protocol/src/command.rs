//! One command of a frame: `code, k, k parameter bytes`.
//!
//! A command with `k = 0` is a **query**; a slave answers it with the same code and its
//! data as parameters. Otherwise the parameters are split into values of the width the
//! [`Revision`] gives for the code. A code the revision does not define is skipped by its
//! length, as the spec requires of receivers, and kept as [`Command::Unknown`] with its
//! raw bytes so that re-encoding reproduces the frame.
//!
//! The number of values is free: "a command may carry fewer or more values than the
//! receiver supports (a slave with fewer drives ignores the extra values, one with more
//! updates only the first ones)". The codec keeps all values; [`Command::for_device`]
//! applies that rule for a device with a given number of slots.

use serde::{Deserialize, Serialize};

use crate::code::CommandCode;
use crate::error::{DecodeError, EncodeError};
use crate::revision::Revision;
use crate::value::{int_to_le, read_int, Regulator, ValueKind};

/// One command, query or answer inside a frame.
///
/// JSON (`kind` tag): `{"kind":"query","code":"read_drives_position"}`,
/// `{"kind":"values","code":"set_drives_position","values":[-5000]}`,
/// `{"kind":"regulators","code":"set_position_regulator","values":[{"p":100,"i":5,"d":20,"t":1000}]}`,
/// `{"kind":"unknown","code":96,"raw":[170,187,204]}`.
#[derive(Clone, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Command {
    /// A query (`k = 0`), for any code, known or not.
    Query {
        /// The queried code.
        code: CommandCode,
    },
    /// Integer values, little-endian, of the width the revision gives for `code`.
    /// A set-point from the master, or a slave's answer to a query.
    Values {
        /// The command.
        code: CommandCode,
        /// One value per drive / channel, in order. An empty list encodes as a query.
        values: Vec<i64>,
    },
    /// Regulator settings (codes 0x40..0x42), 8 bytes each.
    Regulators {
        /// The command.
        code: CommandCode,
        /// One setting per drive, in order.
        values: Vec<Regulator>,
    },
    /// A command whose value width the revision does not know, skipped by its length and
    /// kept raw.
    Unknown {
        /// The code byte.
        code: u8,
        /// The `k` parameter bytes, as received.
        raw: Vec<u8>,
    },
}

impl Command {
    /// A query (`k = 0`) for `code`.
    #[must_use]
    pub fn query(code: CommandCode) -> Self {
        Command::Query { code }
    }

    /// Integer values for `code` (a set-point, or an answer).
    #[must_use]
    pub fn values(code: CommandCode, values: impl Into<Vec<i64>>) -> Self {
        Command::Values { code, values: values.into() }
    }

    /// Regulator settings for a `Set*Regulator` code.
    #[must_use]
    pub fn regulators(code: CommandCode, values: impl Into<Vec<Regulator>>) -> Self {
        Command::Regulators { code, values: values.into() }
    }

    /// The command's code.
    #[must_use]
    pub fn code(&self) -> CommandCode {
        match self {
            Command::Query { code } | Command::Values { code, .. } | Command::Regulators { code, .. } => {
                *code
            }
            Command::Unknown { code, .. } => CommandCode::from_u8(*code),
        }
    }

    /// True for a query (`k = 0` on the wire).
    #[must_use]
    pub fn is_query(&self) -> bool {
        match self {
            Command::Query { .. } => true,
            Command::Values { values, .. } => values.is_empty(),
            Command::Regulators { values, .. } => values.is_empty(),
            Command::Unknown { raw, .. } => raw.is_empty(),
        }
    }

    /// The integer values, if this is a [`Command::Values`].
    #[must_use]
    pub fn int_values(&self) -> Option<&[i64]> {
        match self {
            Command::Values { values, .. } => Some(values),
            _ => None,
        }
    }

    /// The spec's rule for a receiver with `slots` drives / channels: it uses only the
    /// first `slots` values and ignores the rest (a shorter list updates only the first
    /// ones). Queries and unknown commands are returned unchanged.
    #[must_use]
    pub fn for_device(&self, slots: usize) -> Command {
        match self {
            Command::Values { code, values } => {
                Command::Values { code: *code, values: values.iter().copied().take(slots).collect() }
            }
            Command::Regulators { code, values } => {
                Command::Regulators { code: *code, values: values.iter().copied().take(slots).collect() }
            }
            other => other.clone(),
        }
    }

    /// Encoded size of this command (`2 + k`), validating it against `rev`.
    ///
    /// # Errors
    /// [`EncodeError`] if the payload does not match the code's kind in `rev`, a value is
    /// out of range, or `k` would exceed 255.
    pub fn encoded_len(&self, rev: Revision) -> Result<usize, EncodeError> {
        let code = self.code();
        let k = match self {
            Command::Query { .. } => 0,
            Command::Values { values, .. } => {
                let kind = int_kind(code, rev)?;
                if let Some(&value) = values.iter().find(|&&v| int_to_le(kind, v).is_none()) {
                    return Err(EncodeError::ValueOutOfRange { code, value, kind });
                }
                values.len().saturating_mul(kind.width())
            }
            Command::Regulators { values, .. } => {
                regulator_kind(code, rev)?;
                values.len().saturating_mul(Regulator::WIRE_LEN)
            }
            Command::Unknown { raw, .. } => raw.len(),
        };
        if k > usize::from(u8::MAX) {
            return Err(EncodeError::CommandTooLong { code, len: k });
        }
        Ok(2 + k)
    }

    /// Writes `code, k, parameters` at the start of `out`; returns the bytes written.
    /// `out` must hold at least [`Command::encoded_len`] bytes.
    pub(crate) fn write(&self, out: &mut [u8], rev: Revision) -> Result<usize, EncodeError> {
        let len = self.encoded_len(rev)?;
        let available = out.len();
        let too_small = EncodeError::BufferTooSmall { needed: len, available };
        let (header, params) =
            out.get_mut(..len).and_then(|o| o.split_first_chunk_mut::<2>()).ok_or(too_small)?;
        // `len - 2 <= 255` was checked by `encoded_len`.
        *header = [self.code().to_u8(), u8::try_from(len - 2).unwrap_or(u8::MAX)];
        match self {
            Command::Query { .. } => {}
            Command::Values { values, .. } => {
                let kind = int_kind(self.code(), rev)?;
                let width = kind.width();
                for (chunk, &value) in params.chunks_exact_mut(width).zip(values) {
                    let bytes = int_to_le(kind, value).unwrap_or_default();
                    chunk.copy_from_slice(bytes.get(..width).unwrap_or_default());
                }
            }
            Command::Regulators { values, .. } => {
                for (chunk, reg) in params.chunks_exact_mut(Regulator::WIRE_LEN).zip(values) {
                    chunk.copy_from_slice(&reg.to_bytes());
                }
            }
            Command::Unknown { raw, .. } => params.copy_from_slice(raw),
        }
        Ok(len)
    }

    /// Decodes one command from its code byte and its `k` parameter bytes.
    pub(crate) fn decode(code: u8, params: &[u8], rev: Revision) -> Result<Command, DecodeError> {
        let cc = CommandCode::from_u8(code);
        if params.is_empty() {
            return Ok(Command::Query { code: cc });
        }
        let Some(kind) = rev.value_kind(cc) else {
            return Ok(Command::Unknown { code, raw: params.to_vec() });
        };
        let width = kind.width();
        let truncated = || DecodeError::TruncatedValue {
            code: cc,
            len: u8::try_from(params.len()).unwrap_or(u8::MAX),
            width,
            revision: rev,
        };
        let chunks = params.chunks_exact(width);
        if !chunks.remainder().is_empty() {
            return Err(truncated());
        }
        if kind == ValueKind::Regulator {
            let values = chunks
                .map(|c| <[u8; 8]>::try_from(c).map(Regulator::from_bytes))
                .collect::<Result<Vec<_>, _>>()
                .map_err(|_| truncated())?;
            Ok(Command::Regulators { code: cc, values })
        } else {
            let values =
                chunks.map(|c| read_int(kind, c)).collect::<Option<Vec<_>>>().ok_or_else(truncated)?;
            Ok(Command::Values { code: cc, values })
        }
    }
}

/// The integer kind of `code` in `rev`, or the matching encode error.
fn int_kind(code: CommandCode, rev: Revision) -> Result<ValueKind, EncodeError> {
    match rev.value_kind(code) {
        None => Err(EncodeError::NoWidth { code, revision: rev }),
        Some(ValueKind::Regulator) => Err(EncodeError::PayloadMismatch { code, kind: ValueKind::Regulator }),
        Some(kind) => Ok(kind),
    }
}

/// Checks that `code` takes regulator settings in `rev`.
fn regulator_kind(code: CommandCode, rev: Revision) -> Result<(), EncodeError> {
    match rev.value_kind(code) {
        None => Err(EncodeError::NoWidth { code, revision: rev }),
        Some(ValueKind::Regulator) => Ok(()),
        Some(kind) => Err(EncodeError::PayloadMismatch { code, kind }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn query_and_values_sizes() {
        let rev = Revision::LATEST;
        assert_eq!(Command::query(CommandCode::ReadDrivesPosition).encoded_len(rev), Ok(2));
        let c = Command::values(CommandCode::SetDrivesPosition, [1, 2]);
        assert_eq!(c.encoded_len(rev), Ok(2 + 8));
    }

    #[test]
    fn out_of_range_is_reported_with_the_value() {
        let c = Command::values(CommandCode::SetDrivesMode, [300]);
        assert_eq!(
            c.encoded_len(Revision::LATEST),
            Err(EncodeError::ValueOutOfRange {
                code: CommandCode::SetDrivesMode,
                value: 300,
                kind: ValueKind::U8
            })
        );
    }

    #[test]
    fn payload_must_match_the_code() {
        let c = Command::values(CommandCode::SetCurrentRegulator, [1]);
        assert!(matches!(c.encoded_len(Revision::LATEST), Err(EncodeError::PayloadMismatch { .. })));
        let c = Command::regulators(CommandCode::SetDrivesPosition, [Regulator::default()]);
        assert!(matches!(c.encoded_len(Revision::LATEST), Err(EncodeError::PayloadMismatch { .. })));
        let c = Command::values(CommandCode::ReadDrivesSpeed, [1]);
        assert_eq!(
            c.encoded_len(Revision::Rev2012),
            Err(EncodeError::NoWidth { code: CommandCode::ReadDrivesSpeed, revision: Revision::Rev2012 })
        );
    }

    #[test]
    fn more_than_255_parameter_bytes() {
        let c = Command::values(CommandCode::SetDrivesPosition, vec![0; 64]);
        assert_eq!(
            c.encoded_len(Revision::LATEST),
            Err(EncodeError::CommandTooLong { code: CommandCode::SetDrivesPosition, len: 256 })
        );
    }

    #[test]
    fn fewer_or_more_values_than_the_device_has() {
        let c = Command::values(CommandCode::SetDrivesPosition, [10, 20, 30]);
        assert_eq!(c.for_device(1), Command::values(CommandCode::SetDrivesPosition, [10]));
        assert_eq!(c.for_device(8), c);
    }

    #[test]
    fn decode_splits_by_width() {
        let c = Command::decode(0x1F, &[0x10, 0x00, 0x01, 0x80], Revision::LATEST);
        assert_eq!(c, Ok(Command::values(CommandCode::ReadDrivesStatus, [0x0010, 0x8001])));
        let c = Command::decode(0x11, &[0x9C, 0xFF, 0xFF], Revision::LATEST);
        assert!(matches!(c, Err(DecodeError::TruncatedValue { len: 3, width: 4, .. })));
    }
}
