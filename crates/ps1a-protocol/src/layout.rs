//! Where each header byte of a command frame sits.
//!
//! The source contradicts itself: its prose lists "address; code; length", its frame
//! table and field list give `ADR N KOD`. We implement the table (`ADR N KOD`). This is
//! the **only** place that knows the order: swap [`LENGTH_INDEX`] and [`CODE_INDEX`] if a
//! real module proves the prose right.

/// Index of the module address.
pub const ADDRESS_INDEX: usize = 0;
/// Index of N, the number of parameter bytes.
pub const LENGTH_INDEX: usize = 1;
/// Index of KOD, the command code.
pub const CODE_INDEX: usize = 2;
/// Index of the first parameter byte.
pub const PARAMS_INDEX: usize = 3;
/// Header (ADR, N, KOD) plus trailer (CHSUM) bytes.
pub const OVERHEAD: usize = 4;
