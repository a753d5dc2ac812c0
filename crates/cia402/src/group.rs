//! Several drives starting together: the seed's pattern.
//!
//! Each drive gets its new set-point by a **synchronous** RPDO (RPDO2: controlword +
//! target position, transmission type 0-240, acted on at the next SYNC); then one SYNC
//! starts them all in the same instant. The alternative, SDO writes of 0x607A and
//! 0x6040 per drive, costs more frames and does not start the drives together.

use crate::io::IoError;
use motus_canopen_protocol::CanFrame;
use motus_cia402_protocol::cw;

/// Sends PDOs and SYNC on the bus (the CANopen master implements it).
pub trait SyncTransport {
    /// Sends one PDO frame with `cob_id`.
    fn send_pdo(&self, cob_id: u16, data: &[u8]) -> Result<(), IoError>;
    /// Sends one SYNC.
    fn send_sync(&self) -> Result<(), IoError>;
}

/// One drive's part of a group move.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GroupMove {
    /// COB-ID of the drive's synchronous RPDO carrying controlword + 0x607A
    /// (the seed's RPDO2: 0x300 + node).
    pub rpdo_cob_id: u16,
    /// Target (increments).
    pub target: i32,
    /// Relative (controlword bit 6) or absolute.
    pub relative: bool,
}

/// The 6-byte RPDO payload: controlword (LE) then target position (LE), as in the seed's
/// `302: 1F 00 55 08 00 00` (controlword 0x001F, target 0x0855 = 2133).
pub fn rpdo_payload(controlword: u16, target: i32) -> [u8; 6] {
    let c = controlword.to_le_bytes();
    let t = target.to_le_bytes();
    [c[0], c[1], t[0], t[1], t[2], t[3]]
}

/// The controlword that hands over a new set-point: enable operation + new set-point,
/// + relative when asked (0x1F absolute, 0x5F relative — the seed's word).
pub fn set_point_controlword(relative: bool, new_set_point: bool) -> u16 {
    let mut word = 0x000F | cw::CHANGE_SET_IMMEDIATELY;
    if relative {
        word |= cw::RELATIVE;
    }
    if new_set_point {
        word |= cw::NEW_SET_POINT;
    }
    word
}

/// Queues every drive's set-point (bit 4 low, to make a clean edge, then high) by
/// synchronous RPDO and sends one SYNC: all drives take their set-point at the same SYNC.
/// The caller then waits for the set-point acknowledge of each and lowers bit 4
/// (see [`finish`]).
pub fn start_together(bus: &dyn SyncTransport, moves: &[GroupMove]) -> Result<(), IoError> {
    for m in moves {
        bus.send_pdo(m.rpdo_cob_id, &rpdo_payload(set_point_controlword(m.relative, true), m.target))?;
    }
    bus.send_sync()
}

/// Lowers bit 4 on every drive (same RPDO, applied at the next SYNC) so the next
/// set-point is an edge again, and sends that SYNC.
pub fn finish(bus: &dyn SyncTransport, moves: &[GroupMove]) -> Result<(), IoError> {
    for m in moves {
        bus.send_pdo(m.rpdo_cob_id, &rpdo_payload(set_point_controlword(m.relative, false), m.target))?;
    }
    bus.send_sync()
}

/// Frames, data bytes and worst-case bits of a way of starting `n` drives.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BusCost {
    /// Frames on the bus.
    pub frames: u32,
    /// Data bytes carried.
    pub data_bytes: u32,
    /// Worst-case bits on the wire (stuffing included).
    pub bits: u32,
}

fn cost_of(frames: &[CanFrame]) -> BusCost {
    let mut c = BusCost { frames: 0, data_bytes: 0, bits: 0 };
    for f in frames {
        c.frames += 1;
        c.data_bytes += u32::from(f.dlc());
        // Classic CAN 2.0A: 47 + 8n bits, worst case + (34 + 8n - 1) / 4 stuff bits.
        let n = u32::from(f.dlc());
        c.bits += 47 + 8 * n + (34 + 8 * n - 1) / 4;
    }
    c
}

/// The cost of the synchronous start: one 6-byte RPDO per drive plus one SYNC.
pub fn cost_rpdo_sync(nodes: &[u8]) -> BusCost {
    let mut frames: Vec<CanFrame> = nodes
        .iter()
        .filter_map(|n| CanFrame::new(0x300 + u32::from(*n), &rpdo_payload(0x5F, 0)).ok())
        .collect();
    frames.extend(CanFrame::new(0x080, &[]).ok());
    cost_of(&frames)
}

/// The cost of the same start by SDO: per drive an expedited download of 0x607A and of
/// 0x6040, each an 8-byte request and an 8-byte confirmation (drives start one by one).
pub fn cost_sdo(nodes: &[u8]) -> BusCost {
    let frames: Vec<CanFrame> = nodes
        .iter()
        .flat_map(|n| {
            let req = CanFrame::new(0x600 + u32::from(*n), &[0x23, 0x7A, 0x60, 0, 0, 0, 0, 0]).ok();
            let resp = CanFrame::new(0x580 + u32::from(*n), &[0x60, 0x7A, 0x60, 0, 0, 0, 0, 0]).ok();
            [req.clone(), resp.clone(), req, resp]
        })
        .flatten()
        .collect();
    cost_of(&frames)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn the_seeds_rpdo2_frame() {
        // specs/omni-robot.md: `302: 1F 00 55 08 00 00` = controlword 0x001F, target 0x0855.
        assert_eq!(rpdo_payload(0x001F, 0x0855), [0x1F, 0x00, 0x55, 0x08, 0x00, 0x00]);
        // The seed's relative start word is 0x5F: enable operation + new set-point + relative
        // (+ change immediately, bit 5, which we set for single set-points: 0x7F).
        assert_eq!(set_point_controlword(true, true) & !cw::CHANGE_SET_IMMEDIATELY, 0x5F);
    }

    #[test]
    fn synchronous_start_is_cheaper_than_sdo() {
        let nodes = [2, 3, 4];
        let pdo = cost_rpdo_sync(&nodes);
        // 3 RPDOs of 6 bytes + SYNC: 4 frames, 18 data bytes (the seed's figures).
        assert_eq!((pdo.frames, pdo.data_bytes), (4, 18));
        let sdo = cost_sdo(&nodes);
        // 3 drives x 2 objects x (request + confirmation) of 8 bytes.
        assert_eq!((sdo.frames, sdo.data_bytes), (12, 96));
        assert!(sdo.bits > 2 * pdo.bits, "{sdo:?} vs {pdo:?}");
    }
}
