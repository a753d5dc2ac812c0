//! Command frames, host -> module: `ADR N KOD P1..PN CHSUM`.

use crate::checksum::sum8;
use crate::error::{DecodeError, EncodeError};
use crate::layout::{ADDRESS_INDEX, CODE_INDEX, LENGTH_INDEX, OVERHEAD, PARAMS_INDEX};
use crate::parameters::{Acceleration, ControlByte, Parameters};
use crate::values::{I24, U24};
use serde::{Deserialize, Serialize};

/// The command codes 0..=10.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum CommandCode {
    /// 0: status request.
    StatusRequest = 0,
    /// 1: set parameters.
    SetParameters = 1,
    /// 2: command byte.
    ControlByte = 2,
    /// 3: set speed and acceleration.
    SetSpeed = 3,
    /// 4: move absolute.
    MoveAbsolute = 4,
    /// 5: move relative.
    MoveRelative = 5,
    /// 6: jog plus.
    JogPlus = 6,
    /// 7: jog minus.
    JogMinus = 7,
    /// 8: reset.
    Reset = 8,
    /// 9: stop.
    Stop = 9,
    /// 10: home.
    Home = 10,
}

impl CommandCode {
    /// The code for a byte, if known.
    pub fn from_u8(v: u8) -> Option<CommandCode> {
        use CommandCode::*;
        Some(match v {
            0 => StatusRequest,
            1 => SetParameters,
            2 => ControlByte,
            3 => SetSpeed,
            4 => MoveAbsolute,
            5 => MoveRelative,
            6 => JogPlus,
            7 => JogMinus,
            8 => Reset,
            9 => Stop,
            10 => Home,
            _ => return None,
        })
    }

    /// Number of parameter bytes (N) this command takes.
    pub fn parameter_len(self) -> u8 {
        match self {
            CommandCode::SetParameters => 11,
            CommandCode::ControlByte => 1,
            CommandCode::SetSpeed | CommandCode::MoveAbsolute | CommandCode::MoveRelative => 3,
            _ => 0,
        }
    }

    /// The spec's name.
    pub fn name(self) -> &'static str {
        match self {
            CommandCode::StatusRequest => "status request",
            CommandCode::SetParameters => "set parameters",
            CommandCode::ControlByte => "command byte",
            CommandCode::SetSpeed => "set speed and acceleration",
            CommandCode::MoveAbsolute => "move absolute",
            CommandCode::MoveRelative => "move relative",
            CommandCode::JogPlus => "jog plus",
            CommandCode::JogMinus => "jog minus",
            CommandCode::Reset => "reset",
            CommandCode::Stop => "stop",
            CommandCode::Home => "home",
        }
    }
}

/// A typed command with its parameters.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(tag = "command", rename_all = "snake_case", deny_unknown_fields)]
pub enum Command {
    /// 0: ask for the status reply.
    StatusRequest,
    /// 1: set (and store in EEPROM) the parameters.
    SetParameters {
        /// The parameter block.
        parameters: Parameters,
    },
    /// 2: the command byte (power stage, interpolation blocking, homing approaches).
    ControlByte {
        /// The byte.
        control: ControlByte,
    },
    /// 3: speed (16 bit, speed units) and acceleration number for later motion.
    SetSpeed {
        /// Speed value V.
        speed: u16,
        /// Acceleration number.
        acceleration: Acceleration,
    },
    /// 4: move to an absolute target.
    MoveAbsolute {
        /// Target in encoder units.
        target: U24,
    },
    /// 5: move by a signed increment.
    MoveRelative {
        /// Increment in encoder units.
        increment: I24,
    },
    /// 6: jog in the plus direction.
    JogPlus,
    /// 7: jog in the minus direction.
    JogMinus,
    /// 8: reset, like power-on.
    Reset,
    /// 9: stop a jog.
    Stop,
    /// 10: home (software reference approach).
    Home,
}

impl Command {
    /// The command code.
    pub fn code(&self) -> CommandCode {
        match self {
            Command::StatusRequest => CommandCode::StatusRequest,
            Command::SetParameters { .. } => CommandCode::SetParameters,
            Command::ControlByte { .. } => CommandCode::ControlByte,
            Command::SetSpeed { .. } => CommandCode::SetSpeed,
            Command::MoveAbsolute { .. } => CommandCode::MoveAbsolute,
            Command::MoveRelative { .. } => CommandCode::MoveRelative,
            Command::JogPlus => CommandCode::JogPlus,
            Command::JogMinus => CommandCode::JogMinus,
            Command::Reset => CommandCode::Reset,
            Command::Stop => CommandCode::Stop,
            Command::Home => CommandCode::Home,
        }
    }

    /// True if sending the command twice is harmless, so a host may retry it after a lost
    /// reply. A relative move is not: a retry could move twice. (A repeated reset or home
    /// restarts the same procedure, which is harmless.)
    pub fn is_idempotent(&self) -> bool {
        !matches!(self, Command::MoveRelative { .. })
    }

    /// True if the command may start motion.
    pub fn starts_motion(&self) -> bool {
        match self {
            Command::MoveAbsolute { .. }
            | Command::MoveRelative { .. }
            | Command::JogPlus
            | Command::JogMinus
            | Command::Home => true,
            Command::ControlByte { control } => {
                control.reference_approach() || control.encoder_zero_approach()
            }
            _ => false,
        }
    }

    /// Encoded frame length in bytes.
    pub fn frame_len(&self) -> usize {
        OVERHEAD + usize::from(self.code().parameter_len())
    }
}

/// A command addressed to one module.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct CommandFrame {
    /// Module address.
    pub addr: u8,
    /// The command.
    #[serde(flatten)]
    pub command: Command,
}

impl CommandFrame {
    /// A frame for `command` to module `addr`.
    pub fn new(addr: u8, command: Command) -> Self {
        CommandFrame { addr, command }
    }

    /// Writes the frame into `buf`, returning its length. Allocation-free.
    pub fn encode_into(&self, buf: &mut [u8]) -> Result<usize, EncodeError> {
        let code = self.command.code();
        let n = code.parameter_len();
        let len = OVERHEAD + usize::from(n);
        let have = buf.len();
        let out = buf.get_mut(..len).ok_or(EncodeError::BufferTooSmall { needed: len, have })?;
        let mut params = [0u8; 11];
        let p: &[u8] = match &self.command {
            Command::SetParameters { parameters } => {
                params = parameters.to_bytes();
                &params
            }
            Command::ControlByte { control } => {
                params[0] = control.0;
                &params[..1]
            }
            Command::SetSpeed { speed, acceleration } => {
                let [lv, hv] = speed.to_le_bytes();
                params[..3].copy_from_slice(&[lv, hv, acceleration.get()]);
                &params[..3]
            }
            Command::MoveAbsolute { target } => {
                params[..3].copy_from_slice(&target.to_le());
                &params[..3]
            }
            Command::MoveRelative { increment } => {
                params[..3].copy_from_slice(&increment.to_le());
                &params[..3]
            }
            _ => &[],
        };
        let (header, rest) = out.split_at_mut(PARAMS_INDEX);
        let mut head = [0u8; PARAMS_INDEX];
        head[ADDRESS_INDEX] = self.addr;
        head[LENGTH_INDEX] = n;
        head[CODE_INDEX] = code as u8;
        header.copy_from_slice(&head);
        let (body, sum) = rest.split_at_mut(p.len());
        body.copy_from_slice(p);
        let total = sum8(header).wrapping_add(sum8(body));
        if let Some(s) = sum.first_mut() {
            *s = total;
        }
        Ok(len)
    }

    /// The encoded frame.
    pub fn encode(&self) -> Vec<u8> {
        let mut buf = [0u8; crate::MAX_COMMAND_LEN];
        let len = self.encode_into(&mut buf).unwrap_or(0);
        buf.get(..len).map(<[u8]>::to_vec).unwrap_or_default()
    }

    /// Decodes exactly one frame occupying all of `bytes`.
    pub fn decode(bytes: &[u8]) -> Result<CommandFrame, DecodeError> {
        let expected = Self::frame_len_from_header(bytes)?;
        if bytes.len() < expected {
            return Err(DecodeError::TooShort { needed: expected, got: bytes.len() });
        }
        if bytes.len() > expected {
            let declared = bytes.get(LENGTH_INDEX).copied().unwrap_or(0);
            return Err(DecodeError::TooLong { declared, expected, got: bytes.len() });
        }
        Self::decode_prefix(bytes)
    }

    /// Total frame length announced by the header, once the code and N are consistent.
    /// Needs at least the three header bytes.
    pub fn frame_len_from_header(bytes: &[u8]) -> Result<usize, DecodeError> {
        let (Some(&n), Some(&code)) = (bytes.get(LENGTH_INDEX), bytes.get(CODE_INDEX)) else {
            return Err(DecodeError::TooShort { needed: PARAMS_INDEX, got: bytes.len() });
        };
        let cc = CommandCode::from_u8(code).ok_or(DecodeError::UnknownCode(code))?;
        if cc.parameter_len() != n {
            return Err(DecodeError::WrongParameterCount {
                code,
                name: cc.name(),
                declared: n,
                expected: cc.parameter_len(),
            });
        }
        Ok(OVERHEAD + usize::from(n))
    }

    /// Decodes the frame at the start of `bytes` (extra bytes after it are ignored).
    pub fn decode_prefix(bytes: &[u8]) -> Result<CommandFrame, DecodeError> {
        let len = Self::frame_len_from_header(bytes)?;
        let frame = bytes.get(..len).ok_or(DecodeError::TooShort { needed: len, got: bytes.len() })?;
        let (body, sum) = frame.split_at(len - 1);
        let received = sum.first().copied().unwrap_or(0);
        let expected = sum8(body);
        if expected != received {
            return Err(DecodeError::Checksum { expected, received });
        }
        let addr = body.first().copied().unwrap_or(0);
        let code = body.get(CODE_INDEX).copied().unwrap_or(0);
        let p = body.get(PARAMS_INDEX..).unwrap_or(&[]);
        let command = match CommandCode::from_u8(code).ok_or(DecodeError::UnknownCode(code))? {
            CommandCode::StatusRequest => Command::StatusRequest,
            CommandCode::SetParameters => {
                let b: [u8; 11] =
                    p.try_into().map_err(|_| DecodeError::TooShort { needed: len, got: bytes.len() })?;
                Command::SetParameters { parameters: Parameters::from_bytes(b)? }
            }
            CommandCode::ControlByte => {
                Command::ControlByte { control: ControlByte(p.first().copied().unwrap_or(0)) }
            }
            CommandCode::SetSpeed => {
                let [lv, hv, a] = three(p, len, bytes.len())?;
                Command::SetSpeed {
                    speed: u16::from_le_bytes([lv, hv]),
                    acceleration: Acceleration::decode("A", a)?,
                }
            }
            CommandCode::MoveAbsolute => {
                Command::MoveAbsolute { target: U24::from_le(three(p, len, bytes.len())?) }
            }
            CommandCode::MoveRelative => {
                Command::MoveRelative { increment: I24::from_le(three(p, len, bytes.len())?) }
            }
            CommandCode::JogPlus => Command::JogPlus,
            CommandCode::JogMinus => Command::JogMinus,
            CommandCode::Reset => Command::Reset,
            CommandCode::Stop => Command::Stop,
            CommandCode::Home => Command::Home,
        };
        Ok(CommandFrame { addr, command })
    }
}

fn three(p: &[u8], needed: usize, got: usize) -> Result<[u8; 3], DecodeError> {
    p.try_into().map_err(|_| DecodeError::TooShort { needed, got })
}
