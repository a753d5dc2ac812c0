//! Interoperability with python-canopen 2.4.1 (the independent peer of
//! specs/can-transports.md): the simulator runtime serves drives on a Motus socketcand hub,
//! the python scripts in tests/python/ act as master, and this test checks their exit
//! status and printed results. python3 with canopen must be installed (CI installs it);
//! a missing package fails the test.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use motus_can::socketcand::{Hub, HubConfig, SocketcandBus};
use motus_can::CanBus;
use motus_cia402_protocol::PowerState;
use motus_icla_sim::{lock, run_shared, SharedDrives, SimConfig, SimDrive};

struct Sim {
    hub: Hub,
    drives: SharedDrives,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl Sim {
    fn start(drives: Vec<SimDrive>) -> Self {
        let hub = Hub::start(HubConfig {
            listen: "127.0.0.1:0".parse().unwrap(),
            bitrate: None,
            channel: "can0".into(),
        })
        .unwrap();
        let bus: Arc<dyn CanBus> = Arc::new(SocketcandBus::connect(hub.local_addr(), "can0").unwrap());
        let drives = Arc::new(Mutex::new(drives));
        let stop = Arc::new(AtomicBool::new(false));
        let (d, s) = (Arc::clone(&drives), Arc::clone(&stop));
        let thread = std::thread::spawn(move || run_shared(bus, d, s).unwrap());
        Self { hub, drives, stop, thread: Some(thread) }
    }
}

impl Drop for Sim {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
        self.hub.stop();
    }
}

fn script(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../tests/python").join(name)
}

/// Runs a python script with a hard time-out; returns (success, `KEY value` lines).
fn python(args: &[String], timeout: Duration) -> (bool, BTreeMap<String, String>, String) {
    let mut child = Command::new("python3")
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("python3");
    let deadline = Instant::now() + timeout;
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break Some(s);
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            break None;
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let output = child.wait_with_output().unwrap();
    let text =
        String::from_utf8_lossy(&output.stdout).into_owned() + &String::from_utf8_lossy(&output.stderr);
    let lines = String::from_utf8_lossy(&output.stdout)
        .lines()
        .filter_map(|l| l.split_once(' ').map(|(k, v)| (k.to_owned(), v.to_owned())))
        .collect();
    (status.is_some_and(|s| s.success()), lines, text)
}

#[test]
fn base_node_402_master_drives_the_simulator() {
    let drive = SimDrive::new(SimConfig::node(2));
    let eds = tempfile::Builder::new().suffix(".eds").tempfile().unwrap();
    std::fs::write(eds.path(), drive.eds()).unwrap();
    let sim = Sim::start(vec![drive]);
    let port = sim.hub.local_addr().port().to_string();
    let args = vec![
        script("icla_402_master.py").display().to_string(),
        "--port".into(),
        port,
        "--node".into(),
        "2".into(),
        "--eds".into(),
        eds.path().display().to_string(),
    ];
    let (ok, r, text) = python(&args, Duration::from_secs(60));
    assert!(ok, "python failed:\n{text}");
    assert_eq!(r["NMT_STATE"], "PRE-OPERATIONAL");
    assert_eq!(r["DEVICE_TYPE"], "0x00020192");
    assert_eq!(r["DEVICE_NAME"], "IclA D065 (Motus simulator)");
    assert_eq!(r["VENDOR"], "0x0800005A");
    assert_eq!(r["SERIAL"], "2");
    assert_eq!(r["PROFILE_VELOCITY"], "300");
    assert_eq!(r["ABORT"], "0x06010002");
    assert_eq!(r["TPDO1_MAP"], "0x6041,0x6061");
    assert_eq!(r["RPDO2_MAP"], "0x6040,0x607A");
    assert_eq!(r["TPDO1_EVENT_TIMER"], "20");
    assert_eq!(r["STATE"], "OPERATION ENABLED");
    assert_eq!(r["MODE"], "PROFILED POSITION");
    assert_eq!(r["POSITION"], "213", "one output revolution");
    assert_eq!(r["TPDO2_POSITION"], "213");
    assert_eq!(r["HOMED"], "True");
    assert_eq!(r["HOMED_POSITION"], "100");
    assert_eq!(r["FINAL_STATE"], "SWITCH ON DISABLED");
    let guard = lock(&sim.drives);
    assert_eq!(guard[0].power_state(), PowerState::SwitchOnDisabled);
    assert_eq!(guard[0].position(), 100);
    assert_eq!(guard[0].od().int(0x1800, 5), 20, "the PDO save reached the drive");
}

#[test]
fn lss_master_configures_three_unconfigured_simulators() {
    let drives = (1..=3u32)
        .map(|serial| {
            let mut cfg = SimConfig::unconfigured(serial);
            cfg.bit_timing = 4; // 125 kbit/s until LSS changes it
            SimDrive::new(cfg)
        })
        .collect();
    let sim = Sim::start(drives);
    let args = vec![
        script("icla_lss.py").display().to_string(),
        "--port".into(),
        sim.hub.local_addr().port().to_string(),
    ];
    let (ok, r, text) = python(&args, Duration::from_secs(120));
    assert!(ok, "python failed:\n{text}");
    assert_eq!(r["NON_CONFIGURED"], "3");
    assert_eq!(r["FASTSCAN1"], "True 0x0800005A 0x00000065 0x00010000 0x00000001");
    assert_eq!(r["INQUIRE_VENDOR"], "0x0800005A");
    assert_eq!(r["INQUIRE_PRODUCT"], "0x00000065");
    assert_eq!(r["INQUIRE_REVISION"], "0x00010000");
    assert_eq!(r["INQUIRE_SERIAL"], "1");
    assert_eq!(r["INQUIRE_NODE_ID_BEFORE"], "255");
    assert_eq!(r["SELECTIVE2"], "True");
    assert_eq!(r["FASTSCAN2"], "True 0x0800005A 0x00000065 0x00010000 0x00000003");
    assert_eq!(r["INQUIRE_NODE_ID_PENDING"], "255");
    assert_eq!(r["BOOTUPS"], "702#00 703#00 704#00");
    assert_eq!(
        (r["NODE2_SERIAL"].as_str(), r["NODE3_SERIAL"].as_str(), r["NODE4_SERIAL"].as_str()),
        ("1", "2", "3")
    );
    let guard = lock(&sim.drives);
    let ids: Vec<_> = guard.iter().map(|d| d.node_id()).collect();
    assert_eq!(ids, vec![Some(2), Some(3), Some(4)]);
    let rates: Vec<_> = guard.iter().map(|d| d.lss().bitrate()).collect();
    assert_eq!(rates, vec![20_000, 125_000, 125_000], "only node 2 activated 20 kbit/s");
    assert_eq!(guard[0].lss().stored(), (2, 7));
}
