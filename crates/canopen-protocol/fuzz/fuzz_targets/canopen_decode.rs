//! Fuzz the candump parser and the CANopen decoder: never panic, and every
//! decoded frame must encode back to itself.
#![no_main]

use libfuzzer_sys::fuzz_target;
use motus_canopen_protocol::{CanFrame, CanOpenMessage};

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = text.parse::<CanFrame>();
    }
    let Some((&id_lo, rest)) = data.split_first() else { return };
    let Some((&id_hi, payload)) = rest.split_first() else { return };
    let id = u32::from(u16::from_le_bytes([id_lo, id_hi]) & 0x7FF);
    let len = payload.len().min(8);
    if let Ok(frame) = CanFrame::new(id, payload.get(..len).unwrap_or(&[])) {
        let msg = CanOpenMessage::decode(&frame);
        let _ = msg.to_string();
        assert_eq!(msg.encode().ok(), Some(frame));
    }
});
