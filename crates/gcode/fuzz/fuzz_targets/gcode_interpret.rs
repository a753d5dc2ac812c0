//! Interprets arbitrary text: must never panic or hang (step limit), and every call must
//! format.
#![no_main]

use libfuzzer_sys::fuzz_target;
use motus_gcode::{
    format_canon, parse_tool_table, CycleOutput, Interpreter, InterpreterConfig, Precision, Units,
};

fuzz_target!(|data: &[u8]| {
    let src = String::from_utf8_lossy(data);
    // The first byte's low bit: canned cycles as LinuxCNC's moves or the drilling unit's jobs.
    let cycles = if data.first().is_some_and(|b| b & 1 == 1) {
        CycleOutput::DrillingTechnology
    } else {
        CycleOutput::Motion
    };
    // A small tool table, so that T, M6 and G43 H reach their tools too.
    let tools = parse_tool_table("T1 P1 D6 Z10\nT2 P2 D3 Z-5 X0.5\n", Units::Mm).unwrap_or_default();
    let cfg = InterpreterConfig { max_steps: 10_000, tools, cycles, ..InterpreterConfig::default() };
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
