//! The simulated arm served on a line, in-process on virtual time ([`SimLine::sim_link`]):
//! every module answers, a wrong address and a bad CRC stay silent, the decoder
//! resynchronises after garbage and drops a half message when the line goes quiet, baud
//! pacing and the controller's time, seeded fault injection, the 700 ms safety time-out,
//! and the test hooks reaching the served arm.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_clock::{Clock, VirtualClock};
use motus_kv01_protocol::{
    crc, Address, Answer, Command, CrcMode, D1Action, Message, MessageScanner, Reply, ReplyBody, ShortCode,
};
use motus_kv01_sim::{lock, ArmSimLink, LineOptions, SharedArm, Side, SimLine};
use motus_serial::{FaultConfig, FramedLink, LineSettings, NullLink};
use std::time::Duration;

/// The host's end of the simulated line, kept by the test too (to read the serve step's
/// counters).
type SharedLink = motus_serial::SharedLink<ArmSimLink>;

/// The host side on a virtual clock (one thread of control): replies read with the
/// codec's stream decoder.
struct Host {
    clock: VirtualClock,
    link: SharedLink,
    framed: FramedLink<MessageScanner>,
    arm: SharedArm,
}

impl Host {
    fn start(baud: u32, options: LineOptions) -> Host {
        let clock = VirtualClock::new();
        let (link, arm) = SimLine::sim_link(options, LineSettings::n81(baud), clock.shared()).unwrap();
        let link = SharedLink::new(link);
        let framed = FramedLink::with_clock(
            Box::new(link.clone()),
            MessageScanner::replies(CrcMode::Strict),
            clock.shared(),
        );
        Host { clock, link, framed, arm }
    }

    fn send_raw(&mut self, bytes: &[u8]) {
        self.framed.send(bytes).unwrap();
    }

    fn receive(&mut self, timeout: Duration) -> Option<Reply> {
        match self.framed.receive(timeout).unwrap()?.message {
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
    let mut host = Host::start(115_200, LineOptions::default());
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
    host.clock.sleep(Duration::from_millis(20));
    assert!(matches!(host.body(3, Command::ReadResolver), ReplyBody::Resolver(_)));
    let link = host.link.get();
    assert_eq!(link.frames_served(), 11);
    let stats = link.decoder_stats();
    assert!(stats.corrupt_frames >= 1 && stats.garbage_bytes >= 4, "{stats:?}");
}

#[test]
fn test_hooks_reach_the_served_arm_and_700_ms_of_silence_latches_to() {
    let mut host = Host::start(115_200, LineOptions::default());
    lock(&host.arm).push_joint_onto_switch(2, Side::Upper).unwrap();
    host.clock.sleep(Duration::from_millis(30));
    let ReplyBody::Status(s) = host.body(2, Command::BrakeLimit(D1Action::EnterRestrictedMode)) else {
        panic!()
    };
    assert!(s.lsstop && s.limit_switch && s.restricted_mode);
    assert_eq!(host.body(2, d0("V1000")), ReplyBody::Faulhaber { answer: Answer::LimVal });
    // 650 ms of silence: still answering.
    host.clock.sleep(Duration::from_millis(650));
    assert!(matches!(host.body(2, Command::ReadResolver), ReplyBody::Resolver(_)));
    // 800 ms of silence trips the safety time-out, latched until a power cycle.
    host.clock.sleep(Duration::from_millis(800));
    assert_eq!(host.body(2, Command::ReadResolver), ReplyBody::Short { text: ShortCode::Timeout });
    assert!(lock(&host.arm).state(2).unwrap().timed_out);
    assert_eq!(host.body(2, Command::ReadResolver), ReplyBody::Short { text: ShortCode::Timeout });
    lock(&host.arm).power_cycle();
    assert!(matches!(host.body(2, Command::ReadResolver), ReplyBody::Resolver(_)));
}

#[test]
fn baud_pacing_and_controller_time() {
    let options = LineOptions {
        baud_pacing: true,
        slow_controller: Some(Duration::from_millis(100)),
        ..LineOptions::default()
    };
    let mut host = Host::start(9600, options);
    // D3: 5 bytes out, 8 back, 10 bits each at 9600 Bd = 13.5 ms at least.
    let t0 = host.clock.now();
    assert!(matches!(host.body(1, Command::ReadResolver), ReplyBody::Resolver(_)));
    let rt = host.clock.elapsed(t0);
    eprintln!("D3 round trip at 9600 Bd: {rt:?} of virtual time");
    // On virtual time: exactly the wire time and the module's turnaround.
    let wire = LineSettings::n81(9600).wire_time(13);
    assert!(rt >= wire && rt <= wire + Duration::from_millis(1), "{rt:?}");
    // Slow controller: the module waits 50 ms after forwarding, then answers TIMEOUT.
    let t0 = host.clock.now();
    assert_eq!(host.body(1, d0("EN")), ReplyBody::Faulhaber { answer: Answer::Timeout });
    let rt = host.clock.elapsed(t0);
    eprintln!("D0 to a slow controller: {rt:?}");
    assert!(rt >= Duration::from_millis(50), "{rt:?}");
}

#[test]
fn dropped_replies_follow_the_seeded_rate() {
    let run = || {
        let options = LineOptions {
            faults: FaultConfig { drop_rate: 0.5, corrupt_rate: 0.0, seed: 7 },
            ..LineOptions::default()
        };
        let mut host = Host::start(115_200, options);
        let answered: Vec<bool> = (0..40)
            .map(|_| {
                let bytes =
                    Message::request(Address::joint(1).unwrap(), Command::ReadResolver).encode().unwrap();
                host.send_raw(&bytes);
                host.receive(Duration::from_millis(60)).is_some()
            })
            .collect();
        let link = host.link.get();
        assert_eq!(link.frames_served(), 40, "every request was decoded and answered (then dropped)");
        answered
    };
    let answered = run();
    let n = answered.iter().filter(|a| **a).count();
    assert!((8..=32).contains(&n), "{n} of 40");
    assert_eq!(run(), answered, "the same seed drops the same replies");
}

#[test]
fn invalid_fault_rates_are_refused() {
    let options = || LineOptions {
        faults: FaultConfig { drop_rate: 1.5, ..FaultConfig::default() },
        ..LineOptions::default()
    };
    let line = LineSettings::n81(115_200);
    assert!(SimLine::new(Box::new(NullLink::new(line)), options()).is_err());
    assert!(SimLine::sim_link(options(), line, VirtualClock::new().shared()).is_err());
}
