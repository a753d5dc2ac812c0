//! Properties: any frame (any codes, values and counts) is handled without panicking and
//! answered exactly as the codec's `DeviceProfile::axis_1209a` predicts; the controller
//! never drives beyond its current limit; a run is a function of the frames and the seed.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_nfv2_protocol::{Command, CommandCode, DeviceProfile, Frame, Regulator, Revision};
use motus_nfv2_sim::{Controller, ControllerConfig};
use proptest::prelude::*;
use std::time::Duration;

fn command() -> impl Strategy<Value = Command> {
    let code = prop_oneof![
        proptest::sample::select(CommandCode::ALL.to_vec()),
        any::<u8>().prop_map(CommandCode::from_u8),
    ];
    (code, prop::collection::vec(any::<i32>(), 0..3), any::<[u16; 4]>()).prop_map(|(code, values, r)| {
        match Revision::LATEST.value_kind(code) {
            None => Command::Unknown { code: code.to_u8(), raw: values.iter().map(|&v| v as u8).collect() },
            Some(kind) => match kind.range() {
                None => Command::regulators(code, [Regulator { p: r[0], i: r[1], d: r[2], t: r[3] }]),
                Some((lo, hi)) => Command::values(
                    code,
                    values.into_iter().map(|v| i64::from(v).clamp(lo, hi)).collect::<Vec<_>>(),
                ),
            },
        }
    })
}

fn frames() -> impl Strategy<Value = Vec<(u8, Vec<Command>, u16)>> {
    prop::collection::vec((0u8..4, prop::collection::vec(command(), 0..6), 0u16..200), 1..12)
}

fn play(frames: &[(u8, Vec<Command>, u16)], seed: u64) -> (Vec<Option<Frame>>, f64) {
    let mut c = Controller::new(1, &ControllerConfig::default().seeded(seed)).unwrap();
    let mut now = Duration::ZERO;
    let profile = DeviceProfile::axis_1209a();
    let mut answers = Vec::new();
    for (address, commands, wait_ms) in frames {
        let request = Frame { address: *address, commands: commands.clone() };
        let answer = c.handle(&request, now);
        let predicted = if *address == 1 { profile.answer_len(&request, Revision::LATEST) } else { None };
        assert_eq!(answer.as_ref().map(|a| a.encode(Revision::LATEST).unwrap().len()), predicted);
        // Limits hold whatever the host sent (with the hardware 13 A cap and the limiter).
        now += Duration::from_millis(u64::from(*wait_ms));
        for _ in 0..*wait_ms {
            c.advance_to(c.now() + Duration::from_millis(1));
            assert!(c.true_state().current_a.abs() <= 20.0 + 1e-9);
        }
        answers.push(answer);
    }
    (answers, c.true_state().position_counts)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    #[test]
    fn any_frames_are_handled_as_predicted_and_deterministically(frames in frames(), seed in any::<u64>()) {
        let first = play(&frames, seed);
        let second = play(&frames, seed);
        prop_assert_eq!(first, second);
    }
}
