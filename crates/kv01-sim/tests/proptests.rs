//! Property tests: any sequence of requests at any times never panics the model, joints stay
//! within their end stops, replies always come from the addressed module and encode, and a
//! tripped safety time-out stays latched.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_kv01_protocol::{Address, Command, Message, ReplyBody, Request, ShortCode};
use motus_kv01_sim::{Arm, ArmConfig};
use proptest::prelude::*;
use std::time::Duration;

fn command() -> impl Strategy<Value = Command> {
    let text = prop_oneof![
        Just("EN".to_owned()),
        Just("DI".to_owned()),
        Just("DIPROG".to_owned()),
        Just("ENPROG".to_owned()),
        Just("M".to_owned()),
        Just("HO".to_owned()),
        (-6000i32..6000).prop_map(|v| format!("V{v}")),
        (-100_000i32..100_000).prop_map(|v| format!("LA{v}")),
        Just("POS".to_owned()),
        Just("GST".to_owned()),
        "[ -~]{0,12}",
    ];
    prop_oneof![
        text.clone().prop_map(|text| Command::Faulhaber { text }),
        text.prop_map(|text| Command::Fast { text }),
        any::<u8>().prop_map(|b| Command::from_wire(0xD1, &[b])),
        Just(Command::ReadResolver),
        Just(Command::ReadVoltages),
        (0u8..32, any::<bool>()).prop_map(|(speed, opening)| Command::Gripper { speed, opening }),
        (any::<u8>(), proptest::collection::vec(any::<u8>(), 0..4))
            .prop_map(|(code, data)| Command::from_wire(code, &data)),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    #[test]
    fn any_traffic_keeps_the_model_sane(
        steps in proptest::collection::vec((1u8..=6, command(), 0u64..900), 1..60),
        pushes in proptest::collection::vec((1u8..=6, -200.0f64..200.0), 0..4),
    ) {
        let config = ArmConfig::default();
        let mut arm = Arm::new(&config).unwrap();
        for (joint, angle) in pushes {
            arm.module_mut(joint).unwrap().set_joint_angle(angle);
        }
        let mut now = Duration::ZERO;
        let mut latched = [false; 6];
        for (joint, command, gap_ms) in steps {
            now += Duration::from_millis(gap_ms);
            let request = Request::new(Address::joint(joint).unwrap(), command);
            let reply = arm.handle(&request, now).expect("every module answers");
            prop_assert_eq!(reply.address, request.address);
            prop_assert!(Message::Reply(reply.clone()).encode().is_ok());
            let i = usize::from(joint - 1);
            if latched[i] {
                prop_assert_eq!(&reply.body, &ReplyBody::Short { text: ShortCode::Timeout });
            }
            latched[i] = arm.state(joint).unwrap().timed_out;
            for (j, c) in config.joints.iter().enumerate() {
                if let Some([lo, hi]) = c.end_stops_deg() {
                    let a = arm.modules()[j].joint_angle();
                    prop_assert!(a >= lo && a <= hi, "joint {} at {}", j + 1, a);
                }
            }
        }
    }
}
