//! Two simulated controllers on one line served in process ([`SimLine::into_sim_link`]) on
//! a virtual clock, a host speaking NFv2 with the codec through the same serve step as a
//! pty: both answer, a wrong address and a bad CRC stay silent, the decoder resynchronises
//! after garbage, a move commanded over the line shows in the true trajectory, baud pacing
//! and the processing delay, the gateway relay, dropped answers, line noise. Timing is
//! exact on virtual time, so it is asserted exactly.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_clock::{Clock, VirtualClock};
use motus_nfv2_protocol::{
    Command, CommandCode as C, DriveMode, DriveStatus, Frame, FrameBuilder, FrameScanner, Revision,
    RS485_BAUD,
};
use motus_nfv2_sim::{lock, Controllers, LineOptions, SharedController, SimClock, SimLine};
use motus_serial::{FaultConfig, FramedLink, LineSettings, NullLink, SimLink};
use std::time::Duration;

const REV: Revision = Revision::LATEST;

type Line = SimLink<FrameScanner, Controllers>;

/// The in-process link, shared so that the test can read the serve step's counters while
/// the host's framed link owns it.
type Shared = motus_serial::SharedLink<Line>;

/// The host, the line and the virtual clock they share (one thread of control: a wait
/// moves time at once).
struct Rig {
    clock: VirtualClock,
    sim_clock: SimClock,
    line: Shared,
    controllers: Vec<(u8, SharedController)>,
    host: FramedLink<FrameScanner>,
}

impl Rig {
    fn start(baud: u32, options: LineOptions) -> Rig {
        let clock = VirtualClock::new();
        let null = NullLink::new(LineSettings::n81(baud));
        let line = SimLine::with_clock(Box::new(null), options, clock.shared()).unwrap();
        let (controllers, sim_clock) = (line.controllers(), line.clock());
        let line = Shared::new(line.into_sim_link());
        let host = FramedLink::with_clock(Box::new(line.clone()), FrameScanner::new(REV), clock.shared());
        Rig { clock, sim_clock, line, controllers, host }
    }

    fn controller(&self, address: u8) -> SharedController {
        self.controllers.iter().find(|(a, _)| *a == address).map(|(_, c)| c.clone()).unwrap()
    }

    fn send(&mut self, frame: &Frame) {
        self.send_raw(&frame.encode(REV).unwrap());
    }

    fn send_raw(&mut self, bytes: &[u8]) {
        self.host.send(bytes).unwrap();
    }

    fn receive(&mut self, timeout: Duration) -> Option<Frame> {
        self.host.receive(timeout).unwrap()
    }

    fn transact(&mut self, frame: &Frame) -> Option<Frame> {
        self.send(frame);
        self.receive(Duration::from_millis(300))
    }

    fn query(&mut self, address: u8, code: C) -> Vec<i64> {
        let answer =
            self.transact(&Frame { address, commands: vec![Command::query(code)] }).expect("an answer");
        assert_eq!(answer.address, address);
        answer.int_values(code).unwrap().to_vec()
    }

    /// The virtual time a query of `code` to `address` takes, and its values.
    fn timed_query(&mut self, address: u8, code: C) -> (Duration, Vec<i64>) {
        let t0 = self.clock.now();
        let values = self.query(address, code);
        (self.clock.elapsed(t0), values)
    }
}

fn two_controllers() -> LineOptions {
    LineOptions { addresses: vec![1, 2], ..LineOptions::default() }
}

#[test]
fn two_controllers_answer_and_a_wrong_address_stays_silent() {
    let mut rig = Rig::start(57_600, two_controllers());
    for address in [1, 2] {
        let status = rig.query(address, C::ReadDrivesStatus)[0] as u16;
        assert_ne!(status & DriveStatus::ERROR, 0, "power-on mode ERROR");
        assert_eq!(rig.query(address, C::ReadDeviceVitals).len(), 4);
    }
    // Address 3 is nobody: a well-formed frame gets no answer.
    rig.send(&Frame { address: 3, commands: vec![Command::query(C::ReadDrivesStatus)] });
    assert!(rig.receive(Duration::from_millis(150)).is_none());
    // A bad CRC: silent too.
    let mut bad =
        Frame { address: 1, commands: vec![Command::query(C::ReadDrivesStatus)] }.encode(REV).unwrap();
    let last = bad.len() - 1;
    bad[last] ^= 0x01;
    rig.send_raw(&bad);
    assert!(rig.receive(Duration::from_millis(150)).is_none());
    // Garbage, then a valid frame in the same write: found.
    let mut bytes = vec![0x00, b'#', 0x23, 0x55];
    bytes.extend(
        Frame { address: 2, commands: vec![Command::query(C::ReadDrivesPosition)] }.encode(REV).unwrap(),
    );
    rig.send_raw(&bytes);
    let answer = rig.receive(Duration::from_millis(300)).expect("answered after garbage");
    assert_eq!(answer.address, 2);
    let line = rig.line.get();
    assert_eq!(line.frames_served(), 5);
    let stats = line.decoder_stats();
    assert!(stats.corrupt_frames >= 1 && stats.garbage_bytes >= 4, "{stats:?}");
}

#[test]
fn a_move_over_the_line_shows_in_the_true_trajectory() {
    let mut rig = Rig::start(57_600, two_controllers());
    let mode = i64::from(DriveMode::Position.to_raw(REV).unwrap());
    let mut b = FrameBuilder::new(2, REV);
    b.set(C::SetDrivesMode, &[mode]).unwrap().set(C::SetDrivesPosition, &[20_000]).unwrap();
    b.query(C::ReadDrivesStatus).unwrap();
    let answer = rig.transact(&b.build()).expect("status answered");
    assert_eq!(answer.commands.len(), 1);
    let t0 = rig.clock.now();
    loop {
        let position = rig.query(2, C::ReadDrivesPosition)[0];
        if (position - 20_000).abs() <= 2 {
            break;
        }
        assert!(rig.clock.elapsed(t0) < Duration::from_secs(3), "never arrived: {position}");
        rig.clock.sleep(Duration::from_millis(20));
    }
    let moved = rig.controller(2);
    let truth = lock(&moved).true_state();
    assert!((truth.position_counts - 20_000.0).abs() < 3.0);
    assert_eq!(truth.mode, DriveMode::Position);
    // Controller 1 never moved.
    assert_eq!(lock(&rig.controller(1)).true_state().position_counts, 0.0);
    // A hook on the running line: ENABLE removed, seen in the next status.
    {
        let mut c = lock(&moved);
        c.advance_to(rig.sim_clock.now());
        c.set_enable(false);
    }
    rig.clock.sleep(Duration::from_millis(10));
    let status = rig.query(2, C::ReadDrivesStatus)[0] as u16;
    assert_ne!(status & DriveStatus::ERROR, 0);
    assert_eq!(lock(&moved).true_state().mode, DriveMode::Error);
}

#[test]
fn pacing_and_processing_delay_set_the_answer_time() {
    let options =
        LineOptions { baud_pacing: true, reply_delay: Duration::from_millis(5), ..two_controllers() };
    let mut rig = Rig::start(9_600, options);
    // 7-byte query, 11-byte answer: 18 bytes of 10 bits at 9600 Bd = 18.75 ms, + 5 ms.
    let wire = LineSettings::n81(9_600);
    let (rt, values) = rig.timed_query(1, C::ReadDrivesPosition);
    assert_eq!(values, vec![0]);
    assert_eq!(rt, wire.wire_time(7) + Duration::from_millis(5) + wire.wire_time(11));
    assert!(rt.abs_diff(Duration::from_micros(23_750)) < Duration::from_micros(1), "{rt:?}");
}

#[test]
fn the_gateway_relays_to_the_other_modules() {
    // Address 0 is the gateway (seed): the PC is on its USB (no pacing), module 1 is
    // reached over the internal 57600 bps bus: 7 + 11 bytes = 3.1 ms, plus 2 x 0.2 ms.
    let mut rig = Rig::start(115_200, LineOptions { addresses: vec![0, 1], ..LineOptions::default() });
    let (direct, values) = rig.timed_query(0, C::ReadDrivesPosition);
    assert_eq!(values, vec![0]);
    let (relayed, values) = rig.timed_query(1, C::ReadDrivesPosition);
    assert_eq!(values, vec![0]);
    let delay = Duration::from_micros(200);
    let bus = LineSettings::n81(RS485_BAUD);
    assert_eq!(direct, delay);
    assert_eq!(relayed, delay + bus.wire_time(7) + delay + bus.wire_time(11));
}

#[test]
fn dropped_answers_follow_the_seeded_rate() {
    let options = LineOptions {
        faults: FaultConfig { drop_rate: 0.5, corrupt_rate: 0.0, seed: 7 },
        ..two_controllers()
    };
    let mut rig = Rig::start(115_200, options);
    let request = Frame { address: 1, commands: vec![Command::query(C::ReadDrivesStatus)] };
    let answered = (0..40)
        .filter(|_| {
            rig.send(&request);
            rig.receive(Duration::from_millis(60)).is_some()
        })
        .count();
    eprintln!("{answered} of 40 answers arrived at a drop rate of 0.5");
    assert!((8..=32).contains(&answered), "{answered} of 40");
    let line = rig.line.get();
    assert_eq!(line.frames_served(), 40, "every request was answered, some answers lost");
    assert_eq!(line.fault_stats().dropped_writes, 40 - answered as u64, "{:?}", line.fault_stats());
}

#[test]
fn line_noise_loses_some_frames_and_the_line_recovers() {
    let options = LineOptions {
        faults: FaultConfig { drop_rate: 0.0, corrupt_rate: 0.03, seed: 11 },
        ..two_controllers()
    };
    let mut rig = Rig::start(115_200, options);
    let request = Frame { address: 2, commands: vec![Command::query(C::ReadDrivesPosition)] };
    let mut answered = 0;
    for _ in 0..60 {
        rig.send(&request);
        if let Some(answer) = rig.receive(Duration::from_millis(60)) {
            assert_eq!(answer.address, 2, "a corrupted answer never decodes as another");
            answered += 1;
        }
        rig.host.stream_mut().clear();
    }
    eprintln!("{answered} of 60 answers arrived at 3 % byte noise");
    assert!((20..60).contains(&answered), "{answered} of 60");
    let stats = rig.line.get().decoder_stats();
    assert!(stats.corrupt_frames + stats.garbage_bytes > 0, "{stats:?}");
}

#[test]
fn the_same_seed_gives_the_same_line() {
    // Virtual time and seeded faults: two runs are the same, byte for byte.
    let run = || {
        let options = LineOptions {
            faults: FaultConfig { drop_rate: 0.1, corrupt_rate: 0.02, seed: 5 },
            ..two_controllers()
        }
        .seeded(5);
        let mut rig = Rig::start(57_600, options);
        let request = Frame { address: 1, commands: vec![Command::query(C::ReadDrivesCurrent)] };
        let answers: Vec<Option<Frame>> = (0..50)
            .map(|_| {
                rig.send(&request);
                let answer = rig.receive(Duration::from_millis(30));
                rig.host.stream_mut().clear();
                answer
            })
            .collect();
        (answers, rig.clock.since_base())
    };
    assert_eq!(run(), run());
}
