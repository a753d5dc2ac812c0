//! Two simulated controllers served on one real pseudo-terminal, a host opening it like any
//! serial port and speaking NFv2 with the codec: both answer, a wrong address and a bad CRC
//! stay silent, the decoder resynchronises after garbage, a move commanded over the line
//! shows in the true trajectory, baud pacing and the processing delay, the gateway relay,
//! dropped answers.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_nfv2_protocol::{
    Command, CommandCode as C, DriveMode, DriveStatus, Frame, FrameBuilder, FrameScanner, Revision,
};
use motus_nfv2_sim::{lock, LineOptions, SharedController, SimClock, SimLine};
use motus_serial::{FaultConfig, FramedLink, LineSettings, PtyLink, SerialLink, ServeThread};
use std::path::Path;
use std::time::{Duration, Instant};

const REV: Revision = Revision::LATEST;

struct Sim {
    line: ServeThread<SimLine>,
    controllers: Vec<(u8, SharedController)>,
    clock: SimClock,
}

impl Sim {
    fn start(path: &Path, baud: u32, options: LineOptions) -> Sim {
        let pty = PtyLink::create(Some(path), LineSettings::n81(baud)).unwrap();
        let line = SimLine::new(Box::new(pty), options).unwrap();
        let (controllers, clock) = (line.controllers(), line.clock());
        Sim { line: ServeThread::spawn("nfv2-sim", line, SimLine::run).unwrap(), controllers, clock }
    }

    fn controller(&self, address: u8) -> SharedController {
        self.controllers.iter().find(|(a, _)| *a == address).map(|(_, c)| c.clone()).unwrap()
    }

    fn stop(self) -> SimLine {
        self.line.stop().unwrap()
    }
}

/// The host side: answers read with the codec's stream decoder.
struct Host(FramedLink<FrameScanner>);

impl Host {
    fn open(path: &Path, baud: u32) -> Host {
        let link = SerialLink::open(path.to_str().unwrap(), baud).unwrap();
        Host(FramedLink::new(Box::new(link), FrameScanner::new(REV)))
    }

    fn send(&mut self, frame: &Frame) {
        self.send_raw(&frame.encode(REV).unwrap());
    }

    fn send_raw(&mut self, bytes: &[u8]) {
        self.0.send(bytes).unwrap();
    }

    fn receive(&mut self, timeout: Duration) -> Option<Frame> {
        self.0.receive(timeout).unwrap()
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
}

fn two_controllers() -> LineOptions {
    LineOptions { addresses: vec![1, 2], ..LineOptions::default() }
}

#[test]
fn two_controllers_answer_and_a_wrong_address_stays_silent() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("nfv2");
    let sim = Sim::start(&path, 57_600, two_controllers());
    let mut host = Host::open(&path, 57_600);
    for address in [1, 2] {
        let status = host.query(address, C::ReadDrivesStatus)[0] as u16;
        assert_ne!(status & DriveStatus::ERROR, 0, "power-on mode ERROR");
        assert_eq!(host.query(address, C::ReadDeviceVitals).len(), 4);
    }
    // Address 3 is nobody: a well-formed frame gets no answer.
    host.send(&Frame { address: 3, commands: vec![Command::query(C::ReadDrivesStatus)] });
    assert!(host.receive(Duration::from_millis(150)).is_none());
    // A bad CRC: silent too.
    let mut bad =
        Frame { address: 1, commands: vec![Command::query(C::ReadDrivesStatus)] }.encode(REV).unwrap();
    let last = bad.len() - 1;
    bad[last] ^= 0x01;
    host.send_raw(&bad);
    assert!(host.receive(Duration::from_millis(150)).is_none());
    // Garbage, then a valid frame in the same write: found.
    let mut bytes = vec![0x00, b'#', 0x23, 0x55];
    bytes.extend(
        Frame { address: 2, commands: vec![Command::query(C::ReadDrivesPosition)] }.encode(REV).unwrap(),
    );
    host.send_raw(&bytes);
    let answer = host.receive(Duration::from_millis(300)).expect("answered after garbage");
    assert_eq!(answer.address, 2);
    let line = sim.stop();
    assert_eq!(line.server().frames_served(), 5);
    let stats = line.server().decoder_stats();
    assert!(stats.corrupt_frames >= 1 && stats.garbage_bytes >= 4, "{stats:?}");
}

#[test]
fn a_move_over_the_line_shows_in_the_true_trajectory() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("nfv2");
    let sim = Sim::start(&path, 57_600, two_controllers());
    let mut host = Host::open(&path, 57_600);
    let mode = i64::from(DriveMode::Position.to_raw(REV).unwrap());
    let mut b = FrameBuilder::new(2, REV);
    b.set(C::SetDrivesMode, &[mode]).unwrap().set(C::SetDrivesPosition, &[20_000]).unwrap();
    b.query(C::ReadDrivesStatus).unwrap();
    let answer = host.transact(&b.build()).expect("status answered");
    assert_eq!(answer.commands.len(), 1);
    let deadline = Instant::now() + Duration::from_secs(3);
    loop {
        let position = host.query(2, C::ReadDrivesPosition)[0];
        if (position - 20_000).abs() <= 2 {
            break;
        }
        assert!(Instant::now() < deadline, "never arrived: {position}");
        std::thread::sleep(Duration::from_millis(20));
    }
    let moved = sim.controller(2);
    let truth = lock(&moved).true_state();
    assert!((truth.position_counts - 20_000.0).abs() < 3.0);
    assert_eq!(truth.mode, DriveMode::Position);
    // Controller 1 never moved.
    assert_eq!(lock(&sim.controller(1)).true_state().position_counts, 0.0);
    // A hook on the running line: ENABLE removed, seen in the next status.
    {
        let mut c = lock(&moved);
        c.advance_to(sim.clock.now());
        c.set_enable(false);
    }
    std::thread::sleep(Duration::from_millis(10));
    let status = host.query(2, C::ReadDrivesStatus)[0] as u16;
    assert_ne!(status & DriveStatus::ERROR, 0);
    assert_eq!(lock(&moved).true_state().mode, DriveMode::Error);
}

#[test]
fn pacing_and_processing_delay_set_the_answer_time() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("nfv2");
    let options =
        LineOptions { baud_pacing: true, reply_delay: Duration::from_millis(5), ..two_controllers() };
    let _sim = Sim::start(&path, 9_600, options);
    let mut host = Host::open(&path, 9_600);
    // 7-byte query, 11-byte answer: 18 bytes of 10 bits at 9600 Bd = 18.75 ms, + 5 ms.
    let t0 = Instant::now();
    let values = host.query(1, C::ReadDrivesPosition);
    let rt = t0.elapsed();
    assert_eq!(values, vec![0]);
    assert!(rt >= Duration::from_micros(23_750), "{rt:?}");
    assert!(rt < Duration::from_millis(150), "{rt:?}");
}

#[test]
fn the_gateway_relays_to_the_other_modules() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("nfv2");
    // Address 0 is the gateway (seed): the PC is on its USB (no pacing), module 1 is
    // reached over the internal 57600 bps bus: 7 + 11 bytes = 3.1 ms, plus 2 x 0.2 ms.
    let _sim = Sim::start(&path, 115_200, LineOptions { addresses: vec![0, 1], ..LineOptions::default() });
    let mut host = Host::open(&path, 115_200);
    let mut direct = Duration::MAX;
    let mut relayed = Duration::MAX;
    for _ in 0..5 {
        let t0 = Instant::now();
        assert_eq!(host.query(0, C::ReadDrivesPosition), vec![0]);
        direct = direct.min(t0.elapsed());
        let t0 = Instant::now();
        assert_eq!(host.query(1, C::ReadDrivesPosition), vec![0]);
        relayed = relayed.min(t0.elapsed());
    }
    assert!(relayed >= Duration::from_micros(3_500), "{relayed:?}");
    assert!(direct < relayed, "{direct:?} vs {relayed:?}");
}

#[test]
fn dropped_answers_follow_the_seeded_rate() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("nfv2");
    let options = LineOptions {
        faults: FaultConfig { drop_rate: 0.5, corrupt_rate: 0.0, seed: 7 },
        ..two_controllers()
    };
    let sim = Sim::start(&path, 115_200, options);
    let mut host = Host::open(&path, 115_200);
    let request = Frame { address: 1, commands: vec![Command::query(C::ReadDrivesStatus)] };
    let answered = (0..40)
        .filter(|_| {
            host.send(&request);
            host.receive(Duration::from_millis(60)).is_some()
        })
        .count();
    assert!((8..=32).contains(&answered), "{answered} of 40");
    let line = sim.stop();
    assert_eq!(line.server().frames_served(), 40, "every request was answered, some answers lost");
}

#[test]
fn line_noise_loses_some_frames_and_the_line_recovers() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("nfv2");
    let options = LineOptions {
        faults: FaultConfig { drop_rate: 0.0, corrupt_rate: 0.03, seed: 11 },
        ..two_controllers()
    };
    let sim = Sim::start(&path, 115_200, options);
    let mut host = Host::open(&path, 115_200);
    let request = Frame { address: 2, commands: vec![Command::query(C::ReadDrivesPosition)] };
    let mut answered = 0;
    for _ in 0..60 {
        host.send(&request);
        if let Some(answer) = host.receive(Duration::from_millis(60)) {
            assert_eq!(answer.address, 2, "a corrupted answer never decodes as another");
            answered += 1;
        }
        host.0.stream_mut().clear();
    }
    assert!((20..60).contains(&answered), "{answered} of 60");
    let line = sim.stop();
    let stats = line.server().decoder_stats();
    assert!(stats.corrupt_frames + stats.garbage_bytes > 0, "{stats:?}");
}
