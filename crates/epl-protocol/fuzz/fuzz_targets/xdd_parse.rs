//! Read arbitrary bytes as a POWERLINK device description (XDD/XDC): never panics, and every
//! accepted dictionary is consistent: each entry holds a value it would accept itself, which
//! is also its default, and every enabled PDO mapping is valid.
#![no_main]

use libfuzzer_sys::fuzz_target;
use motus_epl_protocol::ObjectDictionary;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(od) = ObjectDictionary::from_xdd(text) {
        for (index, object) in od.objects() {
            for (subindex, entry) in object.entries() {
                assert_eq!(entry.check(entry.value()), Ok(()), "{index:#06x}/{subindex}");
                assert_eq!(entry.value(), entry.default_value());
            }
        }
        for mapping in (0x1600..=0x16FF).chain(0x1A00..=0x1AFF) {
            assert!(od.pdo_mapping(mapping).is_ok(), "{mapping:#06x}");
        }
    }
});
