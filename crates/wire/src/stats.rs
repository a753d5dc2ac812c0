//! [`StreamStats`]: the counters of every stream decoder.

use serde::{Deserialize, Serialize};

/// Running totals of a [`crate::Stream`] since it was created. Every byte pushed is in a
/// frame, counted as garbage, or still pending:
/// `bytes_in == frame_bytes + garbage_bytes + pending`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct StreamStats {
    /// Bytes pushed.
    pub bytes_in: u64,
    /// Frames decoded.
    pub frames: u64,
    /// Bytes of the decoded frames.
    pub frame_bytes: u64,
    /// Bytes dropped while resynchronising: noise, the first byte of a rejected or corrupt
    /// candidate, and what [`crate::Stream::clear`] dropped.
    pub garbage_bytes: u64,
    /// Frame-shaped candidates that failed their integrity check or did not decode.
    pub corrupt_frames: u64,
}
