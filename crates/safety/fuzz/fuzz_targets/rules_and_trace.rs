//! Arbitrary text as a rules file, as a rule expression inside the juggler's rules, and as a
//! trace evaluated with the juggler's rules: errors are fine, panics are not.
#![no_main]

use libfuzzer_sys::fuzz_target;
use motus_safety::{trace, RuleSet, JUGGLER_TOML};

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let _ = RuleSet::from_toml(text);
    // The text as the expression of one more rule (reaches the expression parser directly).
    let escaped = text.replace('\\', "\\\\").replace('"', "\\\"").replace('\n', " ");
    let with_rule = format!("{JUGGLER_TOML}\n[[rule]]\nname = \"fuzz\"\nexpr = \"{escaped}\"\n");
    let _ = RuleSet::from_toml(&with_rule);
    if let Ok(rules) = RuleSet::from_toml(JUGGLER_TOML) {
        if let Ok(rows) = trace::evaluate(&rules, text) {
            let _ = trace::format_rows(&rules, &rows);
        }
    }
});
