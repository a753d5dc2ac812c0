//! `cargo run --release -p motus-gcode --example vs_rs274 [-- LINES [ROUNDS]]`: interpretation speed
//! of Motus against LinuxCNC's standalone `rs274` on the same generated program
//! (default 100,000 lines, the program of `benches/interpret.rs`).
//!
//! * rs274: wall time of `rs274 -g -n 2 -t tool.tbl -v fresh.var prog.ngc < /dev/null >
//!   /dev/null` (private HOME, fresh var file each run). Its start-up time (the
//!   same command on a one-line program) is printed too: it is part of its wall time.
//! * Motus: `interpret(&src)` (all calls into a `Vec`) and the streaming `Interpreter`
//!   iterator, on the text read from the same file; and, closest to what rs274 does,
//!   reading the file + interpreting + printing rs274-style lines to a sink.
//!
//! Each figure is the best of ROUNDS (default 3) rounds; a round runs every measurement
//! once, so rs274 and Motus see the same load on a shared machine.
//!
//! Wall time is what the comparison is about; CPU time (rs274: the child's user + system
//! time; Motus: this thread's) is printed too, as it varies less on a loaded machine.
//!
//! Before timing, both outputs are checked to hold the same number of motion calls.
//! Fails (does not skip) when `rs274` is missing (`apt-get install linuxcnc-uspace`).
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

#[path = "../benches/common/program.rs"]
mod program;

use std::io::Write;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Instant;

use nix::sys::resource::{getrusage, UsageWho};
use nix::time::{clock_gettime, ClockId};

use motus_gcode::{interpret, write_line, Canon, Interpreter, Precision};

/// Wall and CPU seconds of one run.
#[derive(Clone, Copy)]
struct Time {
    wall: f64,
    cpu: f64,
}

fn secs(t: nix::sys::time::TimeVal) -> f64 {
    t.tv_sec() as f64 + t.tv_usec() as f64 * 1e-6
}

/// CPU time (user + system) of the waited-for children so far.
fn children_cpu() -> f64 {
    let u = getrusage(UsageWho::RUSAGE_CHILDREN).unwrap();
    secs(u.user_time()) + secs(u.system_time())
}

/// CPU time of this thread so far.
fn thread_cpu() -> f64 {
    let t = clock_gettime(ClockId::CLOCK_THREAD_CPUTIME_ID).unwrap();
    t.tv_sec() as f64 + t.tv_nsec() as f64 * 1e-9
}

/// Runs rs274 on `prog` in `dir` (private HOME, fresh var file); returns its times and
/// its stdout (when `capture`).
fn rs274(dir: &Path, prog: &Path, capture: bool) -> (Time, String) {
    let var = dir.join("fresh.var");
    std::fs::write(&var, "").unwrap();
    let mut cmd = Command::new("rs274");
    cmd.args(["-g", "-n", "2", "-t"])
        .arg(dir.join("tool.tbl"))
        .arg("-v")
        .arg(&var)
        .arg(prog)
        .env("HOME", dir)
        .stdin(Stdio::null())
        .stdout(if capture { Stdio::piped() } else { Stdio::null() })
        .stderr(Stdio::piped());
    let (c, t) = (children_cpu(), Instant::now());
    let out = cmd.output().expect("rs274 must be installed (apt-get install linuxcnc-uspace)");
    let time = Time { wall: t.elapsed().as_secs_f64(), cpu: children_cpu() - c };
    assert!(out.status.success(), "rs274 failed: {}", String::from_utf8_lossy(&out.stderr));
    (time, String::from_utf8_lossy(&out.stdout).into_owned())
}

fn timed(f: impl FnOnce()) -> Time {
    let (c, t) = (thread_cpu(), Instant::now());
    f();
    Time { wall: t.elapsed().as_secs_f64(), cpu: thread_cpu() - c }
}

fn main() {
    let lines: usize =
        std::env::args().nth(1).map_or(100_000, |a| a.parse().expect("LINES must be a number"));
    let rounds: usize = std::env::args().nth(2).map_or(3, |a| a.parse().expect("ROUNDS must be a number"));
    let dir = tempfile::tempdir().unwrap();
    let prog = dir.path().join("prog.ngc");
    std::fs::write(&prog, program::program(lines)).unwrap();
    std::fs::write(dir.path().join("tool.tbl"), "T1 P1 D0.125 Z0 ;\n").unwrap();
    let empty = dir.path().join("empty.ngc");
    std::fs::write(&empty, "M2\n").unwrap();
    let src = std::fs::read_to_string(&prog).unwrap();
    let n = src.lines().count();

    // Same work on both sides: count the motion calls.
    let (_, text) = rs274(dir.path(), &prog, true);
    let theirs = text.lines().filter(|l| l.contains("STRAIGHT_FEED(") || l.contains("ARC_FEED(")).count();
    let calls = interpret(&src).expect("Motus must run the program");
    let ours =
        calls.iter().filter(|c| matches!(c.canon, Canon::StraightFeed { .. } | Canon::ArcFeed(_))).count();
    assert_eq!(theirs, ours, "rs274 and Motus disagree on the number of motion calls");

    // Rounds interleave the two sides, so that both see the same load on a shared machine.
    let mut best = [Time { wall: f64::MAX, cpu: f64::MAX }; 5];
    for _ in 0..rounds {
        let times = [
            rs274(dir.path(), &prog, false).0,
            rs274(dir.path(), &empty, false).0,
            timed(|| assert_eq!(interpret(&src).unwrap().len(), calls.len())),
            timed(|| {
                let mut k = 0;
                for c in Interpreter::new(&src) {
                    c.unwrap();
                    k += 1;
                }
                assert_eq!(k, calls.len());
            }),
            timed(|| {
                let src = std::fs::read_to_string(&prog).unwrap();
                let mut sink = std::io::BufWriter::new(std::io::sink());
                let mut line = String::new();
                for (k, c) in Interpreter::new(&src).enumerate() {
                    let counter = u32::try_from(k + 1).unwrap_or(u32::MAX);
                    line.clear();
                    write_line(&mut line, counter, &c.unwrap(), Precision::Rs274);
                    line.push('\n');
                    sink.write_all(line.as_bytes()).unwrap();
                }
            }),
        ];
        for (b, t) in best.iter_mut().zip(times) {
            b.wall = b.wall.min(t.wall);
            b.cpu = b.cpu.min(t.cpu);
        }
    }
    let [t_rs274, t_start, t_vec, t_stream, t_text] = best;

    let rate = |t: f64| n as f64 / t;
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!(
        "program: {n} lines, {ours} motion calls (same in both); best of {rounds} rounds; load average {}",
        load.trim()
    );
    println!(
        "{:32}  {:>9} {:>12} {:>7}   {:>9} {:>12} {:>7}",
        "", "wall ms", "lines/s", "ratio", "CPU ms", "lines/s", "ratio"
    );
    println!(
        "{:33} {:9.1} {:>12} {:>7}   {:9.1} {:>12} {:>7}",
        "rs274 start-up (one-line program)",
        t_start.wall * 1e3,
        "-",
        "-",
        t_start.cpu * 1e3,
        "-",
        "-"
    );
    for (name, t) in [
        ("rs274", t_rs274),
        ("Motus interpret() -> Vec", t_vec),
        ("Motus Interpreter (streaming)", t_stream),
        ("Motus read + interpret + print", t_text),
    ] {
        println!(
            "{name:33} {:9.1} {:12.0} {:>7}   {:9.1} {:12.0} {:>7}",
            t.wall * 1e3,
            rate(t.wall),
            format!("x{:.1}", t_rs274.wall / t.wall),
            t.cpu * 1e3,
            rate(t.cpu),
            format!("x{:.1}", t_rs274.cpu / t.cpu),
        );
    }
}
