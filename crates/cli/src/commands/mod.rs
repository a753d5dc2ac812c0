//! Command implementations, one module per top-level command.

mod axis;
mod canbus;
mod canopen;
mod cnc;
mod codec;
mod demo;
mod epl;
mod epl_cn;
mod epl_mn;
mod gcode;
mod kv01;
mod nfv2;
mod ps1a;
mod robot;
mod safety;
mod serve;
mod sim;
mod sim_can;
mod user;

use crate::cli::Command;
use anyhow::Result;

/// Runs one command.
pub fn run(command: Command) -> Result<()> {
    match command {
        Command::Decode { format, hex, crc, direction, revision } => {
            codec::decode(format, &hex, crc, direction, &revision)
        }
        Command::Encode { format, json, revision } => codec::encode(format, &json, &revision),
        Command::Sim(s) => sim::run(s),
        Command::Axis(a) => axis::run(a),
        Command::Ps1a(p) => ps1a::run(p),
        Command::Kv01(k) => kv01::run(k),
        Command::Nfv2(n) => nfv2::run_nfv2(n),
        Command::Pantilt(p) => nfv2::run_pantilt(p),
        Command::Demo(d) if d.ps1a_sequence => demo::run(d),
        Command::Demo(d) => serve::demo(d),
        Command::Canbus(c) => canbus::run(c),
        Command::Canopen(c) => canopen::run(c),
        Command::Robot(r) => robot::run(r),
        Command::Safety(c) => safety::run(c),
        Command::Epl(c) => epl::run(c),
        Command::Gcode(c) => gcode::run(c),
        Command::User(u) => user::run(u),
        Command::Serve(a) => serve::serve(a),
    }
}

/// A stop flag set by SIGINT / SIGTERM.
pub fn stop_flag() -> Result<std::sync::Arc<std::sync::atomic::AtomicBool>> {
    let flag = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(sig, flag.clone())?;
    }
    Ok(flag)
}
