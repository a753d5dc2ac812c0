//! LSS slave (CiA 305, specs/canopen.md part 4; behaviour after CANopenNode's
//! CO_LSSslave.c): waiting / configuration states, switch global and selective, configure
//! node-id (pending until the next reset communication) and bit timing, activate bit timing
//! (switch delay, then silence for another delay), store configuration (kept in memory so a
//! reset node keeps it), inquire identity and node-id, identify remote slave, identify
//! non-configured slave and fastscan.

use std::time::{Duration, Instant};

use motus_canopen_protocol::{LssIdentityField, LssRequest, LssResponse};

use crate::config::{bitrate_of_index, Identity, UNCONFIGURED};

/// What the node must do after an LSS request.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LssEvent {
    /// Nothing more.
    None,
    /// Left configuration after an unconfigured node got an id: NMT reset communication.
    ResetCommunication,
}

/// LSS slave state of one node.
#[derive(Debug, Clone)]
pub struct LssSlave {
    configuration: bool,
    active_id: u8,
    pending_id: u8,
    stored_id: u8,
    active_bit_timing: u8,
    pending_bit_timing: u8,
    stored_bit_timing: u8,
    selective_step: u8,
    identify_step: u8,
    fastscan_pos: u8,
    switch_at: Option<(Instant, u8)>,
    mute_until: Option<Instant>,
}

fn field_index(f: LssIdentityField) -> u8 {
    match f {
        LssIdentityField::Vendor => 0,
        LssIdentityField::Product => 1,
        LssIdentityField::Revision => 2,
        LssIdentityField::Serial => 3,
    }
}

impl LssSlave {
    /// A slave powered on with this stored node id (0xFF = unconfigured) and bit timing.
    pub fn new(node_id: u8, bit_timing: u8) -> Self {
        Self {
            configuration: false,
            active_id: node_id,
            pending_id: node_id,
            stored_id: node_id,
            active_bit_timing: bit_timing,
            pending_bit_timing: bit_timing,
            stored_bit_timing: bit_timing,
            selective_step: 0,
            identify_step: 0,
            fastscan_pos: 0,
            switch_at: None,
            mute_until: None,
        }
    }

    /// The node id in use (0xFF = unconfigured).
    pub fn active_id(&self) -> u8 {
        self.active_id
    }

    /// The node id that the next reset communication activates.
    pub fn pending_id(&self) -> u8 {
        self.pending_id
    }

    /// Whether the slave is in the configuration state.
    pub fn in_configuration(&self) -> bool {
        self.configuration
    }

    /// The active bit rate in bit/s.
    pub fn bitrate(&self) -> u32 {
        bitrate_of_index(self.active_bit_timing).unwrap_or(0)
    }

    /// The stored (node id, bit-timing index).
    pub fn stored(&self) -> (u8, u8) {
        (self.stored_id, self.stored_bit_timing)
    }

    /// NMT reset communication: the pending node id becomes active.
    pub fn reset_communication(&mut self) {
        self.active_id = self.pending_id;
    }

    /// Reset node / power cycle: the stored values come back (then reset communication).
    pub fn reset_node(&mut self) {
        self.pending_id = self.stored_id;
        self.pending_bit_timing = self.stored_bit_timing;
        self.configuration = false;
    }

    /// Advances the bit-timing switch; true while the node must stay silent.
    pub fn muted(&mut self, now: Instant) -> bool {
        if let Some((at, index)) = self.switch_at {
            if now >= at {
                self.active_bit_timing = index;
                self.switch_at = None;
            }
        }
        self.mute_until.is_some_and(|t| now < t)
    }

    fn unconfigured(&self) -> bool {
        self.active_id == UNCONFIGURED && self.pending_id == UNCONFIGURED
    }

    /// Handles one request; returns the response (if any) and what the node must do.
    pub fn handle(
        &mut self,
        req: &LssRequest,
        id: &Identity,
        now: Instant,
    ) -> (Option<LssResponse>, LssEvent) {
        let part = |f: LssIdentityField| id.part(field_index(f)).unwrap_or(0);
        match *req {
            LssRequest::SwitchStateGlobal { configuration } => {
                let leaving = self.configuration && !configuration;
                self.configuration = configuration;
                self.selective_step = 0;
                if leaving && self.active_id == UNCONFIGURED && self.pending_id != UNCONFIGURED {
                    return (None, LssEvent::ResetCommunication);
                }
            }
            LssRequest::SwitchStateSelective { field, value } if !self.configuration => {
                let step = field_index(field);
                self.selective_step =
                    if step == self.selective_step && value == part(field) { step + 1 } else { 0 };
                if self.selective_step == 4 {
                    self.selective_step = 0;
                    self.configuration = true;
                    return (Some(LssResponse::SwitchStateSelective), LssEvent::None);
                }
            }
            LssRequest::ConfigureNodeId { node_id } if self.configuration => {
                let ok = (1..=127).contains(&node_id) || node_id == UNCONFIGURED;
                if ok {
                    self.pending_id = node_id;
                }
                return (
                    Some(LssResponse::ConfigureNodeId { error: u8::from(!ok), spec_error: 0 }),
                    LssEvent::None,
                );
            }
            LssRequest::ConfigureBitTiming { table, index } if self.configuration => {
                let ok = table == 0 && bitrate_of_index(index).is_some();
                if ok {
                    self.pending_bit_timing = index;
                }
                return (
                    Some(LssResponse::ConfigureBitTiming { error: u8::from(!ok), spec_error: 0 }),
                    LssEvent::None,
                );
            }
            LssRequest::ActivateBitTiming { delay_ms } if self.configuration => {
                let delay = Duration::from_millis(u64::from(delay_ms));
                self.switch_at = Some((now + delay, self.pending_bit_timing));
                self.mute_until = Some(now + 2 * delay);
            }
            LssRequest::StoreConfiguration if self.configuration => {
                self.stored_id = self.pending_id;
                self.stored_bit_timing = self.pending_bit_timing;
                return (Some(LssResponse::StoreConfiguration { error: 0, spec_error: 0 }), LssEvent::None);
            }
            LssRequest::InquireIdentity { field } if self.configuration => {
                return (Some(LssResponse::InquireIdentity { field, value: part(field) }), LssEvent::None);
            }
            LssRequest::InquireNodeId if self.configuration => {
                return (Some(LssResponse::InquireNodeId { node_id: self.active_id }), LssEvent::None);
            }
            LssRequest::IdentifyRemoteSlave { selector, value } => {
                let ok = match selector {
                    0 => value == id.vendor,
                    1 => value == id.product,
                    2 => id.revision >= value,
                    3 => id.revision <= value,
                    4 => id.serial >= value,
                    _ => id.serial <= value,
                };
                let step_ok = selector == 0 || self.identify_step == selector;
                self.identify_step = if ok && step_ok { selector + 1 } else { 0 };
                if self.identify_step == 6 {
                    self.identify_step = 0;
                    return (Some(LssResponse::IdentifySlave), LssEvent::None);
                }
            }
            LssRequest::IdentifyNonConfigured if self.unconfigured() => {
                return (Some(LssResponse::IdentifyNonConfiguredSlave), LssEvent::None);
            }
            LssRequest::Fastscan { id_number, bit_check, lss_sub, lss_next }
                if !self.configuration && self.unconfigured() =>
            {
                return (self.fastscan(id, id_number, bit_check, lss_sub, lss_next), LssEvent::None);
            }
            _ => {}
        }
        (None, LssEvent::None)
    }

    fn fastscan(
        &mut self,
        id: &Identity,
        id_number: u32,
        bit_check: u8,
        lss_sub: u8,
        lss_next: u8,
    ) -> Option<LssResponse> {
        if bit_check == 0x80 {
            self.fastscan_pos = 0;
            return Some(LssResponse::IdentifySlave);
        }
        if bit_check > 31 || lss_sub > 3 || lss_next > 3 || lss_sub != self.fastscan_pos {
            return None;
        }
        let mask = u32::MAX.checked_shl(u32::from(bit_check)).unwrap_or(0);
        if (id_number ^ id.part(lss_sub)?) & mask != 0 {
            return None;
        }
        // CANopenNode: every match moves the scan to LSSNext; BitCheck 0 with LSSNext below
        // LSSSub completes the address and enters configuration.
        self.fastscan_pos = lss_next;
        if bit_check == 0 && lss_next < lss_sub {
            self.configuration = true;
            self.fastscan_pos = 0;
        }
        Some(LssResponse::IdentifySlave)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;
    use motus_canopen_protocol::CanFrame;

    fn req(hex: &str) -> LssRequest {
        let f: CanFrame = format!("7E5#{hex}").parse().unwrap();
        LssRequest::decode(f.data()).unwrap()
    }

    fn resp(r: Option<LssResponse>) -> String {
        r.map(|r| r.encode().iter().map(|b| format!("{b:02X}")).collect()).unwrap_or_default()
    }

    #[test]
    fn seed_set_node_id_sequence() {
        // specs/canopen.md "Seed 000's LSS usage": 04 01, 11 02, 17 -> 17 00 00, 04 00.
        let (t, id) = (Instant::now(), Identity::icla(1));
        let mut s = LssSlave::new(127, 7);
        assert_eq!(s.handle(&req("0401000000000000"), &id, t), (None, LssEvent::None));
        let (r, _) = s.handle(&req("1102000000000000"), &id, t);
        // 11 = configure node-ID response, 00 = no error.
        assert_eq!(resp(r), "1100000000000000");
        assert_eq!((s.active_id(), s.pending_id()), (127, 2));
        let (r, _) = s.handle(&req("1700000000000000"), &id, t);
        assert_eq!(resp(r), "1700000000000000");
        // 127 was configured, so leaving configuration does not reset by itself: the new id
        // waits for the next reset communication (the seed then power-cycles / resets).
        assert_eq!(s.handle(&req("0400000000000000"), &id, t), (None, LssEvent::None));
        s.reset_node();
        s.reset_communication();
        assert_eq!(s.active_id(), 2, "stored id survives a reset node");
    }

    #[test]
    fn seed_bit_rate_sequence() {
        // 04 01, 13 00 07 -> 13 00 00, 17 -> 17 00 00, 15 E8 03 (1000 ms), 04 00.
        let (t, id) = (Instant::now(), Identity::icla(1));
        let mut s = LssSlave::new(2, 4);
        s.handle(&req("0401000000000000"), &id, t);
        assert_eq!(resp(s.handle(&req("1300070000000000"), &id, t).0), "1300000000000000");
        assert_eq!(resp(s.handle(&req("1700000000000000"), &id, t).0), "1700000000000000");
        assert_eq!(s.handle(&req("15E8030000000000"), &id, t).0, None);
        assert_eq!(s.bitrate(), 125_000);
        assert!(s.muted(t + Duration::from_millis(999)));
        assert!(s.muted(t + Duration::from_millis(1500)));
        assert_eq!(s.bitrate(), 20_000, "switched after the delay");
        assert!(!s.muted(t + Duration::from_millis(2000)), "silent for a second delay only");
        s.handle(&req("0400000000000000"), &id, t);
        // Reserved index 5 and automatic (9) are refused: 13 01.
        s.handle(&req("0401000000000000"), &id, t);
        assert_eq!(resp(s.handle(&req("1300050000000000"), &id, t).0), "1301000000000000");
        assert_eq!(resp(s.handle(&req("1300090000000000"), &id, t).0), "1301000000000000");
        // Node id 0 and 128 are out of range: 11 01.
        assert_eq!(resp(s.handle(&req("1100000000000000"), &id, t).0), "1101000000000000");
        assert_eq!(resp(s.handle(&req("1180000000000000"), &id, t).0), "1101000000000000");
    }

    #[test]
    fn unconfigured_node_resets_when_leaving_configuration() {
        let (t, id) = (Instant::now(), Identity::icla(7));
        let mut s = LssSlave::new(UNCONFIGURED, 7);
        assert_eq!(resp(s.handle(&req("4C00000000000000"), &id, t).0), "5000000000000000");
        s.handle(&req("0401000000000000"), &id, t);
        // Inquire node-ID: 5E FF (unconfigured).
        assert_eq!(resp(s.handle(&req("5E00000000000000"), &id, t).0), "5EFF000000000000");
        s.handle(&req("1103000000000000"), &id, t);
        assert_eq!(s.handle(&req("0400000000000000"), &id, t), (None, LssEvent::ResetCommunication));
    }

    #[test]
    fn selective_inquire_and_identify() {
        let (t, id) = (Instant::now(), Identity::icla(0x0000_0102));
        let mut s = LssSlave::new(3, 7);
        // 40 vendor 5A 00 00 08, 41 product 65, 42 revision 00 00 01 00, 43 serial 02 01.
        assert_eq!(s.handle(&req("405A000008000000"), &id, t).0, None);
        s.handle(&req("4165000000000000"), &id, t);
        s.handle(&req("4200000100000000"), &id, t);
        assert_eq!(resp(s.handle(&req("4302010000000000"), &id, t).0), "4400000000000000");
        assert!(s.in_configuration());
        // Inquire serial: 5D + 02 01 00 00.
        assert_eq!(resp(s.handle(&req("5D00000000000000"), &id, t).0), "5D02010000000000");
        assert_eq!(resp(s.handle(&req("5A00000000000000"), &id, t).0), "5A5A000008000000");
        s.handle(&req("0400000000000000"), &id, t);
        // A wrong serial does not select.
        for r in ["405A000008000000", "4165000000000000", "4200000100000000"] {
            s.handle(&req(r), &id, t);
        }
        assert_eq!(s.handle(&req("4303010000000000"), &id, t).0, None);
        // Identify remote slave: vendor, product, revision 0..0xFFFFFFFF, serial 0x100..0x200.
        for r in [
            "465A000008000000",
            "4765000000000000",
            "4800000000000000",
            "49FFFFFFFF000000",
            "4A00010000000000",
        ] {
            assert_eq!(s.handle(&req(r), &id, t).0, None);
        }
        assert_eq!(resp(s.handle(&req("4B00020000000000"), &id, t).0), "4F00000000000000");
        // A configured node does not answer identify non-configured.
        assert_eq!(s.handle(&req("4C00000000000000"), &id, t).0, None);
    }

    #[test]
    fn fastscan_finds_the_address_bit_by_bit() {
        let (t, id) = (Instant::now(), Identity::icla(0x0000_0003));
        let mut s = LssSlave::new(UNCONFIGURED, 7);
        let mut scan = |idn: u32, bit: u8, sub: u8, next: u8| {
            let r = LssRequest::Fastscan { id_number: idn, bit_check: bit, lss_sub: sub, lss_next: next };
            s.handle(&r, &id, t).0.is_some()
        };
        assert!(scan(0, 0x80, 0, 0));
        // The master's algorithm (python-canopen LssMaster.fast_scan).
        let mut found = [0u32; 4];
        let mut next = 0;
        for sub in 0..4u8 {
            for bit in (0..32u8).rev() {
                if !scan(found[usize::from(sub)], bit, sub, next) {
                    found[usize::from(sub)] |= 1 << bit;
                }
            }
            next = (sub + 1) & 3;
            assert!(scan(found[usize::from(sub)], 0, sub, next));
        }
        assert_eq!(found, [id.vendor, id.product, id.revision, id.serial]);
        assert!(s.in_configuration());
    }
}
