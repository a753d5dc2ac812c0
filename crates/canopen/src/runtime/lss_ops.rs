//! LSS master services of the runtime (CiA 305). One LSS operation at a time. Time-outs
//! are on the master's clock (on a threaded one, the waiting thread parks on it).

use std::sync::mpsc::{channel, Receiver, RecvTimeoutError};
use std::time::Duration;

use motus_canopen_protocol::{LssIdentityField, LssRequest, LssResponse};

use crate::error::MasterError;
use crate::lss::{self, Fastscan, FastscanStep, LssError, LssIdentity, LssMode};

use super::wake::Waiter;
use super::{lock, Inner, Master};

/// Clears the LSS waiter when an operation ends.
struct LssWaiter<'a> {
    inner: &'a Inner,
    rx: Receiver<LssResponse>,
}

impl<'a> LssWaiter<'a> {
    fn new(inner: &'a Inner) -> Self {
        let (tx, rx) = channel();
        *lock(&inner.lss_waiter) = Some(Waiter::new(tx, inner.wake_slot()));
        Self { inner, rx }
    }
}

impl Drop for LssWaiter<'_> {
    fn drop(&mut self) {
        *lock(&self.inner.lss_waiter) = None;
    }
}

fn service_name(req: &LssRequest) -> &'static str {
    match req {
        LssRequest::SwitchStateSelective { .. } => "switch state selective",
        LssRequest::ConfigureNodeId { .. } => "configure node-ID",
        LssRequest::ConfigureBitTiming { .. } => "configure bit timing",
        LssRequest::StoreConfiguration => "store configuration",
        LssRequest::InquireIdentity { .. } => "inquire identity",
        LssRequest::InquireNodeId => "inquire node-ID",
        _ => "LSS request",
    }
}

impl Master {
    /// Sets the time-out of LSS confirmed services (default 500 ms).
    pub fn set_lss_timeout(&self, timeout: Duration) {
        *lock(&self.inner.lss_timeout) = timeout;
    }

    fn lss_send(&self, req: &LssRequest) -> Result<(), MasterError> {
        let frame = lss::request_frame(req)?;
        self.inner.send(&frame, || format!("sending LSS {req}"))
    }

    /// Sends `reqs` in order and waits for the answer to the last one.
    fn lss_confirmed(&self, reqs: &[LssRequest]) -> Result<LssResponse, MasterError> {
        let _one_at_a_time = lock(&self.inner.lss_lock);
        let waiter = LssWaiter::new(&self.inner);
        let timeout = *lock(&self.inner.lss_timeout);
        let Some(last) = reqs.last() else {
            return Err(MasterError::InvalidArgument("no LSS request".into()));
        };
        for r in reqs {
            self.lss_send(r)?;
        }
        let deadline = self.inner.clock.now() + timeout;
        loop {
            match self.inner.recv_until(&waiter.rx, deadline) {
                Ok(resp) if lss::answers(last, &resp) => {
                    lss::check_result(&resp)?;
                    return Ok(resp);
                }
                Ok(_) => {}
                Err(RecvTimeoutError::Timeout | RecvTimeoutError::Disconnected) => {
                    return Err(LssError::Timeout { service: service_name(last), timeout }.into())
                }
            }
        }
    }

    /// Switch state global: all slaves to waiting or configuration (no answer).
    pub fn lss_switch_global(&self, mode: LssMode) -> Result<(), MasterError> {
        self.lss_send(&LssRequest::SwitchStateGlobal { configuration: mode == LssMode::Configuration })
    }

    /// Switch state selective: the slave with this identity enters configuration
    /// (waits for its 0x44 answer).
    pub fn lss_switch_selective(&self, identity: &LssIdentity) -> Result<(), MasterError> {
        self.lss_confirmed(&lss::switch_selective(identity)).map(|_| ())
    }

    /// Configures the node-ID of the slave in configuration state (1..=127 or 255).
    pub fn lss_configure_node_id(&self, node_id: u8) -> Result<(), MasterError> {
        self.lss_confirmed(&[lss::configure_node_id(node_id)?]).map(|_| ())
    }

    /// Configures the bit rate (CiA 305 standard table) of the slave in configuration state.
    pub fn lss_configure_bit_timing(&self, bitrate: u32) -> Result<(), MasterError> {
        self.lss_confirmed(&[lss::configure_bit_timing(bitrate)?]).map(|_| ())
    }

    /// Activates the configured bit timing on every slave after `delay_ms` (no answer).
    pub fn lss_activate_bit_timing(&self, delay_ms: u16) -> Result<(), MasterError> {
        self.lss_send(&LssRequest::ActivateBitTiming { delay_ms })
    }

    /// Stores the configuration of the slave in configuration state.
    pub fn lss_store(&self) -> Result<(), MasterError> {
        self.lss_confirmed(&[LssRequest::StoreConfiguration]).map(|_| ())
    }

    /// Inquires one identity part of the slave in configuration state.
    pub fn lss_inquire(&self, field: LssIdentityField) -> Result<u32, MasterError> {
        match self.lss_confirmed(&[LssRequest::InquireIdentity { field }])? {
            LssResponse::InquireIdentity { value, .. } => Ok(value),
            other => Err(MasterError::InvalidArgument(format!("unexpected LSS answer {other}"))),
        }
    }

    /// Inquires the whole identity of the slave in configuration state.
    pub fn lss_inquire_identity(&self) -> Result<LssIdentity, MasterError> {
        Ok(LssIdentity {
            vendor: self.lss_inquire(LssIdentityField::Vendor)?,
            product: self.lss_inquire(LssIdentityField::Product)?,
            revision: self.lss_inquire(LssIdentityField::Revision)?,
            serial: self.lss_inquire(LssIdentityField::Serial)?,
        })
    }

    /// Inquires the active node-ID of the slave in configuration state (255 = unconfigured).
    pub fn lss_inquire_node_id(&self) -> Result<u8, MasterError> {
        match self.lss_confirmed(&[LssRequest::InquireNodeId])? {
            LssResponse::InquireNodeId { node_id } => Ok(node_id),
            other => Err(MasterError::InvalidArgument(format!("unexpected LSS answer {other}"))),
        }
    }

    /// FASTSCAN for one unconfigured slave; `step_timeout` per request (CiA 305 suggests
    /// tens of ms). On success the slave is in configuration state.
    pub fn lss_fastscan(&self, step_timeout: Duration) -> Result<Option<LssIdentity>, MasterError> {
        let _one_at_a_time = lock(&self.inner.lss_lock);
        let waiter = LssWaiter::new(&self.inner);
        let clock = &*self.inner.clock;
        let (mut scan, first) = Fastscan::start(clock.now(), step_timeout)?;
        self.inner.send(&first, || "sending LSS fastscan".into())?;
        loop {
            let deadline = scan.deadline().unwrap_or_else(|| clock.now());
            let step = match self.inner.recv_until(&waiter.rx, deadline) {
                Ok(resp) => {
                    // Several unconfigured slaves may answer the same request: wait a
                    // little and drop the other answers, or they would be taken as the
                    // answers to the next requests.
                    let settle = clock.now() + step_timeout / 4;
                    while self.inner.recv_until(&waiter.rx, settle).is_ok() {}
                    scan.on_response(&resp, clock.now())
                }
                Err(_) => scan.poll(clock.now()),
            };
            match step {
                FastscanStep::Wait => {}
                FastscanStep::Send(f) => self.inner.send(&f, || "sending LSS fastscan".into())?,
                FastscanStep::Done(id) => return Ok(id),
            }
        }
    }
}
