//! Resolver readings (`specs/kv01.md`, D3 and "Joint offsets and soft limits"): the module
//! reports `raw = (joint angle + offset)` in `2^bits` counts per turn, without offset
//! correction, so `joint angle = raw * 360 / 2^bits - offset`, normalised to (-180, 180].
//! Joints 1-5 use 16 bits; the gripper module reports its 12-bit rotation resolver as the
//! plain value 0..=4095 (right-aligned in ResH:ResL; the source does not say which).

/// The raw reading of a resolver at `angle_deg` with `offset_deg`, `bits` bits per turn.
#[must_use]
pub fn raw_from_angle(angle_deg: f64, offset_deg: f64, bits: u8) -> u16 {
    let per_turn = f64::from(1u32 << bits.min(16));
    let counts = ((angle_deg + offset_deg) / 360.0 * per_turn).round().rem_euclid(per_turn);
    // 0 <= counts < 65536, and `as` saturates anyway.
    counts as u16
}

/// The joint angle of a raw reading (the spec's formula, in the codec), normalised to
/// (-180, 180].
pub use motus_kv01_protocol::status::joint_angle_deg as angle_from_raw;
pub use motus_kv01_protocol::status::normalise_deg;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spec_offsets_by_hand() {
        // Joint 2 at 0 deg: raw angle = 190.577 deg = 190.577 / 360 * 65536 = 34693.48 -> 34693.
        assert_eq!(raw_from_angle(0.0, 190.577, 16), 34693);
        // Joint 1 at 0 deg: -81.85 deg -> 278.15 / 360 * 65536 = 50635.66 -> 50636.
        assert_eq!(raw_from_angle(0.0, -81.85, 16), 50636);
        // Gripper (12 bits) at 0 deg: 310.593 / 360 * 4096 = 3533.86 -> 3534.
        assert_eq!(raw_from_angle(0.0, 310.593, 12), 3534);
        // Back: within half a count (360 / 65536 / 2 deg).
        assert!((angle_from_raw(34693, 190.577, 16)).abs() < 0.003);
        assert!((angle_from_raw(raw_from_angle(-170.0, 91.962, 16), 91.962, 16) + 170.0).abs() < 0.003);
        assert!((angle_from_raw(raw_from_angle(180.0, 0.0, 16), 0.0, 16) - 180.0).abs() < 1e-9);
    }

    #[test]
    fn normalisation() {
        assert_eq!(normalise_deg(-180.0), 180.0);
        assert_eq!(normalise_deg(540.0), 180.0);
        assert_eq!(normalise_deg(-190.0), 170.0);
        assert_eq!(normalise_deg(0.0), 0.0);
    }
}
