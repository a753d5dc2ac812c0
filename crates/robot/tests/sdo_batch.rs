//! Concurrent SDO uploads to several nodes from one thread (`Master::sdo_upload_many`),
//! against the three simulated drives on the virtual bus.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_can::socketcand::{Hub, HubConfig, SocketcandBus};
use motus_can::CanBus;
use motus_canopen::{Master, MasterError};
use motus_robot::sim::{SimRobot, SimRobotConfig};
use std::sync::Arc;
use std::time::Duration;

#[test]
fn a_batch_reads_every_node_and_reports_each_failure_on_its_own() {
    let hub = Hub::start(HubConfig {
        listen: "127.0.0.1:0".parse().unwrap(),
        bitrate: None,
        channel: "can0".into(),
    })
    .unwrap();
    let connect =
        || -> Arc<dyn CanBus> { Arc::new(SocketcandBus::connect(hub.local_addr(), "can0").unwrap()) };
    let _sim = SimRobot::start(connect(), SimRobotConfig::seed()).unwrap();
    let master = Master::new(connect());
    master.set_sdo_timeout(Duration::from_millis(150));
    std::thread::sleep(Duration::from_millis(150));
    // 0x1018:04 = serial number (the simulator's = node id); node 9 does not exist; node 3
    // twice is refused for its second request.
    let requests =
        [(4, 0x1018, 4), (2, 0x1018, 4), (3, 0x1018, 4), (9, 0x1000, 0), (3, 0x1000, 0), (2, 0x1234, 0)];
    let out = master.sdo_upload_many(&requests[..4]);
    let serial =
        |r: &Result<Vec<u8>, MasterError>| u32::from_le_bytes(r.as_ref().unwrap()[..4].try_into().unwrap());
    assert_eq!((serial(&out[0]), serial(&out[1]), serial(&out[2])), (4, 2, 3));
    assert!(out[3].as_ref().unwrap_err().is_timeout(), "{:?}", out[3]);
    let out = master.sdo_upload_many(&requests[2..]);
    assert_eq!(serial(&out[0]), 3);
    assert!(matches!(out[2], Err(MasterError::InvalidArgument(_))), "{:?}", out[2]);
    assert_eq!(out[3].as_ref().unwrap_err().abort_code().map(|c| c.raw()), Some(0x0602_0000));
    // The device type of every drive in one go, many times over.
    for _ in 0..200 {
        let out = master.sdo_upload_many(&[(2, 0x1000, 0), (3, 0x1000, 0), (4, 0x1000, 0)]);
        for r in out {
            assert_eq!(r.unwrap(), vec![0x92, 0x01, 0x02, 0x00]);
        }
    }
}
