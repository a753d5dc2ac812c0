//! SDO expedited round trips per second on the virtual bus (the socketcand hub on
//! 127.0.0.1, no bit-rate model), issue 5 point 5:
//!
//! * (a) Motus's master against Motus's simulated IclA drive (node 2);
//! * (b) Motus's master against python-canopen's `LocalNode` (node 5, the simulator's EDS);
//! * (c) python-canopen's master (`RemoteNode(2)`, `sdo.upload(0x6041, 0)` in a loop)
//!   against Motus's simulated drive, run once by `tests/python/bench_sdo_master.py`;
//! * (d), (e) Motus's master with concurrent transfers to N simulated drives (N threads;
//!   one thread with `sdo_upload_many`), and (f) python-canopen's master with the same
//!   workload (N `RemoteNode`s, one thread each), for N = 8, 16 and 32 (`BENCH_SDO_NODES=4,8`
//!   sets the list).
//!
//! Each master's CPU time per upload is printed as well: Motus's caller and receive thread
//! (from `/proc/self/task/*/schedstat`), the whole python process (`time.process_time`).
//! Criterion measures one upload of 0x6041:00 per iteration for (a) and (b). Besides,
//! each pair runs a timed loop of the same length as the python master's, and the rates
//! and the ratios (target: at least 10) are printed as `RATE ...` and `RATIO ...` lines.
//! `BENCH_QUICK=1` shortens the timed loops from 3 s to 1.5 s.
//!
//! Three floors come first: a raw frame echoed through the hub between two `SocketcandBus`
//! clients; the same with a client that spins on a non-blocking socket, no CANopen and
//! no receive thread: the most any master doing one transfer at a time can reach here; and
//! one loopback TCP round trip between two spinning threads with no hub: a transfer through
//! the hub takes at least two, even with a CPU for every party to spin on.
//!
//! The `RATIO peak` line compares each master at its best over the workloads both
//! were given. `docs/decisions.md` says what the figures mean for the 10x target.
//! The main figures are also printed as `REALTIME <name> <value> <unit>` lines for
//! `scripts/realtime.sh`.
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

use std::io::{BufRead, BufReader, Read};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{channel, Receiver};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use criterion::{Criterion, Throughput};
use motus_can::socketcand::{Hub, HubConfig, Message, SocketcandBus, StreamParser, SETTLE};
use motus_can::{CanBus, CanFrame};
use motus_canopen::Master;
use motus_icla_sim::{run_shared, SharedDrives, SimConfig, SimDrive};

/// Node of the Motus simulated drive in (a) and (c).
const SIM_NODE: u8 = 2;
/// Node of python-canopen's LocalNode in (b).
const LOCAL_NODE: u8 = 5;

fn repo_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn start_hub() -> Hub {
    Hub::start(HubConfig { listen: "127.0.0.1:0".parse().unwrap(), bitrate: None, channel: "can0".into() })
        .unwrap()
}

fn connect(hub: &Hub) -> Arc<dyn CanBus> {
    Arc::new(SocketcandBus::connect(hub.local_addr(), "can0").unwrap())
}

/// Motus's simulated drive served on its own hub connection.
struct Sim {
    _drives: SharedDrives,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl Sim {
    fn start(hub: &Hub, node: u8) -> Sim {
        Sim::start_many(hub, &[node])
    }

    fn start_many(hub: &Hub, nodes: &[u8]) -> Sim {
        let bus = connect(hub);
        let drives: SharedDrives =
            Arc::new(Mutex::new(nodes.iter().map(|n| SimDrive::new(SimConfig::node(*n))).collect()));
        let stop = Arc::new(AtomicBool::new(false));
        let (d, s) = (Arc::clone(&drives), Arc::clone(&stop));
        let thread = std::thread::spawn(move || run_shared(bus, d, s).unwrap());
        Sim { _drives: drives, stop, thread: Some(thread) }
    }
}

impl Drop for Sim {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// A python child whose stdout lines arrive on a channel.
struct Python {
    child: Child,
    lines: Receiver<String>,
    seen: Vec<String>,
}

impl Python {
    fn spawn(args: &[String]) -> Python {
        let mut child = Command::new("python3")
            .args(args)
            .current_dir(repo_root())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("python3 must be installed (with python-can 4.6.1 and canopen 2.4.1)");
        let stdout = child.stdout.take().unwrap();
        let (tx, lines) = channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines() {
                let Ok(line) = line else { return };
                if tx.send(line).is_err() {
                    return;
                }
            }
        });
        Python { child, lines, seen: Vec::new() }
    }

    /// Waits for a stdout line containing `needle`.
    fn wait_line(&mut self, needle: &str, timeout: Duration) -> Option<String> {
        let deadline = Instant::now() + timeout;
        loop {
            let left = deadline.checked_duration_since(Instant::now())?;
            let line = self.lines.recv_timeout(left).ok()?;
            self.seen.push(line.clone());
            if line.contains(needle) {
                return Some(line);
            }
        }
    }

    /// Waits for the exit (killing the child after `timeout`); returns (exited cleanly,
    /// stdout lines, stderr).
    fn finish(mut self, timeout: Duration) -> (bool, Vec<String>, String) {
        let deadline = Instant::now() + timeout;
        let status = loop {
            if let Some(s) = self.child.try_wait().unwrap() {
                break Some(s);
            }
            if Instant::now() > deadline {
                let _ = self.child.kill();
                let _ = self.child.wait();
                break None;
            }
            std::thread::sleep(Duration::from_millis(20));
        };
        let mut stderr = String::new();
        if let Some(mut e) = self.child.stderr.take() {
            let _ = e.read_to_string(&mut stderr);
        }
        // The reader thread ends at EOF; collect what is left.
        while let Ok(l) = self.lines.recv_timeout(Duration::from_millis(200)) {
            self.seen.push(l);
        }
        (status.is_some_and(|s| s.success()), self.seen, stderr)
    }
}

fn script_args(role: &str, hub: &Hub, node: u8, eds: &std::path::Path, seconds: f64) -> Vec<String> {
    vec![
        repo_root().join("tests/python/bench_sdo_master.py").display().to_string(),
        "--role".into(),
        role.into(),
        "--port".into(),
        hub.local_addr().port().to_string(),
        "--node".into(),
        node.to_string(),
        "--eds".into(),
        eds.display().to_string(),
        "--seconds".into(),
        format!("{seconds}"),
    ]
}

/// Expedited uploads of 0x6041:00 for `seconds`: (uploads, errors, uploads per second).
fn timed_rate(master: &Master, node: u8, seconds: f64) -> (u64, u64, f64) {
    let (mut ok, mut errors) = (0u64, 0u64);
    let start = Instant::now();
    let until = start + Duration::from_secs_f64(seconds);
    while Instant::now() < until {
        match master.read_u16(node, 0x6041, 0) {
            Ok(_) => ok += 1,
            Err(_) => errors += 1,
        }
    }
    let elapsed = start.elapsed().as_secs_f64();
    (ok, errors, ok as f64 / elapsed)
}

fn bench_upload(c: &mut Criterion, name: &str, master: &Master, node: u8) {
    let mut g = c.benchmark_group("sdo_expedited_upload_socketcand");
    g.throughput(Throughput::Elements(1));
    g.sample_size(30).warm_up_time(Duration::from_secs(1)).measurement_time(Duration::from_secs(3));
    g.bench_function(name, |b| b.iter(|| master.read_u16(node, 0x6041, 0).unwrap()));
    g.finish();
}

fn eds_file(node: u8) -> tempfile::NamedTempFile {
    let eds = tempfile::Builder::new().suffix(".eds").tempfile().unwrap();
    std::fs::write(eds.path(), SimDrive::new(SimConfig::node(node)).eds()).unwrap();
    eds
}

/// 602#4041600000000000: the SDO upload request of 0x6041:00 to node 2 (CiA 301 §7.2.4.3.6).
fn upload_request() -> CanFrame {
    "602#4041600000000000".parse().unwrap()
}

/// The frame that ends [`spawn_echo`]'s thread.
fn echo_stop() -> CanFrame {
    CanFrame::new(0x7FF, &[]).unwrap()
}

/// A thread that answers every frame on `bus` with the same data 0x80 higher (as an SDO
/// server's response COB-ID is its request's plus 0x80), until [`echo_stop`].
fn spawn_echo(bus: Arc<dyn CanBus>) -> JoinHandle<()> {
    std::thread::spawn(move || loop {
        let Ok(Some(r)) = bus.recv(Duration::from_secs(5)) else { return };
        if r.frame.id() == echo_stop().id() {
            return;
        }
        bus.send(&CanFrame::new(r.frame.id() + 0x80, r.frame.data()).unwrap()).unwrap();
    })
}

/// The floor of any request/response on this bus: a raw frame from client A through the
/// hub to an echo thread on client B and back (no CANopen at all).
fn hub_floor(c: &mut Criterion, seconds: f64) -> f64 {
    let hub = start_hub();
    let a = connect(&hub);
    let b = connect(&hub);
    std::thread::sleep(SETTLE * 2);
    let echo = spawn_echo(b);
    let request = upload_request();
    let once = || {
        a.send(&request).unwrap();
        a.recv(Duration::from_secs(1)).unwrap().expect("echo")
    };
    let mut g = c.benchmark_group("sdo_expedited_upload_socketcand");
    g.throughput(Throughput::Elements(1));
    g.sample_size(30).warm_up_time(Duration::from_secs(1)).measurement_time(Duration::from_secs(3));
    g.bench_function("floor_raw_frame_echo_via_hub", |bch| bch.iter(once));
    g.finish();
    let start = Instant::now();
    let until = start + Duration::from_secs_f64(seconds);
    let mut n = 0u64;
    while Instant::now() < until {
        once();
        n += 1;
    }
    let rate = n as f64 / start.elapsed().as_secs_f64();
    println!(
        "RATE floor: raw frame echo via the hub (no CANopen): {rate:.0} round trips/s ({n} in {seconds} s)"
    );
    a.send(&echo_stop()).unwrap();
    let _ = echo.join();
    rate
}

/// The ceiling of any master doing one transfer at a time on this bus: a client with no
/// CANopen and no receive thread, which spins on a non-blocking socket, sends the raw
/// request text through the hub to a blocking echo client (waiting as the simulator does)
/// and waits for the echo. No master, however fast, completes exchanges quicker.
fn spinning_floor(seconds: f64) -> f64 {
    use std::io::Write;
    let hub = start_hub();
    let echo = spawn_echo(connect(&hub));
    let mut raw = std::net::TcpStream::connect(hub.local_addr()).unwrap();
    raw.set_nodelay(true).unwrap();
    // The socketcand handshake, read with the crate's parser.
    let mut parser = StreamParser::new();
    let mut buf = [0u8; 4096];
    let mut expect = |raw: &mut std::net::TcpStream, want: Message| loop {
        if let Some(m) = parser.next() {
            assert_eq!(m, want, "socketcand handshake");
            return;
        }
        let n = raw.read(&mut buf).unwrap();
        assert!(n > 0, "hub closed during the handshake");
        parser.push(&buf[..n]);
    };
    expect(&mut raw, Message::Hi);
    raw.write_all(Message::Open("can0".into()).format().as_bytes()).unwrap();
    expect(&mut raw, Message::Ok);
    raw.write_all(Message::Rawmode.format().as_bytes()).unwrap();
    expect(&mut raw, Message::Ok);
    std::thread::sleep(SETTLE * 2);
    raw.set_nonblocking(true).unwrap();
    let request = Message::Send(upload_request()).format();
    let start = Instant::now();
    let until = start + Duration::from_secs_f64(seconds);
    let mut n = 0u64;
    while Instant::now() < until {
        raw.write_all(request.as_bytes()).unwrap();
        loop {
            match raw.read(&mut buf) {
                Ok(k) if buf[..k].contains(&b'>') => break,
                Ok(0) => panic!("hub closed"),
                Ok(_) => {}
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => std::hint::spin_loop(),
                Err(e) => panic!("{e}"),
            }
        }
        n += 1;
    }
    let rate = n as f64 / start.elapsed().as_secs_f64();
    println!(
        "RATE floor (spinning raw client, blocking echo client): {rate:.0} round trips/s ({n} in {seconds} s)"
    );
    raw.set_nonblocking(false).unwrap();
    raw.write_all(Message::Send(echo_stop()).format().as_bytes()).unwrap();
    let _ = echo.join();
    rate
}

/// The least one socket hop costs on this host: a frame-sized message bounced over one
/// loopback TCP connection between two threads that both spin on non-blocking sockets (no
/// hub, no CANopen, nobody asleep). A transfer through the hub crosses two such round
/// trips (master to hub to drive, and back), so one transfer at a time cannot beat
/// `1 / (2 * round trip)` here, however fast the master, hub and drive, and even with a
/// CPU for each of them to spin on. Returns microseconds per round trip.
fn tcp_pingpong_floor(seconds: f64) -> f64 {
    use std::io::Write;
    use std::net::{TcpListener, TcpStream};
    fn read_spinning(s: &mut TcpStream, buf: &mut [u8]) -> usize {
        loop {
            match s.read(buf) {
                Ok(n) => return n,
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => std::hint::spin_loop(),
                Err(e) => panic!("{e}"),
            }
        }
    }
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap();
    let message = Message::Frame { frame: upload_request(), timestamp: Duration::ZERO }.format();
    let echo = std::thread::spawn(move || {
        let (mut s, _) = listener.accept().unwrap();
        s.set_nodelay(true).unwrap();
        s.set_nonblocking(true).unwrap();
        let mut buf = [0u8; 256];
        loop {
            let n = read_spinning(&mut s, &mut buf);
            if n == 0 {
                return;
            }
            s.write_all(&buf[..n]).unwrap();
        }
    });
    let mut c = TcpStream::connect(addr).unwrap();
    c.set_nodelay(true).unwrap();
    c.set_nonblocking(true).unwrap();
    let mut buf = [0u8; 256];
    let start = Instant::now();
    let until = start + Duration::from_secs_f64(seconds);
    let mut n = 0u64;
    while Instant::now() < until {
        c.write_all(message.as_bytes()).unwrap();
        let mut got = 0;
        while got < message.len() {
            got += read_spinning(&mut c, &mut buf);
        }
        n += 1;
    }
    let us = start.elapsed().as_secs_f64() * 1e6 / n.max(1) as f64;
    println!(
        "RATE floor (one loopback TCP round trip, both ends spinning, no hub): {us:.1} us ({n} in {seconds} s); \
         through the hub a transfer makes two, so one transfer at a time is at most {:.0}/s here",
        1e6 / (2.0 * us)
    );
    drop(c);
    let _ = echo.join();
    us
}

/// CPU time (user + system) consumed so far by this process's threads whose name starts
/// with `prefix`, and by the calling thread (from `/proc/self/task/*/schedstat`, ns).
fn thread_cpu(prefix: &str) -> Duration {
    let read_ns = |path: std::path::PathBuf| -> u64 {
        std::fs::read_to_string(path)
            .ok()
            .and_then(|t| t.split_whitespace().next().and_then(|v| v.parse().ok()))
            .unwrap_or(0)
    };
    let mut ns = read_ns(PathBuf::from("/proc/thread-self/schedstat"));
    if let Ok(tasks) = std::fs::read_dir("/proc/self/task") {
        for task in tasks.flatten() {
            let comm = std::fs::read_to_string(task.path().join("comm")).unwrap_or_default();
            if comm.starts_with(prefix) {
                ns += read_ns(task.path().join("schedstat"));
            }
        }
    }
    Duration::from_nanos(ns)
}

/// Measurement pairs per drive count: the host's speed drifts over seconds (a shared
/// VM), so each Motus run is followed at once by a python run and the ratio is taken per
/// pair; the median pair is reported.
const PAIRS: usize = 3;

/// (e) Motus's master, one thread, `sdo_upload_many` over `nodes` for `seconds`:
/// (uploads/s, errors, master CPU per upload in us).
fn upload_many_rate(master: &Master, nodes: &[u8], seconds: f64) -> (f64, u64, f64) {
    // Every request sent in one batch, then the answers collected as they come.
    let requests: Vec<(u8, u16, u8)> = nodes.iter().map(|node| (*node, 0x6041, 0)).collect();
    let (mut ok, mut errs) = (0u64, 0u64);
    let cpu0 = thread_cpu("canopen-master");
    let start = Instant::now();
    let until = start + Duration::from_secs_f64(seconds);
    while Instant::now() < until {
        for r in master.sdo_upload_many(&requests) {
            if r.is_ok() {
                ok += 1;
            } else {
                errs += 1;
            }
        }
    }
    let rate = ok as f64 / start.elapsed().as_secs_f64();
    let cpu = thread_cpu("canopen-master").saturating_sub(cpu0).as_secs_f64();
    (rate, errs, cpu * 1e6 / ok.max(1) as f64)
}

/// The python master's JSON line among its stdout lines.
fn master_json(lines: &[String]) -> Option<serde_json::Value> {
    lines
        .iter()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .find(|v| v["role"] == "master")
}

/// (f) python-canopen's master with `nodes.len()` threads on `hub` for `seconds`:
/// (uploads/s, CPU per upload in us), or the failure's output.
fn python_concurrent_rate(
    hub: &Hub,
    nodes: &[u8],
    eds: &std::path::Path,
    seconds: f64,
) -> Result<(f64, f64), String> {
    let mut args = script_args("master", hub, nodes[0], eds, seconds);
    args.push("--nodes".into());
    args.push(nodes.iter().map(ToString::to_string).collect::<Vec<_>>().join(","));
    let (exited, lines, stderr) = Python::spawn(&args).finish(Duration::from_secs_f64(seconds + 30.0));
    let json = master_json(&lines);
    json.as_ref()
        .and_then(|v| {
            let cpu_us = v["cpu_s"].as_f64()? * 1e6 / v["uploads"].as_f64()?.max(1.0);
            Some((v["rate_per_s"].as_f64()?, cpu_us))
        })
        .ok_or_else(|| format!("exit ok: {exited}\nstdout: {lines:?}\nstderr: {stderr}"))
}

/// (d) Motus's master with concurrent transfers to `n` simulated drives from `n` threads,
/// then [`PAIRS`] pairs of (e) Motus's master from one thread with `sdo_upload_many` and
/// (f) python-canopen's master with the same workload (`n` `RemoteNode`s, one thread
/// each), on one hub. Prints the rates, each master's CPU time per transfer and the
/// ratios; returns the median rates of (e) and of (f) (`None` if python-canopen failed).
fn concurrent(n: usize, seconds: f64) -> (f64, Option<f64>) {
    let hub = start_hub();
    let nodes: Vec<u8> = (20..20 + n.min(100) as u8).collect();
    let _sims = Sim::start_many(&hub, &nodes);
    let master = Arc::new(Master::new(connect(&hub)));
    std::thread::sleep(SETTLE * 2);
    for node in &nodes {
        master.read_u16(*node, 0x6041, 0).expect("the simulated drives answer");
    }
    let start = Instant::now();
    let threads: Vec<_> = nodes
        .iter()
        .map(|node| {
            let (m, node) = (Arc::clone(&master), *node);
            std::thread::spawn(move || timed_rate(&m, node, seconds))
        })
        .collect();
    let (mut total, mut errors) = (0u64, 0u64);
    for t in threads {
        let (ok, e, _) = t.join().unwrap();
        total += ok;
        errors += e;
    }
    let d_rate = total as f64 / start.elapsed().as_secs_f64();
    println!(
        "RATE (d) Motus master, concurrent transfers to {n} simulated drives ({n} threads): {d_rate:.0} uploads/s \
         ({total} in {seconds} s, {errors} errors)"
    );
    let eds = eds_file(nodes[0]);
    let (mut e_rates, mut f_rates, mut ratios) = (Vec::new(), Vec::new(), Vec::new());
    for pair in 1..=PAIRS {
        let (e_rate, errs, e_cpu_us) = upload_many_rate(&master, &nodes, seconds);
        e_rates.push(e_rate);
        println!(
            "RATE (e) pair {pair}: Motus master, one thread, sdo_upload_many over {n} simulated drives: \
             {e_rate:.0} uploads/s ({errs} errors); master CPU {e_cpu_us:.1} us per upload (caller and receive \
             thread, spinning included)"
        );
        // Motus's master is idle while python-canopen's runs on the same hub.
        match python_concurrent_rate(&hub, &nodes, eds.path(), seconds) {
            Ok((f_rate, f_cpu_us)) => {
                println!(
                    "RATE (f) pair {pair}: python-canopen master, concurrent transfers to {n} simulated drives \
                     ({n} threads): {f_rate:.0} uploads/s; master CPU {f_cpu_us:.1} us per upload (whole python \
                     process)"
                );
                f_rates.push(f_rate);
                ratios.push(e_rate / f_rate);
            }
            Err(why) => println!("RATE (f) pair {pair}, python-canopen master, concurrent: FAILED ({why})"),
        }
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(0.0)
    };
    let (lo, hi) =
        (ratios.iter().copied().fold(f64::INFINITY, f64::min), ratios.iter().copied().fold(0.0, f64::max));
    let mid = median(&mut ratios);
    println!(
        "RATIO (e)/(f) Motus master / python-canopen master, both with concurrent transfers to {n} drives, \
         median of {} pairs: {mid:.1}x (pairs {lo:.1}-{hi:.1}x; 10x {} with this workload)",
        ratios.len(),
        if mid >= 10.0 { "reached" } else { "NOT reached" }
    );
    let f_median = (!f_rates.is_empty()).then(|| median(&mut f_rates));
    let e_median = median(&mut e_rates);
    println!("REALTIME sdo.motus.many{n} {e_median:.0} uploads/s");
    if !ratios.is_empty() {
        println!("REALTIME sdo.ratio.many{n} {mid:.2} x");
    }
    (e_median, f_median)
}

/// A master's SDO throughput at its best on this bus: the most round trips per second it
/// reached in any workload both masters were given (`one_at_a_time`, and the median rate
/// per drive count), with the workload that gave it.
fn peak(
    one_at_a_time: Option<f64>,
    per_drive_count: impl Iterator<Item = (usize, Option<f64>)>,
) -> Option<(f64, String)> {
    let mut best: Option<(f64, String)> = one_at_a_time.map(|r| (r, "one at a time".to_owned()));
    for (n, rate) in per_drive_count {
        if let Some(r) = rate {
            if best.as_ref().is_none_or(|(b, _)| r > *b) {
                best = Some((r, format!("{n} drives")));
            }
        }
    }
    best
}

fn main() {
    let mut c = Criterion::default().configure_from_args();
    let seconds = if std::env::var_os("BENCH_QUICK").is_some() { 1.5 } else { 3.0 };
    let floor = hub_floor(&mut c, seconds);
    let spin_floor = spinning_floor(seconds);
    let pingpong_us = tcp_pingpong_floor(seconds);

    // (a) and (c): one hub with Motus's simulated drive at node 2.
    let hub = start_hub();
    let _sim = Sim::start(&hub, SIM_NODE);
    let a_rate = {
        let master = Master::new(connect(&hub));
        std::thread::sleep(SETTLE * 2);
        master.read_u16(SIM_NODE, 0x6041, 0).expect("the simulated drive answers");
        bench_upload(&mut c, "a_motus_master_vs_motus_sim", &master, SIM_NODE);
        let cpu0 = thread_cpu("canopen-master");
        let (n, err, rate) = timed_rate(&master, SIM_NODE, seconds);
        let cpu_us = thread_cpu("canopen-master").saturating_sub(cpu0).as_secs_f64() * 1e6 / n.max(1) as f64;
        println!(
            "RATE (a) Motus master -> Motus sim drive (node {SIM_NODE}): {rate:.0} uploads/s \
             ({n} in {seconds} s, {err} errors); master CPU {cpu_us:.1} us per upload"
        );
        println!("REALTIME sdo.motus.one_at_a_time {rate:.0} uploads/s");
        rate
        // The master leaves the hub here, so the python master has the bus to itself; (c)
        // runs right after (a), as the host's speed drifts.
    };

    // (c) python-canopen's master against the same simulated drive.
    let eds_sim = eds_file(SIM_NODE);
    let py = Python::spawn(&script_args("master", &hub, SIM_NODE, eds_sim.path(), seconds));
    let (ok, lines, stderr) = py.finish(Duration::from_secs_f64(seconds + 30.0));
    let c_json = master_json(&lines);
    let c_rate = c_json.as_ref().and_then(|v| v["rate_per_s"].as_f64());
    match (ok, &c_json, c_rate) {
        (true, Some(v), Some(rate)) => {
            let cpu_us =
                v["cpu_s"].as_f64().unwrap_or(0.0) * 1e6 / v["uploads"].as_f64().unwrap_or(1.0).max(1.0);
            println!(
                "RATE (c) python-canopen master -> Motus sim drive (node {SIM_NODE}): {rate:.0} uploads/s; \
                 master CPU {cpu_us:.1} us per upload ({v})"
            );
            println!(
                "RATIO (a)/(c) Motus master / python-canopen master on the same bus, one transfer at a time: \
                 {:.1}x (10x {} with this workload; the ceiling and bound lines below limit it)",
                a_rate / rate,
                if a_rate >= 10.0 * rate { "reached" } else { "NOT reached" }
            );
            println!("REALTIME sdo.ratio.one_at_a_time {:.2} x", a_rate / rate);
            println!(
                "RATIO (c)/floor python-canopen master / raw hub echo: {:.2}; (a)/floor: {:.2} \
                 (a ratio near 1 means the bus, not the master, sets the rate)",
                rate / floor,
                a_rate / floor
            );
            println!(
                "RATIO ceiling one transfer at a time: spinning raw client / (c) = {:.1}x \
                 (no master doing one transfer at a time exceeds this on this bus; (a) reached {:.0} % of it)",
                spin_floor / rate,
                100.0 * a_rate / spin_floor
            );
            println!(
                "RATIO bound one transfer at a time, every party spinning on a CPU of its own: \
                 1 / (2 x {pingpong_us:.1} us) / (c) = {:.1}x (python-canopen's loop takes {:.0} us a transfer)",
                1e6 / (2.0 * pingpong_us) / rate,
                1e6 / rate
            );
        }
        _ => println!(
            "RATE (c) python-canopen master: FAILED (exit ok: {ok})\nstdout: {lines:?}\nstderr: {stderr}"
        ),
    }
    drop(_sim);
    drop(hub);

    // (d), (e), (f): concurrent transfers to N drives (one SDO channel per node).
    let sizes: Vec<usize> = std::env::var("BENCH_SDO_NODES")
        .ok()
        .map(|v| v.split(',').filter_map(|n| n.trim().parse().ok()).collect())
        .unwrap_or_else(|| vec![8, 16, 32]);
    let medians: Vec<(usize, f64, Option<f64>)> = sizes
        .iter()
        .map(|n| {
            let (e, f) = concurrent(*n, seconds);
            (*n, e, f)
        })
        .collect();
    let motus = peak(Some(a_rate), medians.iter().map(|m| (m.0, Some(m.1))));
    let python = peak(c_rate, medians.iter().map(|m| (m.0, m.2)));
    if let (Some((m_rate, m_how)), Some((p_rate, p_how))) = (motus, python) {
        println!(
            "RATIO peak: Motus master's best / python-canopen master's best, same bus, same workloads: \
             {m_rate:.0} ({m_how}) / {p_rate:.0} ({p_how}) uploads/s = {:.1}x (10x {})",
            m_rate / p_rate,
            if m_rate >= 10.0 * p_rate { "reached" } else { "NOT reached" }
        );
        println!("REALTIME sdo.ratio.peak {:.2} x", m_rate / p_rate);
        println!("REALTIME sdo.motus.peak {m_rate:.0} uploads/s");
    }

    // (b) Motus's master against python-canopen's LocalNode, on a hub of their own.
    let hub = start_hub();
    let eds_local = eds_file(LOCAL_NODE);
    // The LocalNode lives through criterion's run and the timed loop, then exits on its timer
    // (or is ended earlier once it is no longer needed).
    let mut py = Python::spawn(&script_args("localnode", &hub, LOCAL_NODE, eds_local.path(), seconds + 60.0));
    let ready = py.wait_line("\"ready\"", Duration::from_secs(20));
    let master = Master::new(connect(&hub));
    std::thread::sleep(SETTLE * 2);
    if ready.is_some() && master.read_u16(LOCAL_NODE, 0x6041, 0).is_ok() {
        bench_upload(&mut c, "b_motus_master_vs_python_localnode", &master, LOCAL_NODE);
        let (n, err, rate) = timed_rate(&master, LOCAL_NODE, seconds);
        println!(
            "RATE (b) Motus master -> python-canopen LocalNode (node {LOCAL_NODE}): {rate:.0} uploads/s \
             ({n} in {seconds} s, {err} errors)"
        );
    } else {
        println!("RATE (b) Motus master -> python-canopen LocalNode: FAILED (LocalNode not ready or silent)");
    }
    drop(master);
    let (_, lines, stderr) = py.finish(Duration::ZERO);
    if ready.is_none() {
        println!("LocalNode stdout: {lines:?}\nstderr: {stderr}");
    }
    c.final_summary();
}
