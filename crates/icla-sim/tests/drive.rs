//! SimDrive end to end over its sans-IO interface, with frames written by hand from
//! specs/canopen.md and specs/omni-robot.md (candump notation `ID#DATA`).
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use std::time::{Duration, Instant};

use motus_canopen_protocol::{CanFrame, NmtState};
use motus_cia402_protocol::PowerState;
use motus_icla_sim::{SimConfig, SimDrive};

/// A drive with a hand-driven clock.
struct Rig {
    drive: SimDrive,
    t0: Instant,
    now: Instant,
}

impl Rig {
    fn new(cfg: SimConfig) -> (Self, Vec<String>) {
        let t0 = Instant::now();
        let mut drive = SimDrive::new(cfg);
        let boot = drive.poll(t0).iter().map(|f| f.to_string()).collect();
        (Self { drive, t0, now: t0 }, boot)
    }

    fn send(&mut self, frame: &str) -> Vec<String> {
        let f: CanFrame = frame.parse().unwrap();
        self.drive.handle(&f, self.now).iter().map(|f| f.to_string()).collect()
    }

    /// Advances `ms` milliseconds in 1 ms polls; returns everything sent.
    fn run(&mut self, ms: u64) -> Vec<String> {
        let mut out = Vec::new();
        for _ in 0..ms {
            self.now += Duration::from_millis(1);
            out.extend(self.drive.poll(self.now).iter().map(|f| f.to_string()));
        }
        out
    }

    fn elapsed(&self) -> f64 {
        (self.now - self.t0).as_secs_f64()
    }

    /// NMT start, then shutdown and switch on + enable operation by RPDO1.
    fn enable(&mut self) {
        self.send("000#0102");
        self.send("202#0600");
        self.send("202#0F00");
        assert_eq!(self.drive.power_state(), PowerState::OperationEnabled);
    }
}

#[test]
fn other_nodes_sdo_frames_are_ignored() {
    let (mut rig, _) = Rig::new(SimConfig::node(2));
    // Another node's request and another server's response (CiA 301 reserves
    // 0x601..=0x67F and 0x581..=0x5FF for SDO): no answer, no change.
    assert!(rig.send("603#2B17100064000000").is_empty());
    assert!(rig.send("582#4B41600050060000").is_empty());
    assert!(rig.send("67F#4000100000000000").is_empty());
    assert_eq!(rig.drive.od().int(0x1017, 0), 1000);
    // Its own request is still served.
    assert_eq!(rig.send("602#4000100000000000"), vec!["582#4300100092010200"]);
}

#[test]
fn boot_up_heartbeat_and_sdo() {
    let (mut rig, boot) = Rig::new(SimConfig::node(2));
    // Boot-up: 0x700 + 2, data 00 (spec 3.2).
    assert_eq!(boot, vec!["702#00"]);
    assert_eq!(rig.drive.nmt_state(), NmtState::PreOperational);
    // Heartbeat 1000 ms later: 7F = pre-operational.
    assert!(rig.run(999).is_empty());
    assert_eq!(rig.run(1), vec!["702#7F"]);
    // SDO upload 0x1000: 43 (4 bytes) 00 10 00, 0x00020192 LE 92 01 02 00.
    assert_eq!(rig.send("602#4000100000000000"), vec!["582#4300100092010200"]);
    // Statusword: switch on disabled 0x40 + voltage 0x10 + remote 0x200 + target reached 0x400
    // (profile position, standing in the window) = 0x0650 -> 4B 41 60 00 50 06.
    assert_eq!(rig.send("602#4041600000000000"), vec!["582#4B41600050060000"]);
    // Write 0x1017 := 100 ms (2B = 2 bytes), heartbeats follow the new period.
    assert_eq!(rig.send("602#2B17100064000000"), vec!["582#6017100000000000"]);
    assert_eq!(rig.run(100).len(), 1);
    // Range: 0x6081 := 800 > 747 -> 0x06090031 (LE 31 00 09 06).
    assert_eq!(rig.send("602#2381600020030000"), vec!["582#8081600031000906"]);
    // Write-only 0x200B read -> 0x06010001; 0x6041 write -> 0x06010002.
    assert_eq!(rig.send("602#400B200000000000"), vec!["582#800B200001000106"]);
    assert_eq!(rig.send("602#2B41600000000000"), vec!["582#8041600002000106"]);
    // Length: 1 byte into the 4-byte 0x607A -> 0x06070010; unknown sub -> 0x06090011.
    assert_eq!(rig.send("602#2F7A600001000000"), vec!["582#807A600010000706"]);
    assert_eq!(rig.send("602#4041600100000000"), vec!["582#8041600111000906"]);
    // Unsupported mode 2 (velocity) -> 0x06090030; unsupported homing method 1 too.
    assert_eq!(rig.send("602#2F60600002000000"), vec!["582#8060600030000906"]);
    assert_eq!(rig.send("602#2F98600001000000"), vec!["582#8098600030000906"]);
    // Stopped: SDO is not served.
    rig.send("000#0202");
    assert!(rig.send("602#4000100000000000").is_empty());
    // Reset communication: boot-up again, pre-operational, heartbeat back to 1000 ms.
    assert_eq!(rig.send("000#8200"), vec!["702#00"]);
    assert_eq!(rig.drive.od().int(0x1017, 0), 1000);
}

#[test]
fn seed_relative_move_by_rpdo2_and_sync_ends_exactly_on_target() {
    let (mut rig, _) = Rig::new(SimConfig::node(2));
    rig.enable();
    // specs/omni-robot.md: 302: 5F 00 55 08 00 00 = controlword 0x005F (enable operation +
    // new set-point + relative), target 0x00000855 = 2133 Inc; acted on at the next SYNC.
    assert!(rig.send("302#5F0055080000").is_empty());
    rig.run(100);
    assert_eq!(rig.drive.position(), 0, "RPDO2 is synchronous: nothing before SYNC");
    // SYNC: TPDO2 (type 1) answers with the sampled statusword + position (0x0637 = operation
    // enabled + voltage + remote + target reached), then the set-point is taken and TPDO1
    // (on change) reports 0x1237: set-point acknowledge, target reached cleared; mode 1.
    assert_eq!(rig.send("080#"), vec!["282#370600000000", "182#371201"]);
    let start = rig.elapsed();
    // Profile 248 Inc/s, 1000 / 400 Inc/s^2: 0.248 s up (30.8 Inc), 0.62 s down (76.9 Inc),
    // (2133 - 107.6) / 248 = 8.167 s cruising -> 9.03 s in all.
    rig.run(5000);
    let mid = rig.drive.position();
    assert!((1100..1300).contains(&mid), "{mid} Inc after 5 s (expected ~1209)");
    assert!(rig.drive.statusword() & 0x0400 == 0, "target not reached while moving");
    rig.run(4200);
    assert_eq!(rig.drive.position(), 2133);
    assert_eq!(rig.drive.velocity(), 0);
    let sw = rig.drive.statusword();
    assert_eq!(sw & 0x0400, 0x0400, "target reached: {sw:#06x}");
    // SW bit 12 (set-point acknowledge) is still 1 while the host holds bit 4 ...
    assert_eq!(sw & 0x1000, 0x1000);
    // ... and drops when it clears it (0x4F by RPDO1).
    rig.send("202#4F00");
    assert_eq!(rig.drive.statusword() & 0x1000, 0);
    assert!(rig.elapsed() - start > 9.0);
    // A second relative move of -133 from the previous target (2133 - 133 = 2000).
    rig.send("302#5F007BFFFFFF");
    rig.send("080#");
    rig.run(2000);
    assert_eq!(rig.drive.position(), 2000);
}

#[test]
fn blocked_load_gives_following_error_fault_and_emcy() {
    let (mut rig, _) = Rig::new(SimConfig::node(3));
    rig.send("000#0103");
    rig.send("203#0600");
    rig.send("203#0F00");
    rig.drive.set_load_blocked(true);
    // Absolute move to 1000 by SDO: 0x607A, then controlword 0x1F (RPDO1).
    assert_eq!(rig.send("603#237A6000E8030000"), vec!["583#607A600000000000"]);
    rig.send("203#1F00");
    let out = rig.run(1000);
    // Demand leaves the blocked shaft: > 50 Inc after ~0.35 s, + 100 ms time-out -> EMCY
    // 0x83: 11 86 = 0x8611, register 0x21 = generic + device profile.
    assert!(out.contains(&"083#1186210000000000".to_owned()), "{out:?}");
    assert_eq!(rig.drive.power_state(), PowerState::Fault);
    assert_eq!(rig.drive.statusword() & 0x2000, 0x2000, "SW bit 13 following error");
    assert_eq!(rig.drive.od().int(0x603F, 0), 0x8611);
    // 0x1003:01 = 0x8611 (history), 0x1003:00 = 1.
    assert_eq!(rig.send("603#4003100100000000"), vec!["583#4303100111860000"]);
    assert_eq!(rig.send("603#4003100200000000"), vec!["583#8003100224000008"]);
    // Fault reset edge (0 -> 0x80): switch on disabled and EMCY 0000 with register 0.
    rig.drive.set_load_blocked(false);
    rig.send("203#0000");
    let out = rig.send("203#8000");
    assert!(out.contains(&"083#0000000000000000".to_owned()), "{out:?}");
    assert_eq!(rig.drive.power_state(), PowerState::SwitchOnDisabled);
}

#[test]
fn injected_overtemperature_holds_until_the_cause_clears() {
    let (mut rig, _) = Rig::new(SimConfig::node(2));
    rig.enable();
    let mut out = Vec::new();
    rig.drive.inject_fault(0x4310);
    out.extend(rig.run(50));
    // The EMCY goes out with the next poll: 0x4310 LE 10 43, register 0x09.
    assert!(out.contains(&"082#1043090000000000".to_owned()), "{out:?}");
    assert_eq!(rig.drive.power_state(), PowerState::Fault);
    rig.send("202#0000");
    rig.send("202#8000");
    assert_eq!(rig.drive.power_state(), PowerState::Fault, "cause still active");
    rig.drive.clear_fault_cause();
    rig.send("202#0000");
    rig.send("202#8000");
    assert_eq!(rig.drive.power_state(), PowerState::SwitchOnDisabled);
}

#[test]
fn homing_on_the_negative_limit_switch_and_on_the_current_position() {
    let mut cfg = SimConfig::node(2);
    cfg.negative_limit_switch = Some(-300.0);
    cfg.initial_position = 100;
    let (mut rig, _) = Rig::new(cfg);
    rig.enable();
    // Mode 6 (homing), method 17, home offset 10.
    rig.send("602#2F60600006000000");
    rig.send("602#2F98600011000000");
    rig.send("602#237C60000A000000");
    rig.run(5);
    rig.send("202#1F00");
    rig.run(50);
    assert_eq!(rig.drive.statusword() & 0x3400, 0x0000, "in progress");
    rig.run(8000);
    assert_eq!(rig.drive.statusword() & 0x3400, 0x1400, "completed: {:#06x}", rig.drive.statusword());
    // The switch edge (world -300) is position 10; the axis stopped a little beyond it.
    let world = rig.drive.world_position();
    let pos = f64::from(rig.drive.position());
    assert!((pos - (world + 300.0 + 10.0)).abs() <= 1.0, "pos {pos} world {world}");
    // Method 35: the current position becomes the home offset (0).
    rig.send("202#0F00");
    rig.send("602#2F98600023000000");
    rig.send("602#237C600000000000");
    rig.send("202#1F00");
    rig.run(5);
    assert_eq!(rig.drive.position(), 0);
    assert_eq!(rig.drive.statusword() & 0x3400, 0x1400);
    // 0x200B := 0 (the seed's "set position") while standing: accepted.
    rig.send("202#0F00");
    assert_eq!(rig.send("602#230B200005000000"), vec!["582#600B200000000000"]);
    rig.run(5);
    assert_eq!(rig.drive.position(), 5);
}

#[test]
fn lss_configures_an_unconfigured_drive_which_then_boots() {
    let (mut rig, boot) = Rig::new(SimConfig::unconfigured(0x11));
    assert!(boot.is_empty(), "an unconfigured node is silent");
    assert!(rig.run(2000).is_empty(), "no heartbeat either");
    rig.send("7E5#0401000000000000");
    assert_eq!(rig.send("7E5#1104000000000000"), vec!["7E4#1100000000000000"]);
    assert_eq!(rig.send("7E5#1700000000000000"), vec!["7E4#1700000000000000"]);
    // Leaving configuration with a new id: reset communication -> boot-up 0x704.
    assert_eq!(rig.send("7E5#0400000000000000"), vec!["704#00"]);
    assert_eq!(rig.drive.node_id(), Some(4));
    assert_eq!(rig.send("604#4018100400000000"), vec!["584#4318100411000000"]);
    // Reset node keeps the stored id.
    assert_eq!(rig.send("000#8104"), vec!["704#00"]);
    assert_eq!(rig.drive.node_id(), Some(4));
}

#[test]
fn pdo_reconfiguration_in_pre_operational() {
    let (mut rig, _) = Rig::new(SimConfig::node(2));
    // TPDO3: enable with 0x6064 + 0x606C, type 1. Mapping while valid... it is disabled
    // by default (0xC0000382): sub0 := 0, entries, sub0 := 2, COB-ID := 0x40000382.
    assert_eq!(rig.send("602#2F021A0000000000"), vec!["582#60021A0000000000"]);
    assert_eq!(rig.send("602#23021A0120006460"), vec!["582#60021A0100000000"]);
    assert_eq!(rig.send("602#23021A0220006C60"), vec!["582#60021A0200000000"]);
    assert_eq!(rig.send("602#2F021A0002000000"), vec!["582#60021A0000000000"]);
    assert_eq!(rig.send("602#2302180182030040"), vec!["582#6002180100000000"]);
    // Now valid: mapping writes are refused with 0x06010000 (LE 00 00 01 06).
    assert_eq!(rig.send("602#2F021A0000000000"), vec!["582#80021A0000000106"]);
    rig.send("000#0102");
    let out = rig.send("080#");
    assert_eq!(out, vec!["282#500600000000", "382#0000000000000000"]);
}

#[test]
fn profile_velocity_halt_and_quick_stop() {
    let (mut rig, _) = Rig::new(SimConfig::node(2));
    rig.enable();
    // Mode 3 (profile velocity), target velocity 200 Inc/s (C8 00 00 00).
    rig.send("602#2F60600003000000");
    rig.send("602#23FF6000C8000000");
    rig.run(400);
    assert_eq!(rig.drive.velocity(), 200, "1000 Inc/s^2 reaches 200 Inc/s in 0.2 s");
    assert_eq!(rig.drive.statusword() & 0x1400, 0x0400, "target velocity reached, speed not zero");
    // Halt (bit 8): 0x010F -> ramp to 0 with 400 Inc/s^2 in 0.5 s; SW bit 12 speed zero.
    rig.send("202#0F01");
    rig.run(600);
    assert_eq!(rig.drive.velocity(), 0);
    assert_eq!(rig.drive.statusword() & 0x1400, 0x1400);
    // Release halt, run, then quick stop (0x02): 2000 Inc/s^2 (option 2), then switch on
    // disabled (transition 12).
    rig.send("202#0F00");
    rig.run(400);
    rig.send("202#0200");
    assert_eq!(rig.drive.power_state(), PowerState::QuickStopActive);
    rig.run(150);
    assert_eq!(rig.drive.velocity(), 0);
    assert_eq!(rig.drive.power_state(), PowerState::SwitchOnDisabled);
}

#[test]
fn software_limits_clamp_the_target() {
    let (mut rig, _) = Rig::new(SimConfig::node(2));
    rig.enable();
    // 0x607D:1 = -100 (9C FF FF FF), 0x607D:2 = 100 (64 00 00 00); target 500 (F4 01).
    assert_eq!(rig.send("602#237D60019CFFFFFF"), vec!["582#607D600100000000"]);
    assert_eq!(rig.send("602#237D600264000000"), vec!["582#607D600200000000"]);
    rig.send("602#237A6000F4010000");
    rig.send("202#1F00");
    rig.run(3000);
    assert_eq!(rig.drive.position(), 100);
    assert_eq!(rig.drive.statusword() & 0x0C00, 0x0C00, "target reached + internal limit");
}

#[test]
fn communication_fault_injection() {
    let (mut rig, _) = Rig::new(SimConfig::node(2));
    rig.drive.set_drop_sdo_replies(true);
    assert!(rig.send("602#2381600064000000").is_empty(), "reply dropped");
    assert_eq!(rig.drive.od().int(0x6081, 0), 100, "but the write was done");
    rig.drive.set_drop_sdo_replies(false);
    rig.drive.set_heartbeat_stopped(true);
    assert!(rig.run(2100).is_empty());
    rig.drive.set_heartbeat_stopped(false);
    rig.send("000#0102");
    rig.drive.set_silent(true);
    assert!(rig.run(500).is_empty(), "no TPDO, no heartbeat");
    assert!(rig.send("602#4000100000000000").is_empty());
    rig.drive.set_silent(false);
    assert!(!rig.run(1000).is_empty());
}

#[test]
fn the_drive_stops_when_the_masters_heartbeat_stops() {
    let (mut rig, _) = Rig::new(SimConfig::node(2));
    // 0x1016:1 := node 126 (0x7E), 300 ms (0x012C): 23 16 10 01 2C 01 7E 00.
    assert_eq!(rig.send("602#231610012C017E00"), vec!["582#6016100100000000"]);
    assert_eq!(rig.send("602#4016100100000000"), vec!["582#431610012C017E00"]);
    rig.enable();
    rig.send("602#2F60600003000000");
    rig.send("602#23FF6000C8000000");
    // The master's heartbeat every 100 ms: the drive runs on.
    for _ in 0..10 {
        rig.send("77E#05");
        let out = rig.run(100);
        assert!(out.iter().all(|f| !f.starts_with("082#")), "no EMCY while the heartbeat comes: {out:?}");
    }
    assert_eq!(rig.drive.velocity(), 200);
    assert_eq!(rig.drive.power_state(), PowerState::OperationEnabled);
    // Other nodes' heartbeats do not count.
    let mut out = Vec::new();
    for _ in 0..4 {
        rig.send("703#05");
        out.extend(rig.run(100));
    }
    // 300 ms after the last one: EMCY 0x8130 (30 81), error register 0x11 (generic +
    // communication), and the fault reaction stops the motor.
    assert!(out.iter().any(|f| f.starts_with("082#308111")), "{out:?}");
    assert_ne!(rig.drive.power_state(), PowerState::OperationEnabled);
    rig.run(500);
    assert_eq!(rig.drive.velocity(), 0);
    assert_eq!(rig.drive.power_state(), PowerState::Fault);
    assert_eq!(rig.drive.emcy().code(), 0x8130);
    // Reported once, not again while the master stays silent.
    assert!(rig.run(1000).iter().all(|f| !f.starts_with("082#")));
}
