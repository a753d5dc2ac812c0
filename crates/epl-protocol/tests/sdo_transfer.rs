//! SDO over ASnd: the client (`SdoClient`) and the server (`SdoServer`) talking to each other
//! on virtual time through a link that can lose and duplicate frames, every frame passing
//! through the wire codec (`EplFrame` encode and decode, padding included); plus scripted peers
//! (a bare `SequenceLayer`) for the abort paths a well-behaved peer never takes, and random
//! input that must never panic.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use std::collections::{BTreeMap, VecDeque};
use std::time::{Duration, Instant};

use motus_epl_protocol::sdo_transfer::{
    LinkState, Role, SdoClient, SdoConfig, SdoError, SdoServer, SeqEvent, SequenceLayer, TransferId,
    TransferKind, TransferOutcome,
};
use motus_epl_protocol::{
    Asnd, EplFrame, MacAddr, Message, ObjectAccess, SdoAbortCode, SdoCommand, SdoCommandId, SdoFrame,
};
use proptest::prelude::*;

// ---------------------------------------------------------------------------------------------
// A small object dictionary.

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Access {
    ReadWrite,
    ReadOnly,
    WriteOnly,
}

#[derive(Debug, Clone)]
struct Obj {
    value: Vec<u8>,
    access: Access,
    /// Writes must have this length.
    fixed_len: Option<usize>,
}

#[derive(Debug, Default)]
struct TestOd {
    objects: BTreeMap<(u16, u8), Obj>,
    /// Every successful write: (index, subindex, length).
    writes: Vec<(u16, u8, usize)>,
}

impl TestOd {
    fn with(mut self, index: u16, sub: u8, value: Vec<u8>, access: Access, fixed_len: Option<usize>) -> Self {
        self.objects.insert((index, sub), Obj { value, access, fixed_len });
        self
    }

    fn demo() -> Self {
        Self::default()
            .with(0x1006, 0, 50_000u32.to_le_bytes().to_vec(), Access::ReadWrite, Some(4))
            .with(0x1000, 0, 0x0001_0191u32.to_le_bytes().to_vec(), Access::ReadOnly, Some(4))
            .with(0x1F50, 1, Vec::new(), Access::ReadWrite, None) // a domain: any size
            .with(0x2000, 0, (0..6000u32).map(|i| (i * 7) as u8).collect(), Access::ReadWrite, None)
            .with(0x2001, 0, Vec::new(), Access::WriteOnly, None)
    }

    fn lookup(&mut self, index: u16, sub: u8) -> Result<&mut Obj, SdoAbortCode> {
        if !self.objects.keys().any(|(i, _)| *i == index) {
            return Err(SdoAbortCode::ObjectDoesNotExist);
        }
        self.objects.get_mut(&(index, sub)).ok_or(SdoAbortCode::SubIndexDoesNotExist)
    }
}

impl ObjectAccess for TestOd {
    fn read(&mut self, index: u16, subindex: u8) -> Result<Vec<u8>, SdoAbortCode> {
        let obj = self.lookup(index, subindex)?;
        if obj.access == Access::WriteOnly {
            return Err(SdoAbortCode::WriteOnly);
        }
        Ok(obj.value.clone())
    }

    fn write(&mut self, index: u16, subindex: u8, value: &[u8]) -> Result<(), SdoAbortCode> {
        let obj = self.lookup(index, subindex)?;
        if obj.access == Access::ReadOnly {
            return Err(SdoAbortCode::ReadOnly);
        }
        if obj.fixed_len.is_some_and(|n| n != value.len()) {
            return Err(SdoAbortCode::TypeLengthMismatch);
        }
        obj.value = value.to_vec();
        self.writes.push((index, subindex, value.len()));
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------------
// The wire and a link on virtual time.

/// Encodes `frame` in an ASnd from `src` to `dst` and decodes it again, as a peer receives it
/// (acknowledgement-only frames come back with an all-zero command layer from the padding).
fn wire(frame: &SdoFrame, src: u8, dst: u8) -> SdoFrame {
    let epl = EplFrame::new(
        MacAddr([2, 0, 0, 0, 0, src]),
        MacAddr::ASND,
        dst,
        src,
        Message::Asnd(Asnd::Sdo(frame.clone())),
    );
    let bytes = epl.encode().unwrap_or_else(|e| panic!("{e}: {frame:?}"));
    assert!((60..=1514).contains(&bytes.len()), "{} bytes", bytes.len());
    match EplFrame::decode(&bytes).unwrap().message {
        Message::Asnd(Asnd::Sdo(sdo)) => sdo,
        other => panic!("{other:?}"),
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Dir {
    ToServer,
    ToClient,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Fault {
    Deliver,
    Drop,
    Duplicate,
}

type FaultFn = Box<dyn FnMut(Dir, usize, &SdoFrame) -> Fault>;

struct Sim {
    t0: Instant,
    now: Instant,
    client: SdoClient,
    server: SdoServer,
    od: TestOd,
    latency: Duration,
    in_flight: VecDeque<(Instant, Dir, SdoFrame)>,
    sent: [usize; 2],
    fault: FaultFn,
    /// Every frame put on the link: (time since t0, direction, frame as received).
    log: Vec<(Duration, Dir, SdoFrame)>,
}

impl Sim {
    fn new(client: SdoConfig, server: SdoConfig, od: TestOd) -> Self {
        let t0 = Instant::now();
        Self {
            t0,
            now: t0,
            client: SdoClient::new(client),
            server: SdoServer::new(server),
            od,
            latency: Duration::from_millis(1),
            in_flight: VecDeque::new(),
            sent: [0, 0],
            fault: Box::new(|_, _, _| Fault::Deliver),
            log: Vec::new(),
        }
    }

    fn faults(mut self, f: impl FnMut(Dir, usize, &SdoFrame) -> Fault + 'static) -> Self {
        self.fault = Box::new(f);
        self
    }

    fn transmit(&mut self, dir: Dir, frame: SdoFrame) {
        let (src, dst) = if dir == Dir::ToServer { (240, 1) } else { (1, 240) };
        let frame = wire(&frame, src, dst);
        let k = usize::from(dir == Dir::ToClient);
        let n = self.sent[k];
        self.sent[k] += 1;
        self.log.push((self.now - self.t0, dir, frame.clone()));
        match (self.fault)(dir, n, &frame) {
            Fault::Deliver => self.in_flight.push_back((self.now + self.latency, dir, frame)),
            Fault::Drop => {}
            Fault::Duplicate => {
                self.in_flight.push_back((self.now + self.latency, dir, frame.clone()));
                self.in_flight.push_back((self.now + self.latency * 2, dir, frame));
            }
        }
    }

    /// Delivers what is due, then polls both ends until they have nothing to send.
    fn step(&mut self) {
        while let Some(pos) = self.in_flight.iter().position(|(at, _, _)| *at <= self.now) {
            let (_, dir, frame) = self.in_flight.remove(pos).unwrap();
            match dir {
                Dir::ToServer => {
                    for f in self.server.on_frame(self.now, &frame, &mut self.od) {
                        self.transmit(Dir::ToClient, f);
                    }
                }
                Dir::ToClient => {
                    for f in self.client.on_frame(self.now, &frame) {
                        self.transmit(Dir::ToServer, f);
                    }
                }
            }
        }
        while let Some(f) = self.client.poll(self.now) {
            self.transmit(Dir::ToServer, f);
        }
        while let Some(f) = self.server.poll(self.now) {
            self.transmit(Dir::ToClient, f);
        }
    }

    /// Runs until the client has finished every transfer and the link is quiet, jumping from
    /// event to event (frame arrivals and the ends' own deadlines). Returns the outcomes.
    fn run(&mut self, limit: Duration) -> Vec<TransferOutcome> {
        let mut outcomes = Vec::new();
        loop {
            self.step();
            outcomes.extend(std::iter::from_fn(|| self.client.pop_outcome()));
            if self.client.is_idle() && self.in_flight.is_empty() {
                return outcomes;
            }
            let next = [
                self.in_flight.iter().map(|(at, _, _)| *at).min(),
                self.client.next_deadline(),
                self.server.next_deadline(),
            ]
            .into_iter()
            .flatten()
            .min()
            .unwrap_or_else(|| {
                panic!("stalled at {:?} with {} pending", self.now - self.t0, self.client.pending())
            });
            self.now = next.max(self.now);
            assert!(self.now - self.t0 <= limit, "not done after {limit:?}: {:?}", self.log.last());
        }
    }

    /// Data frames sent in `dir` that go back in the numbering (first transmissions count up
    /// by one): how often a history was sent again.
    fn retransmissions(&self, dir: Dir) -> usize {
        let seqs: Vec<u8> = self
            .log
            .iter()
            .filter(|(_, d, f)| {
                *d == dir && f.command.as_ref().is_some_and(|c| c.command_id != SdoCommandId::Nil)
            })
            .map(|(_, _, f)| f.send_sequence)
            .collect();
        seqs.windows(2).filter(|w| w[1] != (w[0] + 1) % 64).count()
    }

    fn data_frames(&self, dir: Dir) -> Vec<&SdoCommand> {
        self.log
            .iter()
            .filter(|(_, d, _)| *d == dir)
            .filter_map(|(_, _, f)| f.command.as_ref())
            .filter(|c| c.command_id != SdoCommandId::Nil || c.abort || c.response)
            .collect()
    }
}

fn pattern(len: usize, seed: u8) -> Vec<u8> {
    (0..len).map(|i| (i as u8).wrapping_mul(31).wrapping_add(seed)).collect()
}

fn ok(outcome: &TransferOutcome) -> &[u8] {
    outcome.result.as_deref().unwrap_or_else(|e| panic!("{:04X}/{}: {e}", outcome.index, outcome.subindex))
}

fn err(outcome: &TransferOutcome) -> SdoError {
    outcome.result.clone().expect_err("transfer should fail")
}

fn small_segments() -> SdoConfig {
    SdoConfig { max_segment_size: 64, ..SdoConfig::default() }
}

// ---------------------------------------------------------------------------------------------
// Transfers on a clean link.

#[test]
fn expedited_and_segmented_transfers_of_several_kilobytes() {
    for config in [SdoConfig::default(), small_segments()] {
        let mut sim = Sim::new(config.clone(), config.clone(), TestOd::demo());
        let big = pattern(5000, 3);
        let w1 = sim.client.write(0x1006, 0, 1000u32.to_le_bytes().to_vec()).unwrap();
        let w2 = sim.client.write(0x1F50, 1, big.clone()).unwrap();
        let r1 = sim.client.read(0x1F50, 1);
        let r2 = sim.client.read(0x2000, 0);
        let r3 = sim.client.read(0x1006, 0);
        let w3 = sim.client.write(0x1F50, 1, Vec::new()).unwrap();
        let r4 = sim.client.read(0x1F50, 1);
        let out = sim.run(Duration::from_secs(5));
        let ids: Vec<TransferId> = out.iter().map(|o| o.id).collect();
        assert_eq!(ids, [w1, w2, r1, r2, r3, w3, r4]);
        assert_eq!(out[0].kind, TransferKind::Write);
        assert_eq!(ok(&out[0]), b"");
        assert_eq!(ok(&out[1]), b"");
        assert_eq!(ok(&out[2]), big.as_slice());
        assert_eq!(ok(&out[3]), sim.od.objects[&(0x2000, 0)].value.as_slice());
        assert_eq!(ok(&out[4]), 1000u32.to_le_bytes());
        assert_eq!(ok(&out[5]), b"");
        assert_eq!(ok(&out[6]), b"");
        assert_eq!(sim.od.writes, [(0x1006, 0, 4), (0x1F50, 1, 5000), (0x1F50, 1, 0)]);
        // Nothing lost, so nothing sent again and no error response; no time-out elapsed.
        assert_eq!(sim.retransmissions(Dir::ToServer) + sim.retransmissions(Dir::ToClient), 0);
        assert!(sim.log.iter().all(|(_, _, f)| f.receive_con != 3));
        assert!(sim.now - sim.t0 < Duration::from_secs(1));
        assert_eq!((sim.client.state(), sim.server.state()), (LinkState::Connected, LinkState::Connected));
        assert!(!sim.server.transfer_in_progress());

        // The segmented write: initiate with the data size openPOWERLINK uses (value + 8), then
        // segments and a complete, every segment within the configured size.
        let segment = config.segment_size();
        let write: Vec<_> =
            sim.data_frames(Dir::ToServer).into_iter().filter(|c| c.transaction_id == 1).collect();
        assert_eq!(write[0].segmentation, 1);
        assert_eq!(write[0].data[..4], 5008u32.to_le_bytes());
        assert_eq!(write[0].data[4..8], [0x50, 0x1F, 1, 0]);
        assert!(write[1..write.len() - 1].iter().all(|c| c.segmentation == 2));
        assert_eq!(write.last().unwrap().segmentation, 3);
        assert!(write.iter().all(|c| c.data.len() <= segment && usize::from(c.segment_size) == c.data.len()));
        assert_eq!(write.len(), 1 + (5000 - (segment - 8)).div_ceil(segment));
        // The segmented read response: data size = value + 4.
        let read: Vec<_> =
            sim.data_frames(Dir::ToClient).into_iter().filter(|c| c.transaction_id == 3).collect();
        assert_eq!(read[0].segmentation, 1);
        assert_eq!(read[0].data[..4], 6004u32.to_le_bytes());
        assert_eq!(read.last().unwrap().segmentation, 3);
    }
}

#[test]
fn sequence_numbers_wrap_through_a_long_transfer() {
    // 20 kB in 64-byte segments: over 300 frames, the 6-bit numbers wrap five times.
    let config = SdoConfig { max_transfer_size: 32 * 1024, ..small_segments() };
    let mut sim = Sim::new(config.clone(), config, TestOd::demo());
    let big = pattern(20_000, 9);
    sim.client.write(0x1F50, 1, big.clone()).unwrap();
    sim.client.read(0x1F50, 1);
    let out = sim.run(Duration::from_secs(10));
    assert_eq!(ok(&out[1]), big.as_slice());
    assert!(sim.log.len() > 600, "{} frames", sim.log.len());
}

// ---------------------------------------------------------------------------------------------
// Lost and duplicated frames.

#[test]
fn lost_frames_are_sent_again() {
    let config = small_segments();
    let timeout = config.timeout;
    // Drop, towards the server: the InitReq, the 3rd and 9th segments of the write (tid 0);
    // towards the client: the Valid, the 2nd and 5th segments of the read response (tid 1),
    // the write response (tid 2) and one acknowledgement.
    let mut seen: BTreeMap<(bool, u8, u8), usize> = BTreeMap::new();
    let dropped = std::rc::Rc::new(std::cell::RefCell::new(Vec::new()));
    let log = dropped.clone();
    let mut sim = Sim::new(config.clone(), config, TestOd::demo()).faults(move |dir, n, f| {
        let to_server = dir == Dir::ToServer;
        let drop = match f.command.as_ref().filter(|c| c.command_id != SdoCommandId::Nil) {
            _ if n == usize::from(!to_server) => true, // InitReq, Valid
            None => !to_server && f.receive_con == 2 && n == 40,
            Some(c) => {
                let k = seen.entry((to_server, c.transaction_id, c.segmentation)).or_default();
                *k += 1;
                matches!(
                    (to_server, c.transaction_id, c.segmentation, *k),
                    (true, 0, 2, 3 | 9) | (false, 1, 2, 2 | 5) | (false, 2, 0, 1)
                )
            }
        };
        if drop {
            log.borrow_mut().push((dir, n));
            Fault::Drop
        } else {
            Fault::Deliver
        }
    });
    let big = pattern(3000, 1);
    sim.client.write(0x1F50, 1, big.clone()).unwrap();
    sim.client.read(0x2000, 0);
    sim.client.write(0x1006, 0, 20u32.to_le_bytes().to_vec()).unwrap();
    sim.client.read(0x1F50, 1);
    let out = sim.run(Duration::from_secs(120));
    assert_eq!(out.len(), 4);
    assert_eq!(ok(&out[0]), b"");
    assert_eq!(ok(&out[1]), sim.od.objects[&(0x2000, 0)].value.as_slice());
    assert_eq!(ok(&out[2]), b"");
    assert_eq!(ok(&out[3]), big.as_slice());
    // Each write reached the dictionary once.
    assert_eq!(sim.od.writes, [(0x1F50, 1, 3000), (0x1006, 0, 4)]);
    assert_eq!(dropped.borrow().len(), 8, "{:?}", dropped.borrow());
    // Recovery took retransmissions, some after a time-out (5 s), not a lucky ordering.
    assert!(sim.retransmissions(Dir::ToServer) > 0 && sim.retransmissions(Dir::ToClient) > 0);
    assert!(sim.now - sim.t0 >= timeout, "{:?}", sim.now - sim.t0);
}

#[test]
fn a_lost_response_is_recovered_by_the_servers_retransmission() {
    // The server's only response is lost: the server sends it again after its time-out with
    // an acknowledge request, as the openPOWERLINK CN does (capture frames 1409 -> 1782).
    let config = SdoConfig::default();
    let mut sim = Sim::new(config.clone(), config.clone(), TestOd::demo()).faults(|dir, _, f| {
        let response = f.command.as_ref().is_some_and(|c| c.response && c.transaction_id == 0);
        if dir == Dir::ToClient && response && f.send_con != 3 {
            Fault::Drop
        } else {
            Fault::Deliver
        }
    });
    sim.client.read(0x1006, 0);
    let out = sim.run(Duration::from_secs(60));
    assert_eq!(ok(&out[0]), 50_000u32.to_le_bytes());
    let again = sim.log.iter().find(|(_, d, f)| *d == Dir::ToClient && f.send_con == 3).unwrap();
    assert!(
        again.0 >= config.timeout && again.0 < config.timeout + Duration::from_millis(10),
        "{:?}",
        again.0
    );
}

#[test]
fn duplicated_frames_are_delivered_once() {
    // Every frame in both directions arrives twice.
    let config = small_segments();
    let mut sim = Sim::new(config.clone(), config, TestOd::demo()).faults(|_, _, _| Fault::Duplicate);
    let big = pattern(2000, 5);
    sim.client.write(0x1006, 0, 7u32.to_le_bytes().to_vec()).unwrap();
    sim.client.write(0x1F50, 1, big.clone()).unwrap();
    sim.client.read(0x1F50, 1);
    let out = sim.run(Duration::from_secs(30));
    assert_eq!(ok(&out[0]), b"");
    assert_eq!(ok(&out[1]), b"");
    assert_eq!(ok(&out[2]), big.as_slice());
    assert_eq!(sim.od.writes, [(0x1006, 0, 4), (0x1F50, 1, 2000)]);
    // Duplicates are dropped, not answered with error responses.
    assert!(sim.log.iter().all(|(_, _, f)| f.receive_con != 3));
}

// ---------------------------------------------------------------------------------------------
// Time-outs.

#[test]
fn a_silent_server_times_every_queued_transfer_out() {
    let config = SdoConfig::default();
    let mut sim = Sim::new(config.clone(), config.clone(), TestOd::demo()).faults(|dir, _, _| {
        if dir == Dir::ToServer {
            Fault::Drop
        } else {
            Fault::Deliver
        }
    });
    sim.client.read(0x1006, 0);
    sim.client.write(0x1006, 0, vec![0; 4]).unwrap();
    let out = sim.run(Duration::from_secs(60));
    assert_eq!(out.iter().map(err).collect::<Vec<_>>(), [SdoError::Timeout, SdoError::Timeout]);
    // InitReq, two retries 5 s apart, then the close at 15 s.
    let sent: Vec<_> = sim.log.iter().map(|(t, _, f)| (t.as_secs(), f.receive_con, f.send_con)).collect();
    assert_eq!(sent, [(0, 0, 1), (5, 0, 1), (10, 0, 1), (15, 0, 0)]);
    assert_eq!(sim.client.state(), LinkState::Closed);
}

#[test]
fn a_link_lost_mid_transfer_times_out_on_both_ends() {
    let config = small_segments();
    let cut = std::rc::Rc::new(std::cell::Cell::new(false));
    let cut2 = cut.clone();
    let mut sim = Sim::new(config.clone(), config.clone(), TestOd::demo()).faults(move |dir, n, _| {
        // The link dies after the 10th frame towards the server, in both directions.
        if dir == Dir::ToServer && n >= 10 {
            cut2.set(true);
        }
        if cut2.get() {
            Fault::Drop
        } else {
            Fault::Deliver
        }
    });
    sim.client.write(0x1F50, 1, pattern(3000, 0)).unwrap();
    let out = sim.run(Duration::from_secs(60));
    assert!(cut.get());
    assert_eq!(err(&out[0]), SdoError::Timeout);
    assert!(sim.od.writes.is_empty());
    // The server gave up on the stalled segmented write with a time-out abort (lost too).
    let end = sim.now + config.transfer_timeout;
    while sim.now < end {
        sim.now += Duration::from_millis(100);
        sim.step();
    }
    let aborts: Vec<_> = sim
        .log
        .iter()
        .filter(|(_, d, f)| *d == Dir::ToClient && f.command.as_ref().is_some_and(|c| c.abort))
        .collect();
    let (at, _, first) = aborts[0];
    assert_eq!(first.command.as_ref().unwrap().abort_code(), Some(SdoAbortCode::Timeout.raw()));
    assert!(
        *at >= config.transfer_timeout && *at < config.transfer_timeout + Duration::from_millis(20),
        "{at:?}"
    );
    // Unacknowledged, the abort is sent again like any frame, then the connection closes.
    assert!(aborts[1..].iter().all(|(_, _, f)| f.send_con == 3 && f.send_sequence == first.send_sequence));
    assert!(!sim.server.transfer_in_progress());
}

// ---------------------------------------------------------------------------------------------
// Abort paths between the two engines.

#[test]
fn dictionary_aborts_reach_the_client_with_their_code() {
    let config = SdoConfig::default();
    let mut sim = Sim::new(config.clone(), config, TestOd::demo());
    sim.client.read(0x1011, 1); // no such object
    sim.client.read(0x1006, 9); // no such subindex
    sim.client.write(0x1000, 0, vec![0; 4]).unwrap(); // read-only
    sim.client.write(0x1006, 0, vec![0; 2]).unwrap(); // wrong length
    sim.client.read(0x2001, 0); // write-only
    sim.client.write(0x1011, 1, pattern(4000, 0)).unwrap(); // segmented, no such object
    sim.client.read(0x1006, 0); // and the connection still works
    let out = sim.run(Duration::from_secs(5));
    let codes: Vec<_> = out[..6]
        .iter()
        .map(|o| match err(o) {
            SdoError::Aborted { code } => code,
            other => panic!("{other:?}"),
        })
        .collect();
    use SdoAbortCode::*;
    assert_eq!(
        codes,
        [
            ObjectDoesNotExist,
            SubIndexDoesNotExist,
            ReadOnly,
            TypeLengthMismatch,
            WriteOnly,
            ObjectDoesNotExist
        ]
    );
    assert_eq!(ok(&out[6]), 50_000u32.to_le_bytes());
    assert!(sim.od.writes.is_empty());
}

#[test]
fn oversize_transfers_are_refused_before_they_are_buffered() {
    // The client's limit: a write is refused at once, a read response after its initiate.
    let client = SdoConfig { max_transfer_size: 1000, ..SdoConfig::default() };
    let mut sim = Sim::new(client, SdoConfig::default(), TestOd::demo());
    assert_eq!(sim.client.write(0x1F50, 1, vec![0; 1001]), Err(SdoError::TooLarge { len: 1001, max: 1000 }));
    sim.client.read(0x2000, 0); // 6000 bytes
    sim.client.read(0x1006, 0);
    let out = sim.run(Duration::from_secs(5));
    assert_eq!(err(&out[0]), SdoError::ClientAbort { code: SdoAbortCode::OutOfMemory });
    assert_eq!(ok(&out[1]), 50_000u32.to_le_bytes());
    let client_aborts: Vec<_> = sim.data_frames(Dir::ToServer).into_iter().filter(|c| c.abort).collect();
    assert_eq!(client_aborts.len(), 1);
    assert!(!client_aborts[0].response);
    assert_eq!(client_aborts[0].abort_code(), Some(SdoAbortCode::OutOfMemory.raw()));
    assert!(!sim.server.transfer_in_progress(), "the server dropped its read response");

    // The server's limit: a segmented write is aborted at its initiate (the segments already
    // in flight are dropped quietly), a large read is refused.
    let server = SdoConfig { max_transfer_size: 2000, ..SdoConfig::default() };
    let mut sim = Sim::new(small_segments(), server, TestOd::demo());
    sim.client.write(0x1F50, 1, pattern(5000, 0)).unwrap();
    sim.client.read(0x2000, 0);
    sim.client.write(0x1F50, 1, pattern(1500, 0)).unwrap();
    let out = sim.run(Duration::from_secs(5));
    assert_eq!(err(&out[0]), SdoError::Aborted { code: SdoAbortCode::OutOfMemory });
    assert_eq!(err(&out[1]), SdoError::Aborted { code: SdoAbortCode::OutOfMemory });
    assert_eq!(ok(&out[2]), b"");
    assert_eq!(sim.od.writes, [(0x1F50, 1, 1500)]);
    let server_aborts: Vec<_> = sim.data_frames(Dir::ToClient).into_iter().filter(|c| c.abort).collect();
    assert_eq!(server_aborts.len(), 2, "{server_aborts:?}");
}

// ---------------------------------------------------------------------------------------------
// Scripted peers: a bare sequence layer on the other end.

/// Sends what `peer` has queued to `server` until both are quiet; returns the server's
/// command-layer answers as `peer` received them.
fn exchange_with_server(
    peer: &mut SequenceLayer,
    server: &mut SdoServer,
    od: &mut TestOd,
    t: Instant,
) -> Vec<SdoCommand> {
    let mut answers = Vec::new();
    for _ in 0..100 {
        let Some(frame) = peer.poll_transmit() else { return answers };
        for answer in server.on_frame(t, &wire(&frame, 240, 1), od) {
            if let SeqEvent::Command(c) = peer.on_frame(t, &wire(&answer, 1, 240)) {
                answers.push(c);
            }
            peer.flush_ack();
        }
    }
    panic!("endless exchange");
}

fn connected_client_peer(server: &mut SdoServer, od: &mut TestOd, t: Instant) -> SequenceLayer {
    let mut peer = SequenceLayer::new(Role::Client, SdoConfig::default());
    peer.open(t);
    assert!(exchange_with_server(&mut peer, server, od, t).is_empty());
    assert_eq!((peer.state(), server.state()), (LinkState::Connected, LinkState::Connected));
    peer
}

fn cmd(tid: u8, segmentation: u8, id: SdoCommandId, data: Vec<u8>) -> SdoCommand {
    SdoCommand {
        transaction_id: tid,
        response: false,
        abort: false,
        segmentation,
        pad_size: 0,
        command_id: id,
        segment_size: data.len() as u16,
        data,
        flags_reserved: 0,
        reserved1: 0,
        reserved2: 0,
    }
}

fn abort_of(answer: &SdoCommand) -> (u8, SdoCommandId, SdoAbortCode) {
    assert!(answer.response && answer.abort, "{answer:?}");
    (answer.transaction_id, answer.command_id, SdoAbortCode::from_raw(answer.abort_code().unwrap()))
}

#[test]
fn server_protocol_aborts() {
    let t = Instant::now();
    let mut od = TestOd::demo();
    let mut server = SdoServer::default();
    let mut peer = connected_client_peer(&mut server, &mut od, t);
    let mut ask = |peer: &mut SequenceLayer, server: &mut SdoServer, c: SdoCommand| {
        peer.send(t, c).unwrap();
        exchange_with_server(peer, server, &mut od, t)
    };
    use SdoAbortCode::*;
    use SdoCommandId::*;
    // Commands this server does not serve.
    for (tid, id) in
        [WriteByName, ReadAllByIndex, WriteMultipleParamByIndex, ReadMultipleParamByIndex, FileRead]
            .into_iter()
            .chain([SdoCommandId::from_raw(0x99)])
            .enumerate()
    {
        let answers = ask(&mut peer, &mut server, cmd(tid as u8, 0, id, vec![0x06, 0x10, 0, 0, 1, 2, 3, 4]));
        assert_eq!(
            answers.iter().map(abort_of).collect::<Vec<_>>(),
            [(tid as u8, id, InvalidCommandSpecifier)]
        );
    }
    // Malformed requests: no room for the index header or the data size.
    for (c, id) in [
        (cmd(20, 0, WriteByIndex, vec![0x06, 0x10]), WriteByIndex),
        (cmd(21, 0, ReadByIndex, vec![0x06, 0x10, 0]), ReadByIndex),
        (cmd(22, 1, WriteByIndex, vec![0, 0, 0, 0, 0x06]), WriteByIndex),
        (cmd(23, 1, ReadByIndex, vec![12, 0, 0, 0, 0x06, 0x10, 0, 0]), ReadByIndex),
    ] {
        let tid = c.transaction_id;
        assert_eq!(
            ask(&mut peer, &mut server, c).iter().map(abort_of).collect::<Vec<_>>(),
            [(tid, id, InvalidCommandSpecifier)]
        );
    }
    // A segment without its initiate.
    let answers = ask(&mut peer, &mut server, cmd(30, 2, WriteByIndex, vec![1, 2, 3]));
    assert_eq!(answers.iter().map(abort_of).collect::<Vec<_>>(), [(30, WriteByIndex, InvalidSequenceNumber)]);
    let answers = ask(&mut peer, &mut server, cmd(31, 3, WriteByIndex, vec![1, 2, 3]));
    assert_eq!(answers.iter().map(abort_of).collect::<Vec<_>>(), [(31, WriteByIndex, InvalidSequenceNumber)]);
    // Fewer bytes than announced: 18 announced (8 of headers + 10), 6 + 2 sent.
    let initiate = |tid: u8, announced: u32| {
        let mut data = announced.to_le_bytes().to_vec();
        data.extend_from_slice(&[0x50, 0x1F, 1, 0, 1, 2, 3, 4, 5, 6]);
        cmd(tid, 1, WriteByIndex, data)
    };
    assert!(ask(&mut peer, &mut server, initiate(40, 18)).is_empty());
    assert!(server.transfer_in_progress());
    let answers = ask(&mut peer, &mut server, cmd(40, 3, WriteByIndex, vec![7, 8]));
    assert_eq!(answers.iter().map(abort_of).collect::<Vec<_>>(), [(40, WriteByIndex, TypeLengthTooLow)]);
    // More bytes than announced.
    assert!(ask(&mut peer, &mut server, initiate(41, 18)).is_empty());
    let answers = ask(&mut peer, &mut server, cmd(41, 2, WriteByIndex, vec![0; 20]));
    assert_eq!(answers.iter().map(abort_of).collect::<Vec<_>>(), [(41, WriteByIndex, TypeLengthTooHigh)]);
    // ...and the rest of that transfer is dropped without a second abort.
    assert!(ask(&mut peer, &mut server, cmd(41, 3, WriteByIndex, vec![0; 2])).is_empty());
    // An announced size beyond the limit.
    let answers = ask(&mut peer, &mut server, initiate(42, u32::MAX));
    assert_eq!(answers.iter().map(abort_of).collect::<Vec<_>>(), [(42, WriteByIndex, OutOfMemory)]);
    // The client's abort ends the transfer without an answer.
    assert!(ask(&mut peer, &mut server, initiate(43, 18)).is_empty());
    let mut client_abort = cmd(43, 0, WriteByIndex, Timeout.raw().to_le_bytes().to_vec());
    client_abort.abort = true;
    assert!(ask(&mut peer, &mut server, client_abort).is_empty());
    assert!(!server.transfer_in_progress());
    // A segmented write the client stops sending: aborted after the transfer time-out.
    assert!(ask(&mut peer, &mut server, initiate(44, 18)).is_empty());
    let timeout = SdoConfig::default().transfer_timeout;
    assert_eq!(server.next_deadline(), Some(t + timeout));
    assert_eq!(server.poll(t + timeout - Duration::from_millis(1)), None);
    let abort = server.poll(t + timeout).unwrap();
    assert_eq!(server.poll(t + timeout), None);
    assert_eq!(abort_of(abort.command.as_ref().unwrap()), (44, WriteByIndex, Timeout));
    assert!(!server.transfer_in_progress());
    // Through all this, nothing reached the dictionary, and it still answers.
    assert!(od.writes.is_empty());
    peer.on_frame(t + timeout, &abort);
    peer.flush_ack();
    let answers = {
        peer.send(t + timeout, cmd(50, 0, ReadByIndex, vec![0x06, 0x10, 0, 0])).unwrap();
        exchange_with_server(&mut peer, &mut server, &mut od, t + timeout)
    };
    assert_eq!(answers.len(), 1);
    assert_eq!((answers[0].transaction_id, answers[0].data.clone()), (50, 50_000u32.to_le_bytes().to_vec()));
}

/// Runs the client against a scripted server: `script` gets each command-layer request and
/// returns the server's answers.
struct ScriptedServer {
    seq: SequenceLayer,
    /// The client's frames as the server received them.
    received: Vec<SdoFrame>,
}

impl ScriptedServer {
    fn new() -> Self {
        Self { seq: SequenceLayer::new(Role::Server, SdoConfig::default()), received: Vec::new() }
    }

    /// Moves frames both ways until quiet; `answer` maps each request to the server's answers.
    fn exchange(
        &mut self,
        client: &mut SdoClient,
        t: Instant,
        answer: &mut dyn FnMut(&SdoCommand) -> Vec<SdoCommand>,
    ) {
        let mut to_server: VecDeque<SdoFrame> = std::iter::from_fn(|| client.poll(t)).collect();
        for _ in 0..1000 {
            let Some(frame) = to_server.pop_front() else { return };
            let frame = wire(&frame, 240, 1);
            self.received.push(frame.clone());
            if let SeqEvent::Command(c) = self.seq.on_frame(t, &frame) {
                for a in answer(&c) {
                    self.seq.send(t, a).unwrap();
                }
            }
            self.seq.flush_ack();
            while let Some(reply) = self.seq.poll_transmit() {
                to_server.extend(client.on_frame(t, &wire(&reply, 1, 240)));
            }
            to_server.extend(std::iter::from_fn(|| client.poll(t)));
        }
        panic!("endless exchange");
    }

    fn client_aborts(&self) -> Vec<(u8, SdoAbortCode)> {
        self.received
            .iter()
            .filter_map(|f| f.command.as_ref())
            .filter(|c| c.abort)
            .map(|c| {
                assert!(!c.response);
                (c.transaction_id, SdoAbortCode::from_raw(c.abort_code().unwrap()))
            })
            .collect()
    }
}

fn response(request: &SdoCommand, segmentation: u8, data: Vec<u8>) -> SdoCommand {
    SdoCommand { response: true, ..cmd(request.transaction_id, segmentation, request.command_id, data) }
}

#[test]
fn client_protocol_aborts() {
    use SdoAbortCode::*;
    let t = Instant::now();
    type Script = Box<dyn FnMut(&SdoCommand) -> Vec<SdoCommand>>;
    let cases: Vec<(&str, Script, SdoError)> = vec![
        (
            "complete short of the announced size",
            Box::new(|r| {
                vec![response(r, 1, [14, 0, 0, 0, 1, 2, 3, 4, 5, 6].to_vec()), response(r, 3, vec![7, 8])]
            }),
            SdoError::ClientAbort { code: TypeLengthTooLow },
        ),
        (
            "segment beyond the announced size",
            Box::new(|r| {
                vec![response(r, 1, [6, 0, 0, 0, 1, 2].to_vec()), response(r, 2, vec![3, 4, 5, 6, 7])]
            }),
            SdoError::ClientAbort { code: TypeLengthTooHigh },
        ),
        (
            "segment without initiate",
            Box::new(|r| vec![response(r, 2, vec![1, 2, 3])]),
            SdoError::ClientAbort { code: InvalidSequenceNumber },
        ),
        (
            "initiate without its data size",
            Box::new(|r| vec![response(r, 1, vec![1, 2])]),
            SdoError::ClientAbort { code: GeneralError },
        ),
        (
            "wrong command",
            Box::new(|r| {
                vec![SdoCommand { command_id: SdoCommandId::WriteByIndex, ..response(r, 0, vec![1]) }]
            }),
            SdoError::ClientAbort { code: GeneralError },
        ),
        (
            "announced size beyond the limit",
            Box::new(|r| vec![response(r, 1, [0xFF, 0xFF, 0xFF, 0x7F, 1].to_vec())]),
            SdoError::ClientAbort { code: OutOfMemory },
        ),
        (
            "server abort",
            Box::new(|r| {
                vec![SdoCommand { abort: true, ..response(r, 0, HardwareError.raw().to_le_bytes().to_vec()) }]
            }),
            SdoError::Aborted { code: HardwareError },
        ),
        (
            "server abort without a code",
            Box::new(|r| vec![SdoCommand { abort: true, ..response(r, 0, vec![]) }]),
            SdoError::Aborted { code: GeneralError },
        ),
    ];
    for (what, mut script, expected) in cases {
        let mut client = SdoClient::default();
        let mut server = ScriptedServer::new();
        client.read(0x2000, 0);
        client.read(0x1006, 0);
        server.exchange(&mut client, t, &mut |r| {
            if r.data[..2] == [0x06, 0x10] {
                vec![response(r, 0, vec![1, 2, 3, 4])]
            } else {
                script(r)
            }
        });
        let first = client.pop_outcome().unwrap_or_else(|| panic!("{what}: no outcome"));
        assert_eq!(first.result, Err(expected.clone()), "{what}");
        assert_eq!(client.pop_outcome().unwrap().result, Ok(vec![1, 2, 3, 4]), "{what}: the next transfer");
        let sent = server.client_aborts();
        match expected {
            SdoError::ClientAbort { code } => assert_eq!(sent, [(0, code)], "{what}"),
            _ => assert!(sent.is_empty(), "{what}"),
        }
    }
}

#[test]
fn client_transfer_time_out_and_closes() {
    let t = Instant::now();
    let config = SdoConfig::default();
    // The server acknowledges the request and never answers.
    let mut client = SdoClient::new(config.clone());
    let mut server = ScriptedServer::new();
    let id = client.read(0x2000, 0);
    server.exchange(&mut client, t, &mut |_| Vec::new());
    assert_eq!(client.pop_outcome(), None);
    let deadline = t + config.transfer_timeout;
    assert_eq!(client.next_deadline(), Some(deadline));
    assert_eq!(client.poll(deadline - Duration::from_millis(1)), None);
    let abort = client.poll(deadline).unwrap();
    let c = abort.command.unwrap();
    assert!(c.abort && !c.response);
    assert_eq!(c.abort_code(), Some(SdoAbortCode::Timeout.raw()));
    let outcome = client.pop_outcome().unwrap();
    assert_eq!(
        (outcome.id, outcome.kind, outcome.index, outcome.result),
        (id, TransferKind::Read, 0x2000, Err(SdoError::Timeout))
    );

    // The server closes the connection during a transfer; the next one opens it again.
    let mut client = SdoClient::new(config.clone());
    let mut server = ScriptedServer::new();
    client.read(0x2000, 0);
    client.read(0x1006, 0);
    server.exchange(&mut client, t, &mut |_| Vec::new());
    server.seq.close();
    let close = server.seq.poll_transmit().unwrap();
    let sent = client.on_frame(t, &wire(&close, 1, 240));
    assert_eq!(client.pop_outcome().unwrap().result, Err(SdoError::ConnectionClosed));
    assert_eq!(
        sent.iter().map(|f| (f.receive_con, f.send_con)).collect::<Vec<_>>(),
        [(0, 1)],
        "InitReq again"
    );

    // close(): everything queued is cancelled, and a close frame goes out.
    client.read(0x1000, 0);
    client.close();
    let out: Vec<_> = std::iter::from_fn(|| client.pop_outcome()).map(|o| o.result).collect();
    assert_eq!(out, [Err(SdoError::Cancelled), Err(SdoError::Cancelled)]);
    let frames: Vec<_> = std::iter::from_fn(|| client.poll(t)).collect();
    assert_eq!(frames.last().map(|f| (f.receive_con, f.send_con)), Some((0, 0)));
    assert!(client.is_idle());
    assert_eq!(client.state(), LinkState::Closed);
}

// ---------------------------------------------------------------------------------------------
// Any input: no panic, and everything sent encodes.

fn arb_command() -> impl Strategy<Value = Option<SdoCommand>> {
    prop::option::of(
        (
            any::<u8>(),
            any::<bool>(),
            any::<bool>(),
            0u8..4,
            prop_oneof![Just(1u8), Just(2u8), any::<u8>()],
            prop::collection::vec(any::<u8>(), 0..40),
        )
            .prop_map(|(tid, response, abort, segmentation, id, data)| SdoCommand {
                transaction_id: tid % 4,
                response,
                abort,
                segmentation,
                pad_size: 0,
                command_id: SdoCommandId::from_raw(id),
                segment_size: data.len() as u16,
                data,
                flags_reserved: 0,
                reserved1: 0,
                reserved2: 0,
            }),
    )
}

fn arb_frame() -> impl Strategy<Value = (u64, SdoFrame)> {
    (0u64..8000, 0u8..6, 0u8..4, 0u8..6, 0u8..4, arb_command()).prop_map(
        |(gap_ms, rs, rc, ss, sc, command)| {
            (
                gap_ms,
                SdoFrame {
                    receive_sequence: rs,
                    receive_con: rc,
                    send_sequence: ss,
                    send_con: sc,
                    command,
                    reserved: 0,
                },
            )
        },
    )
}

fn encodes(frame: &SdoFrame) {
    let epl = EplFrame::new(
        MacAddr([2, 0, 0, 0, 0, 1]),
        MacAddr::ASND,
        240,
        1,
        Message::Asnd(Asnd::Sdo(frame.clone())),
    );
    epl.encode().unwrap_or_else(|e| panic!("{e}: {frame:?}"));
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]
    #[test]
    fn random_frames_never_panic(frames in prop::collection::vec(arb_frame(), 1..60)) {
        let config = SdoConfig { max_transfer_size: 100, max_segment_size: 16, ..SdoConfig::default() };
        let mut server = SdoServer::new(config.clone());
        let mut client = SdoClient::new(config);
        let mut od = TestOd::demo();
        client.read(0x2000, 0);
        client.write(0x1F50, 1, vec![1; 60]).unwrap();
        let mut now = Instant::now();
        for (gap, frame) in &frames {
            now += Duration::from_millis(*gap);
            for f in server.on_frame(now, frame, &mut od) { encodes(&f); }
            for f in client.on_frame(now, frame) { encodes(&f); }
            while let Some(f) = server.poll(now) { encodes(&f); }
            while let Some(f) = client.poll(now) { encodes(&f); }
        }
        prop_assert!(od.objects.values().all(|o| o.value.len() <= 6000));
    }
}
