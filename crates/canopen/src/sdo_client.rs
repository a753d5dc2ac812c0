//! SDO client (CiA 301 §7.2.4): one transfer as a sans-IO state machine.
//!
//! Expedited and segmented upload and download, toggle check, abort in both
//! directions and time-out. The caller feeds received frames ([`SdoTransfer::on_frame`])
//! and the current time ([`SdoTransfer::poll`]); the machine answers with the frame to
//! send next or the outcome. No threads, no clocks: `now` is always passed in.

use std::time::{Duration, Instant};

use motus_canopen_protocol::{CanFrame, SdoAbortCode, SdoPayload, SdoRequest, SdoResponse};

/// COB-ID base of client → server SDO frames (0x600 + node).
pub const SDO_REQUEST_BASE: u32 = 0x600;
/// COB-ID base of server → client SDO frames (0x580 + node).
pub const SDO_RESPONSE_BASE: u32 = 0x580;

/// Why an SDO transfer failed. Every message names the node and the object.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SdoError {
    /// The device refused the transfer with an abort frame.
    #[error("SDO abort from node {node} on 0x{index:04X}:{sub:02X}: {} (0x{:08X})", capitalised(code.description()), code.raw())]
    Aborted {
        /// Server node.
        node: u8,
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// The device's abort code.
        code: SdoAbortCode,
    },
    /// The node did not answer in time; the client sent abort 0x05040000.
    #[error("SDO time-out: node {node} did not answer on 0x{index:04X}:{sub:02X} within {timeout:?}")]
    Timeout {
        /// Server node.
        node: u8,
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// The time-out that expired.
        timeout: Duration,
    },
    /// The node answered something the protocol does not allow here; the client
    /// aborted the transfer with `code`.
    #[error("SDO protocol error with node {node} on 0x{index:04X}:{sub:02X}: {reason} (sent abort 0x{:08X})", code.raw())]
    Protocol {
        /// Server node.
        node: u8,
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// What was wrong.
        reason: String,
        /// The abort code the client sent.
        code: SdoAbortCode,
    },
    /// Our own misuse (node id out of range...), nothing was sent.
    #[error("invalid SDO request to node {node} on 0x{index:04X}:{sub:02X}: {reason}")]
    Invalid {
        /// Server node.
        node: u8,
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// What was wrong.
        reason: String,
    },
}

fn capitalised(s: &str) -> String {
    let mut c = s.chars();
    match c.next() {
        Some(first) => first.to_uppercase().chain(c).collect(),
        None => String::new(),
    }
}

/// What the caller must do after feeding the machine.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SdoStep {
    /// Nothing (the frame was not for this transfer, or the deadline is not reached).
    Wait,
    /// Send this frame and keep waiting.
    Send(CanFrame),
    /// The transfer succeeded: the uploaded data (empty for a download).
    Done(Vec<u8>),
    /// The transfer failed; send `abort` first if present.
    Failed {
        /// Abort frame to send to the server (time-out, toggle error, protocol error).
        abort: Option<CanFrame>,
        /// The error.
        error: SdoError,
    },
}

#[derive(Debug, Clone, PartialEq, Eq)]
enum State {
    /// Waiting for the initiate upload response.
    UploadInit,
    /// Waiting for an upload segment with this toggle.
    UploadSegment { toggle: bool, size: Option<u32> },
    /// Waiting for the initiate download response.
    DownloadInit { expedited: bool },
    /// Waiting for the response to the segment sent with this toggle.
    DownloadSegment { toggle: bool, last: bool },
    /// Finished (success or failure); every further input is ignored.
    Finished,
}

/// One SDO transfer (upload or download) with one server node.
#[derive(Debug, Clone)]
pub struct SdoTransfer {
    node: u8,
    index: u16,
    sub: u8,
    timeout: Duration,
    deadline: Instant,
    state: State,
    /// Download: data still to send. Upload: data received so far.
    data: Vec<u8>,
    /// Download: bytes already sent.
    sent: usize,
}

impl SdoTransfer {
    fn new(node: u8, index: u16, sub: u8, now: Instant, timeout: Duration, state: State) -> Self {
        Self { node, index, sub, timeout, deadline: now + timeout, state, data: Vec::new(), sent: 0 }
    }

    fn invalid(node: u8, index: u16, sub: u8, reason: &str) -> SdoError {
        SdoError::Invalid { node, index, sub, reason: reason.to_owned() }
    }

    /// Starts reading `index:sub` from `node`; returns the machine and the first frame.
    pub fn upload(
        node: u8,
        index: u16,
        sub: u8,
        now: Instant,
        timeout: Duration,
    ) -> Result<(Self, CanFrame), SdoError> {
        let t = Self::new(node, index, sub, now, timeout, State::UploadInit);
        let frame = t.request(&SdoRequest::InitiateUpload { index, subindex: sub })?;
        Ok((t, frame))
    }

    /// Starts writing `data` to `index:sub` of `node`: expedited for 1–4 bytes,
    /// segmented (size indicated) otherwise. Returns the machine and the first frame.
    pub fn download(
        node: u8,
        index: u16,
        sub: u8,
        data: &[u8],
        now: Instant,
        timeout: Duration,
    ) -> Result<(Self, CanFrame), SdoError> {
        let expedited = (1..=4).contains(&data.len());
        let mut t = Self::new(node, index, sub, now, timeout, State::DownloadInit { expedited });
        let payload = if expedited {
            SdoPayload::Expedited { data: data.to_vec() }
        } else {
            let size =
                u32::try_from(data.len()).map_err(|_| Self::invalid(node, index, sub, "data too long"))?;
            SdoPayload::Segmented { size: Some(size) }
        };
        t.data = data.to_vec();
        let frame = t.request(&SdoRequest::InitiateDownload { index, subindex: sub, payload })?;
        Ok((t, frame))
    }

    /// The server node.
    pub fn node(&self) -> u8 {
        self.node
    }

    /// The object (index, sub-index).
    pub fn object(&self) -> (u16, u8) {
        (self.index, self.sub)
    }

    /// When the transfer times out unless the server answers (None once finished).
    pub fn deadline(&self) -> Option<Instant> {
        (self.state != State::Finished).then_some(self.deadline)
    }

    /// Whether the transfer is over.
    pub fn is_finished(&self) -> bool {
        self.state == State::Finished
    }

    fn request(&self, req: &SdoRequest) -> Result<CanFrame, SdoError> {
        let body =
            req.encode().map_err(|e| Self::invalid(self.node, self.index, self.sub, &e.to_string()))?;
        if !(1..=127).contains(&self.node) {
            return Err(Self::invalid(self.node, self.index, self.sub, "node id outside 1..=127"));
        }
        CanFrame::new(SDO_REQUEST_BASE + u32::from(self.node), &body)
            .map_err(|e| Self::invalid(self.node, self.index, self.sub, &e.to_string()))
    }

    fn send(&mut self, req: &SdoRequest, now: Instant) -> SdoStep {
        match self.request(req) {
            Ok(frame) => {
                self.deadline = now + self.timeout;
                SdoStep::Send(frame)
            }
            Err(error) => self.fail(None, error),
        }
    }

    fn fail(&mut self, abort: Option<SdoAbortCode>, error: SdoError) -> SdoStep {
        self.state = State::Finished;
        let abort = abort.and_then(|code| {
            self.request(&SdoRequest::Abort { index: self.index, subindex: self.sub, code }).ok()
        });
        SdoStep::Failed { abort, error }
    }

    fn protocol(&mut self, code: SdoAbortCode, reason: String) -> SdoStep {
        let error = SdoError::Protocol { node: self.node, index: self.index, sub: self.sub, reason, code };
        self.fail(Some(code), error)
    }

    /// Checks the deadline: past it, the transfer fails with a time-out and an abort
    /// 0x05040000 to send to the server.
    pub fn poll(&mut self, now: Instant) -> SdoStep {
        if self.state == State::Finished || now < self.deadline {
            return SdoStep::Wait;
        }
        let error =
            SdoError::Timeout { node: self.node, index: self.index, sub: self.sub, timeout: self.timeout };
        self.fail(Some(SdoAbortCode::Timeout), error)
    }

    /// Whether `frame` is an SDO response of this transfer's node (0x580 + node, 8 bytes,
    /// decodable). A frame that fails this test must not be fed to [`Self::on_frame`].
    pub fn decode_response(node: u8, frame: &CanFrame) -> Option<SdoResponse> {
        if frame.is_extended() || frame.is_remote() || frame.id() != SDO_RESPONSE_BASE + u32::from(node) {
            return None;
        }
        SdoResponse::decode(frame.data())
    }

    /// Feeds a received frame. Frames of other COB-IDs, and SDO responses that do not
    /// decode, are ignored ([`SdoStep::Wait`]).
    pub fn on_frame(&mut self, frame: &CanFrame, now: Instant) -> SdoStep {
        if self.state == State::Finished {
            return SdoStep::Wait;
        }
        match Self::decode_response(self.node, frame) {
            Some(resp) => self.on_response(resp, now),
            None => SdoStep::Wait,
        }
    }

    /// Feeds a decoded SDO response of this node.
    pub fn on_response(&mut self, resp: SdoResponse, now: Instant) -> SdoStep {
        if let SdoResponse::Abort { index, subindex, code } = resp {
            // An abort ends the transfer whatever its object fields say.
            // (index, subindex) are those of the device's view; ours name the error.
            let _ = (index, subindex);
            self.state = State::Finished;
            return SdoStep::Failed {
                abort: None,
                error: SdoError::Aborted { node: self.node, index: self.index, sub: self.sub, code },
            };
        }
        match (self.state.clone(), resp) {
            (State::Finished, _) => SdoStep::Wait,
            (State::UploadInit, SdoResponse::InitiateUpload { index, subindex, payload }) => {
                if (index, subindex) != (self.index, self.sub) {
                    return self.wrong_object(index, subindex);
                }
                match payload {
                    SdoPayload::Expedited { data } => self.done(data),
                    SdoPayload::ExpeditedUnsized { data } => self.done(data.to_vec()),
                    SdoPayload::Segmented { size } => {
                        self.state = State::UploadSegment { toggle: false, size };
                        self.send(&SdoRequest::UploadSegment { toggle: false }, now)
                    }
                }
            }
            (State::UploadSegment { toggle, size }, SdoResponse::UploadSegment { toggle: t, last, data }) => {
                if t != toggle {
                    return self
                        .protocol(SdoAbortCode::ToggleBitNotAlternated, "toggle bit not alternated".into());
                }
                self.data.extend_from_slice(&data);
                if last {
                    if let Some(size) = size {
                        if usize::try_from(size).ok() != Some(self.data.len()) {
                            let reason =
                                format!("size {size} indicated but {} bytes received", self.data.len());
                            return self.protocol(SdoAbortCode::TypeLengthMismatch, reason);
                        }
                    }
                    let data = std::mem::take(&mut self.data);
                    return self.done(data);
                }
                self.state = State::UploadSegment { toggle: !toggle, size };
                self.send(&SdoRequest::UploadSegment { toggle: !toggle }, now)
            }
            (State::DownloadInit { expedited }, SdoResponse::InitiateDownload { index, subindex }) => {
                if (index, subindex) != (self.index, self.sub) {
                    return self.wrong_object(index, subindex);
                }
                if expedited {
                    return self.done(Vec::new());
                }
                self.next_segment(false, now)
            }
            (State::DownloadSegment { toggle, last }, SdoResponse::DownloadSegment { toggle: t }) => {
                if t != toggle {
                    return self
                        .protocol(SdoAbortCode::ToggleBitNotAlternated, "toggle bit not alternated".into());
                }
                if last {
                    return self.done(Vec::new());
                }
                self.next_segment(!toggle, now)
            }
            (_, other) => self.protocol(
                SdoAbortCode::InvalidCommandSpecifier,
                format!("unexpected response {other:?} in state {:?}", self.state),
            ),
        }
    }

    /// An initiate response naming another object: the answer to another SDO client on the
    /// same channel (a second master, a diagnostic tool). The server answers requests in
    /// order, so ours follows; it is ignored, and no abort is sent, which would break the
    /// other client's transfer. The time-out still bounds the wait.
    fn wrong_object(&mut self, index: u16, sub: u8) -> SdoStep {
        tracing::debug!(
            node = self.node,
            "SDO response for 0x{index:04X}:{sub:02X} while waiting for 0x{:04X}:{:02X}: another client on this channel; ignored",
            self.index,
            self.sub
        );
        SdoStep::Wait
    }

    fn next_segment(&mut self, toggle: bool, now: Instant) -> SdoStep {
        let rest = self.data.get(self.sent..).unwrap_or(&[]);
        let n = rest.len().min(7);
        let chunk = rest.get(..n).unwrap_or(&[]).to_vec();
        self.sent += n;
        let last = self.sent >= self.data.len();
        self.state = State::DownloadSegment { toggle, last };
        self.send(&SdoRequest::DownloadSegment { toggle, last, data: chunk }, now)
    }

    fn done(&mut self, data: Vec<u8>) -> SdoStep {
        self.state = State::Finished;
        SdoStep::Done(data)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    fn f(s: &str) -> CanFrame {
        s.parse().unwrap()
    }

    // All frames below are computed by hand from specs/canopen.md §3.3 (SDO table).

    #[test]
    fn expedited_upload() {
        let t0 = Instant::now();
        let (mut t, first) = SdoTransfer::upload(5, 0x6041, 0, t0, Duration::from_millis(500)).unwrap();
        // 0x605 = 0x600 + node 5; 40 = initiate upload; 41 60 = index 0x6041 LE; 00 = sub.
        assert_eq!(first, f("605#4041600000000000"));
        // 4B = 010 0 10 1 1: upload response, n = 2 (2 bytes unused), e = 1, s = 1; value 0x0237.
        assert_eq!(t.on_frame(&f("585#4B41600037020000"), t0), SdoStep::Done(vec![0x37, 0x02]));
        assert!(t.is_finished());
    }

    #[test]
    fn frames_of_other_nodes_are_ignored() {
        let t0 = Instant::now();
        let (mut t, _) = SdoTransfer::upload(5, 0x6041, 0, t0, Duration::from_millis(500)).unwrap();
        assert_eq!(t.on_frame(&f("586#4B41600037020000"), t0), SdoStep::Wait);
        // 7-byte frame: not an SDO response (DLC must be 8).
        assert_eq!(t.on_frame(&f("585#4B416000370200"), t0), SdoStep::Wait);
        assert!(!t.is_finished());
    }

    #[test]
    fn another_clients_answer_on_the_channel_is_ignored_without_abort() {
        let t0 = Instant::now();
        let (mut t, _) = SdoTransfer::upload(5, 0x606C, 0, t0, Duration::from_millis(500)).unwrap();
        // A second master's upload of 0x6064:00 was answered first (43 = 4 bytes, e, s).
        assert_eq!(t.on_frame(&f("585#4364600010270000"), t0), SdoStep::Wait);
        assert!(!t.is_finished());
        // Then ours: 0x606C:00 = -100 (0xFFFFFF9C).
        assert_eq!(t.on_frame(&f("585#436C60009CFFFFFF"), t0), SdoStep::Done(vec![0x9C, 0xFF, 0xFF, 0xFF]));
        // A download waits the same way past an initiate response for another object.
        let (mut d, _) =
            SdoTransfer::download(5, 0x6040, 0, &[0x0F, 0x00], t0, Duration::from_millis(500)).unwrap();
        assert_eq!(d.on_frame(&f("585#60FF600000000000"), t0), SdoStep::Wait);
        assert_eq!(d.on_frame(&f("585#6040600000000000"), t0), SdoStep::Done(Vec::new()));
    }

    #[test]
    fn segmented_upload_with_toggle() {
        let t0 = Instant::now();
        let (mut t, _) = SdoTransfer::upload(5, 0x1008, 0, t0, Duration::from_millis(500)).unwrap();
        // 41 = segmented, size indicated; size 10 (0x0A) in bytes 4-7.
        let s = t.on_frame(&f("585#410810000A000000"), t0);
        // 60 = upload segment request, toggle 0.
        assert_eq!(s, SdoStep::Send(f("605#6000000000000000")));
        // 00 = segment, t = 0, n = 0, c = 0: 7 bytes "Motus-d".
        let s = t.on_frame(&f("585#004D6F7475732D64"), t0);
        // 70 = upload segment request, toggle 1.
        assert_eq!(s, SdoStep::Send(f("605#7000000000000000")));
        // 19 = 000 1 100 1: t = 1, n = 4 (3 bytes used), c = 1: "rv\0" then padding.
        let s = t.on_frame(&f("585#1972760000000000"), t0);
        assert_eq!(s, SdoStep::Done(b"Motus-drv\0".to_vec()));
    }

    #[test]
    fn wrong_toggle_aborts_with_05030000() {
        let t0 = Instant::now();
        let (mut t, _) = SdoTransfer::upload(5, 0x1008, 0, t0, Duration::from_millis(500)).unwrap();
        t.on_frame(&f("585#4108100014000000"), t0);
        // Segment with t = 1 where 0 was expected.
        match t.on_frame(&f("585#104D6F7475732D64"), t0) {
            SdoStep::Failed { abort, error } => {
                // 80 = abort; 08 10 00 = 0x1008:00; 00 00 03 05 = 0x05030000 LE.
                assert_eq!(abort, Some(f("605#8008100000000305")));
                assert!(matches!(
                    error,
                    SdoError::Protocol { code: SdoAbortCode::ToggleBitNotAlternated, .. }
                ));
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn expedited_download() {
        let t0 = Instant::now();
        let (mut t, first) =
            SdoTransfer::download(5, 0x6040, 0, &[0x0F, 0x00], t0, Duration::from_secs(1)).unwrap();
        // 2B = 001 0 10 1 1: download, n = 2, e = 1, s = 1; data 0F 00.
        assert_eq!(first, f("605#2B4060000F000000"));
        // 60 = initiate download response.
        assert_eq!(t.on_frame(&f("585#6040600000000000"), t0), SdoStep::Done(vec![]));
    }

    #[test]
    fn segmented_download() {
        let t0 = Instant::now();
        let data = b"ABCDEFGHIJ"; // 10 bytes: segments of 7 and 3.
        let (mut t, first) = SdoTransfer::download(5, 0x2000, 1, data, t0, Duration::from_secs(1)).unwrap();
        // 21 = download, segmented, size indicated; 00 20 = 0x2000; 01 = sub; size 10.
        assert_eq!(first, f("605#210020010A000000"));
        // Response 60 -> first segment 00 (t=0, n=0, c=0) "ABCDEFG".
        let s = t.on_frame(&f("585#6000200100000000"), t0);
        assert_eq!(s, SdoStep::Send(f("605#0041424344454647")));
        // Segment response 20 (t = 0) -> last segment 19 = 000 1 100 1 (t=1, n=4, c=1) "HIJ".
        let s = t.on_frame(&f("585#2000000000000000"), t0);
        assert_eq!(s, SdoStep::Send(f("605#1948494A00000000")));
        // 30 = segment response t = 1.
        assert_eq!(t.on_frame(&f("585#3000000000000000"), t0), SdoStep::Done(vec![]));
    }

    #[test]
    fn device_abort_names_the_code() {
        let t0 = Instant::now();
        let (mut t, _) = SdoTransfer::upload(5, 0x6041, 0, t0, Duration::from_secs(1)).unwrap();
        // 80 41 60 00 + 0x06020000 LE = 00 00 02 06.
        match t.on_frame(&f("585#8041600000000206"), t0) {
            SdoStep::Failed { abort: None, error } => assert_eq!(
                error.to_string(),
                "SDO abort from node 5 on 0x6041:00: Object does not exist in the object dictionary (0x06020000)"
            ),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn timeout_sends_abort_05040000() {
        let t0 = Instant::now();
        let (mut t, _) = SdoTransfer::upload(5, 0x6041, 0, t0, Duration::from_millis(100)).unwrap();
        assert_eq!(t.poll(t0 + Duration::from_millis(99)), SdoStep::Wait);
        match t.poll(t0 + Duration::from_millis(100)) {
            // 0x05040000 LE = 00 00 04 05.
            SdoStep::Failed { abort, error } => {
                assert_eq!(abort, Some(f("605#8041600000000405")));
                assert!(matches!(error, SdoError::Timeout { node: 5, index: 0x6041, sub: 0, .. }));
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(t.poll(t0 + Duration::from_secs(9)), SdoStep::Wait);
    }

    #[test]
    fn unexpected_command_is_a_protocol_error() {
        let t0 = Instant::now();
        let (mut t, _) = SdoTransfer::upload(5, 0x6041, 0, t0, Duration::from_secs(1)).unwrap();
        // A download response while uploading: abort 0x05040001 (00 01 04 05 LE... = 01 00 04 05).
        match t.on_frame(&f("585#6041600000000000"), t0) {
            SdoStep::Failed { abort, .. } => assert_eq!(abort, Some(f("605#8041600001000405"))),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn segmented_upload_size_mismatch_is_detected() {
        let t0 = Instant::now();
        let (mut t, _) = SdoTransfer::upload(5, 0x1008, 0, t0, Duration::from_secs(1)).unwrap();
        t.on_frame(&f("585#4108100009000000"), t0); // size 9
                                                    // Last segment with 7 bytes (c = 1, n = 0): 7 != 9.
        assert!(matches!(t.on_frame(&f("585#0141424344454647"), t0), SdoStep::Failed { .. }));
    }
}
