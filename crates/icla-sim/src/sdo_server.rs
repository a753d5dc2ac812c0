//! SDO server (CiA 301 §7.2.4, specs/canopen.md 3.3): expedited and segmented upload and
//! download with toggle checks, a protocol time-out, and aborts by name. Block transfers are
//! not supported (abort 0x05040001, as python-canopen's `LocalNode` does).

use std::time::{Duration, Instant};

use motus_canopen_protocol::{SdoAbortCode, SdoPayload, SdoRequest, SdoResponse};

/// A segmented transfer left idle this long is aborted with 0x05040000.
pub const SDO_TIMEOUT: Duration = Duration::from_millis(1000);

/// What the SDO server reads and writes: the device's object dictionary with its hooks.
pub trait SdoTarget {
    /// Reads an entry (all checks done: existence, access, state).
    fn upload(&mut self, index: u16, sub: u8) -> Result<Vec<u8>, SdoAbortCode>;
    /// Writes an entry (all checks done: existence, access, length, range, state).
    fn download(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), SdoAbortCode>;
    /// Early checks for a download (existence and write access); the entry's fixed size
    /// in bytes, or `None` for variable-size entries.
    fn download_size(&self, index: u16, sub: u8) -> Result<Option<usize>, SdoAbortCode>;
}

#[derive(Debug, Clone, PartialEq, Eq)]
enum Transfer {
    Idle,
    Download { index: u16, sub: u8, size: Option<u32>, toggle: bool, data: Vec<u8> },
    Upload { index: u16, sub: u8, data: Vec<u8>, pos: usize, toggle: bool },
}

/// The server side of one SDO channel.
#[derive(Debug, Clone)]
pub struct SdoServer {
    transfer: Transfer,
    last: Option<Instant>,
}

impl Default for SdoServer {
    fn default() -> Self {
        Self::new()
    }
}

fn abort(index: u16, sub: u8, code: SdoAbortCode) -> SdoResponse {
    SdoResponse::Abort { index, subindex: sub, code }
}

impl SdoServer {
    /// An idle server.
    pub fn new() -> Self {
        Self { transfer: Transfer::Idle, last: None }
    }

    /// Whether a segmented transfer is in progress.
    pub fn busy(&self) -> bool {
        self.transfer != Transfer::Idle
    }

    /// Drops any transfer (NMT reset).
    pub fn reset(&mut self) {
        self.transfer = Transfer::Idle;
    }

    /// Handles one request frame body; returns the response frame body, if any.
    pub fn handle(&mut self, data: &[u8], now: Instant, target: &mut dyn SdoTarget) -> Option<[u8; 8]> {
        if data.len() != 8 {
            return None; // CiA 301: SDO frames have DLC 8; others are ignored.
        }
        self.last = Some(now);
        let response = match SdoRequest::decode(data) {
            Some(req) => self.request(req, target),
            None => {
                // ccs 5 (block upload), 6 (block download), 7: not supported.
                self.transfer = Transfer::Idle;
                let index = u16::from_le_bytes([data.get(1).copied()?, data.get(2).copied()?]);
                Some(abort(index, data.get(3).copied()?, SdoAbortCode::InvalidCommandSpecifier))
            }
        }?;
        response.encode().ok()
    }

    /// Aborts a segmented transfer idle for longer than [`SDO_TIMEOUT`].
    pub fn poll(&mut self, now: Instant) -> Option<[u8; 8]> {
        let (index, sub) = match &self.transfer {
            Transfer::Idle => return None,
            Transfer::Download { index, sub, .. } | Transfer::Upload { index, sub, .. } => (*index, *sub),
        };
        if self.last.is_some_and(|t| now.saturating_duration_since(t) > SDO_TIMEOUT) {
            self.transfer = Transfer::Idle;
            return abort(index, sub, SdoAbortCode::Timeout).encode().ok();
        }
        None
    }

    fn request(&mut self, req: SdoRequest, target: &mut dyn SdoTarget) -> Option<SdoResponse> {
        match req {
            SdoRequest::InitiateDownload { index, subindex: sub, payload } => {
                self.transfer = Transfer::Idle;
                Some(self.initiate_download(index, sub, payload, target))
            }
            SdoRequest::DownloadSegment { toggle, last, data } => {
                Some(self.download_segment(toggle, last, &data, target))
            }
            SdoRequest::InitiateUpload { index, subindex: sub } => {
                self.transfer = Transfer::Idle;
                Some(self.initiate_upload(index, sub, target))
            }
            SdoRequest::UploadSegment { toggle } => Some(self.upload_segment(toggle)),
            SdoRequest::Abort { .. } => {
                self.transfer = Transfer::Idle;
                None
            }
        }
    }

    fn initiate_download(
        &mut self,
        index: u16,
        sub: u8,
        payload: SdoPayload,
        target: &mut dyn SdoTarget,
    ) -> SdoResponse {
        let size = match target.download_size(index, sub) {
            Ok(s) => s,
            Err(code) => return abort(index, sub, code),
        };
        let bytes: Vec<u8> = match payload {
            SdoPayload::Expedited { data } => data,
            // e = 1, s = 0: the size is the entry's (CiA 301 leaves it to the server).
            SdoPayload::ExpeditedUnsized { data } => data.iter().take(size.unwrap_or(4)).copied().collect(),
            SdoPayload::Segmented { size: indicated } => {
                if let (Some(n), Some(want)) = (indicated, size) {
                    if n as usize != want {
                        return abort(index, sub, SdoAbortCode::TypeLengthMismatch);
                    }
                }
                self.transfer =
                    Transfer::Download { index, sub, size: indicated, toggle: false, data: Vec::new() };
                return SdoResponse::InitiateDownload { index, subindex: sub };
            }
        };
        match target.download(index, sub, &bytes) {
            Ok(()) => SdoResponse::InitiateDownload { index, subindex: sub },
            Err(code) => abort(index, sub, code),
        }
    }

    fn download_segment(
        &mut self,
        toggle: bool,
        last: bool,
        seg: &[u8],
        target: &mut dyn SdoTarget,
    ) -> SdoResponse {
        let Transfer::Download { index, sub, size, toggle: expected, data } = &mut self.transfer else {
            self.transfer = Transfer::Idle;
            return abort(0, 0, SdoAbortCode::InvalidCommandSpecifier);
        };
        let (index, sub) = (*index, *sub);
        if toggle != *expected {
            self.transfer = Transfer::Idle;
            return abort(index, sub, SdoAbortCode::ToggleBitNotAlternated);
        }
        data.extend_from_slice(seg);
        *expected = !*expected;
        if !last {
            return SdoResponse::DownloadSegment { toggle };
        }
        let (size, data) = (*size, std::mem::take(data));
        self.transfer = Transfer::Idle;
        if size.is_some_and(|n| n as usize != data.len()) {
            return abort(index, sub, SdoAbortCode::TypeLengthMismatch);
        }
        match target.download(index, sub, &data) {
            Ok(()) => SdoResponse::DownloadSegment { toggle },
            Err(code) => abort(index, sub, code),
        }
    }

    fn initiate_upload(&mut self, index: u16, sub: u8, target: &mut dyn SdoTarget) -> SdoResponse {
        let data = match target.upload(index, sub) {
            Ok(d) => d,
            Err(code) => return abort(index, sub, code),
        };
        if (1..=4).contains(&data.len()) {
            return SdoResponse::InitiateUpload {
                index,
                subindex: sub,
                payload: SdoPayload::Expedited { data },
            };
        }
        let size = data.len() as u32;
        self.transfer = Transfer::Upload { index, sub, data, pos: 0, toggle: false };
        SdoResponse::InitiateUpload {
            index,
            subindex: sub,
            payload: SdoPayload::Segmented { size: Some(size) },
        }
    }

    fn upload_segment(&mut self, toggle: bool) -> SdoResponse {
        let Transfer::Upload { index, sub, data, pos, toggle: expected } = &mut self.transfer else {
            self.transfer = Transfer::Idle;
            return abort(0, 0, SdoAbortCode::InvalidCommandSpecifier);
        };
        if toggle != *expected {
            let (index, sub) = (*index, *sub);
            self.transfer = Transfer::Idle;
            return abort(index, sub, SdoAbortCode::ToggleBitNotAlternated);
        }
        let chunk: Vec<u8> = data.iter().skip(*pos).take(7).copied().collect();
        *pos += chunk.len();
        *expected = !*expected;
        let last = *pos >= data.len();
        if last {
            self.transfer = Transfer::Idle;
        }
        SdoResponse::UploadSegment { toggle, last, data: chunk }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;
    use std::collections::BTreeMap;

    /// A toy dictionary: 0x6081:00 U32 rw, 0x1008:00 a 27-byte string (ro), 0x6041 ro.
    struct Toy(BTreeMap<(u16, u8), (Vec<u8>, bool)>);

    impl SdoTarget for Toy {
        fn upload(&mut self, index: u16, sub: u8) -> Result<Vec<u8>, SdoAbortCode> {
            self.0.get(&(index, sub)).map(|v| v.0.clone()).ok_or(SdoAbortCode::ObjectDoesNotExist)
        }
        fn download(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), SdoAbortCode> {
            let e = self.0.get_mut(&(index, sub)).ok_or(SdoAbortCode::ObjectDoesNotExist)?;
            e.0 = data.to_vec();
            Ok(())
        }
        fn download_size(&self, index: u16, sub: u8) -> Result<Option<usize>, SdoAbortCode> {
            let e = self.0.get(&(index, sub)).ok_or(SdoAbortCode::ObjectDoesNotExist)?;
            if !e.1 {
                return Err(SdoAbortCode::ReadOnly);
            }
            Ok((index != 0x1008).then_some(e.0.len()))
        }
    }

    fn toy() -> Toy {
        let mut m = BTreeMap::new();
        m.insert((0x6081, 0), (vec![0xF8, 0, 0, 0], true));
        m.insert((0x1008, 0), (b"IclA D065 (Motus simulator)".to_vec(), false));
        m.insert((0x6041, 0), (vec![0x37, 0x02], false));
        Toy(m)
    }

    fn hex(s: &str) -> Vec<u8> {
        (0..s.len()).step_by(2).map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap()).collect()
    }

    fn run(server: &mut SdoServer, t: &mut Toy, req: &str) -> String {
        let out = server.handle(&hex(req), Instant::now(), t);
        out.map(|b| b.iter().map(|x| format!("{x:02X}")).collect()).unwrap_or_default()
    }

    #[test]
    fn expedited_upload_and_download() {
        let (mut s, mut t) = (SdoServer::new(), toy());
        // 40 = initiate upload, 4160 = index 0x6041 LE, 00 = sub.
        // Reply 4B = scs 2, n = 2 (2 unused bytes), e = s = 1; data 37 02.
        assert_eq!(run(&mut s, &mut t, "4041600000000000"), "4B41600037020000");
        // 23 = download 4 bytes expedited; 0x6081 := 500 = F4 01 00 00. Reply 60.
        assert_eq!(run(&mut s, &mut t, "23816000F4010000"), "6081600000000000");
        assert_eq!(t.0[&(0x6081, 0)].0, vec![0xF4, 1, 0, 0]);
        // 2B = 2 bytes into a 4-byte entry: the toy accepts; length is the target's job.
        // Write to a read-only object: abort 80, code 0x06010002 LE 02 00 01 06.
        assert_eq!(run(&mut s, &mut t, "2B41600001000000"), "8041600002000106");
        // Unknown object: 0x06020000 LE 00 00 02 06.
        assert_eq!(run(&mut s, &mut t, "4000200000000000"), "8000200000000206");
    }

    #[test]
    fn segmented_upload_with_toggle() {
        let (mut s, mut t) = (SdoServer::new(), toy());
        // 41 = segmented, size indicated: 27 = 0x1B bytes.
        assert_eq!(run(&mut s, &mut t, "4008100000000000"), "410810001B000000");
        // 60 = upload segment t=0 -> 00 (t=0, n=0, c=0) + "IclA D0".
        assert_eq!(run(&mut s, &mut t, "6000000000000000"), "0049636C41204430");
        // 70 = t=1 -> 10 + "65 (Mot".
        assert_eq!(run(&mut s, &mut t, "7000000000000000"), "10363520284D6F74");
        // t=0 -> 00 + "us simu".
        assert_eq!(run(&mut s, &mut t, "6000000000000000"), "0075732073696D75");
        // t=1 -> 13 = t=1, n=1 (one byte unused), c=1 + "lator)".
        assert_eq!(run(&mut s, &mut t, "7000000000000000"), "136C61746F722900");
        assert!(!s.busy());
    }

    #[test]
    fn toggle_errors_and_block_transfers_abort() {
        let (mut s, mut t) = (SdoServer::new(), toy());
        run(&mut s, &mut t, "4008100000000000");
        run(&mut s, &mut t, "6000000000000000");
        // Second segment with t=0 again: abort 0x05030000 (LE 00 00 03 05) on 0x1008:00.
        assert_eq!(run(&mut s, &mut t, "6000000000000000"), "8008100000000305");
        // Segment request with no transfer: 0x05040001 (LE 01 00 04 05).
        assert_eq!(run(&mut s, &mut t, "6000000000000000"), "8000000001000405");
        // Block download initiate (ccs 6: C2 = C0 + s): 0x05040001 with index/sub echoed.
        assert_eq!(run(&mut s, &mut t, "C281600004000000"), "8081600001000405");
        // Block upload (ccs 5, A0).
        assert_eq!(run(&mut s, &mut t, "A041600000000000"), "8041600001000405");
    }

    #[test]
    fn segmented_download_checks_size_and_times_out() {
        let (mut s, mut t) = (SdoServer::new(), toy());
        // 21 = segmented download, size 4 into 0x6081.
        assert_eq!(run(&mut s, &mut t, "2181600004000000"), "6081600000000000");
        // Segment t=0, n=3 (3 unused), c=1: 0x07; data E8 03 00 00 = 1000. Reply 20 (t=0).
        assert_eq!(run(&mut s, &mut t, "07E8030000000000"), "2000000000000000");
        assert_eq!(t.0[&(0x6081, 0)].0, vec![0xE8, 3, 0, 0]);
        // Indicated size 2 for a 4-byte entry: 0x06070010 (LE 10 00 07 06).
        assert_eq!(run(&mut s, &mut t, "2181600002000000"), "8081600010000706");
        // A transfer left idle aborts with 0x05040000 (LE 00 00 04 05).
        let t0 = Instant::now();
        s.handle(&hex("2181600004000000"), t0, &mut t).unwrap();
        assert_eq!(s.poll(t0 + Duration::from_millis(500)), None);
        let out = s.poll(t0 + Duration::from_millis(1500)).unwrap();
        assert_eq!(out, [0x80, 0x81, 0x60, 0x00, 0x00, 0x00, 0x04, 0x05]);
    }
}
