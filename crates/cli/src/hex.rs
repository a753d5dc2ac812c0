//! Hex text in and out.

use anyhow::{bail, Result};

/// Parses hex bytes: "03 00 00 03", "03000003", "0x03,0x00" and mixtures.
pub fn parse(text: &str) -> Result<Vec<u8>> {
    let mut digits = String::new();
    for token in text.split(|c: char| c.is_whitespace() || c == ',' || c == ':' || c == '-') {
        let t = token.trim_start_matches("0x").trim_start_matches("0X");
        if t.len() % 2 == 1 && !t.is_empty() {
            bail!("invalid hex input: {token:?} has an odd number of digits");
        }
        digits.push_str(t);
    }
    if digits.is_empty() {
        bail!("invalid hex input: no bytes given");
    }
    let mut out = Vec::with_capacity(digits.len() / 2);
    let chars: Vec<char> = digits.chars().collect();
    for pair in chars.chunks(2) {
        let s: String = pair.iter().collect();
        let b = u8::from_str_radix(&s, 16)
            .map_err(|_| anyhow::anyhow!("invalid hex input: {s:?} is not a hex byte"))?;
        out.push(b);
    }
    Ok(out)
}

/// Uppercase hex bytes separated by spaces.
pub fn format(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02X}")).collect::<Vec<_>>().join(" ")
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used)]
    use super::*;

    #[test]
    fn forms() {
        assert_eq!(parse("03 00 00 03").unwrap(), [3, 0, 0, 3]);
        assert_eq!(parse("03000003").unwrap(), [3, 0, 0, 3]);
        assert_eq!(parse("0x03,0x00").unwrap(), [3, 0]);
        assert!(parse("0").is_err());
        assert!(parse("zz").is_err());
        assert!(parse("").is_err());
        assert_eq!(format(&[0xAB, 1]), "AB 01");
    }
}
