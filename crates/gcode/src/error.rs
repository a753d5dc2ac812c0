//! Errors: every error names the 1-based source line and column where it was found.

use std::fmt;

/// What was wrong (the message follows LinuxCNC's wording where LinuxCNC has one).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ErrorKind {
    /// A `(` inside a comment (LinuxCNC: "Nested comment found").
    #[error("Nested comment found")]
    NestedComment,
    /// A `(` comment without its `)`.
    #[error("Unclosed comment found")]
    UnclosedComment,
    /// A character that starts no word.
    #[error("Bad character used: '{0}'")]
    BadCharacter(char),
    /// A word letter this interpreter does not implement.
    #[error("Unsupported word letter: '{0}'")]
    UnsupportedLetter(char),
    /// A number could not be read.
    #[error("Bad number format")]
    BadNumber,
    /// The line ended where a value was expected.
    #[error("Missing value after '{0}'")]
    MissingValue(char),
    /// A malformed expression (`[..]`).
    #[error("Bad expression: {0}")]
    BadExpression(&'static str),
    /// A name that is no function or operator.
    #[error("Unknown operation or function: {0}")]
    UnknownOperation(String),
    /// A function argument outside its domain (SQRT of a negative number, ...).
    #[error("Argument out of range for {0}")]
    FunctionDomain(&'static str),
    /// Division (or MOD) by zero.
    #[error("Attempt to divide by zero")]
    DivideByZero,
    /// A numbered parameter outside 1..=5602.
    #[error("Parameter number out of range: {0}")]
    ParameterOutOfRange(f64),
    /// A named parameter read before it was set.
    #[error("Named parameter #<{0}> not defined")]
    UndefinedNamedParameter(String),
    /// A polar word (`@`, `^`) beside an X or Y word.
    #[error("Cannot specify both polar coordinate and {0} word")]
    PolarWithAxis(char),
    /// A polar word in a block whose motion is not G0-G3.
    #[error("Polar coordinates (@, ^) are used by G0, G1, G2 and G3 only")]
    PolarWithoutStraightOrArc,
    /// A feed move under G93 without its F word.
    #[error("F word missing with inverse time g{0} move")]
    InverseTimeWithoutF(u8),
    /// A feed move under G95 with the spindle speed zero.
    #[error("Cannot feed with zero spindle speed in feed per rev mode")]
    ZeroSpindlePerRevolution,
    /// A feed move under G95 and G96 without the rpm limit (D) to plan its speed with.
    #[error("Feed per revolution under G96 needs its D word (the rpm limit) to plan the move")]
    PerRevolutionUnderCssWithoutLimit,
    /// A canned cycle under G93 (inverse time).
    #[error("Canned cycles need G94 or G95, not inverse time (G93)")]
    CycleInverseTime,
    /// A P, Q, R, L or H word in a block with no code that uses it (LinuxCNC's check).
    #[error("{0} word with no {1} to use it")]
    WordWithoutCode(char, &'static str),
    /// Cutter radius compensation: misuse, or a path the tool cannot follow.
    #[error("{0}")]
    CutterComp(CompError),
    /// G41.1/G42.1 without the D word (the diameter).
    #[error("{0} with no D word")]
    CompNoD(&'static str),
    /// G41.1/G42.1 with an L word (a lathe tool orientation) outside G18.
    #[error("{0} with L word, but plane is not G18")]
    CompLWordNotG18(&'static str),
    /// G41/G42 D naming a lathe tool (orientation 1-8) outside G18.
    #[error("{0} with lathe tool, but plane is not G18")]
    CompLatheToolNotG18(&'static str),
    /// G41/G42 with a D word that is not a whole, non-negative tool number.
    #[error("{0} requires D word to be a whole number")]
    CompDNotWhole(&'static str),
    /// A T or H word naming a tool that is not in the tool table.
    #[error("Requested tool {0} not found in the tool table")]
    ToolNotFound(u32),
    /// A T, H or similar word that is not a whole, non-negative number.
    #[error("Bad tool number: {0}")]
    BadToolNumber(f64),
    /// A canned cycle outside the XY plane (G18/G19 cycles are not implemented).
    #[error("Canned cycles are implemented in the XY plane (G17) only")]
    CycleOutsideXy,
    /// A rotary axis word in a canned-cycle block.
    #[error("Cannot put an {0} in canned cycle")]
    RotaryInCycle(char),
    /// L below 1 in a canned-cycle block.
    #[error("Cannot do zero repeats of cycle")]
    CycleRepeats,
    /// The first block of a canned cycle without its R word.
    #[error("R clearance plane unspecified in cycle")]
    CycleWithoutR,
    /// A canned cycle with the feed rate still zero.
    #[error("Cannot feed with zero feed rate")]
    CycleZeroFeed,
    /// The first block of a canned cycle without its Z word.
    #[error("Z value unspecified in xy plane canned cycle")]
    CycleWithoutZ,
    /// The R plane below the cycle's bottom.
    #[error("R less than z in cycle in xy plane")]
    CycleRBelowZ,
    /// The first G82/G89 block without its dwell.
    #[error("Dwell time P word missing with G{0}")]
    CycleWithoutP(u16),
    /// The first G73/G83 block without its peck depth.
    #[error("Q word missing with G{0}")]
    CycleWithoutQ(u16),
    /// A peck depth that is not positive.
    #[error("Negative or zero q value used: {0}")]
    CycleQNotPositive(f64),
    /// One canned-cycle block would make more moves than the interpreter allows.
    #[error("Canned cycle block would make more than {0} moves (L repeats x pecks)")]
    CycleTooManyMoves(u64),
    /// A cycle the seed's drilling technology cannot do (G82, G85, G89).
    #[error("G{0} cannot run on the drilling technology: its unit drills (G81) and pecks (G73, G83), but cannot dwell at the bottom or feed out of the hole")]
    CycleNotOnTechnology(u16),
    /// A drilling-technology cycle without a spindle speed the unit takes (EXW60: 1-32767).
    #[error("Spindle speed S{0} out of the drilling technology's range (1-32767 rpm) for a canned cycle")]
    TechnologySpindleSpeed(f64),
    /// A drilling-technology hole whose bottom is not below the material surface (Z 0).
    #[error("Hole bottom Z{0} is not below the material surface (Z0) for the drilling technology")]
    HoleNotBelowSurface(f64),
    /// An assignment to one of LinuxCNC's read-only named parameters (`#<_feed>`, ...).
    #[error("Cannot assign to read-only parameter #<{0}>")]
    ReadOnlyNamedParameter(String),
    /// An assignment to a read-only numbered parameter (tool data #5400-#5413, the current
    /// position #5420-#5428).
    #[error("Parameter is readonly: #{0}")]
    ReadOnlyParameter(usize),
    /// A value that must be an integer is not one.
    #[error("Non-integer value for integer: {0}")]
    NonInteger(f64),
    /// A word given twice in one block.
    #[error("Multiple {0} words on one line")]
    DuplicateWord(char),
    /// Two G codes of the same modal group in one block.
    #[error("Two g codes used from same modal group")]
    GModalConflict,
    /// Two M codes of the same modal group in one block.
    #[error("Two m codes used from same modal group")]
    MModalConflict,
    /// A G code this interpreter does not implement.
    #[error("Unknown or unsupported g code used: G{0}")]
    UnsupportedG(f64),
    /// An M number outside 0..=1023.
    #[error("Unknown m code used: M{0}")]
    UnsupportedM(f64),
    /// Axis words without a motion (or G10/G92/G53) to use them.
    #[error("Cannot use axis values without a g code that uses them")]
    AxisWithoutMotion,
    /// Motion with the feed rate still zero.
    #[error("Cannot do g{0} with zero feed rate")]
    ZeroFeed(u8),
    /// A G0/G1 with no axis word.
    #[error("All axes missing with motion code")]
    AllAxesMissing,
    /// G2/G3 with neither R nor a centre word.
    #[error("R, I, J, or K words missing for arc")]
    ArcMissingCentre,
    /// G2/G3 with both R and centre words.
    #[error("Mixed radius-ijk format for arc")]
    ArcMixedFormat,
    /// A centre word that does not belong to the selected plane.
    #[error("{0} word given for arc in {1} plane")]
    ArcWrongCentreWord(char, &'static str),
    /// The arc's end radius differs from its start radius (LinuxCNC's rule and wording).
    #[error(
        "Radius to end of arc differs from radius to start: start=({a}{:.4},{b}{:.4}) center=({a}{:.4},{b}{:.4}) end=({a}{:.4},{b}{:.4}) r1={r1:.4} r2={r2:.4} abs_err={} rel_err={rel_err:.4}%",
        start.0, start.1, centre.0, centre.1, end.0, end.1, crate::error::format_g4(*abs_err),
        a = axes.0, b = axes.1
    )]
    ArcRadiusMismatch {
        /// The plane's two axes (X Y under G17, Z X under G18, Y Z under G19).
        axes: (char, char),
        /// Start, centre and end in the plane (program units).
        start: (f64, f64),
        /// See [`ErrorKind::ArcRadiusMismatch::start`].
        centre: (f64, f64),
        /// See [`ErrorKind::ArcRadiusMismatch::start`].
        end: (f64, f64),
        /// Radius from the centre to the start point.
        r1: f64,
        /// Radius from the centre to the end point.
        r2: f64,
        /// |r1 - r2|.
        abs_err: f64,
        /// |r1 - r2| / max(r1, r2) * 100.
        rel_err: f64,
    },
    /// An arc with (near) zero radius.
    #[error("Zero-radius arc")]
    ZeroRadiusArc,
    /// R-form arc with the end point equal to the start point.
    #[error("Current point same as end point of arc")]
    ArcSameEndPoint,
    /// R-form arc whose radius cannot reach the end point.
    #[error("Arc radius too small to reach end point")]
    ArcRadiusTooSmall,
    /// G2/G3 P word that is not a positive integer.
    #[error("P value not an integer or less than one with G2/G3")]
    ArcBadTurns,
    /// G4 without P.
    #[error("Dwell time missing with g4")]
    DwellMissing,
    /// A negative dwell.
    #[error("Negative P word used with g4")]
    NegativeDwell,
    /// G53 in incremental mode.
    #[error("Cannot use g53 incremental")]
    G53Incremental,
    /// G53 with something other than G0/G1.
    #[error("Must use g0 or g1 with g53")]
    G53WithoutStraight,
    /// G10 with a bad or missing L/P.
    #[error("Invalid G10 use: {0}")]
    BadG10(&'static str),
    /// M60-M68 in the LinuxCNC dialect with missing or bad words (LinuxCNC's message).
    #[error("{0}")]
    BadIo(&'static str),
    /// G92 without an axis word.
    #[error("All axes missing with g92")]
    G92NoAxes,
    /// Axis and G10/G92 in one block, or two axis-word users.
    #[error("Cannot use two g codes that both use axis values")]
    TwoAxisUsers,
    /// A negative feed rate.
    #[error("Negative f word used")]
    NegativeFeed,
    /// A negative spindle speed.
    #[error("Negative spindle speed used")]
    NegativeSpindle,
    /// An O-word problem (unknown keyword, unmatched structure, ...).
    #[error("O-word error: {0}")]
    OWord(String),
    /// A `call` of a subroutine that is never defined.
    #[error("Unknown subroutine: o{0}")]
    UnknownSub(String),
    /// Subroutine calls nested too deep.
    #[error("Too many nested subroutine calls (limit {0})")]
    CallDepth(usize),
    /// The configured limit on executed lines was reached (endless loop guard).
    #[error("Too many lines executed (limit {0}); endless loop?")]
    StepLimit(u64),
    /// The interpreter's [`crate::CancelFlag`] was set (after this many lines executed).
    #[error("Interpretation cancelled after {0} lines")]
    Cancelled(u64),
    /// An EX external parameter word is malformed.
    #[error("Bad external parameter: {0}")]
    BadExternal(&'static str),
    /// An EX value does not fit the array's type.
    #[error("External parameter value {value} out of range for EX{array}")]
    ExternalRange {
        /// Array letter (B, W, L, F).
        array: char,
        /// The value given.
        value: f64,
    },
    /// The program ended without M2/M30 or a closing `%`.
    #[error("File ended with no percent sign or program end")]
    NoProgramEnd,
}

/// An interpreter error with the 1-based line and column of its source.
#[derive(Debug, Clone, PartialEq)]
pub struct GcodeError {
    /// 1-based line number in the program text.
    pub line: u32,
    /// 1-based column (in characters) where the offending item starts.
    pub column: u32,
    /// What went wrong.
    pub kind: ErrorKind,
    /// Optional file name shown in front of the position by `Display`.
    pub file: Option<String>,
}

impl GcodeError {
    /// A new error at `line:column`.
    pub fn new(line: u32, column: u32, kind: ErrorKind) -> Self {
        Self { line, column, kind, file: None }
    }

    /// The same error, displayed as `file:line:column: message`.
    #[must_use]
    pub fn with_file(mut self, file: impl Into<String>) -> Self {
        self.file = Some(file.into());
        self
    }
}

impl fmt::Display for GcodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(file) = &self.file {
            write!(f, "{file}:")?;
        }
        write!(f, "{}:{}: {}", self.line, self.column, self.kind)
    }
}

impl std::error::Error for GcodeError {}

/// A cutter radius compensation error (LinuxCNC's wording).
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum CompError {
    /// G41/G42 under G19.
    #[error("Cutter radius compensation allowed only in XY, XZ planes")]
    PlaneNotXyOrXz,
    /// G41/G42 while compensation is on.
    #[error("Cannot turn cutter radius comp on when on")]
    AlreadyOn,
    /// A G41.1/G42.1 L word outside 0-9.
    #[error("Invalid tool orientation")]
    InvalidOrientation,
    /// G17/G18/G19 changing the plane while on.
    #[error("Cannot change planes with cutter radius compensation on")]
    PlaneChange,
    /// G54-G59.3 while on.
    #[error("Cannot change coordinate systems with cutter radius compensation on")]
    CoordSystemChange,
    /// G10 L2/L20 on the active coordinate system while on.
    #[error("Cannot change the active coordinate system with cutter radius compensation on")]
    ActiveSystemChange,
    /// G61/G61.1/G64 while on.
    #[error("Cannot change control mode with cutter radius compensation on")]
    ControlModeChange,
    /// G98/G99 while on.
    #[error("Cannot change retract mode with cutter radius compensation on")]
    RetractModeChange,
    /// G52/G92/G92.x while on.
    #[error("Cannot change axis offsets with cutter radius comp")]
    AxisOffsetChange,
    /// G28/G30 while on.
    #[error("Cannot use g28 or g30 with cutter radius comp")]
    ReferenceMove,
    /// G28.1/G30.1 while on.
    #[error("Cannot set reference point with cutter compensation in effect")]
    ReferenceSet,
    /// A canned cycle while on.
    #[error("Cannot use canned cycles with cutter compensation on")]
    CannedCycle,
    /// G53 while on.
    #[error("Cannot use g53 with cutter radius comp")]
    MachineCoordinates,
    /// M6 while on.
    #[error("Cannot change tools with cutter radius compensation on")]
    ToolChange,
    /// G43/G43.1/G49 while on.
    #[error("Cannot change tool offset with cutter radius compensation on")]
    ToolOffsetChange,
    /// M62/M63 while on.
    #[error("Cannot set motion output with cutter radius compensation on")]
    MotionDigitalOutput,
    /// M64/M65 while on.
    #[error("Cannot set auxiliary digital output with cutter radius compensation on")]
    AuxDigitalOutput,
    /// M66 P while on.
    #[error("Cannot wait for digital input with cutter radius compensation on")]
    DigitalInputWait,
    /// M66 E while on.
    #[error("Cannot wait for analog input with cutter radius compensation on")]
    AnalogInputWait,
    /// M67 while on.
    #[error("Cannot set motion analog output with cutter radius compensation on")]
    MotionAnalogOutput,
    /// M68 while on.
    #[error("Cannot set auxiliary analog output with cutter radius compensation on")]
    AuxAnalogOutput,
    /// An arc as the first move after G40.
    #[error("The move just after exiting cutter compensation mode must be straight, not an arc")]
    ArcAfterExit,
    /// A straight entry move not longer than the tool radius.
    #[error("Length of cutter compensation entry move is not greater than the tool radius")]
    EntryTooShort,
    /// An entry arc ending within a tool radius of its start.
    #[error("Radius of cutter compensation entry arc is not greater than the tool radius")]
    EntryArcTooShort,
    /// An arc the tool, inside it, does not fit in.
    #[error("Tool radius not less than arc radius with comp")]
    ArcTooSmall,
    /// A straight move going straight back.
    #[error("Zero degree inside corner is invalid for cutter compensation")]
    ZeroDegreeCorner,
    /// A concave corner moves a held feed move's end behind its start.
    #[error("Straight feed in concave corner cannot be reached by the tool without gouging")]
    StraightFeedGouge,
    /// A concave corner moves a held traverse's end behind its start.
    #[error("Straight traverse in concave corner cannot be reached by the tool without gouging")]
    StraightTraverseGouge,
    /// A concave corner the arc cannot reach, or lengthens a held arc.
    #[error("Arc move in concave corner cannot be reached by the tool without gouging")]
    ArcGouge,
    /// An arc then a line meeting where the tool cannot fit.
    #[error("Arc to straight motion makes a corner the compensated tool can't fit in without gouging")]
    ArcToStraightGouge,
    /// Two arcs meeting where the tool cannot fit.
    #[error("Arc to arc motion makes a corner the compensated tool can't fit in without gouging")]
    ArcToArcGouge,
    /// Two arcs with the same centre meeting in a concave corner.
    #[error("Arc to arc motion is invalid because the arcs have the same center")]
    ArcToArcSameCentre,
    /// Moving a held arc's end changed its radius (a bug, as LinuxCNC words it).
    #[error("BUG: cutter compensation has generated an invalid arc")]
    InvalidArc,
}

/// An error without position yet (filled in by the caller that knows the column).
pub(crate) type KResult<T> = Result<T, (u32, ErrorKind)>;

/// A number as C's `%.4g` prints it (four significant digits, no trailing zeros; an
/// exponent for very small or large values), for LinuxCNC's wording.
pub(crate) fn format_g4(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let exp = v.abs().log10().floor() as i32;
    if !(-4..4).contains(&exp) {
        let s = format!("{v:.3e}");
        // Rust prints 1.235e-5; C prints 1.235e-05.
        let (m, e) = s.split_once('e').unwrap_or((&s, "0"));
        let m = m.trim_end_matches('0').trim_end_matches('.');
        let (sign, digits) = e.strip_prefix('-').map_or(("+", e), |d| ("-", d));
        return format!("{m}e{sign}{digits:0>2}");
    }
    let decimals = usize::try_from(3 - exp).unwrap_or(0);
    let s = format!("{v:.decimals$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_owned()
    } else {
        s
    }
}
