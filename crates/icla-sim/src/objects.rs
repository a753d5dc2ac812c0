//! The IclA simulator's object dictionary contents (CiA 301 communication area, the
//! manufacturer object 0x200B, the CiA 402 objects) and its default PDO set.
//!
//! Default PDO set (designed so that the seed's host code and python-canopen's
//! `BaseNode402` both work):
//!
//! | PDO | COB-ID | type | mapping |
//! |---|---|---|---|
//! | RPDO1 | 0x200+id | 255 (at once) | 0x6040 controlword |
//! | RPDO2 | 0x300+id | 1 (at the next SYNC) | 0x6040 + 0x607A target position |
//! | RPDO3 | 0x400+id, disabled | 255 | 0x6040 + 0x60FF target velocity |
//! | RPDO4 | 0x500+id, disabled | 255 | 0x6060 modes of operation |
//! | TPDO1 | 0x180+id | 255, event timer 50 ms | 0x6041 statusword + 0x6061 mode display |
//! | TPDO2 | 0x280+id | 1 (every SYNC) | 0x6041 + 0x6064 position actual |
//! | TPDO3 | 0x380+id, disabled | 1 | 0x6064 + 0x606C velocity actual |
//! | TPDO4 | 0x480+id, disabled | 255 | 0x603F error code + 0x1001 error register |
//!
//! TPDO1 is the seed's asynchronous statusword TPDO plus the mode display byte, repeated
//! by a 50 ms event timer: `BaseNode402` infers a period after two receptions and then
//! waits at most 0.2 s for the next one (specs/can-transports.md).

use crate::config::SimConfig;
use crate::od::{Access, DataType, ObjectDictionary, ObjectKind, Spec};

use Access::{Const, Ro, Rw, Wo};
use DataType::{
    Integer16 as I16, Integer32 as I32, Integer8 as I8, Unsigned16 as U16, Unsigned32 as U32, Unsigned8 as U8,
};

/// Device type 0x1000: CiA 402 (0x0192) servo drive (additional information 0x0002).
pub const DEVICE_TYPE: u32 = 0x0002_0192;
/// Manufacturer device name 0x1008.
pub const DEVICE_NAME: &str = "IclA D065 (Motus simulator)";
/// Manufacturer object: writing a value sets the actual position to it (the seed wrote 0).
pub const SET_POSITION: u16 = 0x200B;
/// Supported drive modes 0x6502: pp (bit 0), pv (bit 2), hm (bit 5).
pub const SUPPORTED_MODES: u32 = 0x25;
/// Largest profile speed in Inc/s: rated 210 rpm at the output x 213.33 Inc/rev / 60.
pub const MAX_SPEED: i64 = 747;

/// (COB-ID default incl. flag bits, transmission type, event timer ms, mapping entries).
type PdoDefault = (i64, i64, i64, &'static [u32]);

/// RPDO1-4 defaults.
pub const RPDO_DEFAULTS: [PdoDefault; 4] = [
    (0x200, 255, 0, &[0x6040_0010]),
    (0x300, 1, 0, &[0x6040_0010, 0x607A_0020]),
    (0x8000_0400, 255, 0, &[0x6040_0010, 0x60FF_0020]),
    (0x8000_0500, 255, 0, &[0x6060_0008]),
];

/// TPDO1-4 defaults (bit 30: no RTR; bit 31: disabled).
pub const TPDO_DEFAULTS: [PdoDefault; 4] = [
    (0x4000_0180, 255, 50, &[0x6041_0010, 0x6061_0008]),
    (0x4000_0280, 1, 0, &[0x6041_0010, 0x6064_0020]),
    (0xC000_0380, 1, 0, &[0x6064_0020, 0x606C_0020]),
    (0xC000_0480, 255, 0, &[0x603F_0010, 0x1001_0008]),
];

fn rw(dt: DataType, default: i64) -> Spec {
    Spec::new(dt, Rw, default)
}

fn ro(dt: DataType, default: i64) -> Spec {
    Spec::new(dt, Ro, default)
}

fn text(s: &str) -> Spec {
    let mut spec = Spec::new(DataType::VisibleString, Const, 0);
    spec.default = crate::od::Default::Text(s.to_owned());
    spec
}

fn record(
    od: &mut ObjectDictionary,
    index: u16,
    name: &str,
    kind: ObjectKind,
    count: u8,
    count_access: Access,
) {
    od.add_object(index, name, kind);
    let sub0 = if kind == ObjectKind::Array { "Number of entries" } else { "Highest sub-index supported" };
    od.add_entry(index, 0, sub0, Spec::new(U8, count_access, i64::from(count)));
}

fn communication(od: &mut ObjectDictionary, cfg: &SimConfig) {
    od.add_var(0x1000, "Device type", ro(U32, i64::from(DEVICE_TYPE)));
    od.add_var(0x1001, "Error register", ro(U8, 0).mappable());
    record(od, 0x1003, "Pre-defined error field", ObjectKind::Array, 0, Rw);
    for sub in 1..=8u8 {
        od.add_entry(0x1003, sub, &format!("Standard error field {sub}"), ro(U32, 0));
    }
    od.add_var(0x1005, "COB-ID SYNC", rw(U32, 0x80));
    od.add_var(0x1008, "Manufacturer device name", text(DEVICE_NAME));
    od.add_var(
        0x100A,
        "Manufacturer software version",
        text(concat!("motus-icla-sim ", env!("CARGO_PKG_VERSION"))),
    );
    od.add_var(0x1014, "COB-ID EMCY", ro(U32, 0x80).node_relative());
    od.add_var(0x1015, "Inhibit time EMCY", rw(U16, 0));
    record(od, 0x1016, "Consumer heartbeat time", ObjectKind::Array, 1, Const);
    od.add_entry(0x1016, 1, "Consumer heartbeat time 1", rw(U32, 0));
    od.add_var(0x1017, "Producer heartbeat time", rw(U16, i64::from(cfg.heartbeat_ms)));
    record(od, 0x1018, "Identity object", ObjectKind::Record, 4, Const);
    let id = cfg.identity;
    od.add_entry(0x1018, 1, "Vendor-ID", ro(U32, i64::from(id.vendor)));
    od.add_entry(0x1018, 2, "Product code", ro(U32, i64::from(id.product)));
    od.add_entry(0x1018, 3, "Revision number", ro(U32, i64::from(id.revision)));
    od.add_entry(0x1018, 4, "Serial number", ro(U32, i64::from(id.serial)));
    for (n, (cob, ty, ev, map)) in RPDO_DEFAULTS.iter().enumerate() {
        let n16 = n as u16;
        let comm = 0x1400 + n16;
        record(od, comm, &format!("RPDO{} communication parameter", n + 1), ObjectKind::Record, 5, Const);
        od.add_entry(comm, 1, "COB-ID used by RPDO", rw(U32, *cob).node_relative());
        od.add_entry(comm, 2, "Transmission type", rw(U8, *ty));
        od.add_entry(comm, 5, "Event timer", rw(U16, *ev));
        mapping(od, 0x1600 + n16, &format!("RPDO{} mapping parameter", n + 1), map);
    }
    for (n, (cob, ty, ev, map)) in TPDO_DEFAULTS.iter().enumerate() {
        let n16 = n as u16;
        let comm = 0x1800 + n16;
        record(od, comm, &format!("TPDO{} communication parameter", n + 1), ObjectKind::Record, 6, Const);
        od.add_entry(comm, 1, "COB-ID used by TPDO", rw(U32, *cob).node_relative());
        od.add_entry(comm, 2, "Transmission type", rw(U8, *ty));
        od.add_entry(comm, 3, "Inhibit time", rw(U16, 0));
        od.add_entry(comm, 5, "Event timer", rw(U16, *ev));
        od.add_entry(comm, 6, "SYNC start value", rw(U8, 0));
        mapping(od, 0x1A00 + n16, &format!("TPDO{} mapping parameter", n + 1), map);
    }
}

fn mapping(od: &mut ObjectDictionary, index: u16, name: &str, map: &[u32]) {
    record(od, index, name, ObjectKind::Record, map.len() as u8, Rw);
    for sub in 1..=8u8 {
        let v = map.get(usize::from(sub) - 1).copied().unwrap_or(0);
        od.add_entry(index, sub, &format!("Mapped object {sub}"), rw(U32, i64::from(v)));
    }
}

fn drive(od: &mut ObjectDictionary) {
    od.add_var(SET_POSITION, "Set actual position", Spec::new(I32, Wo, 0));
    od.add_var(0x603F, "Error code", ro(U16, 0).mappable());
    od.add_var(0x6040, "Controlword", rw(U16, 0).mappable());
    od.add_var(0x6041, "Statusword", ro(U16, 0).mappable());
    od.add_var(0x605A, "Quick stop option code", rw(I16, 2).limits(0, 8));
    od.add_var(0x605B, "Shutdown option code", rw(I16, 0).limits(0, 1));
    od.add_var(0x605C, "Disable operation option code", rw(I16, 1).limits(0, 1));
    od.add_var(0x605E, "Fault reaction option code", rw(I16, 2).limits(0, 4));
    od.add_var(0x6060, "Modes of operation", rw(I8, 1).mappable());
    od.add_var(0x6061, "Modes of operation display", ro(I8, 1).mappable());
    od.add_var(0x6062, "Position demand value", ro(I32, 0).mappable());
    od.add_var(0x6064, "Position actual value", ro(I32, 0).mappable());
    od.add_var(0x6065, "Following error window", rw(U32, 50));
    od.add_var(0x6066, "Following error time out", rw(U16, 100));
    od.add_var(0x6067, "Position window", rw(U32, 2));
    od.add_var(0x6068, "Position window time", rw(U16, 0));
    od.add_var(0x606C, "Velocity actual value", ro(I32, 0).mappable());
    od.add_var(0x607A, "Target position", rw(I32, 0).mappable());
    od.add_var(0x607C, "Home offset", rw(I32, 0));
    record(od, 0x607D, "Software position limit", ObjectKind::Array, 2, Const);
    od.add_entry(0x607D, 1, "Min position limit", rw(I32, 0));
    od.add_entry(0x607D, 2, "Max position limit", rw(I32, 0));
    od.add_var(0x6081, "Profile velocity", rw(U32, 248).mappable().limits(0, MAX_SPEED));
    od.add_var(0x6083, "Profile acceleration", rw(U32, 1000).mappable().limits(1, 100_000));
    od.add_var(0x6084, "Profile deceleration", rw(U32, 400).mappable().limits(1, 100_000));
    od.add_var(0x6085, "Quick stop deceleration", rw(U32, 2000).limits(1, 100_000));
    od.add_var(0x6098, "Homing method", rw(I8, 35));
    record(od, 0x6099, "Homing speeds", ObjectKind::Array, 2, Const);
    od.add_entry(0x6099, 1, "Speed during search for switch", rw(U32, 100).limits(1, MAX_SPEED));
    od.add_entry(0x6099, 2, "Speed during search for zero", rw(U32, 20).limits(1, MAX_SPEED));
    od.add_var(0x609A, "Homing acceleration", rw(U32, 500).limits(1, 100_000));
    od.add_var(0x60F4, "Following error actual value", ro(I32, 0).mappable());
    od.add_var(0x60FF, "Target velocity", rw(I32, 0).mappable().limits(-MAX_SPEED, MAX_SPEED));
    od.add_var(0x6502, "Supported drive modes", ro(U32, i64::from(SUPPORTED_MODES)));
}

/// Builds the dictionary of a drive with its values set for its node id.
pub fn build(cfg: &SimConfig) -> ObjectDictionary {
    let mut od = ObjectDictionary::new();
    communication(&mut od, cfg);
    drive(&mut od);
    od.reset(0x0000..=0xFFFF, cfg.node_id);
    od
}
