//! Faulhaber ASCII requests (`specs/faulhaber.md` §1.1, §1.2, §1.4): a typed subset of the
//! command set for a KV-01 simulator and driver, with [`Command::Unknown`] for the rest.
//!
//! Grammar (§1.5 step 1): spaces are dropped and case is ignored, then
//! `[node digits] LETTERS [+|-][digits]` with nothing after. The node number is 0..=255, the
//! argument an `i32`.

use std::fmt;

use serde::{Deserialize, Serialize};
use thiserror::Error;

use super::query::Query;
use super::reply::{ControllerError, Reply};

/// A Faulhaber command (without node number). Arguments are `i32`; the controller's own
/// range checks are not known (the spec lists them as "not found") and are not applied.
#[derive(Debug, Clone, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(tag = "cmd", content = "arg", rename_all = "snake_case")]
pub enum Command {
    /// `EN`: enable the drive.
    Enable,
    /// `DI`: disable the drive.
    Disable,
    /// `V<rpm>`: velocity mode at `rpm` (`V0` stops).
    Velocity(i32),
    /// `LA<n>`: load an absolute target position.
    LoadAbsolute(i32),
    /// `LR<n>`: load a relative target position.
    LoadRelative(i32),
    /// `M`: start positioning to the loaded target.
    Move,
    /// `HO[n]`: define the actual position as `n` (0 without argument).
    Home(Option<i32>),
    /// `NP[n]`: notify position (`p`).
    NotifyPosition(Option<i32>),
    /// `NPOFF`: cancel a pending position notification.
    NotifyPositionOff,
    /// `NV<n>`: notify velocity (`v`).
    NotifyVelocity(i32),
    /// `NVOFF`: cancel a pending velocity notification.
    NotifyVelocityOff,
    /// `U<n>`: output PWM value in voltage mode.
    Voltage(i32),
    /// `ENPROG`: enable the controller's sequence program.
    EnableProgram,
    /// `DIPROG`: stop the controller's sequence program.
    DisableProgram,
    /// `RESUME`: continue the program after `DIPROG`.
    Resume,
    /// `ANSW<n>`: answer mode (0, 1, 2).
    AnswerMode(i32),
    /// `SOR<n>`: velocity source (0 = serial interface).
    VelocitySource(i32),
    /// `SP<n>`: maximum (profile) speed, rpm.
    MaxSpeed(i32),
    /// `AC<n>`: acceleration, rev/s².
    Acceleration(i32),
    /// `DEC<n>`: deceleration, rev/s².
    Deceleration(i32),
    /// `LL<n>`: position range limit (positive = upper, negative = lower).
    PositionLimit(i32),
    /// `APL<0|1>`: deactivate / activate the position limits.
    ActivatePositionLimits(i32),
    /// `LPC<n>`: peak current limit, mA.
    PeakCurrent(i32),
    /// `LCC<n>`: continuous current limit, mA.
    ContinuousCurrent(i32),
    /// `BAUD<n>`: baud rate.
    Baud(i32),
    /// `NODEADR<n>`: node number.
    NodeAddress(i32),
    /// `SAVE`: store settings (reply `EEPROM writing done`).
    Save,
    /// `EEPSAV`: same as `SAVE`.
    EepSave,
    /// `GADV<i>`: voltage at analog input `i` (1000 digits = 1 V).
    AnalogInput(i32),
    /// A query without argument (`POS`, `GN`, `GST`, `VER`...).
    Query(Query),
    /// Any other command, normalised (upper case, no spaces, node number removed), e.g.
    /// `GPROGSEQ1`. It always starts with a letter.
    Unknown(String),
}

/// Why a string is not a well-formed Faulhaber request.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum RequestError {
    /// Nothing but spaces (and perhaps a node number).
    #[error("empty command")]
    Empty,
    /// The text does not have the form `[node] LETTERS [sign digits]`.
    #[error("not a command: {0:?}")]
    Syntax(String),
    /// The node number is above 255.
    #[error("node number out of range (0..=255)")]
    NodeOutOfRange,
    /// A known command needs an argument and has none.
    #[error("{0} needs an argument")]
    MissingArgument(&'static str),
    /// A known command takes no argument and has one.
    #[error("{0} takes no argument")]
    UnexpectedArgument(&'static str),
    /// The argument does not fit in an `i32`.
    #[error("argument of {0} out of range")]
    ArgumentOutOfRange(&'static str),
}

impl RequestError {
    /// What a controller in answer mode 2 would answer (`specs/faulhaber.md` §1.5 step 5):
    /// `Unknown command` for text that is no command, `Invalid parameter` otherwise.
    #[must_use]
    pub fn controller_reply(&self) -> Reply {
        match self {
            Self::Empty | Self::Syntax(_) => Reply::Error(ControllerError::UnknownCommand),
            _ => Reply::Error(ControllerError::InvalidParameter),
        }
    }
}

/// A Faulhaber request: optional node number and a command.
#[derive(Debug, Clone, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Request {
    /// Node number prefix (0..=255); `None` addresses every drive on the line.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub node: Option<u8>,
    /// The command.
    #[serde(flatten)]
    pub command: Command,
}

impl From<Command> for Request {
    fn from(command: Command) -> Self {
        Self { node: None, command }
    }
}

#[derive(Clone, Copy)]
enum Arg {
    None,
    Required,
    Optional,
}

/// The known mnemonics other than the queries, with their argument rule.
const RULES: [(&str, Arg); 29] = [
    ("EN", Arg::None),
    ("DI", Arg::None),
    ("V", Arg::Required),
    ("LA", Arg::Required),
    ("LR", Arg::Required),
    ("M", Arg::None),
    ("HO", Arg::Optional),
    ("NP", Arg::Optional),
    ("NPOFF", Arg::None),
    ("NV", Arg::Required),
    ("NVOFF", Arg::None),
    ("U", Arg::Required),
    ("ENPROG", Arg::None),
    ("DIPROG", Arg::None),
    ("RESUME", Arg::None),
    ("ANSW", Arg::Required),
    ("SOR", Arg::Required),
    ("SP", Arg::Required),
    ("AC", Arg::Required),
    ("DEC", Arg::Required),
    ("LL", Arg::Required),
    ("APL", Arg::Required),
    ("LPC", Arg::Required),
    ("LCC", Arg::Required),
    ("BAUD", Arg::Required),
    ("NODEADR", Arg::Required),
    ("SAVE", Arg::None),
    ("EEPSAV", Arg::None),
    ("GADV", Arg::Required),
];

/// The static mnemonic and argument rule of a known upper-case mnemonic.
fn rule(m: &str) -> Option<(&'static str, Arg)> {
    RULES
        .iter()
        .find(|(s, _)| *s == m)
        .copied()
        .or_else(|| Query::from_mnemonic(m).map(|q| (q.mnemonic(), Arg::None)))
}

fn build(m: &str, a: Option<i32>) -> Command {
    let n = a.unwrap_or(0);
    match m {
        "EN" => Command::Enable,
        "DI" => Command::Disable,
        "V" => Command::Velocity(n),
        "LA" => Command::LoadAbsolute(n),
        "LR" => Command::LoadRelative(n),
        "M" => Command::Move,
        "HO" => Command::Home(a),
        "NP" => Command::NotifyPosition(a),
        "NPOFF" => Command::NotifyPositionOff,
        "NV" => Command::NotifyVelocity(n),
        "NVOFF" => Command::NotifyVelocityOff,
        "U" => Command::Voltage(n),
        "ENPROG" => Command::EnableProgram,
        "DIPROG" => Command::DisableProgram,
        "RESUME" => Command::Resume,
        "ANSW" => Command::AnswerMode(n),
        "SOR" => Command::VelocitySource(n),
        "SP" => Command::MaxSpeed(n),
        "AC" => Command::Acceleration(n),
        "DEC" => Command::Deceleration(n),
        "LL" => Command::PositionLimit(n),
        "APL" => Command::ActivatePositionLimits(n),
        "LPC" => Command::PeakCurrent(n),
        "LCC" => Command::ContinuousCurrent(n),
        "BAUD" => Command::Baud(n),
        "NODEADR" => Command::NodeAddress(n),
        "SAVE" => Command::Save,
        "EEPSAV" => Command::EepSave,
        "GADV" => Command::AnalogInput(n),
        _ => match Query::from_mnemonic(m) {
            Some(q) => Command::Query(q),
            None => Command::Unknown(m.to_owned()),
        },
    }
}

impl Command {
    /// The mnemonic and the argument, as formatted.
    #[must_use]
    pub fn parts(&self) -> (&str, Option<i32>) {
        match self {
            Self::Enable => ("EN", None),
            Self::Disable => ("DI", None),
            Self::Velocity(n) => ("V", Some(*n)),
            Self::LoadAbsolute(n) => ("LA", Some(*n)),
            Self::LoadRelative(n) => ("LR", Some(*n)),
            Self::Move => ("M", None),
            Self::Home(a) => ("HO", *a),
            Self::NotifyPosition(a) => ("NP", *a),
            Self::NotifyPositionOff => ("NPOFF", None),
            Self::NotifyVelocity(n) => ("NV", Some(*n)),
            Self::NotifyVelocityOff => ("NVOFF", None),
            Self::Voltage(n) => ("U", Some(*n)),
            Self::EnableProgram => ("ENPROG", None),
            Self::DisableProgram => ("DIPROG", None),
            Self::Resume => ("RESUME", None),
            Self::AnswerMode(n) => ("ANSW", Some(*n)),
            Self::VelocitySource(n) => ("SOR", Some(*n)),
            Self::MaxSpeed(n) => ("SP", Some(*n)),
            Self::Acceleration(n) => ("AC", Some(*n)),
            Self::Deceleration(n) => ("DEC", Some(*n)),
            Self::PositionLimit(n) => ("LL", Some(*n)),
            Self::ActivatePositionLimits(n) => ("APL", Some(*n)),
            Self::PeakCurrent(n) => ("LPC", Some(*n)),
            Self::ContinuousCurrent(n) => ("LCC", Some(*n)),
            Self::Baud(n) => ("BAUD", Some(*n)),
            Self::NodeAddress(n) => ("NODEADR", Some(*n)),
            Self::Save => ("SAVE", None),
            Self::EepSave => ("EEPSAV", None),
            Self::AnalogInput(n) => ("GADV", Some(*n)),
            Self::Query(q) => (q.mnemonic(), None),
            Self::Unknown(s) => (s.as_str(), None),
        }
    }

    /// Whether the controller answers this command with a value in every answer mode.
    #[must_use]
    pub fn is_query(&self) -> bool {
        matches!(self, Self::Query(_) | Self::AnalogInput(_))
    }
}

/// Splits off the longest prefix whose bytes satisfy `f`.
fn split_while(s: &str, f: impl Fn(u8) -> bool) -> (&str, &str) {
    let n = s.bytes().take_while(|&b| f(b)).count();
    // `n` counts ASCII bytes only, so it is a char boundary.
    s.split_at_checked(n).unwrap_or((s, ""))
}

impl Request {
    /// Parses a request (without terminator): spaces ignored, case ignored, optional node
    /// number prefix. Unknown mnemonics give [`Command::Unknown`]; a known mnemonic with a
    /// missing, extra or too large argument is an error. Never panics.
    pub fn parse(text: &str) -> Result<Self, RequestError> {
        let norm: String = text.chars().filter(|&c| c != ' ').map(|c| c.to_ascii_uppercase()).collect();
        let (node_digits, rest) = split_while(&norm, |b| b.is_ascii_digit());
        let (mnemonic, rest) = split_while(rest, |b| b.is_ascii_uppercase());
        let (sign, rest) = split_while(rest, |b| b == b'+' || b == b'-');
        let (digits, tail) = split_while(rest, |b| b.is_ascii_digit());
        if mnemonic.is_empty() {
            return Err(if rest.is_empty() && sign.is_empty() {
                RequestError::Empty
            } else {
                RequestError::Syntax(text.to_owned())
            });
        }
        if !tail.is_empty() || sign.len() > 1 || (!sign.is_empty() && digits.is_empty()) {
            return Err(RequestError::Syntax(text.to_owned()));
        }
        let node = if node_digits.is_empty() {
            None
        } else {
            Some(node_digits.parse::<u8>().map_err(|_| RequestError::NodeOutOfRange)?)
        };
        let arg_text = format!("{sign}{digits}");
        let Some((name, rule)) = rule(mnemonic) else {
            return Ok(Self { node, command: Command::Unknown(format!("{mnemonic}{arg_text}")) });
        };
        let arg = if digits.is_empty() {
            None
        } else {
            Some(arg_text.parse::<i32>().map_err(|_| RequestError::ArgumentOutOfRange(name))?)
        };
        match (rule, arg) {
            (Arg::None, Some(_)) => Err(RequestError::UnexpectedArgument(name)),
            (Arg::Required, None) => Err(RequestError::MissingArgument(name)),
            _ => Ok(Self { node, command: build(name, arg) }),
        }
    }

    /// The velocity of a `V` command, the command the KV-01 module filters (LSSTOP/LIMVAL).
    #[must_use]
    pub fn velocity(&self) -> Option<i32> {
        match self.command {
            Command::Velocity(v) => Some(v),
            _ => None,
        }
    }
}

impl fmt::Display for Request {
    /// Canonical form: `[node]MNEMONIC[argument]`, upper case, no spaces.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(n) = self.node {
            write!(f, "{n}")?;
        }
        let (m, a) = self.command.parts();
        f.write_str(m)?;
        if let Some(a) = a {
            write!(f, "{a}")?;
        }
        Ok(())
    }
}

impl std::str::FromStr for Request {
    type Err = RequestError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::parse(s)
    }
}
