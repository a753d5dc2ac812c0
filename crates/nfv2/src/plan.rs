//! The wire budget of one scheduler cycle, computed before the first byte is sent
//! (sans-IO): every slave's request and answer sizes, their wire time at the baud rate,
//! the slave's turnaround, the minimum cycle the line allows, and whether the requested
//! cycle is physically possible.
//!
//! The minimum cycle is the sum over slaves and exchanges of
//! `wire(request) + turnaround + wire(answer)` (no turnaround for a frame without answer).
//! The source's "2 ms communication cycle" is impossible on RS-485 at 57600 Bd: one
//! 7-byte query plus its 11-byte answer already take 3.1 ms of wire time
//! (`two_ms_is_impossible_at_57600` below).

use std::fmt;
use std::time::Duration;

use motus_nfv2_protocol::{wire_time, DeviceProfile, EncodeError, Frame, Revision};

/// How the due commands and queries of a slave are put into frames.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Packing {
    /// One frame per slave per cycle carrying everything due (the NFv2 way).
    #[default]
    Packed,
    /// One command or query per frame (for comparison: more headers, more turnarounds,
    /// and set-point frames without an answer).
    Unpacked,
}

impl fmt::Display for Packing {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Packing::Packed => "packed",
            Packing::Unpacked => "unpacked",
        })
    }
}

/// One frame exchange of a cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ExchangeBudget {
    /// Request bytes.
    pub request: usize,
    /// Answer bytes, `None` if the slave does not answer the frame.
    pub answer: Option<usize>,
    /// Wire time of request and answer plus the turnaround (if answered).
    pub time: Duration,
}

/// The exchanges of one slave in one cycle.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SlaveBudget {
    /// Slave address.
    pub address: u8,
    /// Its exchanges, in order.
    pub exchanges: Vec<ExchangeBudget>,
    /// Their total time on the line.
    pub time: Duration,
}

/// The wire budget of one cycle.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CyclePlan {
    /// The cycle asked for.
    pub requested: Duration,
    /// Line speed, bits per second (8N1).
    pub baud: u32,
    /// Time between the end of a request and the start of its answer (slave processing
    /// and line turnaround).
    pub turnaround: Duration,
    /// How frames are packed.
    pub packing: Packing,
    /// Per-slave budget, in cycle order.
    pub slaves: Vec<SlaveBudget>,
    /// The shortest cycle the line allows for these frames.
    pub min_cycle: Duration,
    /// `requested >= min_cycle`.
    pub feasible: bool,
}

/// Splits `frame` into one frame per command (the unpacked mode).
#[must_use]
pub fn unpack(frame: &Frame) -> Vec<Frame> {
    frame.commands.iter().map(|c| Frame { address: frame.address, commands: vec![c.clone()] }).collect()
}

impl CyclePlan {
    /// The budget of sending, each cycle, `frames` (one per slave, with its revision) as
    /// `packing` says, answered as `profile` says.
    ///
    /// # Errors
    /// [`EncodeError`] if a frame cannot be encoded in its revision.
    pub fn new(
        requested: Duration,
        baud: u32,
        turnaround: Duration,
        packing: Packing,
        frames: &[(Frame, Revision)],
        profile: &DeviceProfile,
    ) -> Result<CyclePlan, EncodeError> {
        let mut slaves = Vec::with_capacity(frames.len());
        for (frame, rev) in frames {
            let parts = match packing {
                Packing::Packed => vec![frame.clone()],
                Packing::Unpacked => unpack(frame),
            };
            let mut exchanges = Vec::with_capacity(parts.len());
            for part in &parts {
                let request = part.encoded_len(*rev)?;
                let answer = profile.answer_len(part, *rev);
                let time = wire_time(request + answer.unwrap_or(0), baud)
                    + if answer.is_some() { turnaround } else { Duration::ZERO };
                exchanges.push(ExchangeBudget { request, answer, time });
            }
            let time = exchanges.iter().map(|e| e.time).sum();
            slaves.push(SlaveBudget { address: frame.address, exchanges, time });
        }
        let min_cycle = slaves.iter().map(|s| s.time).sum();
        Ok(CyclePlan {
            requested,
            baud,
            turnaround,
            packing,
            slaves,
            min_cycle,
            feasible: requested >= min_cycle,
        })
    }

    /// The cycle the scheduler runs: the requested one, or the minimum if that is longer.
    #[must_use]
    pub fn effective_cycle(&self) -> Duration {
        self.requested.max(self.min_cycle)
    }

    /// Fraction of the effective cycle the line is busy (1.0: no idle time left).
    #[must_use]
    pub fn utilisation(&self) -> f64 {
        let cycle = self.effective_cycle().as_secs_f64();
        if cycle > 0.0 {
            self.min_cycle.as_secs_f64() / cycle
        } else {
            0.0
        }
    }

    /// Request plus answer bytes per cycle.
    #[must_use]
    pub fn bytes_per_cycle(&self) -> usize {
        self.slaves.iter().flat_map(|s| &s.exchanges).map(|e| e.request + e.answer.unwrap_or(0)).sum()
    }

    /// The warning to give when the requested cycle is physically impossible.
    #[must_use]
    pub fn warning(&self) -> Option<String> {
        (!self.feasible).then(|| {
            format!(
                "requested NFv2 cycle of {:.3} ms is physically impossible at {} Bd: {} slave(s), {} bytes per cycle \
                 ({}) need at least {:.3} ms of wire time and turnaround; running at {:.3} ms instead",
                ms(self.requested),
                self.baud,
                self.slaves.len(),
                self.bytes_per_cycle(),
                self.packing,
                ms(self.min_cycle),
                ms(self.effective_cycle()),
            )
        })
    }
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1000.0
}

impl fmt::Display for CyclePlan {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} cycle: requested {:.3} ms, minimum {:.3} ms at {} Bd ({} bytes, turnaround {:.3} ms), {}",
            self.packing,
            ms(self.requested),
            ms(self.min_cycle),
            self.baud,
            self.bytes_per_cycle(),
            ms(self.turnaround),
            if self.feasible { "feasible" } else { "IMPOSSIBLE" }
        )?;
        for s in &self.slaves {
            write!(f, "; slave {}: {:.3} ms", s.address, ms(s.time))?;
            for e in &s.exchanges {
                match e.answer {
                    Some(a) => write!(f, " [{}+{} B]", e.request, a)?,
                    None => write!(f, " [{} B, no answer]", e.request)?,
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;
    use motus_nfv2_protocol::{Command, CommandCode as C, RS485_BAUD};

    fn query_position(address: u8) -> Frame {
        Frame { address, commands: vec![Command::query(C::ReadDrivesPosition)] }
    }

    #[test]
    fn two_ms_is_impossible_at_57600() {
        // specs/nfv2.md: a 7-byte query plus its 11-byte answer take 3.1 ms at 57600 Bd.
        let frames = [(query_position(1), Revision::LATEST)];
        let p = CyclePlan::new(
            Duration::from_millis(2),
            RS485_BAUD,
            Duration::ZERO,
            Packing::Packed,
            &frames,
            &DeviceProfile::axis_1209a(),
        )
        .unwrap();
        assert_eq!(p.slaves[0].exchanges[0].request, 7);
        assert_eq!(p.slaves[0].exchanges[0].answer, Some(11));
        assert_eq!(p.min_cycle.as_micros(), 3125); // 18 bytes x 10 bits / 57600
        assert!(!p.feasible);
        assert_eq!(p.effective_cycle(), p.min_cycle);
        let w = p.warning().unwrap();
        assert!(w.contains("physically impossible") && w.contains("3.125 ms"), "{w}");
    }

    #[test]
    fn packing_saves_headers_and_turnarounds() {
        // Per slave: position set-point (6 B) + position and status queries (2 B each).
        let frame = |address| Frame {
            address,
            commands: vec![
                Command::values(C::SetDrivesPosition, [1000]),
                Command::query(C::ReadDrivesPosition),
                Command::query(C::ReadDrivesStatus),
            ],
        };
        let frames = [(frame(1), Revision::LATEST), (frame(2), Revision::LATEST)];
        let turnaround = Duration::from_micros(200);
        let profile = DeviceProfile::axis_1209a();
        let packed = CyclePlan::new(
            Duration::from_millis(12),
            RS485_BAUD,
            turnaround,
            Packing::Packed,
            &frames,
            &profile,
        )
        .unwrap();
        // Request 5 + 6 + 2 + 2 = 15 B; answer 5 + 6 + 4 = 15 B; 30 B = 5.208 ms + 0.2 ms.
        assert_eq!(
            (packed.slaves[0].exchanges[0].request, packed.slaves[0].exchanges[0].answer),
            (15, Some(15))
        );
        assert_eq!(packed.min_cycle.as_micros(), 2 * (5208 + 200));
        assert!(packed.feasible);
        let unpacked = CyclePlan::new(
            Duration::from_millis(12),
            RS485_BAUD,
            turnaround,
            Packing::Unpacked,
            &frames,
            &profile,
        )
        .unwrap();
        // 11 B set-point without answer, 7 + 11 B position, 7 + 9 B status, two turnarounds.
        let e = &unpacked.slaves[0].exchanges;
        assert_eq!((e[0].request, e[0].answer), (11, None));
        assert_eq!((e[1].request, e[1].answer), (7, Some(11)));
        assert_eq!((e[2].request, e[2].answer), (7, Some(9)));
        assert_eq!(unpacked.bytes_per_cycle(), 2 * 45);
        assert!(!unpacked.feasible, "{unpacked}");
        assert!(unpacked.min_cycle > packed.min_cycle);
    }
}
