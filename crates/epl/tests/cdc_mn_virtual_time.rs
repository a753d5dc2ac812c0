//! The CDC-driven Managing Node (`motus_epl::node::mn`) against openPOWERLINK's CN as captured
//! in `shared/fixtures/powerlink/oplk_mn_cn_veth_merged.pcapng`, on virtual time.
//!
//! The CN's frames are the captured ones (frame numbers below), with its NMT state, its
//! process data and its VerifyConfiguration date and time filled in as the CN's state moves
//! (what openPOWERLINK's CN does: the captured frames 866 and 1451 differ only there). Its
//! SDO side is the production SDO server (`SdoServer`) over an object store that records
//! every write. The MN is driven directly (its sans-IO API) and through its runtime on an
//! in-memory segment with a threaded virtual clock.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use motus_clock::{Clock, VirtualClock};
use motus_epl::node::mn::runtime::{self, RuntimeConfig};
use motus_epl::node::mn::{BootPhase, CdcMn, EventKind, MnConfig, MnEvent};
use motus_epl::transport::MemHub;
use motus_epl::EthLink;
use motus_epl_protocol::cdc::{encode_block, CdcEntry};
use motus_epl_protocol::{
    Asnd, Cdc, EplFrame, Flags, Message, NmtCommandId, NmtState, ObjectAccess, RequestedService,
    SdoAbortCode, SdoConfig, SdoServer,
};

/// Frame 866: the CN's IdentResponse (NMT_CS_PRE_OPERATIONAL_1, 176 bytes).
const IDENT_RESPONSE_866: &str = "01111e0000046a503919f39d88ab06ff010100001d00200065020100dc052400240050c30000000091010f00000000000000000007000200000000000000000000000000000000000000000000000000000000000164a8c000fffffffe64a8c030312d6666666666666666000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000";
/// Frame 882: the CN's StatusResponse to the first StatusRequest (ER): EC set, PRE_OPERATIONAL_2.
const STATUS_RESPONSE_882: &str = "01111e0000046a503919f39d88ab06ff010208195d000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000";
/// Frame 1456: the CN's PRes in PRE_OPERATIONAL_2 with its one mapped byte (0x6000/1).
const PRES_1456: &str = "01111e0000026a503919f39d88ab04ff015d000000000100010000000000000000000000000000000000000000000000000000000000000000000000";

fn hex(s: &str) -> Vec<u8> {
    (0..s.len()).step_by(2).map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap()).collect()
}

fn captured(s: &str) -> EplFrame {
    EplFrame::decode(&hex(s)).unwrap()
}

fn oracle_dir() -> std::path::PathBuf {
    std::env::var_os("MOTUS_OPLK_DIR").map(Into::into).unwrap_or_else(|| {
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/oracles/openpowerlink")
    })
}

fn demo_cdc() -> Option<Cdc> {
    let path = oracle_dir().join("cdc/demo_3cn_1ms.cdc");
    match std::fs::read(&path) {
        Ok(bytes) => Some(Cdc::parse(&bytes).unwrap()),
        Err(e) => {
            eprintln!("skipped: {}: {e}", path.display());
            None
        }
    }
}

/// Objects the CN holds: every write is kept (in order) and readable.
#[derive(Debug, Default)]
struct Store {
    values: BTreeMap<(u16, u8), Vec<u8>>,
    writes: Vec<(u16, u8, Vec<u8>)>,
}

impl ObjectAccess for Store {
    fn read(&mut self, index: u16, subindex: u8) -> Result<Vec<u8>, SdoAbortCode> {
        self.values.get(&(index, subindex)).cloned().ok_or(SdoAbortCode::ObjectDoesNotExist)
    }

    fn write(&mut self, index: u16, subindex: u8, value: &[u8]) -> Result<(), SdoAbortCode> {
        self.values.insert((index, subindex), value.to_vec());
        self.writes.push((index, subindex, value.to_vec()));
        Ok(())
    }
}

/// openPOWERLINK's CN 1 as captured: answers with the captured frames.
struct CapturedCn {
    state: NmtState,
    /// Answers PReq/SoA at all (false: the process is gone).
    alive: bool,
    store: Store,
    sdo: SdoServer,
    sdo_out: Vec<motus_epl_protocol::SdoFrame>,
    /// Error signalling initialised (EC in StatusResponse).
    ec: bool,
    /// The digital inputs (0x6000/1) sent in PRes.
    inputs: u8,
    /// The outputs (0x6200/1) received in PReq with RD.
    outputs: Vec<u8>,
    /// The configuration (0x1020/1, /2) in force since the last reset of the configuration.
    conf: (u32, u32),
    commands: Vec<NmtCommandId>,
    /// EN in the PRes and StatusResponse (new errors to report).
    en: bool,
    /// EA of the last PReq.
    ea: bool,
    status_requests: u32,
}

impl CapturedCn {
    fn new() -> Self {
        Self {
            state: NmtState::PreOperational1,
            alive: true,
            store: Store::default(),
            sdo: SdoServer::new(SdoConfig::default()),
            sdo_out: Vec::new(),
            ec: false,
            inputs: 0x5A,
            outputs: Vec::new(),
            conf: (0, 0),
            commands: Vec::new(),
            en: false,
            ea: false,
            status_requests: 0,
        }
    }

    /// A process restart: configuration lost.
    fn restart(&mut self) {
        let inputs = self.inputs;
        *self = Self::new();
        self.inputs = inputs;
    }

    fn u32_of(&self, index: u16, sub: u8) -> u32 {
        self.store
            .values
            .get(&(index, sub))
            .and_then(|v| v.as_slice().try_into().ok())
            .map_or(0, u32::from_le_bytes)
    }

    fn frame_from(&self, template: &str, edit: impl FnOnce(&mut Message)) -> EplFrame {
        let mut f = captured(template);
        edit(&mut f.message);
        f
    }

    /// The CN's answers to one frame of the MN.
    fn on_frame(&mut self, now: Instant, f: &EplFrame) -> Vec<EplFrame> {
        if !self.alive {
            return Vec::new();
        }
        match &f.message {
            Message::Soc(_) if self.state == NmtState::PreOperational1 => {
                self.state = NmtState::PreOperational2;
                Vec::new()
            }
            Message::PReq(p) if f.dst_node == 1 && self.state != NmtState::PreOperational1 => {
                self.ea = p.flags.contains(Flags::EA);
                if p.flags.contains(Flags::RD) && self.state == NmtState::Operational {
                    self.outputs.push(p.payload.first().copied().unwrap_or(0));
                }
                let (state, inputs, rs, en) =
                    (self.state, self.inputs, u8::from(!self.sdo_out.is_empty()), self.en);
                vec![self.frame_from(PRES_1456, |m| {
                    let Message::PRes(r) = m else { unreachable!() };
                    r.nmt_state = state;
                    r.flags = if state == NmtState::Operational { Flags::RD } else { Flags::empty() };
                    r.flags.set(Flags::EN, en);
                    r.payload = vec![inputs];
                    r.pr_rs.rs = rs;
                })]
            }
            Message::Soa(soa) if soa.target == 1 => match soa.requested_service {
                RequestedService::IdentRequest => {
                    let (state, conf) = (self.state, self.conf);
                    vec![self.frame_from(IDENT_RESPONSE_866, |m| {
                        let Message::Asnd(Asnd::IdentResponse(r)) = m else { unreachable!() };
                        r.nmt_state = state;
                        (r.verify_conf_date, r.verify_conf_time) = conf;
                    })]
                }
                RequestedService::StatusRequest => {
                    if soa.flags.contains(Flags::ER) {
                        self.ec = true;
                    }
                    self.status_requests += 1;
                    let (state, ec, rs, en) =
                        (self.state, self.ec, u8::from(!self.sdo_out.is_empty()), self.en);
                    vec![self.frame_from(STATUS_RESPONSE_882, |m| {
                        let Message::Asnd(Asnd::StatusResponse(r)) = m else { unreachable!() };
                        r.nmt_state = state;
                        r.flags = if ec { Flags::EC } else { Flags::empty() };
                        r.flags.set(Flags::EN, en);
                        r.pr_rs.rs = rs;
                    })]
                }
                RequestedService::UnspecifiedInvite => {
                    while let Some(x) = self.sdo.poll(now) {
                        self.sdo_out.push(x);
                    }
                    if self.sdo_out.is_empty() {
                        return Vec::new();
                    }
                    let sdo = self.sdo_out.remove(0);
                    let mut frame = captured(IDENT_RESPONSE_866);
                    frame.dst_node = 240;
                    frame.message = Message::Asnd(Asnd::Sdo(sdo));
                    frame.padding = motus_epl_protocol::Padding::Auto;
                    vec![frame]
                }
                _ => Vec::new(),
            },
            Message::Asnd(Asnd::Sdo(sdo)) if f.dst_node == 1 => {
                let answers = self.sdo.on_frame(now, sdo, &mut self.store);
                self.sdo_out.extend(answers);
                Vec::new()
            }
            Message::Asnd(Asnd::NmtCommand(c)) if f.dst_node == 1 || f.dst_node == 255 => {
                self.commands.push(c.command);
                match c.command {
                    NmtCommandId::ResetNode | NmtCommandId::ResetCommunication => {
                        self.state = NmtState::PreOperational1;
                        self.ec = false;
                    }
                    NmtCommandId::ResetConfiguration => {
                        self.state = NmtState::PreOperational1;
                        self.ec = false;
                        self.conf = (self.u32_of(0x1020, 1), self.u32_of(0x1020, 2));
                        self.sdo.reset();
                    }
                    NmtCommandId::EnableReadyToOperate if self.state == NmtState::PreOperational2 => {
                        self.state = NmtState::ReadyToOperate;
                    }
                    NmtCommandId::StartNode if self.state == NmtState::ReadyToOperate => {
                        self.state = NmtState::Operational;
                    }
                    _ => {}
                }
                Vec::new()
            }
            _ => Vec::new(),
        }
    }
}

/// Runs the MN's cycles directly (its sans-IO API) against the captured CN, on virtual time:
/// the CN answers at once, every PReq and invitation is answered within the cycle.
struct Bench {
    mn: CdcMn,
    cn: CapturedCn,
    now: Instant,
    events: Vec<MnEvent>,
}

impl Bench {
    fn new(cdc: &Cdc, config: MnConfig) -> Self {
        Self {
            mn: CdcMn::new(cdc, config).unwrap(),
            cn: CapturedCn::new(),
            now: Instant::now(),
            events: Vec::new(),
        }
    }

    fn deliver(&mut self, frames: Vec<EplFrame>, expect_pres: Option<u8>) -> bool {
        let mut answered = false;
        for f in frames {
            // Every frame crosses the wire: encoded and decoded.
            let f = EplFrame::decode(&f.encode().unwrap()).unwrap();
            for a in self.cn.on_frame(self.now, &f) {
                let a = EplFrame::decode(&a.encode().unwrap()).unwrap();
                answered |= self.mn.on_frame(self.now, &a, expect_pres);
            }
        }
        answered
    }

    fn cycle(&mut self) {
        let start = self.now;
        if self.mn.start_cycle(start) {
            let soc = self.mn.soc(start);
            self.deliver(vec![soc], None);
            for node in self.mn.poll_list() {
                let preq = self.mn.preq(node).unwrap();
                if !self.deliver(vec![preq], Some(node)) {
                    self.mn.pres_missed(node);
                }
            }
        }
        let frames = self.mn.async_slot(self.now);
        self.deliver(frames, None);
        self.mn.end_cycle(self.now);
        while let Some(e) = self.mn.pop_event() {
            self.events.push(e);
        }
        self.now = start + self.mn.cycle();
    }

    /// Runs cycles until node 1 is `phase`, at most `max`; returns the cycles run.
    fn until(&mut self, phase: BootPhase, max: u32) -> u32 {
        for k in 0..max {
            if self.phase() == phase {
                return k;
            }
            self.cycle();
        }
        panic!("node 1 not {phase} after {max} cycles: {:?}\nevents: {:#?}", self.mn.nodes()[0], self.events);
    }

    fn phase(&self) -> BootPhase {
        self.mn.nodes().iter().find(|n| n.node == 1).unwrap().phase
    }

    fn node1(&self) -> motus_epl::node::mn::NodeReport {
        self.mn.nodes().into_iter().find(|n| n.node == 1).unwrap()
    }
}

#[test]
fn the_demo_cdc_gives_the_nodes_the_cycle_and_the_mappings() {
    let Some(cdc) = demo_cdc() else { return };
    let mn = CdcMn::new(&cdc, MnConfig::default()).unwrap();
    assert_eq!(mn.cycle(), Duration::from_millis(1));
    assert_eq!(mn.async_timeout(), Duration::from_micros(500));
    let nodes = mn.nodes();
    assert_eq!(nodes.iter().map(|n| n.node).collect::<Vec<_>>(), [1, 32, 110]);
    for n in &nodes {
        assert_eq!(mn.pres_timeout(n.node), Duration::from_micros(200));
        assert_eq!(n.phase, BootPhase::Unidentified);
        // CN 0x1600/1 = 0x0008_0000_0001_6200: 0x6200/1, 8 bits at 0 (PReq); 0x1A00/1: 0x6000/1.
        assert_eq!(
            n.outputs.iter().map(|o| (o.index, o.subindex, o.bit_offset, o.bit_length)).collect::<Vec<_>>(),
            [(0x6200, 1, 0, 8)]
        );
        assert_eq!(
            n.inputs.iter().map(|o| (o.index, o.subindex, o.bit_offset, o.bit_length)).collect::<Vec<_>>(),
            [(0x6000, 1, 0, 8)]
        );
    }
    let bad = MnConfig { overrides: vec![(7, 0x6200, 1, 1)], ..MnConfig::default() };
    assert!(CdcMn::new(&cdc, bad).is_err());
}

#[test]
fn boots_configures_and_runs_the_captured_openpowerlink_cn() {
    let Some(cdc) = demo_cdc() else { return };
    let mut b = Bench::new(&cdc, MnConfig { counter_every: 1, ..MnConfig::default() });
    let cycles = b.until(BootPhase::Operational, 5000);
    eprintln!("node 1 OPERATIONAL after {cycles} cycles ({:?} of virtual time)", b.mn.cycle() * cycles);
    // The MN reset every CN first (frames 11, 12), then configured node 1 with exactly the
    // CDC's entries, in order, then reset its configuration, enabled and started it.
    let expected: Vec<(u16, u8, Vec<u8>)> =
        cdc.node_config(1).unwrap().into_iter().map(|e| (e.index, e.subindex, e.data)).collect();
    assert_eq!(expected.len(), 14);
    assert_eq!(b.cn.store.writes, expected);
    assert_eq!(
        b.cn.commands,
        [
            NmtCommandId::ResetNode,
            NmtCommandId::ResetConfiguration,
            NmtCommandId::EnableReadyToOperate,
            NmtCommandId::StartNode
        ]
    );
    let n = b.node1();
    assert_eq!((n.boots, n.config_errors, n.state), (1, 0, NmtState::Operational));
    assert!(b
        .events
        .iter()
        .any(|e| e.kind == EventKind::Configured { index: 0x1A00, subindex: 0, done: 14, total: 14 }));
    // The absent CNs are still asked to identify themselves.
    assert!(b.mn.nodes().iter().filter(|n| n.node != 1).all(|n| n.phase == BootPhase::Unidentified));
    // Process data both ways: the counter arrives at the CN, its inputs at the MN.
    for _ in 0..50 {
        b.cycle();
    }
    let outs = &b.cn.outputs;
    assert!(outs.len() >= 49, "{outs:?}");
    assert!(outs.windows(2).all(|w| w[1] == w[0].wrapping_add(1)), "{outs:?}");
    let n = b.node1();
    assert_eq!(n.inputs[0].value, Some(0x5A));
    assert_eq!(n.outputs[0].value, Some(u64::from(*outs.last().unwrap())));
    assert_eq!((n.pres_missed, n.phase), (0, BootPhase::Operational));
    b.cn.inputs = 0x33;
    b.cycle();
    assert_eq!(b.node1().inputs[0].value, Some(0x33));
}

#[test]
fn a_cn_that_leaves_operational_is_booted_again_without_reconfiguration() {
    let Some(cdc) = demo_cdc() else { return };
    let mut b = Bench::new(&cdc, MnConfig::default());
    b.until(BootPhase::Operational, 5000);
    let writes = b.cn.store.writes.len();
    // Loss of SoC on the CN: back to PRE_OPERATIONAL_2, configuration kept.
    b.cn.state = NmtState::PreOperational2;
    b.cycle();
    assert!(
        b.events.iter().any(|e| matches!(&e.kind, EventKind::Lost(why) if why.contains("left OPERATIONAL"))),
        "{:#?}",
        b.events
    );
    let cycles = b.until(BootPhase::Operational, 5000);
    eprintln!("booted again in {cycles} cycles");
    // Identified again with the CDC's configuration date and time (0x1F26/0x1F27 = 0x1020):
    // not configured again.
    assert!(b.events.iter().any(|e| e.kind == EventKind::ConfigurationCurrent));
    assert_eq!(b.cn.store.writes.len(), writes);
    let n = b.node1();
    assert_eq!((n.boots, n.operational_entries), (2, 2));
}

#[test]
fn a_restarted_cn_is_lost_found_and_configured_again() {
    let Some(cdc) = demo_cdc() else { return };
    let mut b = Bench::new(&cdc, MnConfig { lost_after: 20, ..MnConfig::default() });
    b.until(BootPhase::Operational, 5000);
    let writes = b.cn.store.writes.len();
    // The process is killed: no more PRes.
    b.cn.alive = false;
    for _ in 0..19 {
        b.cycle();
    }
    assert_eq!(b.phase(), BootPhase::Operational);
    b.cycle();
    assert_eq!(b.phase(), BootPhase::Unidentified);
    assert_eq!(b.node1().pres_missed, 20);
    for _ in 0..100 {
        b.cycle();
    }
    // Restarted: its configuration is gone (VerifyConfiguration 0): configured again.
    b.cn.restart();
    let cycles = b.until(BootPhase::Operational, 5000);
    eprintln!("restarted CN OPERATIONAL again after {cycles} cycles");
    assert_eq!(b.cn.store.writes.len(), writes);
    let n = b.node1();
    assert_eq!((n.boots, n.operational_entries, n.config_errors), (2, 2, 0));
}

#[test]
fn a_cn_with_another_identity_is_not_configured() {
    let Some(cdc) = demo_cdc() else { return };
    // Expect product code 0x1234 from node 1 (0x1F86/1); the captured CN's is 0.
    let mut entries = cdc.entries().to_vec();
    entries.push(CdcEntry { index: 0x1F86, subindex: 1, data: 0x1234u32.to_le_bytes().to_vec() });
    let cdc = Cdc::parse(&encode_block(&entries)).unwrap();
    let mut b = Bench::new(&cdc, MnConfig::default());
    b.until(BootPhase::IdentityMismatch, 5000);
    for _ in 0..500 {
        b.cycle();
    }
    assert!(b.cn.store.writes.is_empty());
    assert!(b.events.iter().any(|e| matches!(&e.kind, EventKind::IdentityMismatch(why) if why.contains("product code 0x0, expected 0x1234"))), "{:#?}", b.events);
    assert_ne!(b.phase(), BootPhase::Operational);
}

#[test]
fn an_output_override_is_sent_and_an_unmapped_one_written_by_sdo() {
    let Some(cdc) = demo_cdc() else { return };
    let config = MnConfig { overrides: vec![(1, 0x6200, 1, 0xA5), (1, 0x2000, 3, 7)], ..MnConfig::default() };
    let mut b = Bench::new(&cdc, config);
    b.until(BootPhase::Operational, 5000);
    for _ in 0..5 {
        b.cycle();
    }
    assert!(b.cn.outputs.iter().all(|&o| o == 0xA5), "{:?}", b.cn.outputs);
    assert_eq!(b.cn.store.writes.last().unwrap(), &(0x2000, 3, vec![7, 0, 0, 0]));
}

/// The runtime on an in-memory segment on virtual time: the MN's thread and the captured CN's
/// thread on one threaded virtual clock.
#[test]
fn the_runtime_boots_the_captured_cn_on_virtual_time() {
    let Some(cdc) = demo_cdc() else { return };
    let clock = VirtualClock::threaded();
    let shared = clock.shared();
    let hub = MemHub::with_clock("cdc-mn", Arc::clone(&shared));
    let cn_link = hub.connect();
    let mn_link: Arc<dyn EthLink> = Arc::new(hub.connect());
    let cn = Arc::new(Mutex::new(CapturedCn::new()));
    let stop = Arc::new(AtomicBool::new(false));
    let cn_thread = {
        let (cn, stop, clock) = (Arc::clone(&cn), Arc::clone(&stop), Arc::clone(&shared));
        motus_clock::spawn(&shared, std::thread::Builder::new().name("captured-cn".into()), move || {
            let mut buf = vec![0u8; 1514];
            while !stop.load(Ordering::Relaxed) {
                let Ok(Some((n, _))) = cn_link.recv(&mut buf, Duration::from_millis(1)) else { continue };
                let Ok(f) = EplFrame::decode(&buf[..n]) else { continue };
                // The captured CN answers a PReq about 75 µs later (frames 1455, 1456).
                let answers = cn.lock().unwrap().on_frame(clock.now(), &f);
                if !answers.is_empty() {
                    clock.sleep(Duration::from_micros(75));
                }
                for a in answers {
                    cn_link.send(&a.encode().unwrap()).unwrap();
                }
            }
        })
        .unwrap()
    };
    let mn = CdcMn::new(&cdc, MnConfig::default()).unwrap();
    let handle = runtime::spawn(mn_link, Arc::clone(&shared), mn, RuntimeConfig::default()).unwrap();
    let mut operational_at = None;
    for _ in 0..5000 {
        clock.sleep(Duration::from_millis(1));
        let node1 = handle.nodes().into_iter().find(|n| n.node == 1);
        if node1.is_some_and(|n| n.phase == BootPhase::Operational) {
            operational_at = Some(clock.since_base());
            break;
        }
    }
    let at = operational_at
        .unwrap_or_else(|| panic!("not OPERATIONAL: {:?} {:#?}", handle.nodes(), handle.take_events()));
    eprintln!("runtime: node 1 OPERATIONAL after {at:?} of virtual time");
    clock.sleep(Duration::from_millis(200));
    let n = handle.nodes().into_iter().find(|n| n.node == 1).unwrap();
    assert_eq!((n.phase, n.pres_missed, n.config_errors), (BootPhase::Operational, 0, 0));
    assert_eq!(n.inputs[0].value, Some(0x5A));
    let stats = handle.stop();
    stop.store(true, Ordering::Relaxed);
    motus_clock::while_blocked(&*shared, || cn_thread.join()).unwrap();
    eprintln!("runtime stats: {stats:?}");
    // On virtual time every SoC is on its deadline.
    assert_eq!(stats.soc_late.max, 0);
    assert_eq!(stats.overruns, 0);
    let cn = cn.lock().unwrap();
    assert!(cn.outputs.len() > 150, "{}", cn.outputs.len());
}

/// The Motus MN and the Motus standards CN (`motus_epl::node::cn`) in one process, on an
/// in-memory segment on virtual time: boot, configuration by SDO from the demo CDC, process
/// data both ways, a restart of the CN (configuration lost) booted again.
#[test]
fn the_motus_mn_boots_the_motus_cn_on_virtual_time() {
    use motus_epl::node::cn::{CnRuntimeConfig, ControlledNode, ControlledNodeRuntime};
    use motus_epl_protocol::{DeviceIdentity, ObjectDictionary};

    let Some(cdc) = demo_cdc() else { return };
    let clock = VirtualClock::threaded();
    let shared = clock.shared();
    let hub = MemHub::with_clock("cdc-mn-motus-cn", Arc::clone(&shared));
    let start_cn = || {
        let link: Arc<dyn EthLink> = Arc::new(hub.connect());
        let identity = DeviceIdentity { mac_address: link.mac().0, ..DeviceIdentity::default() };
        let od = ObjectDictionary::controlled_node(1, &identity);
        let node = ControlledNode::new(1, link.mac(), od, clock.now()).unwrap();
        ControlledNodeRuntime::start(node, link, Arc::clone(&shared), CnRuntimeConfig::default()).unwrap()
    };
    let cn = start_cn();
    let mn = CdcMn::new(&cdc, MnConfig { counter_every: 10, ..MnConfig::default() }).unwrap();
    let mn_link: Arc<dyn EthLink> = Arc::new(hub.connect());
    let handle = runtime::spawn(mn_link, Arc::clone(&shared), mn, RuntimeConfig::default()).unwrap();
    let node1 = |h: &runtime::MnHandle| h.nodes().into_iter().find(|n| n.node == 1).unwrap();
    let wait_operational = |h: &runtime::MnHandle, what: &str| {
        for _ in 0..10_000 {
            clock.sleep(Duration::from_millis(1));
            if node1(h).phase == BootPhase::Operational {
                return clock.since_base();
            }
        }
        panic!("{what}: not OPERATIONAL: {:?}\n{:#?}", node1(h), h.take_events());
    };
    let at = wait_operational(&handle, "first boot");
    eprintln!("Motus CN OPERATIONAL under the Motus MN after {at:?} of virtual time");
    // The application sets its inputs (the MN's NMTResetNode restored the defaults at boot).
    cn.with_node(|c| c.od_mut().set_u8(0x6000, 1, 0x21)).unwrap();
    clock.sleep(Duration::from_millis(300));
    let n = node1(&handle);
    assert_eq!(
        (n.phase, n.pres_missed, n.config_errors, n.boots),
        (BootPhase::Operational, 0, 0, 1),
        "{n:?}"
    );
    assert_eq!(n.inputs[0].value, Some(0x21));
    let sent = n.outputs[0].value.unwrap();
    let received = cn.with_node(|c| c.od().u8(0x6200, 1)).unwrap();
    assert!(u64::from(received).abs_diff(sent) <= 1, "CN holds {received}, MN sends {sent}");
    assert!(received > 0);
    assert_eq!(cn.state(), NmtState::Operational);
    assert_eq!(cn.with_node(|c| c.od().u32(0x1006, 0)), Some(1000));
    // The CN restarts (a new process: default configuration).
    let cn_stats = cn.stop();
    eprintln!("Motus CN PRes turnaround on virtual time: {:?}", cn_stats.turnaround);
    clock.sleep(Duration::from_millis(100));
    let cn = start_cn();
    let at = wait_operational(&handle, "after the restart");
    eprintln!("restarted Motus CN OPERATIONAL again at {at:?}");
    cn.with_node(|c| c.od_mut().set_u8(0x6000, 1, 0x42)).unwrap();
    clock.sleep(Duration::from_millis(100));
    let n = node1(&handle);
    assert_eq!((n.boots, n.operational_entries, n.config_errors), (2, 2, 0), "{n:?}");
    assert_eq!(n.inputs[0].value, Some(0x42));
    let events = handle.take_events();
    assert!(events.iter().any(|e| matches!(&e.kind, EventKind::Lost(_))), "{events:#?}");
    let stats = handle.stop();
    cn.stop();
    assert_eq!((stats.soc_late.max, stats.overruns), (0, 0), "{stats:?}");
}

#[test]
fn new_errors_signalled_by_en_are_read_and_acknowledged_by_ea() {
    let Some(cdc) = demo_cdc() else { return };
    let mut b = Bench::new(&cdc, MnConfig { status_every: 0, ..MnConfig::default() });
    b.until(BootPhase::Operational, 5000);
    for _ in 0..10 {
        b.cycle();
    }
    let asked = b.cn.status_requests;
    assert!(!b.cn.ea);
    // The CN has a new error: EN toggles in its PRes.
    b.cn.en = true;
    for _ in 0..4 {
        b.cycle();
    }
    assert_eq!(b.cn.status_requests, asked + 1, "one StatusRequest reads the new error");
    assert!(b.cn.ea, "EA acknowledges EN in the PReq");
    for _ in 0..10 {
        b.cycle();
    }
    assert_eq!(b.cn.status_requests, asked + 1, "no more requests once acknowledged");
}
