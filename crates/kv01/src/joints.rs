//! The arm's joints: the spec's offset and soft-limit table, gear ratios, speed polarity,
//! and the conversion between resolver counts, joint angles and motor rpm.
//!
//! Spec (`specs/kv01.md`, "Joint offsets and soft limits"): joint angle =
//! raw * 360 / 65536 - offset, normalised to (-180, 180]. The offsets depend on how each
//! resolver was mounted and change after service: they are configuration.

use motus_kv01_protocol::status::joint_angle_deg;
pub use motus_kv01_protocol::status::normalise_deg;
use serde::{Deserialize, Serialize};

/// Offsets in degrees of joints 1..6 (spec table, measured with the arm forward and raised).
pub const SPEC_OFFSETS_DEG: [f64; 6] = [-81.85, 190.577, 91.962, -102.549, 252.451, 310.593];

/// Soft limits (lower, upper) in degrees of joints 1..6 (spec table; joints 4 and 6 turn
/// endlessly).
pub const SPEC_SOFT_LIMITS_DEG: [Option<(f64, f64)>; 6] =
    [Some((-120.0, 120.0)), Some((-90.0, 90.0)), Some((-132.0, 132.0)), None, Some((-135.0, 135.0)), None];

/// One joint's configuration.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointSpec {
    /// Resolver offset in degrees.
    pub offset_deg: f64,
    /// Soft limits (lower, upper) in degrees, `None` for endless joints.
    pub soft_limits_deg: Option<(f64, f64)>,
    /// Gear ratio motor : joint (motor rpm * 6 / ratio = joint deg/s).
    pub gear_ratio: f64,
    /// +1 or -1: the sign relating a positive rpm to a growing joint angle (the figure of
    /// the source that gave it is lost).
    pub speed_sign: i8,
    /// Resolver bits per turn (16; 12 for the gripper rotation on module 0xE6).
    pub resolver_bits: u8,
    /// The joint has a holding brake (joints 1-5).
    pub brake: bool,
    /// Largest motor speed the driver commands (rpm).
    pub max_rpm: f64,
}

impl JointSpec {
    /// The default specification of joint `joint` (1..=6).
    pub fn kv01(joint: u8) -> JointSpec {
        let i = usize::from(joint.clamp(1, 6)) - 1;
        JointSpec {
            offset_deg: SPEC_OFFSETS_DEG.get(i).copied().unwrap_or(0.0),
            soft_limits_deg: SPEC_SOFT_LIMITS_DEG.get(i).copied().flatten(),
            gear_ratio: match joint {
                1..=3 => 400.0,
                4 | 5 => 250.0,
                _ => 150.0,
            },
            speed_sign: 1,
            resolver_bits: if joint == 6 { 12 } else { 16 },
            brake: joint <= 5,
            max_rpm: 3000.0,
        }
    }

    /// Joint angle in degrees, normalised to (-180, 180], from a raw resolver value.
    pub fn angle_deg(&self, raw: u16) -> f64 {
        joint_angle_deg(raw, self.offset_deg, self.resolver_bits)
    }

    /// Joint deg/s for one motor rpm (sign included).
    pub fn deg_s_per_rpm(&self) -> f64 {
        f64::from(self.speed_sign.signum()) * 6.0 / self.gear_ratio
    }

    /// Motor rpm for a joint velocity in deg/s.
    pub fn rpm_for(&self, deg_s: f64) -> f64 {
        deg_s / self.deg_s_per_rpm()
    }

    /// The joint's largest velocity in deg/s.
    pub fn max_deg_s(&self) -> f64 {
        (self.max_rpm * self.deg_s_per_rpm()).abs()
    }

    /// True if `angle` lies within the soft limits (always for endless joints).
    pub fn within_soft_limits(&self, angle: f64) -> bool {
        self.soft_limits_deg.is_none_or(|(lo, hi)| (lo..=hi).contains(&angle))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spec_formula() {
        let j2 = JointSpec::kv01(2);
        // raw 0x8000 = 180 deg; 180 - 190.577 = -10.577
        assert!((j2.angle_deg(0x8000) + 10.577).abs() < 1e-9);
        let j1 = JointSpec::kv01(1);
        // raw 0 -> 0 + 81.85
        assert!((j1.angle_deg(0) - 81.85).abs() < 1e-9);
        assert_eq!(normalise_deg(-180.0), 180.0);
        assert_eq!(normalise_deg(540.0), 180.0);
        let g = JointSpec::kv01(6);
        assert!((g.angle_deg(1024) - normalise_deg(90.0 - 310.593)).abs() < 1e-9);
        assert!((j1.rpm_for(6.0) - 400.0).abs() < 1e-9);
    }
}
