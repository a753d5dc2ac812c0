//! The cell file as written: serde structs with spans on every value the validator checks.

use serde::Deserialize;
use toml::Spanned;

use super::model::{DeviceKind, GroupKind, LinkKind, TaskKind, Unit};

/// The whole file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawCell {
    pub station: RawStation,
    #[serde(default)]
    pub link: Vec<RawLink>,
    #[serde(default)]
    pub device: Vec<RawDevice>,
    #[serde(default)]
    pub axis: Vec<RawAxis>,
    #[serde(default)]
    pub group: Vec<RawGroup>,
    pub supervisor: Option<RawSupervisor>,
    #[serde(default)]
    pub task: Vec<RawTask>,
    #[serde(default)]
    pub program: Vec<RawProgram>,
    #[serde(default)]
    pub tool: Vec<RawTool>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawStation {
    pub name: Spanned<String>,
    pub listen: Option<Spanned<String>>,
    pub data_dir: Option<Spanned<String>>,
    #[serde(default)]
    pub origins: Vec<Spanned<String>>,
    pub program_check_time: Option<Spanned<f64>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawLink {
    pub name: Spanned<String>,
    pub kind: LinkKind,
    pub uri: Spanned<String>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawDevice {
    pub name: Spanned<String>,
    pub kind: Spanned<DeviceKind>,
    pub link: Option<Spanned<String>>,
    pub address: Option<Spanned<i64>>,
    #[serde(default)]
    pub simulate: bool,
    pub baud: Option<Spanned<i64>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawLimits {
    pub min: Spanned<f64>,
    pub max: Spanned<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawStudent {
    pub min: Option<Spanned<f64>>,
    pub max: Option<Spanned<f64>>,
    pub max_velocity: Option<Spanned<f64>>,
    pub max_acceleration: Option<Spanned<f64>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawAxis {
    pub name: Spanned<String>,
    pub device: Spanned<String>,
    pub index: Option<Spanned<i64>>,
    pub unit: Unit,
    pub scale: Spanned<f64>,
    pub offset: Option<Spanned<f64>>,
    pub limits: RawLimits,
    pub max_velocity: Spanned<f64>,
    pub max_acceleration: Spanned<f64>,
    pub student: Option<RawStudent>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawGroup {
    pub name: Spanned<String>,
    pub kind: GroupKind,
    pub axes: Spanned<Vec<Spanned<String>>>,
    #[serde(default)]
    pub camera: Option<Spanned<String>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawSupervisor {
    pub rules: Spanned<String>,
    pub drives: Option<Spanned<String>>,
    pub approval: Option<Spanned<String>>,
    pub key: Option<Spanned<String>>,
    pub group: Option<Spanned<String>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawTask {
    pub name: Spanned<String>,
    pub period_ms: Spanned<f64>,
    pub kind: Spanned<TaskKind>,
    pub group: Option<Spanned<String>>,
    pub program: Option<Spanned<String>>,
    pub overrun_limit: Option<Spanned<i64>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawTool {
    pub number: Spanned<i64>,
    pub diameter_mm: Spanned<f64>,
    pub length_mm: Spanned<f64>,
    pub comment: Option<String>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawProgram {
    pub name: Spanned<String>,
    pub file: Spanned<String>,
    pub group: Option<Spanned<String>>,
}
