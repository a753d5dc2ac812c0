#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
//! Recovery of the station as `motus serve` runs it, with the KV-01 arm's simulator as a
//! separate process would be (`motus sim kv01 --link pty:PATH`, here on a thread):
//!
//! - the station starts while the arm's simulator is not running: it serves, the arm is
//!   marked disconnected with an alarm, and when the simulator starts the arm is connected
//!   and its joints move;
//! - a module that latches its 700 ms safety time-out is one alarm that says what the
//!   operator must do; a power cycle of the arm clears it and the joint moves again.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use motus_axis::{Axis, AxisCommand, AxisState, MotionProfile};
use motus_kv01_sim::{LineOptions, SharedArm, SimLine};
use motus_serial::{LineSettings, PtyLink};
use motus_station::alarm::{AlarmCode, MemoryAlarms};
use motus_station_machine::{StationMachine, StationOptions};

/// A cell with the KV-01 arm (joints 1 and 3) on a serial path and a simulated gantry axis.
fn cell(dir: &Path) -> (motus_station::config::Cell, PathBuf) {
    let arm_path = dir.join("kv01");
    let mut text = format!(
        "[station]\nname = \"recovery\"\nlisten = \"127.0.0.1:0\"\ndata_dir = \"data\"\n\n\
         [[link]]\nname = \"arm-line\"\nkind = \"serial\"\nuri = \"{}\"\n\n\
         [[device]]\nname = \"arm\"\nkind = \"kv01\"\nlink = \"arm-line\"\nbaud = 115200\n\n\
         [[device]]\nname = \"cnc-x\"\nkind = \"sim-axis\"\n\n\
         [[axis]]\nname = \"x\"\ndevice = \"cnc-x\"\nunit = \"m\"\nscale = 1e-6\n\
         limits = {{ min = 0.0, max = 0.6 }}\nmax_velocity = 0.1\nmax_acceleration = 1.0\n\
         student = {{ max_velocity = 0.08 }}\n",
        arm_path.display()
    );
    for (index, name) in [(0, "joint1"), (2, "joint3")] {
        text.push_str(&format!(
            "\n[[axis]]\nname = \"{name}\"\ndevice = \"arm\"\nindex = {index}\nunit = \"rad\"\n\
             scale = 1.745329e-5\nlimits = {{ min = -1.9, max = 1.9 }}\nmax_velocity = 1.0\n\
             max_acceleration = 2.0\nstudent = {{ max_velocity = 0.5 }}\n"
        ));
    }
    let path = dir.join("cell.toml");
    std::fs::write(&path, text).unwrap();
    (motus_station::config::load(&path).unwrap_or_else(|e| panic!("{e}")), arm_path)
}

/// `motus sim kv01 --link pty:PATH`: the simulated arm on a new pty at `path`.
struct ArmSim {
    arm: SharedArm,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl ArmSim {
    fn start(path: &Path) -> Self {
        let pty = PtyLink::create(Some(path), LineSettings::n81(115_200)).unwrap();
        let mut line = SimLine::new(Box::new(pty), LineOptions::default()).unwrap();
        let arm = line.arm();
        let stop = Arc::new(AtomicBool::new(false));
        let s = Arc::clone(&stop);
        let thread = std::thread::spawn(move || line.run(&s).unwrap());
        Self { arm, stop, thread: Some(thread) }
    }
}

impl Drop for ArmSim {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

fn start_station(cell: &motus_station::config::Cell) -> (StationMachine, Arc<MemoryAlarms>) {
    let _ = tracing_subscriber::fmt().with_env_filter("info").with_test_writer().try_init();
    let sink = Arc::new(MemoryAlarms::new());
    let options = StationOptions { alarm_sink: Some(sink.clone()), ..StationOptions::default() };
    let machine =
        StationMachine::start(cell, options).unwrap_or_else(|e| panic!("the station must start: {e}"));
    (machine, sink)
}

fn until(what: &str, timeout: Duration, mut done: impl FnMut() -> bool) {
    let t0 = Instant::now();
    while !done() {
        assert!(t0.elapsed() < timeout, "{what}: not within {timeout:?}");
        std::thread::sleep(Duration::from_millis(50));
    }
}

fn has_alarm(machine: &StationMachine, source: &str, code: AlarmCode) -> bool {
    machine.alarms().iter().any(|(s, c)| s == source && *c == code)
}

fn axis(machine: &StationMachine, name: &str) -> Box<dyn Axis + Send> {
    machine.with_cell(|rc| rc.axis(name)).unwrap()
}

fn wait(axis: &mut dyn Axis, timeout: Duration, done: impl Fn(&AxisState) -> bool) -> AxisState {
    let t0 = Instant::now();
    let mut last;
    loop {
        match axis.read_state() {
            Ok(s) if done(&s) => return s,
            Ok(s) => last = format!("{s:?}"),
            Err(e) => last = e.to_string(),
        }
        assert!(t0.elapsed() < timeout, "{}: not done within {timeout:?}; last {last}", axis.name());
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Enables the joint and moves it to `target` rad.
fn enable_and_move(machine: &StationMachine, name: &str, target: f64) {
    let mut j = axis(machine, name);
    j.execute(&AxisCommand::Enable).unwrap_or_else(|e| panic!("{name}: enable: {e}"));
    j.execute(&AxisCommand::MoveAbsolute { target, profile: MotionProfile::default() })
        .unwrap_or_else(|e| panic!("{name}: move: {e}"));
    wait(j.as_mut(), Duration::from_secs(20), |s| !s.flags.moving && (s.position - target).abs() < 0.005);
}

#[test]
fn the_station_starts_with_the_arm_absent_and_connects_it_when_it_appears() {
    let dir = tempfile::tempdir().unwrap();
    let (cell, arm_path) = cell(dir.path());
    let (machine, sink) = start_station(&cell);

    // It serves: the arm is marked disconnected with an alarm, the other device works.
    until("arm alarm", Duration::from_secs(10), || {
        has_alarm(&machine, "device:arm", AlarmCode::DeviceDisconnected)
    });
    let raised = sink.raised();
    let alarm = raised.iter().find(|a| a.source == "device:arm").unwrap();
    assert!(alarm.message.contains("cannot be reached"), "{alarm:?}");
    assert!(axis(&machine, "joint1").read_state().is_err(), "a disconnected joint has no state");
    axis(&machine, "x").read_state().unwrap();

    // The simulator starts: the arm is connected and its joints move.
    let _sim = ArmSim::start(&arm_path);
    let appeared = Instant::now();
    until("arm connected", Duration::from_secs(20), || machine.alarms().is_empty());
    eprintln!("arm connected {:?} after its simulator started", appeared.elapsed());
    enable_and_move(&machine, "joint1", 0.2);
    enable_and_move(&machine, "joint3", -0.1);
    drop(machine); // before its simulator
}

#[test]
fn a_latched_kv01_time_out_is_one_alarm_that_says_what_to_do() {
    let dir = tempfile::tempdir().unwrap();
    let (cell, arm_path) = cell(dir.path());
    let sim = ArmSim::start(&arm_path);
    let (machine, sink) = start_station(&cell);
    until("arm connected", Duration::from_secs(20), || {
        machine.alarms().is_empty() && axis(&machine, "joint3").read_state().is_ok()
    });
    enable_and_move(&machine, "joint3", 0.1);

    // Module 3 hears nothing for 1 s: it latches its 700 ms safety time-out.
    motus_kv01_sim::lock(&sim.arm).module_mut(3).unwrap().faults_mut().deaf = true;
    std::thread::sleep(Duration::from_secs(1));
    motus_kv01_sim::lock(&sim.arm).module_mut(3).unwrap().faults_mut().deaf = false;
    assert!(motus_kv01_sim::lock(&sim.arm).state(3).unwrap().timed_out);
    until("latched alarm", Duration::from_secs(10), || {
        has_alarm(&machine, "device:arm", AlarmCode::DeviceLatched)
    });
    // The arm stays connected (it answers), and the alarm stays one alarm.
    std::thread::sleep(Duration::from_secs(3));
    let latched: Vec<_> = sink.raised().into_iter().filter(|a| a.code == AlarmCode::DeviceLatched).collect();
    assert_eq!(latched.len(), 1, "{latched:?}");
    let message = &latched[0].message;
    eprintln!("alarm: {message}");
    assert!(message.contains("KV-01 module 3 latched its 700 ms communication time-out"), "{message}");
    assert!(message.contains("power-cycle the arm (or restart its simulator)"), "{message}");
    assert!(!has_alarm(&machine, "device:arm", AlarmCode::DeviceDisconnected), "{:?}", machine.alarms());
    let err = axis(&machine, "joint3").execute(&AxisCommand::Enable).unwrap_err();
    assert!(err.to_string().contains("700 ms"), "{err}");

    // The operator power-cycles the arm: the alarm clears and the joint moves again.
    motus_kv01_sim::lock(&sim.arm).power_cycle();
    until("latch cleared", Duration::from_secs(20), || machine.alarms().is_empty());
    enable_and_move(&machine, "joint3", -0.1);
    let latched = sink.raised().into_iter().filter(|a| a.code == AlarmCode::DeviceLatched).count();
    assert_eq!(latched, 1);
    drop(machine); // before its simulator
}
