//! The Faulhaber motion-controller ASCII protocol carried inside KV-01 D0/D2 messages
//! (`specs/faulhaber.md`). The module adds and strips the terminator, so every string here is
//! **without** its CR / CR LF.
//!
//! - [`Request`]: `[node] COMMAND [argument]`, parsed case-insensitively with spaces ignored
//!   ([`Request::parse`]) and formatted canonically (upper case, no spaces) by `Display`.
//! - [`Reply`]: the controller's answer: a number, `OK`, an error string,
//!   `EEPROM writing done`... ([`Reply::parse`] is total and exact: anything else is
//!   [`Reply::Text`]).
//! - [`status`]: the OST bits and GST/GFS/GAST status strings.

mod query;
mod reply;
mod request;
pub mod status;

pub use query::Query;
pub use reply::{ControllerError, Reply};
pub use request::{Command, Request, RequestError};
