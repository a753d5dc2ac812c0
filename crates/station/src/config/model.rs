//! The validated cell: what the runtime builds links, devices, axes and tasks from.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

use motus_axis::{Scale, UnitKind};
use serde::{Deserialize, Serialize};

/// A validated cell configuration. Names are unique per section and every reference
/// resolves; paths are resolved against the cell file's folder.
#[derive(Debug, Clone, PartialEq)]
pub struct Cell {
    /// The file it was read from.
    pub file: PathBuf,
    /// `[station]`.
    pub station: Station,
    /// `[[link]]`, in file order.
    pub links: Vec<Link>,
    /// `[[device]]`, in file order.
    pub devices: Vec<Device>,
    /// `[[axis]]`, in file order.
    pub axes: Vec<AxisConfig>,
    /// `[[group]]`, in file order.
    pub groups: Vec<Group>,
    /// `[supervisor]`, if any.
    pub supervisor: Option<Supervisor>,
    /// `[[task]]`, in file order.
    pub tasks: Vec<TaskConfig>,
    /// `[[program]]`, in file order.
    pub programs: Vec<Program>,
    /// `[[tool]]`: the CNC's tool table (T, M6, G43 H, G41/G42 D), in file order.
    pub tools: Vec<ToolConfig>,
}

/// One task class: every task with the same period runs on one thread.
#[derive(Debug, Clone, PartialEq)]
pub struct TaskClassConfig {
    /// The period.
    pub period: Duration,
    /// Names of the tasks of this class, in file order.
    pub tasks: Vec<String>,
    /// The smallest `overrun_limit` of its tasks.
    pub overrun_limit: u32,
}

impl Cell {
    /// The link called `name`.
    pub fn link(&self, name: &str) -> Option<&Link> {
        self.links.iter().find(|l| l.name == name)
    }

    /// The device called `name`.
    pub fn device(&self, name: &str) -> Option<&Device> {
        self.devices.iter().find(|d| d.name == name)
    }

    /// The axis called `name`.
    pub fn axis(&self, name: &str) -> Option<&AxisConfig> {
        self.axes.iter().find(|a| a.name == name)
    }

    /// The group called `name`.
    pub fn group(&self, name: &str) -> Option<&Group> {
        self.groups.iter().find(|g| g.name == name)
    }

    /// The program called `name`.
    pub fn program(&self, name: &str) -> Option<&Program> {
        self.programs.iter().find(|p| p.name == name)
    }

    /// The axes of a device, ordered by index.
    pub fn axes_of_device(&self, device: &str) -> Vec<&AxisConfig> {
        let mut axes: Vec<&AxisConfig> = self.axes.iter().filter(|a| a.device == device).collect();
        axes.sort_by_key(|a| a.index);
        axes
    }

    /// The devices on a link, in file order.
    pub fn devices_on_link(&self, link: &str) -> Vec<&Device> {
        self.devices.iter().filter(|d| d.link.as_deref() == Some(link)).collect()
    }

    /// The task classes (one per distinct period), fastest first.
    pub fn task_classes(&self) -> Vec<TaskClassConfig> {
        let mut classes: Vec<TaskClassConfig> = Vec::new();
        for t in &self.tasks {
            match classes.iter_mut().find(|c| c.period == t.period) {
                Some(c) => {
                    c.tasks.push(t.name.clone());
                    c.overrun_limit = c.overrun_limit.min(t.overrun_limit);
                }
                None => classes.push(TaskClassConfig {
                    period: t.period,
                    tasks: vec![t.name.clone()],
                    overrun_limit: t.overrun_limit,
                }),
            }
        }
        classes.sort_by_key(|c| c.period);
        classes
    }
}

/// `[station]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Station {
    /// Shown in the HMI.
    pub name: String,
    /// Where the web server listens (default `127.0.0.1:8080`).
    pub listen: SocketAddr,
    /// Where the station keeps its data (default `data` beside the cell file).
    pub data_dir: PathBuf,
    /// Origins (`http://host:port`, `https://host`) whose pages may open the station's
    /// WebSocket, e.g. the name the browsers use when the station listens on `0.0.0.0` or
    /// behind a proxy. Empty (default): the origins the web server is served on.
    pub origins: Vec<String>,
    /// Longest time one check of an uploaded G-code program may take (`program_check_time`
    /// in seconds, default [`DEFAULT_PROGRAM_CHECK_TIME`]); beyond it the check stops with
    /// an error and the program cannot run.
    pub program_check_time: std::time::Duration,
}

/// The default time budget of a program check.
pub const DEFAULT_PROGRAM_CHECK_TIME: std::time::Duration = std::time::Duration::from_secs(3);

/// The default listen address.
pub const DEFAULT_LISTEN: &str = "127.0.0.1:8080";

/// What a link is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LinkKind {
    /// A serial port (`/dev/ttyUSB0`).
    Serial,
    /// A pseudo-terminal created by a simulator the station starts; `uri` is its symlink.
    PtySim,
    /// A CAN bus (`socketcand://`, `socketcan://`, `slcan://`).
    Can,
    /// A POWERLINK segment (`udp://127.0.0.1:<base>` or an interface name).
    Powerlink,
}

impl LinkKind {
    /// The name used in the file.
    pub fn as_str(self) -> &'static str {
        match self {
            LinkKind::Serial => "serial",
            LinkKind::PtySim => "pty-sim",
            LinkKind::Can => "can",
            LinkKind::Powerlink => "powerlink",
        }
    }

    /// True for serial-like links (a serial port or a pty).
    pub fn is_serial(self) -> bool {
        matches!(self, LinkKind::Serial | LinkKind::PtySim)
    }
}

/// `[[link]]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Link {
    /// Unique name.
    pub name: String,
    /// What it is.
    pub kind: LinkKind,
    /// Port path, bus URI or segment.
    pub uri: String,
}

/// What a device is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum DeviceKind {
    /// A PS1A stepper module (serial, address 0-255).
    Ps1a,
    /// The KV-01 arm (serial, six joints, fixed module addresses).
    Kv01,
    /// A 1209A axis controller (NFv2, serial, address 1-255).
    Nfv2,
    /// A CiA 402 drive on CANopen (node 1-127).
    Cia402,
    /// A servo drive on POWERLINK (node 1-239).
    EplDrive,
    /// An axis simulated inside the station (no link).
    SimAxis,
}

impl DeviceKind {
    /// The name used in the file.
    pub fn as_str(self) -> &'static str {
        match self {
            DeviceKind::Ps1a => "ps1a",
            DeviceKind::Kv01 => "kv01",
            DeviceKind::Nfv2 => "nfv2",
            DeviceKind::Cia402 => "cia402",
            DeviceKind::EplDrive => "epl-drive",
            DeviceKind::SimAxis => "sim-axis",
        }
    }

    /// How many axes the device has.
    pub fn axis_count(self) -> u32 {
        match self {
            DeviceKind::Kv01 => 6,
            _ => 1,
        }
    }

    /// The allowed address range, `None` when the device takes no address.
    pub fn address_range(self) -> Option<(i64, i64)> {
        match self {
            DeviceKind::Ps1a => Some((0, 255)),
            DeviceKind::Nfv2 => Some((1, 255)),
            DeviceKind::Cia402 => Some((1, 127)),
            DeviceKind::EplDrive => Some((1, 239)),
            DeviceKind::Kv01 | DeviceKind::SimAxis => None,
        }
    }

    /// Whether a device of this kind can sit on a link of that kind (`None`: no link).
    pub fn accepts_link(self, link: Option<LinkKind>) -> bool {
        match self {
            DeviceKind::Ps1a | DeviceKind::Kv01 | DeviceKind::Nfv2 => link.is_some_and(LinkKind::is_serial),
            DeviceKind::Cia402 => link == Some(LinkKind::Can),
            DeviceKind::EplDrive => link == Some(LinkKind::Powerlink),
            DeviceKind::SimAxis => link.is_none(),
        }
    }

    /// The link kinds this device needs, for messages.
    pub fn link_hint(self) -> &'static str {
        match self {
            DeviceKind::Ps1a | DeviceKind::Kv01 | DeviceKind::Nfv2 => "a serial or pty-sim link",
            DeviceKind::Cia402 => "a can link",
            DeviceKind::EplDrive => "a powerlink link",
            DeviceKind::SimAxis => "no link",
        }
    }
}

/// `[[device]]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Device {
    /// Unique name.
    pub name: String,
    /// What it is.
    pub kind: DeviceKind,
    /// The link it sits on (`None` for `sim-axis`).
    pub link: Option<String>,
    /// Bus address / node ID, where the kind has one.
    pub address: Option<u32>,
    /// Start the simulator for this device (always true for `sim-axis`).
    pub simulate: bool,
    /// Baud rate of a serial link, when not the device's default.
    pub baud: Option<u32>,
}

/// The SI unit of an axis's positions.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Unit {
    /// Metres (linear axis).
    #[serde(rename = "m")]
    Metre,
    /// Radians (rotary axis).
    #[serde(rename = "rad")]
    Radian,
}

impl Unit {
    /// The axis-model kind.
    pub fn kind(self) -> UnitKind {
        match self {
            Unit::Metre => UnitKind::Linear,
            Unit::Radian => UnitKind::Rotary,
        }
    }

    /// The symbol.
    pub fn symbol(self) -> &'static str {
        self.kind().symbol()
    }
}

/// A position range in SI units, `min < max`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    /// Lowest allowed position.
    pub min: f64,
    /// Highest allowed position.
    pub max: f64,
}

/// What a student may do with an axis: always inside the machine limits. Every field of the
/// cell file's `student` table defaults to the machine's value; an axis without the table has
/// no student limits and students cannot move it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StudentLimits {
    /// Allowed positions (defaults to the machine limits).
    pub limits: Limits,
    /// Highest velocity (defaults to the machine's).
    pub max_velocity: f64,
    /// Highest acceleration (defaults to the machine's).
    pub max_acceleration: f64,
}

/// `[[axis]]`.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisConfig {
    /// Unique name.
    pub name: String,
    /// The device that moves it.
    pub device: String,
    /// Joint / channel on the device (0-based).
    pub index: u32,
    /// Metres or radians.
    pub unit: Unit,
    /// Device units to SI.
    pub scale: Scale,
    /// Machine limits.
    pub limits: Limits,
    /// Machine velocity limit (SI, positive).
    pub max_velocity: f64,
    /// Machine acceleration limit (SI, positive).
    pub max_acceleration: f64,
    /// Student limits; `None` (no `student` table in the cell file): students cannot move
    /// this axis at all (fail closed). A table with some keys missing takes the machine's
    /// values for them.
    pub student: Option<StudentLimits>,
}

/// What a group of axes is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum GroupKind {
    /// Three-wheel omnidirectional robot (3 axes).
    Omni,
    /// Pan-tilt head (2 axes).
    Pantilt,
    /// Serial arm (1-6 joints).
    Arm,
    /// Gantry (2 or 3 axes).
    Gantry,
    /// The juggler (1-8 axes).
    Juggler,
    /// Axes that form one machine without a controller of their own (1-16 axes: e.g. a
    /// bench of single-axis modules), booked and shown together.
    Axes,
}

impl GroupKind {
    /// The name used in the file.
    pub fn as_str(self) -> &'static str {
        match self {
            GroupKind::Omni => "omni",
            GroupKind::Pantilt => "pantilt",
            GroupKind::Arm => "arm",
            GroupKind::Gantry => "gantry",
            GroupKind::Juggler => "juggler",
            GroupKind::Axes => "axes",
        }
    }

    /// Allowed number of axes (inclusive).
    pub fn axis_count(self) -> (usize, usize) {
        match self {
            GroupKind::Omni => (3, 3),
            GroupKind::Pantilt => (2, 2),
            GroupKind::Arm => (1, 6),
            GroupKind::Gantry => (2, 3),
            GroupKind::Juggler => (1, 8),
            GroupKind::Axes => (1, 16),
        }
    }
}

/// `[[group]]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Group {
    /// Unique name.
    pub name: String,
    /// What it is.
    pub kind: GroupKind,
    /// Its axes, in the group's order (e.g. wheel 1..3, pan then tilt).
    pub axes: Vec<String>,
    /// The machine's camera, relayed by the station to logged-in users (`None`: no camera).
    pub camera: Option<Camera>,
}

/// `camera = ...` of a `[[group]]`: where the pictures of the machine come from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Camera {
    /// `"simulated"`: the station draws the machine's axes as they are, as an MJPEG stream.
    Simulated,
    /// `"http://host[:port]/path"`: an HTTP camera (an MJPEG stream or a still JPEG image)
    /// on the lab's network, fetched by the station for each viewer (browsers need no route
    /// to it).
    Http(String),
}

/// `[supervisor]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Supervisor {
    /// Rules file (must exist).
    pub rules: PathBuf,
    /// Drive-parameter file (TOML `[[drive]]`, `motus_safety::DrivesFile`; must exist when
    /// named): approved with the rules and watched with them, so a changed drive parameter
    /// blocks motion and the diagnosis names it.
    pub drives: Option<PathBuf>,
    /// Approval file written by `motus safety approve` (may not exist yet).
    pub approval: Option<PathBuf>,
    /// Administrator key file.
    pub key: Option<PathBuf>,
    /// The group it supervises.
    pub group: Option<String>,
}

/// What a cyclic task does.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum TaskKind {
    /// The control cycle of a group (needs `group`).
    Motion,
    /// Safety supervisor evaluation.
    Supervisor,
    /// Watch and trace recording.
    Trace,
    /// Device supervision and reconnection.
    Devices,
    /// Runs a `[[program]]` (needs `program`).
    Program,
}

impl TaskKind {
    /// The name used in the file.
    pub fn as_str(self) -> &'static str {
        match self {
            TaskKind::Motion => "motion",
            TaskKind::Supervisor => "supervisor",
            TaskKind::Trace => "trace",
            TaskKind::Devices => "devices",
            TaskKind::Program => "program",
        }
    }
}

/// Default number of consecutive overruns before a task class degrades.
pub const DEFAULT_OVERRUN_LIMIT: u32 = 3;

/// `[[task]]`.
#[derive(Debug, Clone, PartialEq)]
pub struct TaskConfig {
    /// Unique name.
    pub name: String,
    /// Cycle period (its task class).
    pub period: Duration,
    /// What it does.
    pub kind: TaskKind,
    /// The group it drives (`motion`, optional for others).
    pub group: Option<String>,
    /// The program it runs (`program`).
    pub program: Option<String>,
    /// Consecutive overruns before the class degrades.
    pub overrun_limit: u32,
}

/// `[[tool]]`: one tool of the CNC's tool table (a non-random changer: the number is its
/// place).
#[derive(Debug, Clone, PartialEq)]
pub struct ToolConfig {
    /// T number, 1-99999, unique.
    pub number: u32,
    /// Diameter, mm (G41/G42 use its half; G41.1/G42.1 take their own).
    pub diameter_mm: f64,
    /// Length offset, mm (G43 H).
    pub length_mm: f64,
    /// What it is ("6 mm drill").
    pub comment: String,
}

/// `[[program]]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Program {
    /// Unique name.
    pub name: String,
    /// The program file (must exist).
    pub file: PathBuf,
    /// The group it is written for.
    pub group: Option<String>,
}
