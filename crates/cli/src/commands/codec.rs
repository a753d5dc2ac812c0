//! `motus decode` and `motus encode`.

use crate::cli::FrameFormat;
use crate::hex;
use anyhow::{Context, Result};
use motus_ps1a_protocol::{CommandFrame, StatusReply};

/// Decodes and prints one JSON object.
pub fn decode(format: FrameFormat, text: &str) -> Result<()> {
    let bytes = hex::parse(text)?;
    let json = match format {
        FrameFormat::Ps1aCmd => serde_json::to_string(
            &CommandFrame::decode(&bytes)
                .with_context(|| format!("invalid PS1A command {}", hex::format(&bytes)))?,
        )?,
        FrameFormat::Ps1aReply => serde_json::to_string(
            &StatusReply::decode(&bytes)
                .with_context(|| format!("invalid PS1A reply {}", hex::format(&bytes)))?,
        )?,
    };
    println!("{json}");
    Ok(())
}

/// Encodes and prints uppercase hex.
pub fn encode(format: FrameFormat, json: &str) -> Result<()> {
    let bytes = match format {
        FrameFormat::Ps1aCmd => serde_json::from_str::<CommandFrame>(json)
            .context(
                "invalid PS1A command JSON (e.g. {\"addr\":3,\"command\":\"move_absolute\",\"target\":1000})",
            )?
            .encode(),
        FrameFormat::Ps1aReply => serde_json::from_str::<StatusReply>(json)
            .context("invalid PS1A reply JSON (e.g. {\"addr\":3,\"lbs\":0,\"hbs\":3,\"position\":1000})")?
            .to_bytes()
            .to_vec(),
    };
    println!("{}", hex::format(&bytes));
    Ok(())
}
