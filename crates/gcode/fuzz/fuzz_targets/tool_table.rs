//! Reads arbitrary text as a tool table: must never panic; every tool read has finite
//! values.
#![no_main]

use libfuzzer_sys::fuzz_target;
use motus_gcode::{parse_tool_table, Units};

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    for units in [Units::Mm, Units::Inch] {
        match parse_tool_table(&text, units) {
            Ok(tools) => {
                for t in tools {
                    assert!(t.offset.iter().all(|v| v.is_finite()) && t.diameter.is_finite());
                }
            }
            Err(e) => {
                let _ = e.to_string();
            }
        }
    }
});
