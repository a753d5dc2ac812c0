//! Process data objects (CiA 301 §7.2.2, specs/canopen.md 3.5): RPDO1-4 / TPDO1-4 read
//! their communication (0x1400 / 0x1800 + n) and mapping (0x1600 / 0x1A00 + n) objects from
//! the dictionary; the write rules for reconfiguration; packing, SYNC and event timing.
//!
//! * TPDO type 0: sent at SYNC when its data changed; 1-240: every n-th SYNC (optionally
//!   from the SYNC counter value in sub 6); 254/255: on change (respecting the inhibit time,
//!   sub 3 in 100 us) and on the event timer (sub 5, ms).
//! * RPDO types 0-240: buffered, applied at the next SYNC; 254/255: applied at once.
//! * Mapping entries are writable only while the PDO is disabled (COB-ID bit 31) and
//!   sub 0 = 0; otherwise abort 0x06010000 (CANopenNode's rule).

use std::time::{Duration, Instant};

use motus_canopen_protocol::{CanFrame, SdoAbortCode};

use crate::od::ObjectDictionary;

/// COB-ID bit 31: PDO not valid.
pub const NOT_VALID: u32 = 0x8000_0000;
/// COB-ID bit 29: extended frame (not supported).
pub const EXTENDED: u32 = 0x2000_0000;

/// Direction of a PDO.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dir {
    /// Receive PDO (0x1400 / 0x1600).
    Rx,
    /// Transmit PDO (0x1800 / 0x1A00).
    Tx,
}

/// The configuration of one PDO read from the dictionary.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PdoConfig {
    /// Raw COB-ID entry.
    pub cob: u32,
    /// Transmission type.
    pub ttype: u8,
    /// Inhibit time in 100 us (TPDO).
    pub inhibit: u16,
    /// Event timer in ms.
    pub event_ms: u16,
    /// SYNC start value (TPDO).
    pub sync_start: u8,
    /// Mapped (index, sub, bits).
    pub map: Vec<(u16, u8, u8)>,
}

impl PdoConfig {
    /// Reads PDO `n` (0-3) of a direction.
    pub fn read(od: &ObjectDictionary, dir: Dir, n: u16) -> Self {
        let (comm, map) = match dir {
            Dir::Rx => (0x1400 + n, 0x1600 + n),
            Dir::Tx => (0x1800 + n, 0x1A00 + n),
        };
        let count = od.int(map, 0).clamp(0, 8) as u8;
        let map = (1..=count).map(|s| split_entry(od.u32(map, s))).collect();
        Self {
            cob: od.u32(comm, 1),
            ttype: od.int(comm, 2) as u8,
            inhibit: od.int(comm, 3) as u16,
            event_ms: od.int(comm, 5) as u16,
            sync_start: od.int(comm, 6) as u8,
            map,
        }
    }

    /// Whether the PDO is valid (bit 31 clear) and maps something.
    pub fn enabled(&self) -> bool {
        self.cob & NOT_VALID == 0 && !self.map.is_empty()
    }

    /// The 11-bit CAN-ID.
    pub fn can_id(&self) -> u32 {
        self.cob & 0x7FF
    }

    /// Mapped length in bytes.
    pub fn len(&self) -> usize {
        self.map.iter().map(|m| usize::from(m.2) / 8).sum()
    }

    /// Whether nothing is mapped.
    pub fn is_empty(&self) -> bool {
        self.map.is_empty()
    }

    /// Packs the current values of the mapped objects.
    pub fn pack(&self, od: &ObjectDictionary) -> Vec<u8> {
        let mut out = Vec::with_capacity(8);
        for &(index, sub, bits) in &self.map {
            let want = usize::from(bits) / 8;
            let bytes = od.bytes(index, sub).unwrap_or(&[]);
            out.extend((0..want).map(|i| bytes.get(i).copied().unwrap_or(0)));
        }
        out
    }

    /// Splits received data into (index, sub, bytes) writes; `None` if too short.
    pub fn unpack(&self, data: &[u8]) -> Option<Vec<PdoWrite>> {
        let mut pos = 0usize;
        let mut out = Vec::with_capacity(self.map.len());
        for &(index, sub, bits) in &self.map {
            let n = usize::from(bits) / 8;
            out.push((index, sub, data.get(pos..pos + n)?.to_vec()));
            pos += n;
        }
        Some(out)
    }
}

/// One object written by a received PDO: (index, sub-index, bytes).
pub type PdoWrite = (u16, u8, Vec<u8>);

/// Splits a mapping entry: index bits 16-31, sub-index 8-15, length 0-7.
pub fn split_entry(v: u32) -> (u16, u8, u8) {
    ((v >> 16) as u16, (v >> 8) as u8, v as u8)
}

/// CAN-IDs CiA 301 restricts from PDO use (specs/canopen.md 3.1).
pub fn restricted(id: u32) -> bool {
    matches!(id, 0x000..=0x07F | 0x101..=0x180 | 0x581..=0x5FF | 0x601..=0x67F | 0x6E0..=0x6FF) || id >= 0x701
}

/// (direction, number 0-3, is mapping object) of a PDO parameter index.
pub fn classify(index: u16) -> Option<(Dir, u16, bool)> {
    Some(match index {
        0x1400..=0x1403 => (Dir::Rx, index - 0x1400, false),
        0x1600..=0x1603 => (Dir::Rx, index - 0x1600, true),
        0x1800..=0x1803 => (Dir::Tx, index - 0x1800, false),
        0x1A00..=0x1A03 => (Dir::Tx, index - 0x1A00, true),
        _ => return None,
    })
}

fn check_entry(od: &ObjectDictionary, dir: Dir, v: u32) -> Result<u8, SdoAbortCode> {
    if v == 0 {
        return Ok(0);
    }
    let (index, sub, bits) = split_entry(v);
    let e = od.locate(index, sub).map_err(|_| SdoAbortCode::NotMappable)?;
    let size_ok = e.data_type.size().is_some_and(|s| s * 8 == usize::from(bits));
    let access_ok = match dir {
        Dir::Rx => e.access.writable(),
        Dir::Tx => e.access.readable(),
    };
    if !e.pdo_mappable || !size_ok || !access_ok {
        return Err(SdoAbortCode::NotMappable);
    }
    Ok(bits)
}

/// The PDO rules for a write of `value` to a PDO parameter (CiA 301 §7.5.2.35-38,
/// CANopenNode's checks). `Ok` when allowed.
pub fn check_write(od: &ObjectDictionary, index: u16, sub: u8, value: i64) -> Result<(), SdoAbortCode> {
    let Some((dir, n, is_map)) = classify(index) else {
        return Ok(());
    };
    let v = value as u32;
    let comm = if dir == Dir::Rx { 0x1400 + n } else { 0x1800 + n };
    let cur = od.u32(comm, 1);
    let disabled = cur & NOT_VALID != 0;
    if is_map {
        let count = od.int(index, 0);
        if !disabled || (sub > 0 && count != 0) {
            return Err(SdoAbortCode::UnsupportedAccess);
        }
        if sub == 0 {
            if v > 8 {
                return Err(SdoAbortCode::PdoLengthExceeded);
            }
            let mut bits = 0u32;
            for s in 1..=v as u8 {
                bits += u32::from(check_entry(od, dir, od.u32(index, s))?);
            }
            if bits > 64 {
                return Err(SdoAbortCode::PdoLengthExceeded);
            }
        } else {
            check_entry(od, dir, v)?;
        }
        return Ok(());
    }
    match sub {
        1 => {
            let new_valid = v & NOT_VALID == 0;
            if v & EXTENDED != 0 || (new_valid && restricted(v & 0x7FF)) {
                return Err(SdoAbortCode::InvalidValue);
            }
            if !disabled && new_valid && (v & 0x7FF) != (cur & 0x7FF) {
                return Err(SdoAbortCode::InvalidValue);
            }
        }
        2 if !(v <= 240 || v >= 254) => return Err(SdoAbortCode::InvalidValue),
        3 if !disabled => return Err(SdoAbortCode::InvalidValue),
        _ => {}
    }
    Ok(())
}

#[derive(Debug, Clone, Default)]
struct TxState {
    last_data: Option<Vec<u8>>,
    last_sent: Option<Instant>,
    sync_left: Option<u32>,
    waiting_start: bool,
}

/// Run-time state of the PDOs of one node.
#[derive(Debug, Clone, Default)]
pub struct PdoEngine {
    tx: [TxState; 4],
    rx_pending: [Option<Vec<u8>>; 4],
}

/// What a received RPDO frame did.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum RpdoResult {
    /// Not one of our valid RPDOs.
    NotOurs,
    /// Write these now (types 254/255).
    Apply(Vec<PdoWrite>),
    /// Buffered until the next SYNC.
    Buffered,
    /// Shorter than the mapping: not processed (EMCY 0x8210).
    TooShort,
}

impl PdoEngine {
    /// Fresh state (entering operational, reset communication).
    pub fn reset(&mut self) {
        *self = Self::default();
    }

    /// Handles a frame that may be an RPDO.
    pub fn on_frame(&mut self, od: &ObjectDictionary, frame: &CanFrame) -> RpdoResult {
        if frame.is_extended() || frame.is_remote() {
            return RpdoResult::NotOurs;
        }
        for n in 0..4u16 {
            let cfg = PdoConfig::read(od, Dir::Rx, n);
            if !cfg.enabled() || cfg.can_id() != frame.id() {
                continue;
            }
            let Some(writes) = cfg.unpack(frame.data()) else {
                return RpdoResult::TooShort;
            };
            if cfg.ttype <= 240 {
                if let Some(slot) = self.rx_pending.get_mut(usize::from(n)) {
                    *slot = Some(frame.data().to_vec());
                }
                return RpdoResult::Buffered;
            }
            return RpdoResult::Apply(writes);
        }
        RpdoResult::NotOurs
    }

    /// SYNC: the TPDO frames due (sampled now) and the buffered RPDO writes to apply.
    pub fn on_sync(
        &mut self,
        od: &ObjectDictionary,
        counter: Option<u8>,
        now: Instant,
    ) -> (Vec<CanFrame>, Vec<PdoWrite>) {
        let mut frames = Vec::new();
        for n in 0..4u16 {
            let cfg = PdoConfig::read(od, Dir::Tx, n);
            let Some(st) = self.tx.get_mut(usize::from(n)) else { continue };
            if !cfg.enabled() || cfg.ttype > 240 {
                continue;
            }
            let data = cfg.pack(od);
            let send = if cfg.ttype == 0 {
                st.last_data.as_ref() != Some(&data)
            } else {
                let period = u32::from(cfg.ttype);
                if st.sync_left.is_none() {
                    st.waiting_start = cfg.sync_start > 0 && counter.is_some();
                    st.sync_left = Some(period);
                }
                if st.waiting_start {
                    if counter == Some(cfg.sync_start) {
                        st.waiting_start = false;
                        st.sync_left = Some(1);
                    } else {
                        continue;
                    }
                }
                let left = st.sync_left.unwrap_or(period).saturating_sub(1);
                st.sync_left = Some(if left == 0 { period } else { left });
                left == 0
            };
            if send {
                if let Ok(f) = CanFrame::new(cfg.can_id(), &data) {
                    frames.push(f);
                }
                st.last_data = Some(data);
                st.last_sent = Some(now);
            }
        }
        let mut writes = Vec::new();
        for n in 0..4u16 {
            let Some(data) = self.rx_pending.get_mut(usize::from(n)).and_then(Option::take) else { continue };
            let cfg = PdoConfig::read(od, Dir::Rx, n);
            if cfg.enabled() && cfg.ttype <= 240 {
                writes.extend(cfg.unpack(&data).unwrap_or_default());
            }
        }
        (frames, writes)
    }

    /// Event-driven TPDOs (types 254/255) due at `now`; with `all`, every enabled TPDO
    /// once (entering operational).
    pub fn events(&mut self, od: &ObjectDictionary, now: Instant, all: bool) -> Vec<CanFrame> {
        let mut frames = Vec::new();
        for n in 0..4u16 {
            let cfg = PdoConfig::read(od, Dir::Tx, n);
            let Some(st) = self.tx.get_mut(usize::from(n)) else { continue };
            if !cfg.enabled() || (!all && cfg.ttype < 254) {
                continue;
            }
            let data = cfg.pack(od);
            let since = st.last_sent.map(|t| now.saturating_duration_since(t));
            let inhibit_ok = since.map_or(true, |s| s >= Duration::from_micros(100 * u64::from(cfg.inhibit)));
            let changed = st.last_data.as_ref() != Some(&data);
            let timer = cfg.event_ms > 0
                && since.map_or(true, |s| s >= Duration::from_millis(u64::from(cfg.event_ms)));
            if all || (inhibit_ok && (changed || timer)) {
                if let Ok(f) = CanFrame::new(cfg.can_id(), &data) {
                    frames.push(f);
                }
                st.last_data = Some(data);
                st.last_sent = Some(now);
            }
        }
        frames
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;
    use crate::config::SimConfig;

    fn od() -> ObjectDictionary {
        crate::objects::build(&SimConfig::node(2))
    }

    #[test]
    fn default_set_reads_back_as_documented() {
        let od = od();
        let t1 = PdoConfig::read(&od, Dir::Tx, 0);
        assert_eq!((t1.can_id(), t1.ttype, t1.event_ms, t1.len()), (0x182, 255, 50, 3));
        let r2 = PdoConfig::read(&od, Dir::Rx, 1);
        assert_eq!((r2.can_id(), r2.ttype, r2.len()), (0x302, 1, 6));
        // The seed's frame 302: 5F 00 55 08 00 00 = controlword 0x005F, target 0x0855.
        let w = r2.unpack(&[0x5F, 0x00, 0x55, 0x08, 0x00, 0x00]).unwrap();
        assert_eq!(w, vec![(0x6040, 0, vec![0x5F, 0]), (0x607A, 0, vec![0x55, 0x08, 0, 0])]);
        assert!(!PdoConfig::read(&od, Dir::Tx, 2).enabled());
    }

    #[test]
    fn reconfiguration_rules() {
        let mut od = od();
        // Mapping of a valid PDO: refused.
        assert_eq!(check_write(&od, 0x1A00, 0, 0), Err(SdoAbortCode::UnsupportedAccess));
        // Changing the CAN-ID of a valid PDO: refused; disabling: fine.
        assert_eq!(check_write(&od, 0x1800, 1, 0x4000_0190), Err(SdoAbortCode::InvalidValue));
        assert_eq!(check_write(&od, 0x1800, 1, 0xC000_0182), Ok(()));
        od.set_int(0x1800, 1, 0xC000_0182);
        // sub0 still 2: entries refused until sub0 = 0.
        assert_eq!(check_write(&od, 0x1A00, 1, 0x6064_0020), Err(SdoAbortCode::UnsupportedAccess));
        assert_eq!(check_write(&od, 0x1A00, 0, 0), Ok(()));
        od.set_int(0x1A00, 0, 0);
        assert_eq!(check_write(&od, 0x1A00, 1, 0x6064_0020), Ok(()));
        // Not mappable (0x6081 is, 0x6065 is not), wrong length, missing object.
        assert_eq!(check_write(&od, 0x1A00, 1, 0x6065_0020), Err(SdoAbortCode::NotMappable));
        assert_eq!(check_write(&od, 0x1A00, 1, 0x6064_0010), Err(SdoAbortCode::NotMappable));
        assert_eq!(check_write(&od, 0x1A00, 1, 0x5FFF_0020), Err(SdoAbortCode::NotMappable));
        // An RPDO cannot map a read-only object.
        od.set_int(0x1400, 1, 0x8000_0202);
        od.set_int(0x1600, 0, 0);
        assert_eq!(check_write(&od, 0x1600, 1, 0x6041_0010), Err(SdoAbortCode::NotMappable));
        // 3 x 32 bits > 64.
        for s in 1..=3 {
            od.set_int(0x1A00, s, 0x6064_0020);
        }
        assert_eq!(check_write(&od, 0x1A00, 0, 3), Err(SdoAbortCode::PdoLengthExceeded));
        assert_eq!(check_write(&od, 0x1A00, 0, 9), Err(SdoAbortCode::PdoLengthExceeded));
        // Types 241-253 refused; restricted CAN-ID refused.
        assert_eq!(check_write(&od, 0x1800, 2, 250), Err(SdoAbortCode::InvalidValue));
        assert_eq!(check_write(&od, 0x1800, 1, 0x0000_0601), Err(SdoAbortCode::InvalidValue));
    }

    #[test]
    fn sync_types_and_event_timer() {
        let mut od = od();
        let t0 = Instant::now();
        let mut e = PdoEngine::default();
        // TPDO2 type 1: one frame per SYNC; 0x282 = 0x280 + node 2; statusword 0, position 0.
        let (f, w) = e.on_sync(&od, None, t0);
        assert_eq!(f, vec![CanFrame::new(0x282, &[0; 6]).unwrap()]);
        assert!(w.is_empty());
        // TPDO1 (type 255, 50 ms timer): first call sends, then nothing until 50 ms or a change.
        assert_eq!(e.events(&od, t0, false).len(), 1);
        assert!(e.events(&od, t0 + Duration::from_millis(49), false).is_empty());
        assert_eq!(e.events(&od, t0 + Duration::from_millis(50), false).len(), 1);
        od.set_int(0x6041, 0, 0x0250);
        let f = e.events(&od, t0 + Duration::from_millis(51), false);
        // 0x182: statusword 0x0250 LE 50 02, mode display 1.
        assert_eq!(f, vec![CanFrame::new(0x182, &[0x50, 0x02, 0x01]).unwrap()]);
        // RPDO2 (type 1) is buffered until SYNC, RPDO1 (255) applies at once.
        let r = e.on_frame(&od, &CanFrame::new(0x302, &[0x5F, 0, 0x55, 0x08, 0, 0]).unwrap());
        assert_eq!(r, RpdoResult::Buffered);
        assert_eq!(
            e.on_frame(&od, &CanFrame::new(0x202, &[0x0F, 0]).unwrap()),
            RpdoResult::Apply(vec![(0x6040, 0, vec![0x0F, 0])])
        );
        assert_eq!(e.on_frame(&od, &CanFrame::new(0x202, &[0x0F]).unwrap()), RpdoResult::TooShort);
        let (_, w) = e.on_sync(&od, None, t0);
        assert_eq!(w.len(), 2);
        // Every 3rd SYNC with type 3.
        od.set_int(0x1801, 2, 3);
        let mut e = PdoEngine::default();
        let sent: Vec<usize> = (0..6).map(|_| e.on_sync(&od, None, t0).0.len()).collect();
        assert_eq!(sent, vec![0, 0, 1, 0, 0, 1]);
    }
}
