//! `motus decode` and `motus encode`.

use crate::cli::{CrcArg, DirectionArg, FrameFormat};
use crate::hex;
use anyhow::{Context, Result};
use motus_ps1a_protocol::{CommandFrame, StatusReply};

/// Decodes and prints one JSON object.
pub fn decode(
    format: FrameFormat,
    text: &str,
    crc: CrcArg,
    direction: DirectionArg,
    revision: &str,
) -> Result<()> {
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
        FrameFormat::Kv01 => {
            use motus_kv01_protocol::{decode_message, CrcMode, Direction};
            let mode = match crc {
                CrcArg::Strict => CrcMode::Strict,
                CrcArg::Lenient => CrcMode::Lenient,
            };
            let dir = match direction {
                DirectionArg::Auto => Direction::Auto,
                DirectionArg::ToDevice => Direction::ToModule,
                DirectionArg::FromDevice => Direction::FromModule,
            };
            let decoded = decode_message(&bytes, dir, mode)
                .with_context(|| format!("invalid KV-01 message {}", hex::format(&bytes)))?;
            if let Some(m) = &decoded.crc_mismatch {
                eprintln!(
                    "warning: CRC mismatch accepted (lenient mode): expected 0x{:02X}, received 0x{:02X}",
                    m.expected, m.received
                );
            }
            serde_json::to_string(&decoded)?
        }
        FrameFormat::Nfv2 => {
            let rev = nfv2_revision(revision)?;
            let frame = motus_nfv2_protocol::decode_frame(&bytes, rev)
                .with_context(|| format!("invalid NFv2 frame {}", hex::format(&bytes)))?;
            serde_json::to_string(&frame)?
        }
    };
    println!("{json}");
    Ok(())
}

/// Encodes and prints uppercase hex.
pub fn encode(format: FrameFormat, json: &str, revision: &str) -> Result<()> {
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
        FrameFormat::Kv01 => {
            let decoded: motus_kv01_protocol::Decoded = serde_json::from_str(json).context(
                "invalid KV-01 JSON (e.g. {\"direction\":\"to_module\",\"address\":226,\"command\":\"d0\",\"text\":\"EN\"})",
            )?;
            decoded.message.encode().context("cannot encode the KV-01 message")?
        }
        FrameFormat::Nfv2 => {
            let frame: motus_nfv2_protocol::Frame = serde_json::from_str(json).context(
                "invalid NFv2 JSON (e.g. {\"address\":1,\"commands\":[{\"kind\":\"query\",\"code\":\"read_drives_position\"}]})",
            )?;
            motus_nfv2_protocol::encode_frame(&frame, nfv2_revision(revision)?)
                .context("cannot encode the NFv2 frame")?
        }
    };
    println!("{}", hex::format(&bytes));
    Ok(())
}

/// Parses an NFv2 revision name.
pub fn nfv2_revision(text: &str) -> Result<motus_nfv2_protocol::Revision> {
    text.parse::<motus_nfv2_protocol::Revision>().map_err(|e| anyhow::anyhow!("--revision {text:?}: {e}"))
}
