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
    if format == FrameFormat::Canopen {
        return decode_canopen(text);
    }
    let bytes = hex::parse(text)?;
    let json = match format {
        FrameFormat::Canopen => unreachable_canopen()?,
        FrameFormat::Epl => serde_json::to_string(
            &motus_epl_protocol::EplFrame::decode(&bytes)
                .with_context(|| format!("invalid POWERLINK frame {}", hex::format(&bytes)))?,
        )?,
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
    if format == FrameFormat::Canopen {
        return encode_canopen(json);
    }
    let bytes = match format {
        FrameFormat::Canopen => unreachable_canopen()?,
        FrameFormat::Epl => serde_json::from_str::<motus_epl_protocol::EplFrame>(json)
            .context("invalid POWERLINK JSON (the form `motus decode epl` prints)")?
            .encode()
            .context("cannot encode the POWERLINK frame")?,
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

fn unreachable_canopen<T>() -> Result<T> {
    anyhow::bail!("internal: CANopen frames are handled before hex parsing")
}

/// The JSON `decode canopen` prints: the frame, a one-line description and the message.
#[derive(serde::Serialize)]
struct CanOpenDecoded<'a> {
    frame: String,
    text: String,
    #[serde(flatten)]
    message: &'a motus_canopen_protocol::CanOpenMessage,
}

/// Decodes a CANopen frame in candump notation and prints one JSON object whose `text`
/// names the service, node and content (e.g. "SDO upload response 0x6064:00 = 1000").
fn decode_canopen(text: &str) -> Result<()> {
    use motus_canopen_protocol::{CanFrame, CanOpenMessage};
    let frame: CanFrame = text.trim().parse().with_context(|| {
        format!(
            "invalid CAN frame {text:?} (expected candump notation <id>#<hex>, e.g. 581#4B64600000000000)"
        )
    })?;
    let message = CanOpenMessage::decode(&frame);
    let out = CanOpenDecoded { frame: frame.to_string(), text: message.to_string(), message: &message };
    println!("{}", serde_json::to_string(&out)?);
    Ok(())
}

/// Encodes a CANopen message given as JSON (the form `decode canopen` prints; `frame`
/// and `text` are ignored) and prints the frame in candump notation.
fn encode_canopen(json: &str) -> Result<()> {
    let message: motus_canopen_protocol::CanOpenMessage = serde_json::from_str(json)
        .context("invalid CANopen JSON (e.g. {\"type\":\"nmt\",\"command\":1,\"node\":5})")?;
    let frame = message.encode().context("cannot encode the CANopen message")?;
    println!("{frame}");
    Ok(())
}
