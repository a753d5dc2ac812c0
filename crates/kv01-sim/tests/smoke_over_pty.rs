//! Smoke test of the simulated arm served on a real pseudo-terminal by its own thread, a
//! host opening it like any serial port (the line's behaviours are checked on virtual time
//! in `line.rs`). Time-outs are generous liveness bounds.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_kv01_protocol::{Address, Command, CrcMode, D1Action, Message, MessageScanner, ReplyBody};
use motus_kv01_sim::{lock, LineOptions, Side, SimLine};
use motus_serial::{FramedLink, LineSettings, PtyLink, SerialLink, ServeThread};
use std::time::{Duration, Instant};

#[test]
fn every_module_answers_over_a_pty_and_the_hooks_reach_the_running_simulator() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("kv01");
    let pty = PtyLink::create(Some(&path), LineSettings::n81(115_200)).unwrap();
    let line = SimLine::new(Box::new(pty), LineOptions::default()).unwrap();
    let arm = line.arm();
    let sim = ServeThread::spawn("kv01-sim", line, SimLine::run).unwrap();
    let link = SerialLink::open(path.to_str().unwrap(), 115_200).unwrap();
    let mut host = FramedLink::new(Box::new(link), MessageScanner::replies(CrcMode::Strict));
    let mut body = |joint: u8, command: Command| {
        let bytes = Message::request(Address::joint(joint).unwrap(), command).encode().unwrap();
        host.send(&bytes).unwrap();
        let t0 = Instant::now();
        let decoded = host.receive(Duration::from_secs(5)).unwrap().expect("a reply");
        let Message::Reply(reply) = decoded.message else { panic!("not a reply: {decoded:?}") };
        assert_eq!(reply.address, Address::joint(joint).unwrap());
        (reply.body, t0.elapsed())
    };
    for joint in 1..=6 {
        let (reply, rt) = body(joint, Command::ReadResolver);
        eprintln!("joint {joint}: {reply:?} after {rt:?}");
        assert!(matches!(reply, ReplyBody::Resolver(_)), "{reply:?}");
    }
    lock(&arm).push_joint_onto_switch(2, Side::Upper).unwrap();
    // The served arm steps while the line is idle; the hook shows within a step or two.
    let t0 = Instant::now();
    loop {
        let (reply, _) = body(2, Command::BrakeLimit(D1Action::EnterRestrictedMode));
        let ReplyBody::Status(s) = reply else { panic!("{reply:?}") };
        if s.lsstop && s.limit_switch {
            break;
        }
        assert!(t0.elapsed() < Duration::from_secs(10), "the hook never showed: {s:?}");
        std::thread::sleep(Duration::from_millis(10));
    }
    let line = sim.stop().unwrap();
    eprintln!("{} frames served", line.server().frames_served());
    assert!(line.server().frames_served() >= 7);
}
