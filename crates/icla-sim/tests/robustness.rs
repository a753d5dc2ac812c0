//! Arbitrary frames never make a drive panic, and it keeps answering afterwards.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use std::time::{Duration, Instant};

use motus_canopen_protocol::CanFrame;
use motus_icla_sim::{SimConfig, SimDrive};
use proptest::prelude::*;

fn frame() -> impl Strategy<Value = CanFrame> {
    // Ids near the drive's COB-IDs (node 2), NMT, SYNC and LSS, plus any id.
    let id = prop_oneof![
        Just(0x000u32),
        Just(0x080),
        Just(0x202),
        Just(0x302),
        Just(0x602),
        Just(0x7E5),
        0u32..0x800,
    ];
    (id, proptest::collection::vec(any::<u8>(), 0..=8)).prop_map(|(id, d)| CanFrame::new(id, &d).unwrap())
}

proptest! {
    #[test]
    fn arbitrary_frames_do_not_break_the_drive(frames in proptest::collection::vec(frame(), 1..60)) {
        let t0 = Instant::now();
        let mut d = SimDrive::new(SimConfig::node(2));
        d.poll(t0);
        let mut now = t0;
        for f in &frames {
            now += Duration::from_millis(3);
            for out in d.handle(f, now).into_iter().chain(d.poll(now)) {
                prop_assert!(out.dlc() <= 8);
            }
        }
        // Whatever happened (even an LSS id change or NMT stop), a reset node via NMT to all
        // nodes brings back a drive that answers SDO on its (possibly new) id.
        // (Past any LSS bit-timing switch silence, at most 2 x 65.535 s.)
        now += Duration::from_secs(132);
        let reset = d.handle(&"000#8100".parse().unwrap(), now);
        if let Some(id) = d.node_id() {
            prop_assert!(reset.iter().any(|f| f.id() == 0x700 + u32::from(id)));
            let req: CanFrame = format!("{:03X}#4000100000000000", 0x600 + u32::from(id)).parse().unwrap();
            let out = d.handle(&req, now);
            prop_assert_eq!(out.len(), 1);
        }
    }
}
