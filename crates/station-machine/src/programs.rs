//! Uploaded programs (owner, publication, the cached check of each), the bounded program
//! checker ([`crate::checker`]) and the CNC program service.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};

use motus_cnc::{Limits3, ProgramService};
use motus_gcode::InterpreterConfig;
use motus_lab::{MotionDemand, Role};
use motus_station::config::{Cell, GroupKind};
use motus_station_web::{BackendError, Caller, ProgramCheck, ProgramDiagnostic, ProgramInfo};

use crate::checker::{Analysis, CheckError, Checker, GantryAxis, ProgramCheckOptions};
use crate::lock;
use motus_station_web::ProgramPreview;

/// One stored program.
pub(crate) struct Entry {
    pub(crate) info: ProgramInfo,
    pub(crate) text: Arc<str>,
    /// Unique per upload: a check result belongs to one version.
    pub(crate) version: u64,
    /// The check of this version, once done.
    pub(crate) analysis: Option<Arc<Analysis>>,
}

/// A visible program: its description, text, version and cached check.
type Visible = (ProgramInfo, Arc<str>, u64, Option<Arc<Analysis>>);

/// Programs by id, their checker, and the service that runs them.
pub(crate) struct Programs {
    pub(crate) store: Mutex<BTreeMap<String, Entry>>,
    pub(crate) service: ProgramService,
    pub(crate) running: Mutex<Option<String>>,
    /// The MDI line of the last run, when it was one.
    pub(crate) mdi_line: Mutex<Option<String>>,
    pub(crate) checker: Checker,
    pub(crate) versions: AtomicU64,
}

/// The cell's gantry (program X, Y, Z onto its axes, in order) and the planner limits of
/// its axes in program millimetres; `None` without a gantry group or with an axis that is not
/// in metres.
fn gantry(cell: &Cell) -> Option<(Vec<GantryAxis>, Limits3)> {
    let group = cell.groups.iter().find(|g| g.kind == GroupKind::Gantry)?;
    let mut limits = Limits3::default();
    let mut axes = Vec::new();
    for (name, slot) in group.axes.iter().zip(limits.axes.iter_mut()) {
        let a = cell.axis(name)?;
        if a.unit.symbol() != "m" {
            tracing::warn!(axis = %name, unit = a.unit.symbol(), "gantry axis not in metres: programs cannot run");
            return None;
        }
        let mm_per_unit = 1000.0;
        slot.velocity = a.max_velocity * mm_per_unit;
        slot.acceleration = a.max_acceleration * mm_per_unit;
        axes.push(GantryAxis {
            name: name.clone(),
            mm_per_unit,
            max_velocity: a.max_velocity,
            acceleration: a.max_acceleration,
        });
    }
    Some((axes, limits))
}

/// The cell's `[[tool]]` table as the interpreter's (the number is the tool's place: the
/// changer is not random).
fn tool_table(cell: &Cell) -> Vec<motus_gcode::Tool> {
    cell.tools
        .iter()
        .map(|t| motus_gcode::Tool {
            number: t.number,
            pocket: t.number,
            offset: [0.0, 0.0, t.length_mm, 0.0, 0.0, 0.0],
            diameter: t.diameter_mm,
            front_angle: 0.0,
            back_angle: 0.0,
            orientation: 0,
            comment: t.comment.clone(),
        })
        .collect()
}

impl Programs {
    pub(crate) fn start(
        cell: &Cell,
        shared: &Arc<crate::Shared>,
        options: ProgramCheckOptions,
    ) -> std::io::Result<Self> {
        let gantry = gantry(cell);
        let limits = gantry.as_ref().map_or_else(Limits3::default, |(_, l)| *l);
        let budget = options.time_budget.unwrap_or(cell.station.program_check_time);
        // One set of interpreter settings for the check and the run: the cell's tool table.
        let config = InterpreterConfig {
            max_steps: options.max_steps,
            tools: tool_table(cell),
            ..InterpreterConfig::default()
        };
        Ok(Self {
            store: Mutex::new(BTreeMap::new()),
            // The booked machine's gantry follows every set-point.
            service: ProgramService::start(limits, config.clone(), crate::gantry::sink(shared, &limits))?,
            running: Mutex::new(None),
            mdi_line: Mutex::new(None),
            checker: Checker::start(options, budget, gantry.map(|(g, _)| g), config)?,
            versions: AtomicU64::new(1),
        })
    }

    pub(crate) fn add(&self, owner: &str, name: &str, text: &str) -> ProgramInfo {
        let mut store = lock(&self.store);
        let base: String = name
            .chars()
            .map(|c| if c.is_ascii_alphanumeric() || c == '.' || c == '-' { c } else { '_' })
            .collect();
        let mut id = base.clone();
        let mut k = 1;
        while store.contains_key(&id) {
            k += 1;
            id = format!("{base}-{k}");
        }
        let info = ProgramInfo {
            id: id.clone(),
            name: name.to_owned(),
            owner: owner.to_owned(),
            size: text.len() as u64,
            lines: text.lines().count(),
            published: false,
        };
        let version = self.versions.fetch_add(1, Ordering::Relaxed);
        store.insert(id, Entry { info: info.clone(), text: Arc::from(text), version, analysis: None });
        info
    }

    /// The programs `caller` may see.
    pub(crate) fn list(&self, caller: &Caller) -> Vec<ProgramInfo> {
        lock(&self.store).values().filter(|e| e.info.visible_to(caller)).map(|e| e.info.clone()).collect()
    }

    /// Program `id`, if `caller` may see it: "not found" otherwise, so that names do not leak.
    fn visible(&self, caller: &Caller, id: &str) -> Result<Visible, BackendError> {
        lock(&self.store)
            .get(id)
            .filter(|e| e.info.visible_to(caller))
            .map(|e| (e.info.clone(), Arc::clone(&e.text), e.version, e.analysis.clone()))
            .ok_or_else(|| BackendError::NotFound { kind: "program", id: id.to_owned() })
    }

    /// The check of program `id` for `caller` (students and admins): cached per version,
    /// else done by the checker (waits up to about its budget; busy: refused at once).
    pub(crate) fn analysis(
        &self,
        caller: &Caller,
        id: &str,
    ) -> Result<(ProgramInfo, Arc<str>, Arc<Analysis>), BackendError> {
        if caller.role == Role::Viewer {
            return Err(BackendError::Forbidden("viewers cannot check or run programs".into()));
        }
        let (info, text, version, cached) = self.visible(caller, id)?;
        if let Some(a) = cached {
            return Ok((info, text, a));
        }
        let analysis = self.checker.check(id, version, Arc::clone(&text)).map_err(|e| match e {
            CheckError::Busy(_) => BackendError::Busy(e.to_string()),
            CheckError::Stopped | CheckError::Late => BackendError::Failed(e.to_string()),
        })?;
        if let Some(e) = lock(&self.store).get_mut(id).filter(|e| e.version == version) {
            e.analysis = Some(Arc::clone(&analysis));
        }
        Ok((info, text, analysis))
    }

    /// The preview of program `id` (from its check).
    pub(crate) fn preview(&self, caller: &Caller, id: &str) -> Result<ProgramPreview, BackendError> {
        Ok(self.analysis(caller, id)?.2.preview.clone())
    }

    /// Publishes program `id` to every student (or withdraws it).
    pub(crate) fn publish(&self, id: &str, published: bool) -> Result<ProgramInfo, BackendError> {
        let mut store = lock(&self.store);
        let e =
            store.get_mut(id).ok_or_else(|| BackendError::NotFound { kind: "program", id: id.to_owned() })?;
        e.info.published = published;
        Ok(e.info.clone())
    }

    /// The slot of `user` ended: their programs go, except the published ones.
    pub(crate) fn remove_owned_by(&self, user: &str) {
        lock(&self.store).retain(|_, e| e.info.owner != user || e.info.published);
    }
}

impl crate::StationMachine {
    /// The check of program `id` for `caller`: the interpreter's errors and, per gantry axis
    /// the program moves, its demand (extent, peak speed and acceleration) — an extent
    /// beyond the axis's machine travel is an error for everyone, at the line that reaches
    /// it.
    pub(crate) fn checked_program(
        &self,
        caller: &Caller,
        id: &str,
    ) -> Result<(ProgramInfo, Arc<str>, ProgramCheck), BackendError> {
        let (info, text, a) = self.programs.analysis(caller, id)?;
        Ok((info, text, self.check_of(&a)))
    }

    /// One MDI line checked as a program of its own (viewers refused; one line of at most
    /// [`motus_station_web::api_cnc::MDI_MAX_LEN`] bytes).
    pub(crate) fn checked_mdi(&self, caller: &Caller, line: &str) -> Result<ProgramCheck, BackendError> {
        if caller.role == Role::Viewer {
            return Err(BackendError::Forbidden("viewers cannot run MDI".into()));
        }
        let line = line.trim();
        if line.is_empty()
            || line.contains(['\n', '\r'])
            || line.len() > motus_station_web::api_cnc::MDI_MAX_LEN
        {
            return Err(BackendError::invalid(
                "line",
                format!("one G-code line of 1 to {} bytes", motus_station_web::api_cnc::MDI_MAX_LEN),
            ));
        }
        let version = self.programs.versions.fetch_add(1, Ordering::Relaxed);
        let analysis =
            self.programs.checker.check(&format!("mdi:{}", caller.user), version, Arc::from(line)).map_err(
                |e| match e {
                    CheckError::Busy(_) => BackendError::Busy(e.to_string()),
                    CheckError::Stopped | CheckError::Late => BackendError::Failed(e.to_string()),
                },
            )?;
        Ok(self.check_of(&analysis))
    }

    /// The station's verdict on an analysis: its errors, plus every extent beyond an axis's
    /// machine travel, and the per-axis demands.
    fn check_of(&self, a: &Analysis) -> ProgramCheck {
        let views = self.shared.views.read().unwrap_or_else(PoisonError::into_inner);
        let mut errors = a.errors.clone();
        let mut demands = Vec::new();
        for e in &a.extents {
            let Some(v) = views.iter().find(|v| v.id == e.axis) else {
                errors.push(ProgramDiagnostic { line: 1, col: 1, message: format!("no axis {}", e.axis) });
                continue;
            };
            let (l, unit) = (&v.limits, &v.unit);
            let below = e.lo.0.is_nan() || e.lo.0 < l.min;
            let above = e.hi.0.is_nan() || e.hi.0 > l.max;
            for ((pos, line), beyond) in [(e.lo, below), (e.hi, above)] {
                if beyond {
                    errors.push(ProgramDiagnostic {
                        line: line as usize,
                        col: 1,
                        message: format!(
                            "axis {} would reach {pos} {unit}, outside the machine travel [{}, {}] {unit}",
                            e.axis, l.min, l.max
                        ),
                    });
                }
            }
            demands.push((e.axis.clone(), MotionDemand::within(e.speed, e.acceleration, e.lo.0, e.hi.0)));
        }
        ProgramCheck { errors, demands }
    }

    /// The gantry ready for a program: every axis connected, not E-stopped, homed (the
    /// program's travel was checked in absolute positions), switched on; returns where it is
    /// (X, Y, Z in program millimetres), where the run starts.
    pub(crate) fn gantry_ready(&self) -> Result<[f64; 3], BackendError> {
        let Some(indices) = crate::gantry::gantry_axes(&self.shared) else {
            return Err(BackendError::State(
                "this cell has no gantry group (kind = \"gantry\"): programs cannot move anything here"
                    .into(),
            ));
        };
        let mut start = [0.0; 3];
        for (slot, index) in start.iter_mut().zip(indices) {
            let Some(entry) = self.shared.axes.get(index) else { continue };
            let view = self.view(&entry.view.id)?;
            self.motion_allowed(&view)?;
            if !view.homed {
                return Err(BackendError::State(format!(
                    "gantry axis {} is not homed: home the gantry first (a program's travel is checked in \
                     absolute positions)",
                    view.id
                )));
            }
            if !view.enabled {
                crate::lock(&entry.axis).execute(&motus_axis::AxisCommand::Enable).map_err(|e| {
                    BackendError::State(format!("gantry axis {} cannot be switched on: {e}", view.id))
                })?;
            }
            *slot = view.position * 1000.0;
        }
        Ok(start)
    }

    /// Whether a program (or an MDI line) is running, held or at a block stop.
    pub(crate) fn program_active(&self) -> bool {
        matches!(
            self.programs.service.status().state,
            motus_cnc::ServiceState::Running
                | motus_cnc::ServiceState::Held
                | motus_cnc::ServiceState::BlockStop
        )
    }

    /// Whether `axis` is one of the gantry's.
    pub(crate) fn is_gantry_axis(&self, axis: &str) -> bool {
        self.shared
            .config
            .groups
            .iter()
            .any(|g| g.kind == motus_station::config::GroupKind::Gantry && g.axes.iter().any(|a| a == axis))
    }

    /// Defence in depth (the lab checked first): a student's program stays within the
    /// student limits of every axis it moves; an axis without student limits refuses it.
    pub(crate) fn check_student_program(
        &self,
        caller: &Caller,
        check: &ProgramCheck,
    ) -> Result<(), BackendError> {
        if caller.role >= Role::Admin {
            return Ok(());
        }
        for (axis, d) in &check.demands {
            let Some(s) = self.shared.config.axis(axis).and_then(|c| c.student) else {
                return Err(BackendError::Forbidden(format!(
                    "the program moves axis {axis}, which has no student limits: students cannot move it"
                )));
            };
            let [lo, hi] = d.range.unwrap_or([f64::NAN; 2]);
            if !(lo >= s.limits.min && hi <= s.limits.max) {
                return Err(BackendError::Forbidden(format!(
                    "axis {axis}: the program reaches [{lo}, {hi}], outside the student range [{}, {}]",
                    s.limits.min, s.limits.max
                )));
            }
            if !(d.speed <= s.max_velocity && d.acceleration <= s.max_acceleration) {
                return Err(BackendError::Forbidden(format!(
                    "axis {axis}: the program's speed {} / acceleration {} exceed the student limits {} / {}",
                    d.speed, d.acceleration, s.max_velocity, s.max_acceleration
                )));
            }
        }
        Ok(())
    }
}
