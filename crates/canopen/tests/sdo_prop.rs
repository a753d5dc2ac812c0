//! Property tests: random data through the sans-IO SDO client against the scripted
//! server of tests/common (written from the spec's byte tables), both directions.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use motus_can::CanFrame;
use motus_canopen::sdo_client::{SdoStep, SdoTransfer};
use proptest::prelude::*;

/// Drives a transfer against the server until it finishes; returns the outcome and the
/// number of request frames.
fn run(
    server: &mut common::SdoServer,
    mut t: SdoTransfer,
    first: CanFrame,
) -> (Result<Vec<u8>, String>, usize) {
    let now = Instant::now();
    let mut req = first;
    let mut frames = 1;
    loop {
        assert_eq!(req.id(), 0x605);
        let body: [u8; 8] = req.data().try_into().unwrap();
        let Some(resp) = server.handle(&body) else { return (Err("client aborted".into()), frames) };
        match t.on_frame(&CanFrame::new(0x585, &resp).unwrap(), now) {
            SdoStep::Send(f) => {
                req = f;
                frames += 1;
            }
            SdoStep::Done(d) => return (Ok(d), frames),
            SdoStep::Failed { error, .. } => return (Err(error.to_string()), frames),
            SdoStep::Wait => panic!("client ignored a response"),
        }
    }
}

proptest! {
    #[test]
    fn download_then_upload_round_trip(data in proptest::collection::vec(any::<u8>(), 0..300)) {
        let objects = Arc::new(Mutex::new(HashMap::new()));
        let mut server = common::SdoServer::new(objects.clone());
        let now = Instant::now();
        let (t, first) = SdoTransfer::download(5, 0x2000, 1, &data, now, Duration::from_secs(1)).unwrap();
        let (res, frames) = run(&mut server, t, first);
        prop_assert_eq!(res, Ok(vec![]));
        // Expedited: 1 frame; segmented: initiate + ceil(n/7) segments (at least 1).
        let want = if (1..=4).contains(&data.len()) { 1 } else { 1 + data.len().div_ceil(7).max(1) };
        prop_assert_eq!(frames, want);
        prop_assert_eq!(objects.lock().unwrap().get(&(0x2000, 1)).cloned(), Some(data.clone()));
        let (t, first) = SdoTransfer::upload(5, 0x2000, 1, now, Duration::from_secs(1)).unwrap();
        let (res, _) = run(&mut server, t, first);
        prop_assert_eq!(res, Ok(data));
    }

    #[test]
    fn client_never_panics_on_arbitrary_responses(bodies in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..=8), 1..20)) {
        let now = Instant::now();
        let (mut t, _) = SdoTransfer::upload(5, 0x1008, 0, now, Duration::from_secs(1)).unwrap();
        for b in bodies {
            let _ = t.on_frame(&CanFrame::new(0x585, &b).unwrap(), now);
        }
        let _ = t.poll(now + Duration::from_secs(2));
        prop_assert!(t.is_finished());
    }
}
