//! A smoke test on a real pseudo-terminal, in real time: two simulated controllers served
//! by the simulator's thread (`SimLine::run`), a host opening the pty like any serial port:
//! both answer and a move commanded over the line shows in the true trajectory. Liveness
//! time-outs only; the line's behaviours and timing are tested on virtual time (`line.rs`).
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_nfv2_protocol::{
    Command, CommandCode as C, DriveMode, DriveStatus, Frame, FrameBuilder, FrameScanner, Revision,
};
use motus_nfv2_sim::{lock, LineOptions, SimLine};
use motus_serial::{FramedLink, LineSettings, PtyLink, SerialLink, ServeThread};
use std::time::{Duration, Instant};

const REV: Revision = Revision::LATEST;
/// A liveness bound, far beyond what an answer takes on a loaded host.
const LIVENESS: Duration = Duration::from_secs(10);

#[test]
fn two_controllers_answer_and_move_over_a_pty() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("nfv2");
    let pty = PtyLink::create(Some(&path), LineSettings::n81(57_600)).unwrap();
    let options = LineOptions { addresses: vec![1, 2], baud_pacing: true, ..LineOptions::default() };
    let line = SimLine::new(Box::new(pty), options).unwrap();
    let moved = line.controller(2).unwrap();
    let sim = ServeThread::spawn("nfv2-sim", line, SimLine::run).unwrap();
    let link = SerialLink::open(path.to_str().unwrap(), 57_600).unwrap();
    let mut host = FramedLink::new(Box::new(link), FrameScanner::new(REV));
    let mut transact = |frame: &Frame| {
        host.send(&frame.encode(REV).unwrap()).unwrap();
        host.receive(LIVENESS).unwrap().expect("an answer")
    };
    for address in [1, 2] {
        let answer = transact(&Frame { address, commands: vec![Command::query(C::ReadDrivesStatus)] });
        assert_eq!(answer.address, address);
        let status = answer.int_values(C::ReadDrivesStatus).unwrap()[0] as u16;
        assert_ne!(status & DriveStatus::ERROR, 0, "power-on mode ERROR");
    }
    let mode = i64::from(DriveMode::Position.to_raw(REV).unwrap());
    let mut b = FrameBuilder::new(2, REV);
    b.set(C::SetDrivesMode, &[mode]).unwrap().set(C::SetDrivesPosition, &[20_000]).unwrap();
    b.query(C::ReadDrivesStatus).unwrap();
    transact(&b.build());
    let t0 = Instant::now();
    let query = Frame { address: 2, commands: vec![Command::query(C::ReadDrivesPosition)] };
    loop {
        let position = transact(&query).int_values(C::ReadDrivesPosition).unwrap()[0];
        if (position - 20_000).abs() <= 2 {
            break;
        }
        assert!(t0.elapsed() < LIVENESS, "never arrived: {position}");
        std::thread::sleep(Duration::from_millis(20));
    }
    eprintln!("moved 20 000 counts over a pty in {:.3?}", t0.elapsed());
    let line = sim.stop().unwrap();
    assert!((lock(&moved).true_state().position_counts - 20_000.0).abs() < 3.0);
    assert!(line.server().frames_served() >= 4);
}
