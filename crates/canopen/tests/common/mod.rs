//! Test doubles written from specs/canopen.md §3.3 independently of the client code:
//! a sans-IO SDO server working on raw bytes, and a fake node thread (SDO server, NMT
//! slave, heartbeat producer) on any `CanBus`.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, dead_code)]

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use motus_can::{CanBus, CanFrame};

/// Completed downloads, in order.
pub type Writes = Arc<Mutex<Vec<(u16, u8, Vec<u8>)>>>;

/// Object store shared with the test.
pub type Objects = Arc<Mutex<HashMap<(u16, u8), Vec<u8>>>>;

enum Transfer {
    Idle,
    Upload { data: Vec<u8>, pos: usize, toggle: u8 },
    Download { index: u16, sub: u8, buf: Vec<u8>, toggle: u8 },
}

/// Sans-IO SDO server on raw 8-byte bodies.
pub struct SdoServer {
    pub objects: Objects,
    state: Transfer,
    /// Every completed download, in order.
    pub writes: Writes,
}

fn abort(index: u16, sub: u8, code: u32) -> [u8; 8] {
    let i = index.to_le_bytes();
    let c = code.to_le_bytes();
    [0x80, i[0], i[1], sub, c[0], c[1], c[2], c[3]]
}

impl SdoServer {
    pub fn new(objects: Objects) -> Self {
        Self { objects, state: Transfer::Idle, writes: Arc::default() }
    }

    /// Handles one request body; returns the response body (None for an abort request).
    pub fn handle(&mut self, d: &[u8; 8]) -> Option<[u8; 8]> {
        let cmd = d[0];
        let index = u16::from_le_bytes([d[1], d[2]]);
        let sub = d[3];
        match cmd >> 5 {
            // Initiate upload.
            2 => {
                let Some(data) = self.objects.lock().unwrap().get(&(index, sub)).cloned() else {
                    return Some(abort(index, sub, 0x0602_0000));
                };
                let mut out = [0u8; 8];
                out[1..4].copy_from_slice(&d[1..4]);
                if !data.is_empty() && data.len() <= 4 {
                    // 010 0 nn 1 1
                    out[0] = 0x43 | (((4 - data.len()) as u8) << 2);
                    out[4..4 + data.len()].copy_from_slice(&data);
                    self.state = Transfer::Idle;
                } else {
                    out[0] = 0x41;
                    out[4..8].copy_from_slice(&(data.len() as u32).to_le_bytes());
                    self.state = Transfer::Upload { data, pos: 0, toggle: 0 };
                }
                Some(out)
            }
            // Upload segment.
            3 => {
                let Transfer::Upload { data, pos, toggle } = &mut self.state else {
                    return Some(abort(0, 0, 0x0504_0001));
                };
                if (cmd >> 4) & 1 != *toggle {
                    self.state = Transfer::Idle;
                    return Some(abort(0, 0, 0x0503_0000));
                }
                let n = (data.len() - *pos).min(7);
                let last = *pos + n == data.len();
                let mut out = [0u8; 8];
                out[0] = (*toggle << 4) | (((7 - n) as u8) << 1) | u8::from(last);
                out[1..1 + n].copy_from_slice(&data[*pos..*pos + n]);
                *pos += n;
                *toggle ^= 1;
                if last {
                    self.state = Transfer::Idle;
                }
                Some(out)
            }
            // Initiate download.
            1 => {
                let mut out = [0x60, d[1], d[2], d[3], 0, 0, 0, 0];
                if cmd & 0x02 != 0 {
                    let n = if cmd & 0x01 != 0 { usize::from((cmd >> 2) & 3) } else { 0 };
                    let data = d[4..8 - n].to_vec();
                    self.store(index, sub, data);
                    self.state = Transfer::Idle;
                } else {
                    self.state = Transfer::Download { index, sub, buf: Vec::new(), toggle: 0 };
                }
                out[0] = 0x60;
                Some(out)
            }
            // Download segment.
            0 => {
                let Transfer::Download { index, sub, buf, toggle } = &mut self.state else {
                    return Some(abort(0, 0, 0x0504_0001));
                };
                if (cmd >> 4) & 1 != *toggle {
                    self.state = Transfer::Idle;
                    return Some(abort(0, 0, 0x0503_0000));
                }
                let n = 7 - usize::from((cmd >> 1) & 7);
                buf.extend_from_slice(&d[1..1 + n]);
                let out = [0x20 | (*toggle << 4), 0, 0, 0, 0, 0, 0, 0];
                *toggle ^= 1;
                if cmd & 1 != 0 {
                    let (i, s, b) = (*index, *sub, std::mem::take(buf));
                    self.store(i, s, b);
                    self.state = Transfer::Idle;
                }
                Some(out)
            }
            4 => {
                self.state = Transfer::Idle;
                None
            }
            _ => Some(abort(index, sub, 0x0504_0001)),
        }
    }

    fn store(&mut self, index: u16, sub: u8, data: Vec<u8>) {
        self.writes.lock().unwrap().push((index, sub, data.clone()));
        self.objects.lock().unwrap().insert((index, sub), data);
    }
}

/// Knobs of a running fake node.
#[derive(Default)]
pub struct Controls {
    /// Stop the thread.
    pub stop: AtomicBool,
    /// Stop sending heartbeats.
    pub silent: AtomicBool,
    /// Ignore SDO requests.
    pub mute_sdo: AtomicBool,
    /// Delay before each SDO response, in µs.
    pub sdo_delay_us: AtomicU64,
    /// SDO requests handled.
    pub requests: AtomicU64,
}

/// A fake CANopen node on its own thread.
pub struct FakeNode {
    pub objects: Objects,
    pub writes: Writes,
    pub controls: Arc<Controls>,
    handle: Option<JoinHandle<()>>,
}

impl Drop for FakeNode {
    fn drop(&mut self) {
        self.controls.stop.store(true, Ordering::SeqCst);
        if let Some(h) = self.handle.take() {
            h.join().unwrap();
        }
    }
}

/// Standard objects of a fake node: 0x1000 device type, 0x1008 name, 0x1018 identity.
pub fn standard_objects(node: u8) -> HashMap<(u16, u8), Vec<u8>> {
    let mut m = HashMap::new();
    m.insert((0x1000, 0), 0x0002_0192u32.to_le_bytes().to_vec());
    m.insert((0x1008, 0), format!("Fake node {node}").into_bytes());
    m.insert((0x1018, 0), vec![4]);
    m.insert((0x1018, 1), 0x123u32.to_le_bytes().to_vec());
    m.insert((0x1018, 2), 0x402u32.to_le_bytes().to_vec());
    m.insert((0x1018, 3), 0x0001_0000u32.to_le_bytes().to_vec());
    m.insert((0x1018, 4), (0xCAFE_0000u32 + u32::from(node)).to_le_bytes().to_vec());
    m.insert((0x6041, 0), 0x0237u16.to_le_bytes().to_vec());
    m
}

/// Starts a fake node: sends boot-up, then heartbeats every `heartbeat` (if any) in its
/// NMT state; serves SDO; obeys NMT.
pub fn spawn_node(bus: Arc<dyn CanBus>, node: u8, heartbeat: Option<Duration>) -> FakeNode {
    let objects: Objects = Arc::new(Mutex::new(standard_objects(node)));
    let mut server = SdoServer::new(objects.clone());
    let writes = server.writes.clone();
    let controls = Arc::new(Controls::default());
    let c = controls.clone();
    let handle = std::thread::spawn(move || {
        let hb = |bus: &Arc<dyn CanBus>, state: u8| {
            bus.send(&CanFrame::new(0x700 + u32::from(node), &[state]).unwrap()).unwrap();
        };
        let mut state = 0x7Fu8;
        hb(&bus, 0);
        let mut next_hb = Instant::now();
        while !c.stop.load(Ordering::SeqCst) {
            if let Some(p) = heartbeat {
                if Instant::now() >= next_hb {
                    if !c.silent.load(Ordering::SeqCst) {
                        hb(&bus, state);
                    }
                    next_hb += p;
                }
            }
            let Ok(Some(r)) = bus.recv(Duration::from_millis(1)) else { continue };
            let f = r.frame;
            if f.id() == 0 && f.data().len() == 2 && (f.data()[1] == 0 || f.data()[1] == node) {
                state = match f.data()[0] {
                    0x01 => 0x05,
                    0x02 => 0x04,
                    0x80 => 0x7F,
                    0x81 | 0x82 => {
                        hb(&bus, 0);
                        0x7F
                    }
                    _ => state,
                };
            } else if f.id() == 0x600 + u32::from(node)
                && f.data().len() == 8
                && !c.mute_sdo.load(Ordering::SeqCst)
            {
                c.requests.fetch_add(1, Ordering::SeqCst);
                let d: [u8; 8] = f.data().try_into().unwrap();
                if let Some(resp) = server.handle(&d) {
                    let delay = c.sdo_delay_us.load(Ordering::SeqCst);
                    if delay > 0 {
                        std::thread::sleep(Duration::from_micros(delay));
                    }
                    bus.send(&CanFrame::new(0x580 + u32::from(node), &resp).unwrap()).unwrap();
                }
            }
        }
    });
    FakeNode { objects, writes, controls, handle: Some(handle) }
}
