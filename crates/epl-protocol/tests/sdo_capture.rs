//! SDO engines against real openPOWERLINK V2.7.2 traffic: at boot the MN (node 240) configures
//! CN 1 by SDO over ASnd (`shared/fixtures/powerlink/`, copied into tests/data/; list them with
//! `tshark -r F -Y "epl.asnd.svid == 5"`).
//!
//! * `oplk_mn_cn_veth_merged.pcapng`, frames 871..1426: the sequence-layer handshake
//!   (871 InitReq, 894 InitAck, 908 InitResp, 922 Valid), then 17 expedited WriteByIndex
//!   requests (TID 0..16: 0x1011/1 "load" and 0x1010/1 "save" aborted 0x06020000 by the CN,
//!   then 0x1600/0, 0x1A00/0, 0x1006, 0x1020/1-2, 0x1C0B/3, 0x1C0D/3, 0x1C14, 0x1F98/4-5,
//!   0x1600/1, 0x1A00/1, ...), each answered by the CN and acknowledged by the MN, then the
//!   MN's close (1426). The CN, busy with NMT ResetConfiguration (6.95 s), never saw the MN's
//!   last acknowledgement and close: it sent its last response again with an acknowledge
//!   request 5 s apart (1782, 2183) and closed the connection (2584).
//! * `oplk_mn_cn_bridge_monitor.pcapng`, frames 864..2595: the same exchange seen from a
//!   bridge port.
//!
//! `SdoServer` fed the MN's frames must answer byte for byte what the CN sent (handshake,
//! numbering, acknowledgements, responses, aborts, retransmissions, close). `SdoClient` fed
//! the CN's frames, with the MN's writes queued one after another, must send byte for byte
//! what the MN sent.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use std::collections::{BTreeMap, VecDeque};
use std::fs::File;
use std::time::{Duration, Instant};

use motus_epl_protocol::sdo_transfer::{LinkState, SdoClient, SdoError, SdoServer};
use motus_epl_protocol::{
    Asnd, EplFrame, Message, ObjectAccess, Padding, SdoAbortCode, SdoCommandId, SdoFrame, ETHERTYPE_EPL,
};
use pcap_file::pcapng::{Block, PcapNgReader};

/// One SDO frame of a capture.
#[derive(Debug, Clone)]
struct Captured {
    /// Frame number, as tshark counts.
    number: usize,
    /// Since the first packet of the capture.
    at: Duration,
    src: u8,
    bytes: Vec<u8>,
    frame: EplFrame,
    sdo: SdoFrame,
}

fn sdo_frames(name: &str) -> Vec<Captured> {
    let path = format!("{}/tests/data/{name}", env!("CARGO_MANIFEST_DIR"));
    let mut reader = PcapNgReader::new(File::open(&path).unwrap()).unwrap();
    let mut packets = Vec::new();
    while let Some(block) = reader.next_block() {
        if let Block::EnhancedPacket(epb) = block.unwrap() {
            packets.push((epb.timestamp, epb.data.to_vec()));
        }
    }
    let first = packets[0].0;
    packets
        .into_iter()
        .enumerate()
        .filter(|(_, (_, b))| b.len() >= 14 && u16::from_be_bytes([b[12], b[13]]) == ETHERTYPE_EPL)
        .filter_map(|(i, (ts, bytes))| {
            let frame = EplFrame::decode(&bytes).unwrap();
            let Message::Asnd(Asnd::Sdo(sdo)) = &frame.message else { return None };
            Some(Captured {
                number: i + 1,
                at: ts - first,
                src: frame.src_node,
                sdo: sdo.clone(),
                bytes,
                frame,
            })
        })
        .collect()
}

/// `sdo` in the captured frame's Ethernet and POWERLINK headers, padded as a sender pads.
fn as_captured(template: &Captured, sdo: &SdoFrame) -> Vec<u8> {
    let mut frame = template.frame.clone();
    frame.message = Message::Asnd(Asnd::Sdo(sdo.clone()));
    frame.padding = Padding::Auto;
    frame.encode().unwrap()
}

fn assert_same(ours: &SdoFrame, captured: &Captured, file: &str) {
    assert_eq!(
        as_captured(captured, ours),
        captured.bytes,
        "{file} frame {}: ours {ours:?}, captured {:?}",
        captured.number,
        captured.sdo
    );
}

const VETH: &str = "oplk_mn_cn_veth_merged.pcapng";
const BRIDGE: &str = "oplk_mn_cn_bridge_monitor.pcapng";

/// The SDO frame numbers tshark lists, per file.
fn expected_numbers(file: &str) -> Vec<usize> {
    let (start, after_close): (usize, [usize; 3]) =
        if file == VETH { (871, [1782, 2183, 2584]) } else { (864, [1797, 2194, 2595]) };
    let frames = sdo_frames(file);
    assert_eq!(frames[0].number, start, "{file}: first SDO frame");
    assert_eq!(
        frames[frames.len() - 3..].iter().map(|f| f.number).collect::<Vec<_>>(),
        after_close,
        "{file}"
    );
    assert_eq!(frames.len(), 59, "{file}");
    frames.iter().map(|f| f.number).collect()
}

/// The CN's objects the demo MN writes (sizes as the CN's XDD declares them); 0x1010 and
/// 0x1011 (store/restore parameters) are absent, as on the captured CN.
#[derive(Debug, Default)]
struct CnOd {
    values: BTreeMap<(u16, u8), Vec<u8>>,
}

fn size_of(index: u16, sub: u8) -> Option<usize> {
    Some(match (index, sub) {
        (0x1600 | 0x1A00, 0) => 1,
        (0x1600 | 0x1A00, 1..=8) => 8,
        (0x1006, 0) | (0x1020, 1 | 2) | (0x1C0B | 0x1C0D, 3) | (0x1C14, 0) => 4,
        (0x1F98, 4 | 5) => 2,
        _ => return None,
    })
}

impl ObjectAccess for CnOd {
    fn read(&mut self, index: u16, subindex: u8) -> Result<Vec<u8>, SdoAbortCode> {
        let size = size_of(index, subindex).ok_or(SdoAbortCode::ObjectDoesNotExist)?;
        Ok(self.values.get(&(index, subindex)).cloned().unwrap_or_else(|| vec![0; size]))
    }

    fn write(&mut self, index: u16, subindex: u8, value: &[u8]) -> Result<(), SdoAbortCode> {
        let size = size_of(index, subindex).ok_or(SdoAbortCode::ObjectDoesNotExist)?;
        if value.len() != size {
            return Err(SdoAbortCode::TypeLengthMismatch);
        }
        self.values.insert((index, subindex), value.to_vec());
        Ok(())
    }
}

fn server_follows_the_cn(file: &str) {
    let numbers = expected_numbers(file);
    let frames = sdo_frames(file);
    let t0 = Instant::now();
    let mut server = SdoServer::default();
    let mut od = CnOd::default();
    // Up to the CN's last response (veth 1409, bridge 1418): the MN's frames in, the CN's out.
    let last_response = frames.iter().rposition(|f| f.src == 1 && f.sdo.send_con == 2).unwrap();
    let mut pending: VecDeque<SdoFrame> = VecDeque::new();
    let mut answered_at = t0;
    for f in &frames[..=last_response] {
        let now = t0 + f.at;
        if f.src == 240 {
            assert!(pending.is_empty(), "{file} frame {}: unanswered {pending:?}", f.number);
            pending.extend(server.on_frame(now, &f.sdo, &mut od));
            answered_at = now;
        } else {
            let ours = pending.pop_front().unwrap_or_else(|| panic!("{file} frame {}: no answer", f.number));
            assert_same(&ours, f, file);
        }
    }
    assert!(pending.is_empty());
    assert_eq!(server.state(), LinkState::Connected);
    // The configuration arrived (0x1006 = 50 ms; TPDO 0x1A00/1 maps 0x6000/1, 8 bits).
    assert_eq!(od.values[&(0x1006, 0)], 50_000u32.to_le_bytes());
    assert_eq!(od.values[&(0x1A00, 1)], 0x0008_0000_0001_6000u64.to_le_bytes());
    assert_eq!(od.values[&(0x1600, 1)], 0x0008_0000_0001_6200u64.to_le_bytes());
    assert_eq!(od.values[&(0x1F98, 5)], 36u16.to_le_bytes());
    assert_eq!(od.values.len(), 12);

    // The CN never got the MN's last acknowledgement: its response goes out again with an
    // acknowledge request after 5 s, twice, and then the close, 5 s apart in the capture too
    // (within the 50 ms cycle: a CN sends only when the MN invites it; veth 5.000 s each,
    // bridge 5.050, 4.950, 5.000 s).
    let tail = &frames[frames.len() - 3..];
    let sent = frames[last_response].at;
    for (k, f) in tail.iter().enumerate() {
        let gap = f.at - sent;
        let expected = Duration::from_secs(5 * (k as u64 + 1));
        let off = if gap > expected { gap - expected } else { expected - gap };
        assert!(off <= Duration::from_millis(60), "{file} frame {}: {gap:?}", f.number);
        let deadline = server.next_deadline().unwrap();
        assert_eq!(
            deadline,
            answered_at + Duration::from_secs(5 * (k as u64 + 1)),
            "{file} frame {}",
            f.number
        );
        assert_eq!(server.poll(deadline - Duration::from_millis(1)), None);
        let ours = server.poll(deadline).unwrap_or_else(|| panic!("{file} frame {}: nothing sent", f.number));
        assert_same(&ours, f, file);
        assert_eq!(server.poll(deadline), None);
    }
    assert_eq!(server.state(), LinkState::Closed);
    assert_eq!(server.next_deadline(), None);

    // Had the CN received them, the MN's acknowledgement (veth 1421) would have ended the
    // retransmissions and its close (1426) the connection, neither answered.
    let mut server = SdoServer::default();
    let mut od = CnOd::default();
    for f in frames.iter().filter(|f| f.src == 240) {
        server.on_frame(t0 + f.at, &f.sdo, &mut od);
    }
    assert_eq!(server.state(), LinkState::Closed);
    assert_eq!(server.next_deadline(), None);
    assert_eq!(server.poll(t0 + Duration::from_secs(60)), None);
    assert_eq!(numbers.len(), frames.len());
}

fn client_follows_the_mn(file: &str) {
    let frames = sdo_frames(file);
    // The MN's requests, in order: (TID, index, subindex, value).
    let requests: Vec<(u8, u16, u8, Vec<u8>)> = frames
        .iter()
        .filter(|f| f.src == 240)
        .filter_map(|f| {
            let c = f.sdo.command.as_ref()?;
            let (index, sub, value) = c.by_index()?;
            assert_eq!((c.command_id, c.segmentation), (SdoCommandId::WriteByIndex, 0));
            Some((c.transaction_id, index, sub, value.to_vec()))
        })
        .collect();
    assert_eq!(requests.len(), 17, "{file}");
    assert!(requests.iter().enumerate().all(|(i, r)| usize::from(r.0) == i));
    assert_eq!((requests[0].1, requests[0].2, requests[0].3.as_slice()), (0x1011, 1, &b"load"[..]));

    let t0 = Instant::now();
    let mut client = SdoClient::default();
    let mut queued = requests.iter();
    let (_, index, sub, value) = queued.next().unwrap();
    client.write(*index, *sub, value.clone()).unwrap();
    let close = frames.iter().position(|f| f.src == 240 && f.sdo.send_con == 0).unwrap();
    let mut pending: VecDeque<SdoFrame> = VecDeque::new();
    let mut outcomes = Vec::new();
    for f in &frames[..=close] {
        let now = t0 + f.at;
        if f.src == 1 {
            assert!(pending.is_empty(), "{file} frame {}: unsent {pending:?}", f.number);
            pending.extend(client.on_frame(now, &f.sdo));
            if let Some(outcome) = client.pop_outcome() {
                outcomes.push(outcome);
                // The MN starts its next write after acknowledging the response.
                if let Some((_, index, sub, value)) = queued.next() {
                    client.write(*index, *sub, value.clone()).unwrap();
                }
            }
        } else {
            if f.number == frames[close].number {
                assert!(client.is_idle());
                client.close();
            }
            let ours = pending
                .pop_front()
                .or_else(|| client.poll(now))
                .unwrap_or_else(|| panic!("{file} frame {}: nothing to send", f.number));
            assert_same(&ours, f, file);
        }
    }
    assert!(pending.is_empty() && client.poll(t0 + frames[close].at).is_none());
    assert_eq!(client.state(), LinkState::Closed);
    assert_eq!(outcomes.len(), 17);
    for (outcome, (tid, index, sub, _)) in outcomes.iter().zip(&requests) {
        assert_eq!((outcome.index, outcome.subindex), (*index, *sub));
        let expected = if matches!(index, 0x1010 | 0x1011) {
            Err(SdoError::Aborted { code: SdoAbortCode::ObjectDoesNotExist })
        } else {
            Ok(Vec::new())
        };
        assert_eq!(outcome.result, expected, "{file}: TID {tid} {index:04X}/{sub}");
    }
}

#[test]
fn server_answers_the_openpowerlink_mn_as_its_cn_did_veth() {
    server_follows_the_cn(VETH);
}

#[test]
fn server_answers_the_openpowerlink_mn_as_its_cn_did_bridge() {
    server_follows_the_cn(BRIDGE);
}

#[test]
fn client_configures_the_openpowerlink_cn_as_its_mn_did_veth() {
    client_follows_the_mn(VETH);
}

#[test]
fn client_configures_the_openpowerlink_cn_as_its_mn_did_bridge() {
    client_follows_the_mn(BRIDGE);
}
