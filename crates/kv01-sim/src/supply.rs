//! Supply-voltage measurement (D4): each rail's volts with a little uniform noise, encoded
//! with the spec's constants (`volts = (H * 256 + L) * constant`, rounded to the nearest count).

use motus_kv01_protocol::status::{VOLTS_PER_COUNT_12V, VOLTS_PER_COUNT_24V, VOLTS_PER_COUNT_5V};
use motus_kv01_protocol::Voltages;
use rand::rngs::SmallRng;
use rand::Rng;

use crate::config::SupplyConfig;

/// Raw count for `volts` at `volts_per_count` (clamped to 0..=65535).
fn count(volts: f64, volts_per_count: f64) -> u16 {
    (volts / volts_per_count).round().clamp(0.0, f64::from(u16::MAX)) as u16
}

/// One D4 measurement of the three rails.
pub(crate) fn measure(supply: &SupplyConfig, rng: &mut SmallRng) -> Voltages {
    let mut noisy = |v: f64| {
        if supply.noise_volts > 0.0 {
            v + rng.gen_range(-supply.noise_volts..=supply.noise_volts)
        } else {
            v
        }
    };
    Voltages {
        raw_24v: count(noisy(supply.volts_24v), VOLTS_PER_COUNT_24V),
        raw_5v: count(noisy(supply.volts_5v), VOLTS_PER_COUNT_5V),
        raw_12v: count(noisy(supply.volts_12v), VOLTS_PER_COUNT_12V),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn nominal_rails_by_hand() {
        // 24 / 0.02740234375 = 875.84 -> 876; 5 / 0.006552734375 = 763.04 -> 763;
        // 12 / 0.01310546875 = 915.65 -> 916.
        let exact = SupplyConfig { noise_volts: 0.0, ..SupplyConfig::default() };
        let v = measure(&exact, &mut SmallRng::seed_from_u64(1));
        assert_eq!((v.raw_24v, v.raw_5v, v.raw_12v), (876, 763, 916));
        assert_eq!(count(-1.0, VOLTS_PER_COUNT_24V), 0);
        assert_eq!(count(1e9, VOLTS_PER_COUNT_24V), u16::MAX);
    }
}
