//! Parse arbitrary bytes as a concise DCF (raw, and behind a valid one-entry 0x1F22 header so
//! the fuzzer reaches the nested node configurations at once): never panics, and every
//! accepted file is written back byte for byte with the same node configurations.
#![no_main]

use libfuzzer_sys::fuzz_target;
use motus_epl_protocol::cdc::{encode_block, CdcEntry};
use motus_epl_protocol::Cdc;

fn check(bytes: &[u8]) {
    if let Ok(cdc) = Cdc::parse(bytes) {
        assert_eq!(cdc.to_bytes(), bytes);
        for node in cdc.configured_nodes() {
            let config = cdc.node_config(node).unwrap_or_default();
            let raw = cdc.value(0x1F22, node).map(|e| e.data.clone()).unwrap_or_default();
            assert!((raw.is_empty() && config.is_empty()) || encode_block(&config) == raw);
        }
        let _ = (cdc.cycle_length(), cdc.assigned_nodes());
    }
}

fuzz_target!(|data: &[u8]| {
    check(data);
    let nested = CdcEntry { index: 0x1F22, subindex: 1, data: data.to_vec() };
    check(&encode_block(&[nested]));
});
