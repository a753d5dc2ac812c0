//! A simulated drilling machine, so whole programs run without hardware.
//!
//! Geometry (all mm, machine coordinates):
//!
//! * The real gantry axes X/Y carry the cutting tool; they follow the CNC's virtual X/Y
//!   1:1 with an offset (real = virtual + offset) that changes only while decoupled
//!   ([`Coupling`]). The drill sits at `drill_mount` from the cutting tool, so the drill's
//!   position on the material is `gantry + drill_mount`.
//! * `z` is the height of the drilling unit's spindle nose above the table (up positive),
//!   limited to `z_min..=z_max` (`z_max` is the upper limit switch) and `z_max_speed`.
//!   The tool tip is at `z - tool_length`.
//! * The spring-loaded pressure plate hangs `plate_drop` below the nose. Once it touches
//!   the material it is pushed up relative to the unit; after `reference_travel` of that
//!   compression the reference switch closes. So the switch is on while
//!   `z <= surface + plate_drop - reference_travel`, and the tool tip is then
//!   `plate_drop - reference_travel - tool_length` above the material.
//! * The material surface height comes from a [`Surface`] at the drill's position.
//!
//! The machine records every hole (the tool tip going below the surface and coming back
//! up) with its depth, the spindle speed at the deepest point and the feed, and records
//! [`MachineEvent`]s for what would damage a real machine.

use crate::setpoint::{Coupling, ZCommand};

/// Height of the material surface (mm above the table) as a function of the position.
#[derive(Debug, Clone, Copy)]
pub enum Surface {
    /// The same height everywhere.
    Flat(f64),
    /// A tilted plane: `height + slope_x * x + slope_y * y`.
    Plane {
        /// Height at x = y = 0.
        height: f64,
        /// mm per mm along X.
        slope_x: f64,
        /// mm per mm along Y.
        slope_y: f64,
    },
    /// Any function of the (drill) position.
    Custom(fn([f64; 2]) -> f64),
}

impl Surface {
    /// The surface height at `xy`.
    pub fn height(&self, xy: [f64; 2]) -> f64 {
        let [x, y] = xy;
        match *self {
            Self::Flat(h) => h,
            Self::Plane { height, slope_x, slope_y } => height + slope_x * x + slope_y * y,
            Self::Custom(f) => f(xy),
        }
    }
}

/// The machine's fixed data.
#[derive(Debug, Clone, Copy)]
pub struct MachineConfig {
    /// Lowest Z, mm.
    pub z_min: f64,
    /// Highest Z (upper limit switch), mm.
    pub z_max: f64,
    /// Fastest Z speed, mm/min.
    pub z_max_speed: f64,
    /// Z at start, mm.
    pub initial_z: f64,
    /// Length of the tool in the spindle, mm.
    pub tool_length: f64,
    /// Distance from the spindle nose down to the free (uncompressed) plate, mm.
    pub plate_drop: f64,
    /// Compression of the plate from first contact to the switch, mm.
    pub reference_travel: f64,
    /// Largest compression of the plate, mm.
    pub plate_stroke: f64,
    /// Position of the drill relative to the cutting tool (X, Y), mm.
    pub drill_mount: [f64; 2],
    /// The material surface.
    pub surface: Surface,
}

impl Default for MachineConfig {
    /// Numbers chosen to match [`crate::DrillingPara::default`]: tool 80 mm, reference
    /// travel 3 mm, tool tip 5 mm above the material at the switch
    /// (`plate_drop = 5 + 3 + 80 = 88`), 20 mm plate on the table, upper limit 400 mm,
    /// drill 120 mm in X and -45 mm in Y from the cutting tool.
    fn default() -> Self {
        Self {
            z_min: 0.0,
            z_max: 400.0,
            z_max_speed: 6000.0,
            initial_z: 380.0,
            tool_length: 80.0,
            plate_drop: 88.0,
            reference_travel: 3.0,
            plate_stroke: 150.0,
            drill_mount: [120.0, -45.0],
            surface: Surface::Flat(20.0),
        }
    }
}

/// What drives the machine in one cycle.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MachineCommand {
    /// Position of the CNC's virtual X/Y axes (program coordinates), mm.
    pub virtual_xy: [f64; 2],
    /// Coupling of the real X/Y to the virtual ones.
    pub coupling: Coupling,
    /// Z set-point.
    pub z: ZCommand,
    /// Spindle motor speed, rpm.
    pub spindle_rpm: f64,
    /// Material clamp (the prototype has none; recorded only).
    pub clamp: bool,
}

/// What the machine's sensors and axes report after a cycle.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MachineFeedback {
    /// Simulated time, s.
    pub time: f64,
    /// Z of the drilling unit, mm.
    pub z: f64,
    /// Z is at the commanded target (or holding).
    pub z_in_position: bool,
    /// The command asked for a Z beyond the travel.
    pub z_limit: bool,
    /// The pressure plate's reference switch.
    pub plate_switch: bool,
    /// The exact Z at which the switch closed during this cycle (a probe latch).
    pub switch_latch: Option<f64>,
    /// Real gantry X/Y (cutting tool), mm.
    pub gantry_xy: [f64; 2],
    /// Drill position (gantry + mount), mm.
    pub tool_xy: [f64; 2],
    /// Real - virtual X/Y, mm.
    pub xy_offset: [f64; 2],
    /// Whether the real axes are coupled to the virtual ones.
    pub xy_coupled: bool,
    /// Material surface under the drill, mm.
    pub surface: f64,
    /// Plate compression (0 when not touching), mm.
    pub plate_compression: f64,
    /// The clamp output as last commanded.
    pub clamp: bool,
}

/// One drilled hole.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hole {
    /// Gantry (real X/Y) position while drilling, mm.
    pub gantry_xy: [f64; 2],
    /// Drill position on the material, mm.
    pub tool_xy: [f64; 2],
    /// Deepest point of the tool tip below the surface, mm.
    pub depth: f64,
    /// Spindle speed at the deepest point, rpm (negative in reverse).
    pub spindle_rpm: f64,
    /// Fastest downward Z speed while the tip cut new material (deeper than the hole was),
    /// mm/min: the drilling feed, not a fast return into the hole between pecks.
    pub feed: f64,
    /// Time the tool left the hole, s.
    pub time: f64,
    /// Times the tool entered the hole (pecking out of the hole enters it again).
    pub entries: u32,
}

/// Something that would damage a real machine.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MachineEvent {
    /// The tool entered the material with the spindle standing still.
    ToolCrash {
        /// Drill position, mm.
        tool_xy: [f64; 2],
        /// Time, s.
        time: f64,
    },
    /// X/Y moved while the tool was in the material.
    MovedInMaterial {
        /// Drill position, mm.
        tool_xy: [f64; 2],
        /// Time, s.
        time: f64,
    },
    /// The plate was compressed beyond its stroke.
    PlateOvertravel {
        /// Compression, mm.
        compression: f64,
        /// Time, s.
        time: f64,
    },
    /// A Z target beyond the travel was commanded (and limited).
    ZLimit {
        /// Target asked for, mm.
        target: f64,
        /// Time, s.
        time: f64,
    },
}

#[derive(Debug, Clone, Copy)]
struct Cut {
    tool_xy: [f64; 2],
    gantry_xy: [f64; 2],
    depth: f64,
    rpm: f64,
    feed: f64,
    entries: u32,
}

/// The simulated machine.
#[derive(Debug, Clone)]
pub struct Machine {
    config: MachineConfig,
    time: f64,
    virtual_xy: [f64; 2],
    gantry_xy: [f64; 2],
    /// Real - virtual X/Y, kept exactly while coupled.
    offset: [f64; 2],
    coupled: bool,
    z: f64,
    clamp: bool,
    cut: Option<Cut>,
    over_stroke: bool,
    holes: Vec<Hole>,
    events: Vec<MachineEvent>,
    last: MachineFeedback,
}

fn add(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    let ([ax, ay], [bx, by]) = (a, b);
    [ax + bx, ay + by]
}

fn sub(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    let ([ax, ay], [bx, by]) = (a, b);
    [ax - bx, ay - by]
}

/// Moves `from` toward `to` by at most `step`, returning the new point.
pub(crate) fn approach(from: [f64; 2], to: [f64; 2], step: f64) -> [f64; 2] {
    let [dx, dy] = sub(to, from);
    let dist = dx.hypot(dy);
    if dist <= step || dist == 0.0 {
        to
    } else {
        let k = step / dist;
        add(from, [dx * k, dy * k])
    }
}

impl Machine {
    /// A machine at rest: virtual and real X/Y at 0, coupled, Z at `initial_z`.
    pub fn new(config: MachineConfig) -> Self {
        let mut m = Self {
            config,
            time: 0.0,
            virtual_xy: [0.0, 0.0],
            gantry_xy: [0.0, 0.0],
            offset: [0.0, 0.0],
            coupled: true,
            z: config.initial_z.clamp(config.z_min, config.z_max),
            clamp: false,
            cut: None,
            over_stroke: false,
            holes: Vec::new(),
            events: Vec::new(),
            last: MachineFeedback::default(),
        };
        m.last = m.sense(None, true, false);
        m
    }

    /// The configuration.
    pub fn config(&self) -> &MachineConfig {
        &self.config
    }

    /// The feedback of the last cycle (or of the rest state before the first).
    pub fn feedback(&self) -> MachineFeedback {
        self.last
    }

    /// Every hole drilled so far.
    pub fn holes(&self) -> &[Hole] {
        &self.holes
    }

    /// Every damaging event so far (empty on a good run).
    pub fn events(&self) -> &[MachineEvent] {
        &self.events
    }

    /// Changes the material (e.g. a new plate between programs).
    pub fn set_surface(&mut self, surface: Surface) {
        self.config.surface = surface;
    }

    fn switch_z(&self, surface: f64) -> f64 {
        surface + self.config.plate_drop - self.config.reference_travel
    }

    fn sense(&self, latch: Option<f64>, in_position: bool, z_limit: bool) -> MachineFeedback {
        let tool_xy = add(self.gantry_xy, self.config.drill_mount);
        let surface = self.config.surface.height(tool_xy);
        MachineFeedback {
            time: self.time,
            z: self.z,
            z_in_position: in_position,
            z_limit,
            plate_switch: self.z <= self.switch_z(surface),
            switch_latch: latch,
            gantry_xy: self.gantry_xy,
            tool_xy,
            xy_offset: self.offset,
            xy_coupled: self.coupled,
            surface,
            plate_compression: (surface - (self.z - self.config.plate_drop)).max(0.0),
            clamp: self.clamp,
        }
    }

    /// Advances the machine by `dt` seconds under `cmd`.
    pub fn step(&mut self, dt: f64, cmd: &MachineCommand) -> MachineFeedback {
        let dt = crate::task::sanitize_dt(dt);
        self.time += dt;
        self.clamp = cmd.clamp;
        let gantry_before = self.gantry_xy;

        // X/Y: real = virtual + offset; the offset changes only while decoupled.
        self.virtual_xy = cmd.virtual_xy;
        if cmd.coupling.coupled {
            self.coupled = true;
        } else {
            self.coupled = false;
            let step = cmd.coupling.shift_speed.max(0.0) / 60.0 * dt;
            self.offset = approach(self.offset, cmd.coupling.offset_target, step);
        }
        self.gantry_xy = add(self.virtual_xy, self.offset);

        // Z: a velocity-limited move to the target, limited to the travel.
        let z_before = self.z;
        let (mut in_position, mut z_limit) = (true, false);
        if let ZCommand::Move { target, speed } = cmd.z {
            let limited = target.clamp(self.config.z_min, self.config.z_max);
            if limited != target || !target.is_finite() {
                z_limit = true;
                if !self.last.z_limit {
                    self.events.push(MachineEvent::ZLimit { target, time: self.time });
                }
            }
            let limited = if limited.is_finite() { limited } else { self.z };
            let v = speed.clamp(0.0, self.config.z_max_speed) / 60.0;
            let step = v * dt;
            let d = limited - self.z;
            self.z = if d.abs() <= step { limited } else { self.z + step.copysign(d) };
            in_position = self.z == limited;
        }

        // The plate switch latches the exact Z it closed at.
        let tool_xy = add(self.gantry_xy, self.config.drill_mount);
        let surface = self.config.surface.height(tool_xy);
        let z_sw = self.switch_z(surface);
        let latch = (z_before > z_sw && self.z <= z_sw).then_some(z_sw);
        let fb = self.sense(latch, in_position, z_limit);

        if fb.plate_compression > self.config.plate_stroke {
            if !self.over_stroke {
                self.events.push(MachineEvent::PlateOvertravel {
                    compression: fb.plate_compression,
                    time: self.time,
                });
            }
            self.over_stroke = true;
        } else {
            self.over_stroke = false;
        }

        self.track_cut(fb, gantry_before, z_before, dt, cmd.spindle_rpm);
        self.last = fb;
        fb
    }

    fn track_cut(&mut self, fb: MachineFeedback, gantry_before: [f64; 2], z_before: f64, dt: f64, rpm: f64) {
        let depth = fb.surface - (fb.z - self.config.tool_length);
        let down_speed = if dt > 0.0 { (z_before - fb.z) / dt * 60.0 } else { 0.0 };
        if depth > 0.0 {
            let moved = gantry_before != fb.gantry_xy;
            match self.cut.as_mut() {
                None => {
                    if rpm.abs() < 1.0 {
                        self.events.push(MachineEvent::ToolCrash { tool_xy: fb.tool_xy, time: self.time });
                    }
                    // Back into the last hole (a peck): the same hole, entered again.
                    let again = self.holes.last().is_some_and(|h| {
                        (h.tool_xy[0] - fb.tool_xy[0]).hypot(h.tool_xy[1] - fb.tool_xy[1]) < 1e-6
                    });
                    let reopened = if again { self.holes.pop() } else { None };
                    self.cut = Some(match reopened {
                        Some(h) => Cut {
                            tool_xy: h.tool_xy,
                            gantry_xy: h.gantry_xy,
                            depth: h.depth,
                            rpm: h.spindle_rpm,
                            feed: h.feed,
                            entries: h.entries.saturating_add(1),
                        },
                        None => Cut {
                            tool_xy: fb.tool_xy,
                            gantry_xy: fb.gantry_xy,
                            depth,
                            rpm,
                            feed: down_speed.max(0.0),
                            entries: 1,
                        },
                    });
                }
                Some(cut) => {
                    if moved {
                        self.events
                            .push(MachineEvent::MovedInMaterial { tool_xy: fb.tool_xy, time: self.time });
                    }
                    if depth > cut.depth {
                        cut.depth = depth;
                        cut.rpm = rpm;
                        cut.feed = cut.feed.max(down_speed);
                    }
                }
            }
        } else if let Some(cut) = self.cut.take() {
            tracing::debug!(depth = cut.depth, rpm = cut.rpm, "hole drilled");
            self.holes.push(Hole {
                gantry_xy: cut.gantry_xy,
                tool_xy: cut.tool_xy,
                depth: cut.depth,
                spindle_rpm: cut.rpm,
                feed: cut.feed,
                time: self.time,
                entries: cut.entries,
            });
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
    use super::*;

    fn z_to(target: f64, speed: f64) -> MachineCommand {
        MachineCommand { z: ZCommand::Move { target, speed }, ..MachineCommand::default() }
    }

    #[test]
    fn switch_geometry_and_latch() {
        // Defaults: surface 20, plate_drop 88, reference travel 3 -> switch at z <= 105;
        // first contact at z = 108; tool tip at the switch = 105 - 80 = 25 = 5 above.
        let mut m = Machine::new(MachineConfig::default());
        assert!(!m.feedback().plate_switch);
        let cmd = z_to(100.0, 600.0); // 10 mm/s
        let mut latch = None;
        let mut touched_at = None;
        for _ in 0..30_000 {
            let fb = m.step(0.001, &cmd);
            if touched_at.is_none() && fb.plate_compression > 0.0 {
                touched_at = Some(fb.z);
            }
            if let Some(l) = fb.switch_latch {
                latch = Some(l);
                assert!(fb.plate_switch);
            }
        }
        assert_eq!(latch, Some(105.0));
        assert!((touched_at.unwrap() - 108.0).abs() < 0.011);
        let fb = m.feedback();
        assert_eq!(fb.z, 100.0);
        assert!(fb.z_in_position);
        assert!((fb.plate_compression - 8.0).abs() < 1e-9);
    }

    #[test]
    fn speed_limit_and_travel_limit() {
        let mut m = Machine::new(MachineConfig::default());
        // Asked 12000 mm/min, limited to 6000 = 100 mm/s: 0.1 s -> 10 mm.
        let fb = (0..100).map(|_| m.step(0.001, &z_to(0.0, 12000.0))).last().unwrap();
        assert!((fb.z - 370.0).abs() < 1e-9);
        let fb = m.step(0.001, &z_to(500.0, 6000.0));
        assert!(fb.z_limit);
        assert!(matches!(m.events()[0], MachineEvent::ZLimit { target, .. } if target == 500.0));
    }

    #[test]
    fn decouple_shift_recouple() {
        let mut m = Machine::new(MachineConfig::default());
        let mut cmd = MachineCommand { virtual_xy: [10.0, 0.0], ..MachineCommand::default() };
        assert_eq!(m.step(0.01, &cmd).gantry_xy, [10.0, 0.0]);
        // Decouple and shift by (-30, 40): 50 mm at 3000 mm/min = 1 s.
        cmd.coupling = Coupling { coupled: false, offset_target: [-30.0, 40.0], shift_speed: 3000.0 };
        let fb = (0..50).map(|_| m.step(0.01, &cmd)).last().unwrap();
        assert!(!fb.xy_coupled);
        assert!((fb.gantry_xy[0] - (10.0 - 15.0)).abs() < 1e-9);
        let fb = (0..60).map(|_| m.step(0.01, &cmd)).last().unwrap();
        assert_eq!(fb.xy_offset, [-30.0, 40.0]);
        cmd.coupling.coupled = true;
        cmd.virtual_xy = [20.0, 5.0];
        let fb = m.step(0.01, &cmd);
        assert_eq!(fb.gantry_xy, [-10.0, 45.0]);
        assert_eq!(fb.tool_xy, [110.0, 0.0]);
    }

    #[test]
    fn hole_recorded_with_depth_rpm_feed_and_crash_without_spindle() {
        let mut m = Machine::new(MachineConfig::default());
        // Tip touches the surface (20) at z = 100; drill to tip 8 deep: z = 92.
        let mut cmd = z_to(92.0, 6000.0);
        cmd.spindle_rpm = 2500.0;
        for _ in 0..4000 {
            m.step(0.001, &cmd);
        }
        assert!(m.holes().is_empty(), "still in the material");
        cmd.z = ZCommand::Move { target: 200.0, speed: 3000.0 };
        for _ in 0..4000 {
            m.step(0.001, &cmd);
        }
        let h = m.holes()[0];
        assert!((h.depth - 8.0).abs() < 1e-9);
        assert_eq!(h.spindle_rpm, 2500.0);
        assert!((h.feed - 6000.0).abs() < 1e-6);
        assert_eq!(h.tool_xy, [120.0, -45.0]);
        assert!(m.events().is_empty());
        // Same again with the spindle standing still: a crash event.
        cmd.spindle_rpm = 0.0;
        cmd.z = ZCommand::Move { target: 95.0, speed: 6000.0 };
        for _ in 0..4000 {
            m.step(0.001, &cmd);
        }
        assert!(matches!(m.events()[0], MachineEvent::ToolCrash { .. }));
    }

    #[test]
    fn surface_shapes() {
        assert_eq!(Surface::Flat(3.0).height([5.0, 5.0]), 3.0);
        let p = Surface::Plane { height: 10.0, slope_x: 0.01, slope_y: -0.02 };
        assert!((p.height([100.0, 50.0]) - (10.0 + 1.0 - 1.0)).abs() < 1e-12);
        fn step_surface(xy: [f64; 2]) -> f64 {
            if xy[0] > 100.0 {
                30.0
            } else {
                20.0
            }
        }
        assert_eq!(Surface::Custom(step_surface).height([150.0, 0.0]), 30.0);
    }
}
