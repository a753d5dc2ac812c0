//! Interprets arbitrary text: must never panic or hang (step limit), and every call must
//! format.
#![no_main]

use libfuzzer_sys::fuzz_target;
use motus_gcode::{format_canon, Interpreter, InterpreterConfig, Precision};

fuzz_target!(|data: &[u8]| {
    let src = String::from_utf8_lossy(data);
    let cfg = InterpreterConfig {
        max_steps: 10_000,
        ..InterpreterConfig::default()
    };
    for call in Interpreter::with_config(&src, cfg) {
        match call {
            Ok(c) => {
                let _ = format_canon(&c.canon, Precision::Full);
            }
            Err(e) => {
                let _ = e.to_string();
                break;
            }
        }
    }
});
