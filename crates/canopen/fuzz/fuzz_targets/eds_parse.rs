//! Fuzz target: the EDS parser and typed decode/encode never panic on arbitrary text.
#![no_main]

use libfuzzer_sys::fuzz_target;
use motus_canopen::ObjectDictionary;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    if let Ok(od) = ObjectDictionary::parse(&text) {
        for v in od.iter() {
            let _ = v.default_value(5);
            let _ = v.data_type.decode(data.get(..4).unwrap_or(data));
            let _ = od.find(&v.full_name());
        }
    }
});
