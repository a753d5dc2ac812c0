//! What an SDO server needs from an object dictionary, and the abort codes it answers with.
//!
//! POWERLINK's SDO (EPSG DS 301, the command layer's abort transfer) uses the abort codes of
//! CiA 301: one table, [`SdoAbortCode`], owned by `motus-canopen-protocol` and re-exported
//! here.

pub use motus_canopen_protocol::SdoAbortCode;

/// Read and write access to objects by index and subindex, as an SDO server serves them.
///
/// Values are the objects' little-endian wire bytes. An implementation checks existence,
/// access rights, size and range, and refuses with the abort code the SDO server sends back.
pub trait ObjectAccess {
    /// The value of object `index`/`subindex`.
    ///
    /// # Errors
    /// The object does not exist or cannot be read (e.g. [`SdoAbortCode::ObjectDoesNotExist`],
    /// [`SdoAbortCode::SubIndexDoesNotExist`], [`SdoAbortCode::WriteOnly`]).
    fn read(&mut self, index: u16, subindex: u8) -> Result<Vec<u8>, SdoAbortCode>;

    /// Writes `value` to object `index`/`subindex`.
    ///
    /// # Errors
    /// The object does not exist, cannot be written or refuses the value (e.g.
    /// [`SdoAbortCode::ReadOnly`], [`SdoAbortCode::TypeLengthMismatch`],
    /// [`SdoAbortCode::ValueTooHigh`]).
    fn write(&mut self, index: u16, subindex: u8, value: &[u8]) -> Result<(), SdoAbortCode>;
}
