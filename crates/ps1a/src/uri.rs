//! Opening PS1A lines and axes from URIs:
//! `ps1a:///dev/ttyUSB0?addr=3&baud=9600&unit=1e-5&max=65535`.

use crate::axis::{AxisConfig, Ps1aAxis};
use crate::bus::Ps1aBus;
use motus_axis::{Scale, UnitKind};
use motus_ps1a_protocol::{Acceleration, DdaCycle, U24};
use motus_serial::{BusConfig, BusMaster, DeviceUri, SerialLink, Traced, UriError};
use std::sync::Arc;
use std::time::Duration;

/// Parameters a `ps1a://` URI may carry.
pub const URI_PARAMS: &[&str] = &[
    "addr",
    "baud",
    "margin_ms",
    "retries",
    "unit",
    "kind",
    "ds",
    "tvz",
    "max",
    "speed",
    "accel",
    "blocking",
];

/// Line options from a URI.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkOptions {
    /// Baud rate (default 9600).
    pub baud: u32,
    /// Bus master settings.
    pub bus: BusConfig,
}

impl LinkOptions {
    /// Reads `baud`, `margin_ms` and `retries` from `uri`.
    pub fn from_uri(uri: &DeviceUri) -> Result<LinkOptions, UriError> {
        let baud = uri.get::<u32>("baud")?.unwrap_or(9600);
        if baud == 0 {
            return Err(UriError::BadValue {
                name: "baud".into(),
                value: "0".into(),
                reason: "must be > 0".into(),
            });
        }
        let mut bus = BusConfig::default();
        if let Some(ms) = uri.get::<u64>("margin_ms")? {
            bus.margin = Duration::from_millis(ms);
        }
        if let Some(r) = uri.get::<u32>("retries")? {
            bus.retries = r;
        }
        Ok(LinkOptions { baud, bus })
    }
}

/// Opens the serial line named by `uri` (any scheme; the path is the port).
pub fn open_bus(uri: &DeviceUri) -> Result<Ps1aBus, Box<dyn std::error::Error + Send + Sync>> {
    let opts = LinkOptions::from_uri(uri)?;
    let link = SerialLink::open(&uri.path, opts.baud)?;
    Ok(Ps1aBus::new(Arc::new(BusMaster::new(Box::new(Traced::new(link)), opts.bus))))
}

/// The axis configuration from a URI.
pub fn axis_config(uri: &DeviceUri) -> Result<AxisConfig, UriError> {
    uri.check_known(URI_PARAMS)?;
    let addr =
        uri.get::<u8>("addr")?.ok_or(UriError::Missing { uri: uri.path.clone(), name: "addr".into() })?;
    let mut c = AxisConfig { addr, ..AxisConfig::default() };
    let kind = match uri.params.get("kind").map(String::as_str) {
        None | Some("linear") => UnitKind::Linear,
        Some("rotary") => UnitKind::Rotary,
        Some(other) => {
            return Err(UriError::BadValue {
                name: "kind".into(),
                value: other.into(),
                reason: "linear or rotary".into(),
            })
        }
    };
    let unit = uri.get::<f64>("unit")?.unwrap_or(1e-5);
    c.scale = Scale::new(kind, unit).map_err(|e| UriError::BadValue {
        name: "unit".into(),
        value: unit.to_string(),
        reason: e.to_string(),
    })?;
    if let Some(ds) = uri.get::<u8>("ds")? {
        c.ds = ds;
    }
    if let Some(tvz) = uri.get::<u8>("tvz")? {
        c.tvz = DdaCycle::from_code(tvz).ok_or(UriError::BadValue {
            name: "tvz".into(),
            value: tvz.to_string(),
            reason: "0..=3".into(),
        })?;
    }
    if let Some(max) = uri.get::<u32>("max")? {
        c.max_position = U24::new(max).ok_or(UriError::BadValue {
            name: "max".into(),
            value: max.to_string(),
            reason: "at most 16777215".into(),
        })?;
    }
    if let Some(s) = uri.get::<u16>("speed")? {
        c.speed = s;
    }
    if let Some(a) = uri.get::<u8>("accel")? {
        c.acceleration = Acceleration::new(a).ok_or(UriError::BadValue {
            name: "accel".into(),
            value: a.to_string(),
            reason: "1..=10".into(),
        })?;
    }
    if let Some(b) = uri.get::<bool>("blocking")? {
        c.interpolation_blocking = b;
    }
    Ok(c)
}

/// Opens the line and the axis named by a `ps1a://` URI.
pub fn open_axis(uri: &DeviceUri) -> Result<Ps1aAxis, Box<dyn std::error::Error + Send + Sync>> {
    let config = axis_config(uri)?;
    Ok(Ps1aAxis::new(open_bus(uri)?, config))
}
