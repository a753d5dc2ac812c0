//! The 1 kHz task class with the whole demo cell running (every simulator, driver, the
//! juggler's 1 ms POWERLINK segment and its supervisor, the HMI's poller): start lateness
//! (jitter) p50/p99/max, execution time, overruns, CPU of the class thread and of the whole
//! process. `cargo run --release -p motus-station-machine --example demo_cell_jitter [secs]`.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::time::{Duration, Instant};

use motus_station_machine::{demo, StationMachine, StationOptions};

fn process_cpu() -> Duration {
    // utime + stime of this process, in clock ticks (100 Hz on Linux).
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let after = stat.rsplit_once(')').map_or("", |(_, r)| r);
    let f: Vec<u64> = after.split_whitespace().filter_map(|x| x.parse().ok()).collect();
    let ticks = f.get(10).copied().unwrap_or(0) + f.get(11).copied().unwrap_or(0);
    Duration::from_millis(ticks * 10)
}

fn main() {
    let secs: u64 = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(20);
    let dir = tempfile::tempdir().unwrap();
    let file = demo::write_demo_cell(dir.path(), "127.0.0.1:0").unwrap();
    let machine = StationMachine::start_file(&file, StationOptions::default()).unwrap();
    std::thread::sleep(Duration::from_secs(3)); // boot-up of the segment and the drives
    machine.reset_task_stats();
    let (cpu0, t0) = (process_cpu(), Instant::now());
    std::thread::sleep(Duration::from_secs(secs));
    let (cpu, wall) = (process_cpu() - cpu0, t0.elapsed());
    for c in machine.task_stats() {
        println!("{}", c.summary());
    }
    println!(
        "whole station process (demo cell): CPU {:.1} % of one core over {:.1} s",
        100.0 * cpu.as_secs_f64() / wall.as_secs_f64(),
        wall.as_secs_f64()
    );
    let traced = machine.traced("trace-fast/thrower-drive.position");
    println!("trace-fast/thrower-drive.position latest: {traced:?}");
}
