//! Time a frame occupies a real CAN bus.
//!
//! A classic CAN 2.0A data frame with `n` data bytes has 47 + 8n bits without stuffing
//! (44 + 8n for the frame itself plus the 3-bit intermission); 2.0B (29-bit IDs) adds 20
//! bits. Bit stuffing inserts one bit after five equal bits in the 34 + 8n (54 + 8n)
//! stuffable bits, so the worst case adds floor((34 + 8n - 1) / 4) bits.

use crate::CanFrame;
use std::time::Duration;

/// Bits of `frame` on the wire without stuff bits (incl. 3-bit intermission).
pub fn nominal_bits(frame: &CanFrame) -> u32 {
    let n = if frame.is_remote() { 0 } else { u32::from(frame.dlc().min(8)) };
    let base = if frame.is_extended() { 67 } else { 47 };
    base + 8 * n
}

/// Bits of `frame` on the wire with the worst-case number of stuff bits.
pub fn worst_case_bits(frame: &CanFrame) -> u32 {
    let n = if frame.is_remote() { 0 } else { u32::from(frame.dlc().min(8)) };
    let stuffable = if frame.is_extended() { 54 } else { 34 } + 8 * n;
    nominal_bits(frame) + (stuffable - 1) / 4
}

/// Worst-case time `frame` occupies a bus running at `bitrate` bit/s.
pub fn frame_time(frame: &CanFrame, bitrate: u32) -> Duration {
    let bits = u64::from(worst_case_bits(frame));
    Duration::from_nanos(bits * 1_000_000_000 / u64::from(bitrate.max(1)))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn eight_byte_standard_frame_at_20_kbit() {
        let f = CanFrame::new(0x181, &[0; 8]).unwrap();
        assert_eq!(nominal_bits(&f), 111);
        // 34 + 64 = 98 stuffable bits -> at most 24 stuff bits.
        assert_eq!(worst_case_bits(&f), 135);
        let t = frame_time(&f, 20_000);
        assert!(t >= Duration::from_micros(5_500) && t <= Duration::from_micros(6_800), "{t:?}");
    }

    #[test]
    fn sync_frame_is_short() {
        let f = CanFrame::new(0x080, &[]).unwrap();
        assert_eq!(nominal_bits(&f), 47);
        assert_eq!(worst_case_bits(&f), 47 + 8);
    }
}
