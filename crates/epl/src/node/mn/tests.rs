#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

use super::*;

fn entry(index: u16, subindex: u8, data: &[u8]) -> CdcEntry {
    CdcEntry { index, subindex, data: data.to_vec() }
}

#[test]
fn bits_are_read_and_written_little_endian_at_any_offset() {
    let mut p = [0u8; 4];
    set_bits(&mut p, 0, 8, 0xA5);
    set_bits(&mut p, 12, 12, 0xABC);
    assert_eq!(p, [0xA5, 0xC0, 0xAB, 0x00]);
    assert_eq!(get_bits(&p, 0, 8), Some(0xA5));
    assert_eq!(get_bits(&p, 12, 12), Some(0xABC));
    assert_eq!(get_bits(&p, 24, 16), None, "past the payload");
    set_bits(&mut p, 30, 8, 0xFF);
    assert_eq!(p[3], 0xC0, "bits past the end are dropped");
    set_bits(&mut p, 0, 8, 0x5A);
    assert_eq!(p[0], 0x5A, "cleared bits are cleared");
}

#[test]
fn mappings_take_the_last_values_and_only_the_own_channel() {
    let config = [
        entry(0x1600, 0, &[0]),
        entry(0x1600, 1, &0x0008_0000_0001_6200u64.to_le_bytes()),
        entry(0x1600, 2, &0x0010_0008_0002_6200u64.to_le_bytes()),
        entry(0x1600, 0, &[2]),
        // Channel 1 consumes node 7's PRes: not in the PReq.
        entry(0x1401, 1, &[7]),
        entry(0x1601, 1, &0x0008_0000_0001_6201u64.to_le_bytes()),
        entry(0x1601, 0, &[1]),
        entry(0x1A00, 1, &0x0008_0000_0001_6000u64.to_le_bytes()),
        entry(0x1A00, 0, &[1]),
    ];
    let rx = mapped_objects(&config, 0x1600, 0x1400);
    assert_eq!(
        rx.iter().map(|o| (o.index, o.subindex, o.bit_offset, o.bit_length)).collect::<Vec<_>>(),
        [(0x6200, 1, 0, 8), (0x6200, 2, 8, 16)]
    );
    assert_eq!(payload_len(&rx), 3);
    let tx = mapped_objects(&config, 0x1A00, 0x1800);
    assert_eq!(tx.len(), 1);
    assert_eq!(mapped_objects(&config[..1], 0x1600, 0x1400), [], "disabled (0 entries)");
}
