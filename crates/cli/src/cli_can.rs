//! Command-line definitions of the CAN / CANopen / robot commands.

use clap::{Args, Subcommand};
use std::path::PathBuf;

/// Options of `motus canbus`.
#[derive(Debug, Subcommand)]
pub enum CanbusCommand {
    /// Run the virtual CAN bus: a socketcand hub on loopback TCP that Motus and
    /// python-can / python-canopen programs join.
    Serve(CanbusServeArgs),
}

/// Options of `motus canbus serve`.
#[derive(Debug, Args)]
pub struct CanbusServeArgs {
    /// Address to listen on.
    #[arg(long, default_value = "127.0.0.1:29536")]
    pub listen: String,
    /// Model a real bus at this bit rate (frames take their wire time); none = instant.
    #[arg(long)]
    pub bitrate: Option<u32>,
    /// Record every frame to a pcap file (LINKTYPE_CAN_SOCKETCAN; Wireshark decodes CANopen).
    #[arg(long)]
    pub pcap: Option<PathBuf>,
    /// Record every frame to a candump log file.
    #[arg(long)]
    pub candump: Option<PathBuf>,
    /// Channel name announced to clients.
    #[arg(long, default_value = "can0")]
    pub channel: String,
}

/// Options of `motus canopen`.
#[derive(Debug, Args)]
pub struct CanopenArgs {
    /// The bus: `socketcand://127.0.0.1:29536/can0`, `socketcan://can0`, `slcan:///dev/ttyACM0?bitrate=20000`.
    #[arg(long)]
    pub bus: String,
    /// SDO time-out in milliseconds.
    #[arg(long, default_value_t = 500)]
    pub timeout_ms: u64,
    /// EDS file naming the objects (for `dump`, and typed values of `sdo read`).
    #[arg(long, global = true)]
    pub eds: Option<PathBuf>,
    /// What to do.
    #[command(subcommand)]
    pub action: CanopenAction,
}

/// CANopen master actions.
#[derive(Debug, Subcommand)]
pub enum CanopenAction {
    /// NMT command to a node (0 = all): start, stop, pre-op, reset, reset-comm.
    Nmt {
        /// Node id (0 = broadcast).
        node: u8,
        /// Command.
        command: String,
    },
    /// SDO transfers.
    #[command(subcommand)]
    Sdo(SdoAction),
    /// Configure a PDO of a node by SDO (disable, map, enable in the standard's order).
    Pdo(PdoArgs),
    /// LSS (CiA 305) services.
    #[command(subcommand)]
    Lss(LssAction),
    /// List the nodes that answer (device type, name, identity).
    Scan {
        /// First node id probed.
        #[arg(long, default_value_t = 1)]
        from: u8,
        /// Last node id probed.
        #[arg(long, default_value_t = 127)]
        to: u8,
    },
    /// Read every object of the EDS (--eds) from a node.
    Dump {
        /// Node id.
        node: u8,
    },
    /// Print the frames on the bus, decoded, for a while.
    Monitor {
        /// Seconds to listen.
        #[arg(long, default_value_t = 5.0)]
        seconds: f64,
    },
}

/// SDO actions.
#[derive(Debug, Subcommand)]
pub enum SdoAction {
    /// Upload (read) an object: `sdo read 2 0x6041 0`.
    Read {
        /// Node id.
        node: u8,
        /// Index (hex with 0x, or decimal).
        index: String,
        /// Sub-index.
        #[arg(default_value = "0")]
        sub: String,
        /// Value type: u8, u16, u32, i8, i16, i32, str, hex (default: from the EDS, else hex).
        #[arg(long = "type")]
        ty: Option<String>,
    },
    /// Download (write) an object: `sdo write 2 0x6081 0 500 --type u32`.
    Write {
        /// Node id.
        node: u8,
        /// Index.
        index: String,
        /// Sub-index.
        sub: String,
        /// Value.
        value: String,
        /// Value type: u8, u16, u32, i8, i16, i32, str, hex (default: from the EDS).
        #[arg(long = "type")]
        ty: Option<String>,
    },
}

/// Options of `motus canopen pdo`.
#[derive(Debug, Args)]
pub struct PdoArgs {
    /// Node id.
    pub node: u8,
    /// `rpdo` or `tpdo`.
    pub direction: String,
    /// PDO number 1..512.
    pub number: u16,
    /// COB-ID (default: the pre-defined connection set's).
    #[arg(long)]
    pub cob_id: Option<String>,
    /// Transmission type (0-240 synchronous, 254/255 event-driven).
    #[arg(long, default_value_t = 255)]
    pub transmission_type: u8,
    /// Event timer in ms.
    #[arg(long)]
    pub event_timer: Option<u16>,
    /// Inhibit time in 100 us units (TPDO).
    #[arg(long)]
    pub inhibit: Option<u16>,
    /// Mapped objects, e.g. `0x6041:0:16,0x6064:0:32` (index:sub:bits).
    #[arg(long, value_delimiter = ',')]
    pub map: Vec<String>,
    /// Leave the PDO disabled after mapping.
    #[arg(long)]
    pub disabled: bool,
}

/// LSS actions.
#[derive(Debug, Subcommand)]
pub enum LssAction {
    /// Switch every slave to configuration (`config`) or waiting (`wait`) state.
    Switch {
        /// `config` or `wait`.
        mode: String,
    },
    /// Switch the slave with this identity to configuration state (vendor product revision serial).
    Select {
        /// Vendor-ID.
        vendor: String,
        /// Product code.
        product: String,
        /// Revision.
        revision: String,
        /// Serial number.
        serial: String,
    },
    /// Configure the node-ID of the slave in configuration state.
    SetNode {
        /// New node id (1-127, 255 = unconfigured).
        node: u8,
    },
    /// Configure the bit rate (bit/s) of the slave in configuration state.
    SetBitrate {
        /// Bit rate, e.g. 20000.
        bitrate: u32,
    },
    /// Activate the configured bit rate on every slave after a delay (ms).
    Activate {
        /// Switch delay in ms.
        #[arg(default_value_t = 1000)]
        delay_ms: u16,
    },
    /// Store the configuration in the slave's non-volatile memory.
    Store,
    /// Inquire the identity and node-ID of the slave in configuration state.
    Inquire,
    /// Find an unconfigured slave with FASTSCAN (it is left in configuration state).
    Fastscan,
    /// Give every unconfigured slave a node id: fastscan, set node, store, back to waiting.
    Assign {
        /// Node ids to hand out in order, e.g. 2,3,4.
        #[arg(value_delimiter = ',', required = true)]
        nodes: Vec<u8>,
        /// Also configure this bit rate (activated later with `lss activate`).
        #[arg(long)]
        bitrate: Option<u32>,
    },
}

/// Options of `motus sim icla`.
#[derive(Debug, Args)]
pub struct SimIclaArgs {
    /// The bus to join, e.g. `socketcand://127.0.0.1:29536/can0`.
    #[arg(long, required_unless_present = "write_eds")]
    pub bus: Option<String>,
    /// One drive at this node id (default 127, the IclA's factory id).
    #[arg(long, conflicts_with = "nodes")]
    pub node: Option<u8>,
    /// Several drives at these node ids, e.g. 2,3,4.
    #[arg(long, value_delimiter = ',')]
    pub nodes: Vec<u8>,
    /// LSS-unconfigured drives with these serial numbers (they wait for LSS to get a node id).
    #[arg(long, value_delimiter = ',')]
    pub unconfigured: Vec<u32>,
    /// Write the simulated drive's EDS to this file and exit.
    #[arg(long)]
    pub write_eds: Option<PathBuf>,
    /// Delay from start to the boot-up message, ms (the real IclA: about 4000).
    #[arg(long, default_value_t = 0)]
    pub boot_delay_ms: u64,
    /// The three drives form the omnidirectional robot: serve its optical-mouse sensor on
    /// a pty at this path (`pty:PATH`).
    #[arg(long)]
    pub robot_mouse: Option<String>,
    /// Robot wheel slip per wheel, e.g. `0.1,0,0` (needs three drives).
    #[arg(long, value_delimiter = ',')]
    pub slip: Vec<f64>,
    /// Fault injection: stop this node's heartbeats (and every answer) after N ms, as `NODE:MS`.
    #[arg(long)]
    pub silence: Option<String>,
    /// Fault injection: raise a drive fault (EMCY + fault state) on NODE after MS with CODE
    /// (hex) that clears CLEAR ms later, as `NODE:MS:CODE[:CLEAR]`.
    #[arg(long)]
    pub fault: Option<String>,
    /// Probability of corrupting each frame the drives send (counted and ignored by CAN receivers).
    #[arg(long, default_value_t = 0.0)]
    pub corrupt_rate: f64,
}

/// Options of `motus sim mouse`.
#[derive(Debug, Args)]
pub struct SimMouseArgs {
    /// Where to serve: `pty:PATH`.
    #[arg(long)]
    pub link: String,
    /// Scripted motion: constant velocity x,y in mm/s.
    #[arg(long, value_delimiter = ',', default_value = "0,0")]
    pub velocity: Vec<f64>,
    /// Device type byte: i (Microsoft mouse), m (Mouse Systems), n (nothing), d, k.
    #[arg(long, default_value = "i")]
    pub device: char,
    /// Probability of a garbage burst before a packet.
    #[arg(long, default_value_t = 0.0)]
    pub garbage_rate: f64,
}

/// Options of `motus robot`.
#[derive(Debug, Args)]
pub struct RobotArgs {
    /// The CAN bus of the three wheel drives (not needed for `bus-load`).
    #[arg(long)]
    pub bus: Option<String>,
    /// Node ids of wheels 1, 2, 3.
    #[arg(long, value_delimiter = ',', default_value = "2,3,4")]
    pub nodes: Vec<u8>,
    /// Serial port of the optical-mouse sensor (9600 bit/s), for slip detection.
    #[arg(long)]
    pub mouse: Option<String>,
    /// Zero the wheel positions (homing on the current position) first.
    #[arg(long)]
    pub home: bool,
    /// Ramp: 1 (500 Inc/s), 2 (200 Inc/s) or seed (248 Inc/s).
    #[arg(long, default_value = "1")]
    pub ramp: String,
    /// Print JSON.
    #[arg(long, global = true)]
    pub json: bool,
    /// What to do.
    #[command(subcommand)]
    pub action: RobotAction,
}

/// Robot actions.
#[derive(Debug, Subcommand)]
pub enum RobotAction {
    /// Run a demo program: line, square, octagon, zero.
    Demo {
        /// Program name.
        program: String,
    },
    /// Go to x, y (metres, world frame) and optionally heading (degrees).
    Goto {
        /// x in metres.
        x: f64,
        /// y in metres.
        y: f64,
        /// Heading in degrees.
        heading: Option<f64>,
        /// Go through the origin first.
        #[arg(long)]
        via_origin: bool,
    },
    /// Print the pose (and the wheel positions).
    Pose,
    /// Quick stop every wheel.
    Stop,
    /// Print the modelled bus load of the robot's cycle at 20 kbit/s and 1 Mbit/s.
    BusLoad {
        /// Control cycle in ms.
        #[arg(long, default_value_t = 10.0)]
        cycle_ms: f64,
    },
}
