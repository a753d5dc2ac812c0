//! # motus-mouse-sim — the omni robot's optical-mouse odometry sensor, simulated
//!
//! The real sensor is a PS/2 optical mouse behind an ATmega converter that sends 7-byte
//! packets on RS-232 at 9600 bit/s 8N1 (see `motus-mouse-protocol`). Here:
//!
//! * [`MouseMotion`]: a thread-safe handle a world model feeds with the **true**
//!   displacement of the sensor, in metres, in the sensor frame.
//! * [`MouseSensor`]: converts the accumulated displacement to counts with the
//!   calibration (keeping the fractional remainder, so nothing is lost), clamps each
//!   packet's counts to i16 (carrying the excess), and builds the packets, optionally with
//!   garbage bytes between them (a noisy line).
//! * [`serve`]: sends a packet every period (10 ms by default) on a [`motus_serial::Link`]
//!   (a pty for tests and demos), paced at the line's baud rate; [`serve_with_clock`]
//!   waits on any [`motus_clock::Clock`] (a virtual one in tests).

#![forbid(unsafe_code)]

mod sensor;
mod serve;

pub use sensor::{MouseMotion, MouseSensor, SensorConfig, SensorError};
pub use serve::{serve, serve_with_clock, ServeStats};
