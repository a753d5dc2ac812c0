//! The simulated arm served on a real pseudo-terminal, a host opening it like any serial
//! port: every module answers, a wrong address and a bad CRC stay silent, the decoder
//! resynchronises after garbage, baud pacing, fault injection, and the test hooks reaching
//! the running simulator.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_kv01_protocol::{
    crc, Address, Answer, Command, CrcMode, D1Action, Message, MessageScanner, Reply, ReplyBody, ShortCode,
};
use motus_kv01_sim::{lock, LineOptions, SharedArm, Side, SimLine};
use motus_serial::{FaultConfig, FramedLink, LineSettings, PtyLink, SerialLink, ServeThread};
use std::path::Path;
use std::time::{Duration, Instant};

struct Sim {
    line: ServeThread<SimLine>,
    arm: SharedArm,
}

impl Sim {
    fn start(path: &Path, baud: u32, options: LineOptions) -> Sim {
        let pty = PtyLink::create(Some(path), LineSettings::n81(baud)).unwrap();
        let line = SimLine::new(Box::new(pty), options).unwrap();
        let arm = line.arm();
        Sim { line: ServeThread::spawn("kv01-sim", line, SimLine::run).unwrap(), arm }
    }

    fn stop(self) -> SimLine {
        self.line.stop().unwrap()
    }
}

/// The host side: replies read with the codec's stream decoder.
struct Host(FramedLink<MessageScanner>);

impl Host {
    fn open(path: &Path, baud: u32) -> Host {
        let link = SerialLink::open(path.to_str().unwrap(), baud).unwrap();
        Host(FramedLink::new(Box::new(link), MessageScanner::replies(CrcMode::Strict)))
    }

    fn send_raw(&mut self, bytes: &[u8]) {
        self.0.send(bytes).unwrap();
    }

    fn receive(&mut self, timeout: Duration) -> Option<Reply> {
        match self.0.receive(timeout).unwrap()?.message {
            Message::Reply(r) => Some(r),
            other => panic!("not a reply: {other:?}"),
        }
    }

    fn transact(&mut self, joint: u8, command: Command) -> Option<Reply> {
        let bytes = Message::request(Address::joint(joint).unwrap(), command).encode().unwrap();
        self.send_raw(&bytes);
        self.receive(Duration::from_millis(300))
    }

    fn body(&mut self, joint: u8, command: Command) -> ReplyBody {
        let reply = self.transact(joint, command).expect("a reply");
        assert_eq!(reply.address, Address::joint(joint).unwrap());
        reply.body
    }
}

fn d0(text: &str) -> Command {
    Command::Faulhaber { text: text.into() }
}

#[test]
fn all_six_modules_answer_and_a_wrong_address_stays_silent() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("kv01");
    let sim = Sim::start(&path, 115_200, LineOptions::default());
    let mut host = Host::open(&path, 115_200);
    for joint in 1..=6 {
        let ReplyBody::Resolver(r) = host.body(joint, Command::ReadResolver) else { panic!() };
        if joint == 6 {
            assert!(r.position < 4096, "12-bit gripper resolver");
        }
    }
    assert_eq!(host.body(2, d0("EN")), ReplyBody::Faulhaber { answer: Answer::parse("OK") });
    let ReplyBody::Voltages(v) = host.body(4, Command::ReadVoltages) else { panic!() };
    assert!((v.volts_24v() - 24.0).abs() < 0.05);
    assert_eq!(host.body(1, d0("")), ReplyBody::Short { text: ShortCode::UnknownCommand });
    // 0xE7 is no module: a well-formed message to it gets no answer.
    let mut wrong = vec![0xE7, 0x05, 0xD3];
    wrong.push(crc::compute(&wrong));
    wrong.push(0xF0);
    host.send_raw(&wrong);
    assert!(host.receive(Duration::from_millis(150)).is_none());
    // A bad CRC: silent too.
    let mut bad = Message::request(Address::joint(1).unwrap(), Command::ReadResolver).encode().unwrap();
    bad[3] ^= 0x01;
    host.send_raw(&bad);
    assert!(host.receive(Duration::from_millis(150)).is_none());
    // Garbage, then a valid message in the same write: the decoder resynchronises.
    let mut bytes = vec![0x00, 0xE3, 0x99, 0x12];
    bytes.extend(Message::request(Address::joint(5).unwrap(), Command::ReadResolver).encode().unwrap());
    host.send_raw(&bytes);
    let reply = host.receive(Duration::from_millis(300)).expect("answered after garbage");
    assert_eq!(reply.address.raw(), 0xE5);
    // A half message left hanging is dropped when the line goes quiet.
    host.send_raw(&[0xE1, 0x05]);
    std::thread::sleep(Duration::from_millis(20));
    assert!(matches!(host.body(3, Command::ReadResolver), ReplyBody::Resolver(_)));
    let line = sim.stop();
    assert_eq!(line.server().frames_served(), 11);
    let stats = line.server().decoder_stats();
    assert!(stats.corrupt_frames >= 1 && stats.garbage_bytes >= 4, "{stats:?}");
}

#[test]
fn test_hooks_reach_the_running_simulator() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("kv01");
    let sim = Sim::start(&path, 115_200, LineOptions::default());
    let mut host = Host::open(&path, 115_200);
    lock(&sim.arm).push_joint_onto_switch(2, Side::Upper).unwrap();
    std::thread::sleep(Duration::from_millis(30));
    let ReplyBody::Status(s) = host.body(2, Command::BrakeLimit(D1Action::EnterRestrictedMode)) else {
        panic!()
    };
    assert!(s.lsstop && s.limit_switch && s.restricted_mode);
    assert_eq!(host.body(2, d0("V1000")), ReplyBody::Faulhaber { answer: Answer::LimVal });
    // The safety time-out runs in real time: 800 ms of silence trips it.
    std::thread::sleep(Duration::from_millis(800));
    assert_eq!(host.body(2, Command::ReadResolver), ReplyBody::Short { text: ShortCode::Timeout });
    assert!(lock(&sim.arm).state(2).unwrap().timed_out);
    lock(&sim.arm).power_cycle();
    assert!(matches!(host.body(2, Command::ReadResolver), ReplyBody::Resolver(_)));
}

#[test]
fn baud_pacing_and_controller_time() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("kv01");
    let options = LineOptions {
        baud_pacing: true,
        slow_controller: Some(Duration::from_millis(100)),
        ..LineOptions::default()
    };
    let _sim = Sim::start(&path, 9600, options);
    let mut host = Host::open(&path, 9600);
    // D3: 5 bytes out, 8 back, 10 bits each at 9600 Bd = 13.5 ms at least.
    let t0 = Instant::now();
    assert!(matches!(host.body(1, Command::ReadResolver), ReplyBody::Resolver(_)));
    let rt = t0.elapsed();
    assert!(rt >= Duration::from_micros(13_500), "{rt:?}");
    // Slow controller: the module waits 50 ms after forwarding, then answers TIMEOUT.
    let t0 = Instant::now();
    assert_eq!(host.body(1, d0("EN")), ReplyBody::Faulhaber { answer: Answer::Timeout });
    assert!(t0.elapsed() >= Duration::from_millis(50), "{:?}", t0.elapsed());
}

#[test]
fn dropped_replies_follow_the_seeded_rate() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("kv01");
    let options = LineOptions {
        faults: FaultConfig { drop_rate: 0.5, corrupt_rate: 0.0, seed: 7 },
        ..LineOptions::default()
    };
    let sim = Sim::start(&path, 115_200, options);
    let mut host = Host::open(&path, 115_200);
    let answered = (0..40)
        .filter(|_| {
            let bytes = Message::request(Address::joint(1).unwrap(), Command::ReadResolver).encode().unwrap();
            host.send_raw(&bytes);
            host.receive(Duration::from_millis(60)).is_some()
        })
        .count();
    assert!((8..=32).contains(&answered), "{answered} of 40");
    let line = sim.stop();
    assert_eq!(line.server().frames_served(), 40, "every request was decoded and answered (then dropped)");
}

#[test]
fn invalid_fault_rates_are_refused() {
    let pty = PtyLink::create(None, LineSettings::n81(115_200)).unwrap();
    let options = LineOptions {
        faults: FaultConfig { drop_rate: 1.5, ..FaultConfig::default() },
        ..LineOptions::default()
    };
    assert!(SimLine::new(Box::new(pty), options).is_err());
}
