//! The buffer shared by the streaming decoders: bytes pushed in arbitrary chunks, a read
//! position, and totals.

use serde::{Deserialize, Serialize};

/// Running totals of a streaming decoder since it was created.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct StreamStats {
    /// Packets decoded.
    pub packets: u64,
    /// Bytes skipped as garbage (outside any packet, or the first byte of a rejected
    /// candidate).
    pub garbage_bytes: u64,
}

/// Bytes received and not yet resolved. `pos` is the first unresolved byte.
#[derive(Debug, Clone, Default)]
pub(crate) struct ScanBuffer {
    buf: Vec<u8>,
    pos: usize,
    pub(crate) stats: StreamStats,
}

impl ScanBuffer {
    /// Appends received bytes.
    pub(crate) fn extend(&mut self, bytes: &[u8]) {
        self.buf.extend_from_slice(bytes);
    }

    /// The unresolved bytes.
    pub(crate) fn rest(&self) -> &[u8] {
        self.buf.get(self.pos..).unwrap_or_default()
    }

    /// Skips `n` bytes as garbage.
    pub(crate) fn skip_garbage(&mut self, n: usize) {
        let n = n.min(self.rest().len());
        self.pos += n;
        self.stats.garbage_bytes += n as u64;
    }

    /// Consumes one packet of `n` bytes.
    pub(crate) fn take_packet(&mut self, n: usize) {
        self.pos += n.min(self.rest().len());
        self.stats.packets += 1;
    }

    /// Drops the resolved bytes (call after a push).
    pub(crate) fn compact(&mut self) {
        if self.pos > 0 {
            self.buf.drain(..self.pos.min(self.buf.len()));
            self.pos = 0;
        }
    }

    /// Unresolved bytes kept for the next push.
    pub(crate) fn pending(&self) -> usize {
        self.rest().len()
    }

    /// Forgets the unresolved bytes, counting them as garbage.
    pub(crate) fn flush(&mut self) {
        let n = self.pending();
        self.skip_garbage(n);
        self.compact();
    }
}
