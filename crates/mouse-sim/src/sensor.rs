//! The sensor model: true displacement in, converter packets out.

use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use motus_mouse_protocol::{Calibration, ConverterPacket, DeviceType};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

/// Configuration of a simulated sensor.
#[derive(Debug, Clone, PartialEq)]
pub struct SensorConfig {
    /// Counts per metre (default: the seed's 850 counts per 10 cm).
    pub calibration: Calibration,
    /// Device type byte sent (default `'i'`, a Microsoft-protocol mouse). For a device
    /// that is not a mouse the packets carry zero counts and the motion is discarded.
    pub device: DeviceType,
    /// Time between packets (default 10 ms; 7 bytes take 7.29 ms at 9600 bit/s).
    pub period: Duration,
    /// Probability, per packet, of a burst of 1-8 garbage bytes (which may contain `'a'`)
    /// before it. Garbage never replaces a packet and never contains `'x'`, so a
    /// resynchronising receiver loses no motion.
    pub garbage_rate: f64,
    /// Seed of the garbage generator.
    pub seed: u64,
}

impl Default for SensorConfig {
    fn default() -> Self {
        SensorConfig {
            calibration: Calibration::default(),
            device: DeviceType::Microsoft,
            period: Duration::from_millis(10),
            garbage_rate: 0.0,
            seed: 0,
        }
    }
}

/// A bad sensor configuration.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SensorError {
    /// Counts per metre must be finite and positive.
    #[error("counts per metre must be finite and > 0, got {0}")]
    Calibration(f64),
    /// The garbage rate is a probability.
    #[error("garbage rate must be within 0..=1, got {0}")]
    GarbageRate(f64),
    /// The period must be positive.
    #[error("the packet period must be > 0")]
    Period,
}

#[derive(Debug, Default)]
struct Accumulated {
    pending: [f64; 2],
    total: [f64; 2],
}

/// The true motion of the sensor, fed by a world model on any thread.
#[derive(Debug, Default)]
pub struct MouseMotion {
    inner: Mutex<Accumulated>,
}

impl MouseMotion {
    /// A handle with no motion yet.
    #[must_use]
    pub fn new() -> Arc<MouseMotion> {
        Arc::new(MouseMotion::default())
    }

    /// Adds a true displacement of the sensor, metres, in the sensor frame.
    pub fn add_displacement(&self, dx_m: f64, dy_m: f64) {
        let mut a = self.inner.lock().unwrap_or_else(PoisonError::into_inner);
        if dx_m.is_finite() && dy_m.is_finite() {
            a.pending[0] += dx_m;
            a.pending[1] += dy_m;
            a.total[0] += dx_m;
            a.total[1] += dy_m;
        }
    }

    /// Total displacement fed since creation, metres.
    #[must_use]
    pub fn total(&self) -> (f64, f64) {
        let a = self.inner.lock().unwrap_or_else(PoisonError::into_inner);
        (a.total[0], a.total[1])
    }

    fn take(&self) -> [f64; 2] {
        let mut a = self.inner.lock().unwrap_or_else(PoisonError::into_inner);
        std::mem::take(&mut a.pending)
    }
}

/// The simulated converter with its mouse.
#[derive(Debug)]
pub struct MouseSensor {
    config: SensorConfig,
    motion: Arc<MouseMotion>,
    /// Counts measured and not yet sent (fractional).
    owed: [f64; 2],
    sent: [i64; 2],
    rng: SmallRng,
}

impl MouseSensor {
    /// A sensor with a new motion handle.
    ///
    /// # Errors
    /// [`SensorError`] for a bad configuration.
    pub fn new(config: SensorConfig) -> Result<MouseSensor, SensorError> {
        let cpm = config.calibration.counts_per_metre;
        if !(cpm.is_finite() && cpm > 0.0) {
            return Err(SensorError::Calibration(cpm));
        }
        if !(0.0..=1.0).contains(&config.garbage_rate) {
            return Err(SensorError::GarbageRate(config.garbage_rate));
        }
        if config.period.is_zero() {
            return Err(SensorError::Period);
        }
        Ok(MouseSensor {
            rng: SmallRng::seed_from_u64(config.seed),
            config,
            motion: MouseMotion::new(),
            owed: [0.0; 2],
            sent: [0; 2],
        })
    }

    /// The handle the world model feeds.
    #[must_use]
    pub fn motion(&self) -> Arc<MouseMotion> {
        self.motion.clone()
    }

    /// The configuration.
    #[must_use]
    pub fn config(&self) -> &SensorConfig {
        &self.config
    }

    /// Counts sent in packets so far (x, y).
    #[must_use]
    pub fn counts_sent(&self) -> (i64, i64) {
        (self.sent[0], self.sent[1])
    }

    /// Counts measured but not yet sent (x, y), fractional.
    #[must_use]
    pub fn counts_owed(&self) -> (f64, f64) {
        (self.owed[0], self.owed[1])
    }

    /// Takes the motion fed since the previous packet and builds the next packet: the
    /// whole counts owed (rounded to nearest, clamped to i16); the rest is carried.
    pub fn next_packet(&mut self) -> ConverterPacket {
        let [mx, my] = self.motion.take();
        let device = self.config.device;
        if !device.is_mouse() {
            return ConverterPacket { device, dx: 0, dy: 0 };
        }
        let cal = self.config.calibration;
        let mut counts = [0i16; 2];
        for ((owed, sent), (m, c)) in
            self.owed.iter_mut().zip(self.sent.iter_mut()).zip([mx, my].into_iter().zip(counts.iter_mut()))
        {
            *owed += cal.metres_to_counts(m);
            let whole = owed.round().clamp(f64::from(i16::MIN), f64::from(i16::MAX));
            // In range after the clamp: the cast is exact.
            *c = whole as i16;
            *owed -= whole;
            *sent += i64::from(*c);
        }
        ConverterPacket { device, dx: counts[0], dy: counts[1] }
    }

    /// The next packet's bytes, with a burst of garbage before it at the configured rate.
    pub fn next_bytes(&mut self) -> Vec<u8> {
        let mut bytes = Vec::with_capacity(16);
        if self.config.garbage_rate > 0.0 && self.rng.gen_bool(self.config.garbage_rate) {
            let n = self.rng.gen_range(1..=8);
            for _ in 0..n {
                // Half the garbage bytes are false starts.
                // Never 'x': a false start is then always detectable and no fake packet
                // (which would add counts) can appear.
                let b = if self.rng.gen_bool(0.5) { b'a' } else { self.rng.gen_range(0..b'x') };
                bytes.push(b);
            }
        }
        bytes.extend_from_slice(&self.next_packet().encode());
        bytes
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;
    use motus_mouse_protocol::ConverterStream;

    #[test]
    fn counts_with_remainder() {
        let mut s = MouseSensor::new(SensorConfig::default()).unwrap();
        let m = s.motion();
        // 0.1 mm = 0.85 counts per step: 10 steps = 8.5 counts, sent as 1,1,1,... with the
        // remainder carried: total after 10 packets is round-half-away(8.5) handled by
        // carry: the sum is within one count of 8.5.
        for _ in 0..10 {
            m.add_displacement(0.0001, -0.0001);
            let _ = s.next_packet();
        }
        let (x, y) = s.counts_sent();
        assert!((x as f64 - 8.5).abs() <= 0.5 + 1e-9, "{x}");
        assert!((y as f64 + 8.5).abs() <= 0.5 + 1e-9, "{y}");
        let (ox, oy) = s.counts_owed();
        assert!((x as f64 + ox - 8.5).abs() < 1e-9 && (y as f64 + oy + 8.5).abs() < 1e-9);
    }

    #[test]
    fn large_motion_is_clamped_and_carried() {
        let mut s = MouseSensor::new(SensorConfig::default()).unwrap();
        // 5 m = 42500 counts: more than i16::MAX.
        s.motion().add_displacement(5.0, -5.0);
        let p = s.next_packet();
        assert_eq!((p.dx, p.dy), (i16::MAX, i16::MIN));
        let p = s.next_packet();
        assert_eq!((i32::from(p.dx), i32::from(p.dy)), (42500 - 32767, -42500 + 32768));
        assert_eq!(s.counts_sent(), (42500, -42500));
    }

    #[test]
    fn not_a_mouse_sends_zero() {
        let cfg = SensorConfig { device: DeviceType::Nothing, ..SensorConfig::default() };
        let mut s = MouseSensor::new(cfg).unwrap();
        s.motion().add_displacement(1.0, 1.0);
        assert_eq!(s.next_packet(), ConverterPacket { device: DeviceType::Nothing, dx: 0, dy: 0 });
    }

    #[test]
    fn garbage_does_not_lose_counts() {
        let cfg = SensorConfig { garbage_rate: 0.5, seed: 7, ..SensorConfig::default() };
        let mut s = MouseSensor::new(cfg).unwrap();
        let m = s.motion();
        let mut dec = ConverterStream::default();
        let (mut sx, mut sy) = (0i64, 0i64);
        for i in 0..500 {
            m.add_displacement(0.00037 * f64::from(i % 7), -0.00021);
            dec.push(&s.next_bytes());
            while let Some(p) = dec.next_frame() {
                sx += i64::from(p.dx);
                sy += i64::from(p.dy);
            }
        }
        assert!(dec.stats().garbage_bytes > 0);
        assert_eq!((sx, sy), s.counts_sent());
    }

    #[test]
    fn bad_config() {
        let c = |f: fn(&mut SensorConfig)| {
            let mut cfg = SensorConfig::default();
            f(&mut cfg);
            MouseSensor::new(cfg).err()
        };
        assert_eq!(c(|c| c.garbage_rate = 2.0), Some(SensorError::GarbageRate(2.0)));
        assert_eq!(c(|c| c.period = Duration::ZERO), Some(SensorError::Period));
        assert_eq!(c(|c| c.calibration.counts_per_metre = 0.0), Some(SensorError::Calibration(0.0)));
    }
}
