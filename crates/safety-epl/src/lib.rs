//! The predictive collision supervisor ([`motus_safety`]) online on a POWERLINK segment
//! ([`motus_epl`]): the juggler's safety chain without the PLC in between.
//!
//! * [`inputs`]: turns each PRes of a supervised drive into a supervisor [`motus_safety::Sample`]
//!   (the node of an axis is its `id` in the rules; values by name from a value map: `position`,
//!   `speed`, optionally `status` for the homed bit), scaled by the axis's `raw_per_unit`.
//! * [`juggler`]: the simulated juggler's drives, patterns (juggle, limit, collide) and value
//!   map, derived from a rules file.
//! * [`lease`]: [`lease::EplLeaseTarget`], a [`motus_safety::StopTarget`] that broadcasts the
//!   safety lease ASnd from node 253 (the simulated segment of the demo) ([`motus_epl_protocol::SafetyLease`]): renewals while SafeToRun holds, a
//!   revoke (quick stop of every drive) the moment it falls.
//! * [`safety_node`]: [`safety_node::SafetyNode`], the supervisor as a CN of the segment: a
//!   standards CN whose PRes carries SafeToRun and a lease counter to every node (cross
//!   traffic), the way to stop drives on a segment with foreign nodes, and
//!   [`safety_node::SafetyNodeTarget`], its stop target.
//! * [`runner`]: [`runner::OnlineSupervisor`] evaluates the rules on **every** PRes and SoC
//!   (not once per cycle: the reaction starts at the frame that makes the state unsafe),
//!   applies the decision through a [`motus_safety::Fanout`] (the lease target plus any axes of
//!   the axis model), checks the configuration's integrity, and records the reaction time
//!   from the reception of the frame to the moment the stop left Motus.
//!   [`runner::OnlineSupervisor::run`] is the one supervisor loop (`motus safety run`, the
//!   station's juggler, the tests): a link, a channel of [`runner::Command`]s (operator stop
//!   and reset, integrity results, approved rules), a stop flag and an event callback.
//! * [`watcher`]: [`watcher::IntegrityWatcher`], the one integrity watcher: a thread that
//!   re-checks the approved configuration files ([`motus_safety::ConfigFiles::check`]) and
//!   sends the results into the loop's channel.

pub mod inputs;
pub mod juggler;
pub mod lease;
pub mod runner;
pub mod safety_node;
pub mod watcher;

pub use inputs::{InputError, InputMap};
pub use lease::EplLeaseTarget;
pub use runner::{Command, OnlineConfig, OnlineEvent, OnlineSupervisor, ReactionStats, ServeEvent};
pub use safety_node::{SafetyNode, SafetyNodeConfig, SafetyNodeTarget};
pub use watcher::{InputsFor, IntegrityWatcher};
