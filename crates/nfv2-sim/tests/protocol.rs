//! The NFv2 side of a controller: one answer frame per request with every queried value,
//! sizes as the codec's `DeviceProfile::axis_1209a` predicts, addresses (own, other,
//! gateway, broadcast), unknown commands skipped, one drive, revisions.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use common::Rig;
use motus_nfv2_protocol::{
    AddressPlan, Command, CommandCode as C, DeviceProfile, DriveMode, DriveStatus, Frame, Revision,
};
use motus_nfv2_sim::{Controller, ControllerConfig};
use std::time::Duration;

fn frame(address: u8, commands: Vec<Command>) -> Frame {
    Frame { address, commands }
}

#[test]
fn one_answer_with_every_query_in_order_and_the_predicted_size() {
    let mut rig = Rig::new();
    let queries = [
        C::ReadDrivesStatus,
        C::ReadDeviceVitals,
        C::ReadDrivesPosition,
        C::ReadAnalogInputs,
        C::ReadDrivesCurrent,
        C::ReadDigitalInputs,
        C::ReadDeviceStatus,
    ];
    let request = frame(1, queries.iter().map(|&q| Command::query(q)).collect());
    let answer = rig.c.handle(&request, Duration::ZERO).unwrap();
    assert_eq!(answer.address, 1);
    let codes: Vec<C> = answer.commands.iter().map(Command::code).collect();
    assert_eq!(codes, queries);
    let rev = Revision::LATEST;
    assert_eq!(
        answer.encode(rev).unwrap().len(),
        DeviceProfile::axis_1209a().answer_len(&request, rev).unwrap()
    );
    let vitals = answer.int_values(C::ReadDeviceVitals).unwrap();
    for (v, nominal) in vitals.iter().zip([24_000, 24_000, 12_000, 5_000]) {
        assert!((v - nominal).abs() <= 20, "{vitals:?}");
    }
    let ai = answer.int_values(C::ReadAnalogInputs).unwrap();
    assert!((ai[0] - 12_000).abs() <= 15 && ai[1] <= 8, "{ai:?}");
    assert_eq!(answer.int_values(C::ReadDigitalInputs), Some(&[0b1000][..]), "only ENABLE");
    let status = answer.int_values(C::ReadDrivesStatus).unwrap()[0];
    assert_eq!(status as u16 & DriveStatus::ERROR, DriveStatus::ERROR, "power-on mode 0 = ERROR");
}

#[test]
fn set_commands_are_not_answered_and_unsupported_queries_are_skipped() {
    let mut rig = Rig::new();
    assert_eq!(rig.send(vec![Command::values(C::SetDrivesPosition, [100])]), None);
    // k = 0 on a set-code, a servo query, an unknown code: nothing to answer.
    let silent = vec![
        Command::query(C::SetDrivesPosition),
        Command::query(C::ReadServosPosition),
        Command::query(C::ReadDrivesSpeed),
        Command::Unknown { code: 0x60, raw: vec![1, 2, 3] },
    ];
    assert_eq!(rig.send(silent.clone()), None);
    let mut with_one = silent;
    with_one.push(Command::query(C::ReadDrivesPosition));
    let answer = rig.send(with_one).unwrap();
    assert_eq!(answer.commands, vec![Command::values(C::ReadDrivesPosition, [0])]);
}

#[test]
fn an_unknown_command_is_skipped_and_the_rest_applied() {
    let mut rig = Rig::new();
    let pos = i64::from(DriveMode::Position.to_raw(Revision::LATEST).unwrap());
    rig.send(vec![
        Command::Unknown { code: 0x60, raw: vec![0xAA; 5] },
        Command::values(C::SetDisplayBacklight, [1]),
        Command::values(C::SetDrivesMode, [pos]),
        Command::values(C::SetDrivesPosition, [3_000, 99_999]), // second drive: ignored
    ]);
    rig.run_ms(500);
    assert!((rig.position() - 3_000).abs() <= 2);
}

#[test]
fn another_address_is_ignored_entirely() {
    let mut c = Controller::new(2, &ControllerConfig::default()).unwrap();
    let pos = i64::from(DriveMode::Position.to_raw(Revision::LATEST).unwrap());
    let request = frame(
        3,
        vec![
            Command::values(C::SetDrivesMode, [pos]),
            Command::values(C::SetDrivesPosition, [5_000]),
            Command::query(C::ReadDrivesPosition),
        ],
    );
    assert_eq!(c.handle(&request, Duration::ZERO), None);
    c.advance_to(Duration::from_millis(300));
    assert_eq!(c.true_state().mode, DriveMode::Error);
    assert_eq!(c.true_state().counter, 0);
}

#[test]
fn broadcast_sets_every_controller_and_nobody_answers() {
    let plan = AddressPlan::REFERENCE_BROADCAST_0;
    let config = ControllerConfig::default();
    let mut a = Controller::with_protocol(1, plan, Revision::LATEST, &config).unwrap();
    let mut b = Controller::with_protocol(2, plan, Revision::LATEST, &config).unwrap();
    let pos = i64::from(DriveMode::Position.to_raw(Revision::LATEST).unwrap());
    let request = frame(
        0,
        vec![
            Command::values(C::SetDrivesMode, [pos]),
            Command::values(C::SetDrivesPosition, [2_000]),
            Command::query(C::ReadDrivesPosition),
        ],
    );
    assert_eq!(a.handle(&request, Duration::ZERO), None);
    assert_eq!(b.handle(&request, Duration::ZERO), None);
    a.advance_to(Duration::from_millis(400));
    b.advance_to(Duration::from_millis(400));
    assert!((a.true_state().counter - 2_000).abs() <= 2);
    assert!((b.true_state().counter - 2_000).abs() <= 2);
}

#[test]
fn the_gateway_address_is_an_ordinary_module_for_its_own_frames() {
    let mut g =
        Controller::with_protocol(0, AddressPlan::SEED_1209A, Revision::LATEST, &ControllerConfig::default())
            .unwrap();
    let answer = g.handle(&frame(0, vec![Command::query(C::ReadDrivesStatus)]), Duration::ZERO).unwrap();
    assert_eq!(answer.address, 0);
}

#[test]
fn rev2012_widths_and_mode_numbers() {
    // Rev2012: 2-byte speeds; 0x11 is SYNC_POS0, the reference's homing.
    let config = ControllerConfig { home_edge_counts: Some(-1_000.0), ..ControllerConfig::default() };
    let mut c = Controller::with_protocol(1, AddressPlan::default(), Revision::Rev2012, &config).unwrap();
    let bytes = frame(1, vec![Command::values(C::SetDrivesMode, [0x11])]).encode(Revision::Rev2012).unwrap();
    let decoded = Frame::decode(&bytes, Revision::Rev2012).unwrap();
    c.handle(&decoded, Duration::ZERO);
    c.advance_to(Duration::from_millis(1));
    assert_eq!(c.true_state().mode, DriveMode::SyncPos0);
    c.advance_to(Duration::from_secs(2));
    assert!(c.true_state().status.contains(DriveStatus::SYNCHRONIZED));
    // The same byte in the latest revision is no mode at all: the bridge stays off.
    let mut c = Controller::new(1, &config).unwrap();
    c.handle(&frame(1, vec![Command::values(C::SetDrivesMode, [0x11])]), Duration::ZERO);
    c.advance_to(Duration::from_millis(100));
    assert_eq!(c.true_state().mode, DriveMode::Unknown(0x11));
    assert!(!c.true_state().bridge_on);
}

#[test]
fn answers_are_deterministic_for_a_seed() {
    let run = |seed: u64| {
        let mut rig = Rig::with(ControllerConfig::default().seeded(seed));
        rig.mode(DriveMode::Speed);
        rig.set(C::SetDrivesSpeed, 3_000);
        (0..50)
            .map(|_| {
                rig.run_ms(7);
                (rig.read(C::ReadDrivesCurrent), rig.read_all(C::ReadDeviceVitals), rig.position())
            })
            .collect::<Vec<_>>()
    };
    assert_eq!(run(5), run(5));
    assert_ne!(run(5), run(6));
}
