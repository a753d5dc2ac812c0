//! Answers to queries, as a slave (or a simulator of one) builds them.
//!
//! "A query is a command header with k = 0; the slave answers with a frame carrying its
//! own address, the same command codes and the data as parameters." Queries for codes
//! the slave does not support are skipped like any unknown command, and a frame without
//! any answerable query gets no answer at all.

use crate::code::CommandCode;
use crate::command::Command;
use crate::frame::Frame;

/// Builds the answer of the slave at `own_address` to `request`.
///
/// `provide` is called once per query, in order, and returns the answering command (its
/// values, usually [`Command::Values`] with the same code) or `None` if the slave does not
/// support the code. Returns `None` if no query was answered. Whether the slave should
/// answer at all (addressed to it, not a broadcast) is
/// [`AddressPlan::answers`](crate::AddressPlan::answers).
///
/// ```
/// use motus_nfv2_protocol::{answer, Command, CommandCode as C, Frame};
/// let mut request = Frame::new(1);
/// request.commands.push(Command::values(C::SetDrivesPosition, [100]));
/// request.commands.push(Command::query(C::ReadDrivesPosition));
/// let reply = answer(&request, 1, |code| match code {
///     C::ReadDrivesPosition => Some(Command::values(code, [98])),
///     _ => None,
/// });
/// assert_eq!(reply.and_then(|f| f.int_values(C::ReadDrivesPosition).map(<[i64]>::to_vec)), Some(vec![98]));
/// ```
pub fn answer(
    request: &Frame,
    own_address: u8,
    mut provide: impl FnMut(CommandCode) -> Option<Command>,
) -> Option<Frame> {
    let commands: Vec<Command> = request.queries().filter_map(&mut provide).collect();
    (!commands.is_empty()).then_some(Frame { address: own_address, commands })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unsupported_queries_are_skipped() {
        let mut request = Frame::new(2);
        request.commands.push(Command::query(CommandCode::Unknown(0x60)));
        assert_eq!(answer(&request, 2, |_| None), None);
        request.commands.push(Command::query(CommandCode::ReadDrivesStatus));
        let reply = answer(&request, 2, |code| {
            (code == CommandCode::ReadDrivesStatus).then(|| Command::values(code, [0x10]))
        });
        assert_eq!(
            reply,
            Some(Frame {
                address: 2,
                commands: vec![Command::values(CommandCode::ReadDrivesStatus, [0x10])]
            })
        );
    }
}
