//! Sans-IO RS274/NGC G-code interpreter (LinuxCNC dialect) producing canonical calls.
//!
//! ```
//! use motus_gcode::{interpret, format_canon, Precision};
//! let calls = interpret("G21 G90\nG1 X10 Y5 F100\nM2\n").unwrap();
//! let text: Vec<String> = calls.iter().map(|c| format_canon(&c.canon, Precision::Full)).collect();
//! assert!(text.contains(&"STRAIGHT_FEED(10, 5, 0, 0, 0, 0)".to_string()));
//! ```
//!
//! * Dialect: LinuxCNC's `rs274` is the reference (see `tests/rs274_oracle.rs`); the
//!   canonical stream uses its call names, argument order and coordinate conventions
//!   (see [`canon`]). Differences: interpreter-generated `COMMENT("interpreter: ...")`
//!   lines and `ON_RESET()` are not emitted; unsupported codes (U/V/W, canned cycles
//!   outside G17, polar words outside G0-G3) are errors.
//! * Coordinate-system rotation: `G10 L2 P.. R..` sets the rotation about Z of G54..G59.3
//!   (degrees, #5230 + 20 k: #5230 for G54, #5250 for G55, ...; R with L20 is an error, as
//!   in LinuxCNC). The active system's rotation turns every programmed XY (lines, arcs
//!   and their centres, cycles, polar moves) about its origin, the G92/G52 offset applied
//!   in the rotated frame; the calls keep program coordinates after
//!   `SET_XY_ROTATION(r)` (emitted with each `SET_G5X_OFFSET` of the active system), while
//!   the [`MachineMove`]s, `#<_abs_x>`/`#<_abs_y>`, G53, G28/G30 and G28.1/G30.1 go through
//!   it. G10 L20 touches off in the target system's rotated frame; selecting a system,
//!   changing the active one's origin or rotation, a tool offset in X/Y and M2/M30 (back
//!   to G54 and its rotation) move the current point as LinuxCNC does.
//! * Cutter radius compensation (`interp/cutter_comp.rs`) as LinuxCNC 2.9 does it, in
//!   G17 (XY) and G18 (XZ: Z and X are the plane's first and second coordinates):
//!   G41/G42 (D: the tool whose radius is used; none or D0: the spindle's tool),
//!   G41.1/G42.1 (D: the diameter, negative swaps the side; L: a lathe orientation, G18
//!   only), G40. Each compensated move is held back until the next one is known: a concave
//!   corner moves the held end point back, a convex one gets an arc about the corner (G0:
//!   a straight traverse); a straight entry move ends a radius beside its programmed end,
//!   square to the move, an entry arc is tangent to the tool at its start; after G40 the
//!   next move starts from the compensated point and must be straight. Feed, spindle,
//!   coolant, dwell and comment calls wait behind the held move (as LinuxCNC queues them);
//!   M0/M1/M2/M30 send it. G93 rates are the programmed move's; G20/G21 scale the held
//!   moves as LinuxCNC's `qc_scale` does; a lathe tool orientation (table Q, or L) shifts
//!   the moves sent to the tool's origin (`latheorigin_x/z`). LinuxCNC's errors at the
//!   same line: gouging in concave corners, tool too large for an arc, entry move too
//!   short, comp already on, G19, G53, canned cycles, G28/G30, G28.1/G30.1, M6, G43/G49,
//!   G52/G92, G54-G59.3, G10 on the active system, G61/G64, G98/G99 or a plane change
//!   while on. `#<_ccomp>` is 400, 410 (left) or 420 (right); the position parameters
//!   (#5420-, `#<_x>`, `#<_abs_x>`) give the compensated tool's position, as LinuxCNC's do.
//! * Feed modes G93 (inverse time: the rate is sent before each move), G94, G95 (per
//!   revolution: planned with the S word, or G96's D limit), spindle modes G96/G97; every
//!   feed move's [`MachineMove`] carries its rate in mm/min.
//! * Canned cycles G73, G81, G82, G83, G85, G89 (G98/G99, L repeats, sticky words, G80)
//!   and path control G61, G61.1, G64 P Q (`SET_MOTION_CONTROL_MODE`,
//!   `SET_NAIVECAM_TOLERANCE`) as LinuxCNC emits them; one cycle block makes at most
//!   100,000 moves (LinuxCNC has no bound).
//! * Parameters as LinuxCNC 2.9 keeps them: the current position #5420-#5428 and the
//!   predefined named parameters (`#<_x>`, `#<_abs_x>`, `#<_feed>`, `#<_motion_mode>`,
//!   `#<_coord_system>`, ...: the list is `params::SYSTEM_NAMES`) are set before each line
//!   is read; they and the tool data #5400-#5413 are read-only (an assignment is an error).
//!   #5220 is 1 (G54) from the start. G92 saves its offsets in #5211-#5216 with the flag
//!   #5210, G92.1 clears both, G92.2 clears the flag only (G92.3 brings them back). Saved
//!   offsets are in millimetres, the machine's units (the standalone `rs274` keeps them in
//!   inches: a program that reads #5211 directly sees 25.4 times its value here).
//! * Tools: T, M6 (non-random changer: `CHANGE_TOOL` with the tool's place in the table,
//!   the spindle stopped), G43 (H word), G43.1, G49 with a tool table
//!   ([`InterpreterConfig::tools`], LinuxCNC's `.tbl` format read by [`parse_tool_table`]);
//!   the tool length offset moves the controlled point as in LinuxCNC. Unlike `rs274`, an
//!   offset in force is converted when G20/G21 changes the units.
//! * M-code dialect, per machine ([`InterpreterConfig::m_codes`], [`MCodeDialect`]): the
//!   seed's (default: M60-M68 are M-functions, the seed's drilling machine uses M60-M64)
//!   or LinuxCNC's, where M60 is `PALLET_SHUTTLE` + `PROGRAM_STOP`, M61 Q declares the
//!   spindle's tool (`CHANGE_TOOL_NUMBER`, #5400.. and G43 follow, as in a running
//!   LinuxCNC; the standalone `rs274` leaves its tool data unchanged), M62/M63 P and
//!   M64/M65 P switch digital outputs with the next move or at once
//!   ([`Canon::DigitalOutput`]), M67/M68 E Q set analog outputs ([`Canon::AnalogOutput`]),
//!   M66 P|E L Q waits on an input ([`Canon::WaitInput`], which `rs274` does not print;
//!   #5399 keeps its value: the input is the machine's). LinuxCNC's checks and messages;
//!   stricter than it, M67/M68 without Q (LinuxCNC sends -1) and M66 L outside 0..=4
//!   are errors. The E word exists only in the LinuxCNC dialect.
//! * Canned cycles per machine ([`InterpreterConfig::cycles`], [`CycleOutput`]): LinuxCNC's
//!   moves (default), or the seed's drilling technology, where each hole of G81/G73/G83 is
//!   the unit's M60 job with EXW60/EXF61/EXF62 and a peck increment (EXF63, EXB64), Z 0 is
//!   the material surface, and M6 activates the drilling technology (M63).
//! * `(DEBUG,text)` is a message and `(PRINT,text)` a comment, each with the values of the
//!   parameters named in `text` (six decimals, `######` for one not defined).
//! * Seed additions: every M number 0..=1023 other than M0-M9, M30 is an
//!   M-function ([`Canon::MFunction`], synchronous unless listed in
//!   [`InterpreterConfig::async_m_functions`]), executed before the block's motion
//!   (in the LinuxCNC dialect below, all but M60-M68);
//!   `EX<B|W|L|F><0..99>=value` writes an external parameter ([`Canon::ExternalParameter`]),
//!   executed right after the block's comment, before its M-functions.
//! * Speed: a line is parsed into reused buffers (plain words straight from the text,
//!   expressions compiled to postfix instructions), so interpretation allocates nothing
//!   per line beyond its canonical calls. `benches/interpret.rs` measures lines per
//!   second; `examples/vs_rs274.rs` times LinuxCNC's `rs274` on the same program.
#![forbid(unsafe_code)]

mod arc;
mod block;
pub mod canon;
pub mod error;
mod expr;
pub mod format;
mod interp;
mod params;
mod parse;
pub mod tools;
mod value;

pub use canon::{
    ArcFeed, Canon, CanonCall, ExArray, ExValue, MSync, MachineMove, MotionControl, Plane, Pose, Units,
    WaitMode,
};
pub use error::{CompError, ErrorKind, GcodeError};
pub use format::{format_canon, format_line, write_canon, write_line, Precision};
pub use interp::{
    interpret, interpret_with, CancelFlag, CycleOutput, Interpreter, InterpreterConfig, MCodeDialect,
};
pub use tools::{parse_tool_table, Tool, ToolTableError};
