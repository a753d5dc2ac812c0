//! What every Motus codec shares, so that each concept has one shape: the total wire code
//! table ([`code_table!`]).
//!
//! A leaf crate (no Motus dependency): the protocol codecs depend on it, never the reverse.
#![forbid(unsafe_code)]

mod codes;

// The shapes of the serial stream decoders: one scan result, one decoder, one set of
// counters for every codec.
mod scan;
mod stats;
mod stream;

pub use scan::{Scan, Scanner};
pub use stats::StreamStats;
pub use stream::{Stream, StreamEvent};
