//! Opening 1209A lines and axes from URIs (device units, as the other Motus families):
//! `nfv2:///dev/ttyUSB0?addr=1&baud=57600&rev=2014&counts_per_rev=200000&speed=5000&accel=200000&min=-40000&max=40000&require_home=true&cycle_ms=15&margin_ms=3&packing=packed`.
//!
//! | parameter | meaning | default |
//! |---|---|---|
//! | `addr` | bus address (required for an axis) | – |
//! | `baud` | line speed | 57600 |
//! | `rev` | protocol revision (`2012`, `2013`, `2014`) | 2014 |
//! | `counts_per_rev` | encoder counts per output revolution (negative inverts) | 200000 |
//! | `speed` | default profile speed, speed units (10 counts/s) | 5000 |
//! | `accel` | default acceleration, counts/s² | 200000 |
//! | `min`, `max` | soft limits, counts (both or neither) | none |
//! | `require_home` | refuse absolute moves before homing | true |
//! | `cycle_ms` | scheduler cycle | 15 |
//! | `margin_ms` | answer time-out beyond the wire time | 3 |
//! | `packing` | `packed` or `unpacked` | packed |

use std::time::Duration;

use motus_nfv2_protocol::Revision;
use motus_serial::{BusConfig, DeviceUri, UriError};

use crate::axis::{AxisConfig, Nfv2Axis};
use crate::bus::Nfv2Bus;
use crate::plan::Packing;
use crate::scheduler::SchedulerConfig;

/// Parameters an `nfv2://` URI may carry.
pub const URI_PARAMS: &[&str] = &[
    "addr",
    "baud",
    "rev",
    "counts_per_rev",
    "speed",
    "accel",
    "min",
    "max",
    "require_home",
    "cycle_ms",
    "margin_ms",
    "packing",
];

/// Default line speed of the 1209A's RS-485.
pub const DEFAULT_BAUD: u32 = motus_nfv2_protocol::RS485_BAUD;

fn bad(name: &str, value: impl ToString, reason: &str) -> UriError {
    UriError::BadValue { name: name.into(), value: value.to_string(), reason: reason.into() }
}

/// Baud rate and bus master settings (margin 3 ms, 2 retries for raw frames).
///
/// # Errors
/// A bad `baud` or `margin_ms`.
pub fn link_options(uri: &DeviceUri) -> Result<(u32, BusConfig), UriError> {
    let baud = uri.get::<u32>("baud")?.unwrap_or(DEFAULT_BAUD);
    if baud == 0 {
        return Err(bad("baud", 0, "must be > 0"));
    }
    let margin = Duration::from_millis(uri.get::<u64>("margin_ms")?.unwrap_or(3));
    Ok((baud, BusConfig { margin, retries: 2 }))
}

/// The scheduler settings of a URI.
///
/// # Errors
/// A bad `cycle_ms` or `packing`.
pub fn scheduler_config(uri: &DeviceUri) -> Result<SchedulerConfig, UriError> {
    let mut c = SchedulerConfig::default();
    if let Some(ms) = uri.get::<f64>("cycle_ms")? {
        if !(ms.is_finite() && ms >= 0.0) {
            return Err(bad("cycle_ms", ms, "must be >= 0"));
        }
        c.cycle = Duration::from_secs_f64(ms / 1000.0);
    }
    c.packing = match uri.params.get("packing").map(String::as_str) {
        None | Some("packed") => Packing::Packed,
        Some("unpacked") => Packing::Unpacked,
        Some(other) => return Err(bad("packing", other, "packed or unpacked")),
    };
    Ok(c)
}

/// Opens the line a URI names, with its revision.
///
/// # Errors
/// A bad parameter, or the port cannot be opened.
pub fn open_bus(uri: &DeviceUri) -> Result<Nfv2Bus, Box<dyn std::error::Error + Send + Sync>> {
    let (baud, bus) = link_options(uri)?;
    let rev = match uri.params.get("rev") {
        Some(text) => text.parse::<Revision>().map_err(|e| bad("rev", text, &e.to_string()))?,
        None => Revision::LATEST,
    };
    Ok(Nfv2Bus::open(&uri.path, baud, bus)?.with_default_revision(rev))
}

/// The axis settings of a URI.
///
/// # Errors
/// An unknown or bad parameter, or a missing `addr`.
pub fn axis_config(uri: &DeviceUri) -> Result<AxisConfig, UriError> {
    uri.check_known(URI_PARAMS)?;
    let addr =
        uri.get::<u8>("addr")?.ok_or(UriError::Missing { uri: uri.path.clone(), name: "addr".into() })?;
    let mut c = AxisConfig::new(addr);
    if let Some(cpr) = uri.get::<f64>("counts_per_rev")? {
        if !(cpr.is_finite() && cpr != 0.0) {
            return Err(bad("counts_per_rev", cpr, "must be a non-zero number"));
        }
        c.counts_per_rev = cpr;
    }
    if let Some(speed) = uri.get::<i64>("speed")? {
        if speed <= 0 {
            return Err(bad("speed", speed, "must be > 0 (speed units of 10 counts/s)"));
        }
        c.drive.speed = speed;
    }
    if let Some(accel) = uri.get::<i64>("accel")? {
        if accel <= 0 {
            return Err(bad("accel", accel, "must be > 0 (counts/s²)"));
        }
        c.drive.acceleration = accel;
    }
    match (uri.get::<i64>("min")?, uri.get::<i64>("max")?) {
        (None, None) => {}
        (Some(min), Some(max)) if min < max => {
            let rad = |counts: i64| counts as f64 * std::f64::consts::TAU / c.counts_per_rev;
            let (a, b) = (rad(min), rad(max));
            c.soft_limits = Some((a.min(b), a.max(b)));
        }
        (min, max) => return Err(bad("min/max", format!("{min:?}/{max:?}"), "give both, with min < max")),
    }
    if let Some(r) = uri.get::<bool>("require_home")? {
        c.require_home = r;
    }
    Ok(c)
}

/// Opens the line and the axis named by an `nfv2://` URI (`motus axis nfv2://<port>?addr=N`);
/// the axis runs its own scheduler.
///
/// # Errors
/// A bad URI, the port cannot be opened, or the scheduler cannot start.
pub fn open_axis(uri: &DeviceUri) -> Result<Nfv2Axis, Box<dyn std::error::Error + Send + Sync>> {
    let config = axis_config(uri)?;
    let scheduler = scheduler_config(uri)?;
    let bus = open_bus(uri)?;
    Ok(Nfv2Axis::start(bus, scheduler, config)?)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn parses_an_axis_uri() {
        let uri: DeviceUri =
            "nfv2:///tmp/line?addr=2&counts_per_rev=-200000&min=-1000&max=50000&cycle_ms=12.5&packing=unpacked"
                .parse()
                .unwrap();
        let c = axis_config(&uri).unwrap();
        assert_eq!((c.drive.address, c.counts_per_rev), (2, -200_000.0));
        let (lo, hi) = c.soft_limits.unwrap();
        assert!(lo < hi && (hi - 1000.0 * std::f64::consts::TAU / 200_000.0).abs() < 1e-12);
        let s = scheduler_config(&uri).unwrap();
        assert_eq!((s.cycle, s.packing), (Duration::from_micros(12_500), Packing::Unpacked));
        assert_eq!(link_options(&uri).unwrap().0, 57_600);
        let missing: DeviceUri = "nfv2:///tmp/line?baud=9600".parse().unwrap();
        assert!(axis_config(&missing).is_err());
        let typo: DeviceUri = "nfv2:///tmp/line?addr=1&sped=3".parse().unwrap();
        assert!(axis_config(&typo).is_err());
    }
}
