//! Groups of axes with the commands their libraries already offer: the pan-tilt head
//! ([`PanTilt`]: homing, synchronised goto, tracking), the KV-01 arm ([`Kv01Arm`]:
//! synchronised multi-joint moves, brakes, gripper), the omni robot (the simulated robot's
//! true pose), the juggler (its supervisor), and plain gantries (axis names only).
//!
//! The objects behind a group are replaced when their device reconnects, so each accessor
//! returns the current one (or `None` while the device is down).

use std::sync::{Arc, Mutex, PoisonError};

use motus_kv01::Kv01Arm;
use motus_nfv2::PanTilt;
use motus_omni::kinematics::Pose;
use motus_robot::sim::SimRobot;
use motus_station::config::GroupKind;

use crate::juggler::JugglerHandle;
use crate::nfv2::Nfv2Link;

/// The pan-tilt head of a `pantilt` group.
#[derive(Clone)]
pub struct PanTiltGroup {
    pub(crate) link: Arc<Nfv2Link>,
}

impl PanTiltGroup {
    /// The head while its link is up.
    pub fn head(&self) -> Option<Arc<PanTilt>> {
        self.link.pantilt()
    }
}

/// The arm of an `arm` group.
#[derive(Clone)]
pub struct ArmGroup {
    pub(crate) arm: crate::kv01::ArmCell,
}

impl ArmGroup {
    /// The arm driver while it is connected.
    pub fn arm(&self) -> Option<Arc<Kv01Arm>> {
        self.arm.lock().unwrap_or_else(PoisonError::into_inner).as_ref().map(|(_, a)| Arc::clone(a))
    }
}

/// The omni robot of an `omni` group.
#[derive(Clone)]
pub struct OmniGroup {
    pub(crate) robot: Option<Arc<Mutex<Option<SimRobot>>>>,
}

impl OmniGroup {
    /// The simulated robot's true pose (ground truth), when the wheels are simulated and run.
    pub fn true_pose(&self) -> Option<Pose> {
        self.robot.as_ref().and_then(|r| crate::cia402::true_pose(r))
    }
}

/// What a group offers beyond its axes.
#[derive(Clone)]
pub enum GroupHandle {
    /// `pantilt`, when the group's two controllers are the only ones on their link.
    PanTilt(PanTiltGroup),
    /// `arm` on a KV-01.
    Arm(ArmGroup),
    /// `omni`.
    Omni(OmniGroup),
    /// `juggler`, when the cell has a supervisor on a POWERLINK segment.
    Juggler(Arc<JugglerHandle>),
    /// Any group with nothing beyond its axes (gantry, or a kind whose library is not there).
    Axes,
}

/// One group of the cell.
#[derive(Clone)]
pub struct CellGroup {
    /// Name from the cell file.
    pub name: String,
    /// Kind from the cell file.
    pub kind: GroupKind,
    /// Its axes, in the group's order.
    pub axes: Vec<String>,
    /// What it offers.
    pub handle: GroupHandle,
}

impl std::fmt::Debug for CellGroup {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let what = match &self.handle {
            GroupHandle::PanTilt(_) => "pantilt head",
            GroupHandle::Arm(_) => "KV-01 arm",
            GroupHandle::Omni(_) => "omni robot",
            GroupHandle::Juggler(_) => "juggler supervisor",
            GroupHandle::Axes => "axes only",
        };
        f.debug_struct("CellGroup")
            .field("name", &self.name)
            .field("axes", &self.axes)
            .field("handle", &what)
            .finish()
    }
}
