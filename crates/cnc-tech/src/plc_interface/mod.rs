//! Data exchange between the CNC program and the PLC (specs/cnc.md, "M-functions" and
//! "External parameters").
//!
//! * [`MFunctions`]: 1024 bits; `M<n>` in the program sets bit `n` ([`MFunctions::set`],
//!   program side), the PLC sees it, acts and clears it ([`MFunctions::clear`], PLC side).
//!   A synchronous M pauses the program until its bit is cleared; an asynchronous one does
//!   not, but may be called again only after it was cleared.
//! * [`ExternalParameters`]: four arrays of 100 values — `B` int8, `W` int16, `L` int32,
//!   `F` float32 — written by `EX<type><index>=<value>` in the program (`EXW60=3600`) and
//!   read by the PLC.

mod external;
mod mfunctions;

pub use external::{ExtParamError, ExtParamRef, ExtType, ExtValue, ExternalParameters, EXT_PARAM_COUNT};
pub use mfunctions::{MFunctionError, MFunctions, MKind, M_FUNCTION_COUNT};
