//! `motus` — the command-line interface. Every command is documented in `docs/cli.md`.

#![forbid(unsafe_code)]

mod cli;
mod cli_can;
mod cli_cnc;
mod cli_epl;
mod cli_station;
mod commands;
mod error_text;
mod hex;
mod progress;

use clap::Parser;
use std::process::ExitCode;

/// The process's allocator. mimalloc gives every thread its own heap, so a device or cyclic
/// thread never waits inside `malloc` for a lock held by a web thread: with glibc's shared
/// arenas, a preempted web thread kept the POWERLINK cycle and the juggler's supervisor
/// waiting for 9 to 26 ms (docs/decisions.md, "Real-time priorities").
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() -> ExitCode {
    let args = cli::Cli::parse();
    let filter = tracing_subscriber::EnvFilter::try_from_env("MOTUS_LOG")
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(if args.verbose { "debug" } else { "warn" }));
    tracing_subscriber::fmt().with_env_filter(filter).with_writer(std::io::stderr).init();
    match commands::run(args.command) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", error_text::error_text(&e));
            ExitCode::FAILURE
        }
    }
}
