//! The half-duplex bus master and its helpers.

pub mod master;
pub mod poller;
pub mod stats;
