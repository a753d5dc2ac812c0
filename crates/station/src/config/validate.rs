//! From the file as written to a validated [`Cell`]: references, uniqueness, ranges.

use std::collections::{HashMap, HashSet};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::time::Duration;

use motus_axis::Scale;
use toml::Spanned;

use super::error::{ConfigError, Locator};
use super::model::{
    AxisConfig, Camera, Cell, Device, DeviceKind, Group, Limits, Link, LinkKind, Program, Station,
    StudentLimits, Supervisor, TaskConfig, TaskKind, ToolConfig, DEFAULT_LISTEN, DEFAULT_OVERRUN_LIMIT,
    DEFAULT_PROGRAM_CHECK_TIME,
};
use super::raw::{RawAxis, RawCell, RawDevice, RawStudent, RawTask};

/// Longest allowed task period.
const MAX_PERIOD_MS: f64 = 60_000.0;
/// Shortest allowed task period (100 us).
const MIN_PERIOD_MS: f64 = 0.1;

/// Collects errors while converting.
pub(crate) struct Validator<'a> {
    loc: Locator<'a>,
    base: PathBuf,
    exists: &'a dyn Fn(&Path) -> bool,
    errors: Vec<(usize, ConfigError)>,
}

impl<'a> Validator<'a> {
    pub(crate) fn new(loc: Locator<'a>, base: PathBuf, exists: &'a dyn Fn(&Path) -> bool) -> Self {
        Validator { loc, base, exists, errors: Vec::new() }
    }

    fn err<T>(&mut self, at: &Spanned<T>, key: String, message: String) {
        let offset = at.span().start;
        self.errors.push((offset, self.loc.error(offset, key, message)));
    }

    fn unique(&mut self, section: &str, names: &[&Spanned<String>]) -> HashSet<String> {
        let mut seen = HashSet::new();
        for (i, n) in names.iter().enumerate() {
            if n.get_ref().is_empty() {
                self.err(
                    n,
                    format!("{section}[{i}].name"),
                    format!("{section}[{i}]: name must not be empty"),
                );
            } else if !seen.insert(n.get_ref().clone()) {
                self.err(
                    n,
                    format!("{section}[{i}].name"),
                    format!("{section} \"{}\": name is used twice", n.get_ref()),
                );
            }
        }
        seen
    }

    fn path(&self, p: &str) -> PathBuf {
        self.base.join(p)
    }

    fn positive(&mut self, v: &Spanned<f64>, section: &str, name: &str, key: &str, i: usize) -> f64 {
        let x = *v.get_ref();
        if !(x.is_finite() && x > 0.0) {
            self.err(
                v,
                format!("{section}[{i}].{key}"),
                format!("{section} \"{name}\": {key} ({x}) must be a positive number"),
            );
        }
        x
    }

    fn finite(&mut self, v: &Spanned<f64>, section: &str, name: &str, key: &str, i: usize) -> f64 {
        let x = *v.get_ref();
        if !x.is_finite() {
            self.err(
                v,
                format!("{section}[{i}].{key}"),
                format!("{section} \"{name}\": {key} ({x}) must be finite"),
            );
        }
        x
    }

    /// Runs every check; returns the cell or the errors in file order.
    pub(crate) fn run(mut self, file: &Path, raw: RawCell) -> Result<Cell, Vec<ConfigError>> {
        let station = self.station(&raw);
        self.unique("link", &raw.link.iter().map(|l| &l.name).collect::<Vec<_>>());
        let links: Vec<Link> = raw.link.iter().enumerate().map(|(i, l)| self.link(i, l)).collect();
        let link_kinds: HashMap<String, LinkKind> = links.iter().map(|l| (l.name.clone(), l.kind)).collect();
        self.unique("device", &raw.device.iter().map(|d| &d.name).collect::<Vec<_>>());
        let devices: Vec<Device> =
            raw.device.iter().enumerate().map(|(i, d)| self.device(i, d, &link_kinds)).collect();
        self.duplicate_addresses(&raw.device);
        let device_kinds: HashMap<String, DeviceKind> =
            devices.iter().map(|d| (d.name.clone(), d.kind)).collect();
        self.unique("axis", &raw.axis.iter().map(|a| &a.name).collect::<Vec<_>>());
        let axes: Vec<AxisConfig> =
            raw.axis.iter().enumerate().map(|(i, a)| self.axis(i, a, &device_kinds)).collect();
        self.duplicate_joints(&raw.axis);
        let axis_names: HashSet<String> = axes.iter().map(|a| a.name.clone()).collect();
        let group_names = self.unique("group", &raw.group.iter().map(|g| &g.name).collect::<Vec<_>>());
        let groups = self.groups(&raw, &axis_names);
        let program_names = self.unique("program", &raw.program.iter().map(|p| &p.name).collect::<Vec<_>>());
        let programs = self.programs(&raw, &group_names);
        let tools = self.tools(&raw);
        let supervisor = raw.supervisor.as_ref().map(|s| {
            let rules = self.path(s.rules.get_ref());
            if !(self.exists)(&rules) {
                self.err(
                    &s.rules,
                    "supervisor.rules".into(),
                    format!("supervisor: rules file {} does not exist", rules.display()),
                );
            }
            let drives = s.drives.as_ref().map(|d| {
                let path = self.path(d.get_ref());
                if !(self.exists)(&path) {
                    self.err(
                        d,
                        "supervisor.drives".into(),
                        format!("supervisor: drive-parameter file {} does not exist", path.display()),
                    );
                }
                path
            });
            if let Some(g) = &s.group {
                if !group_names.contains(g.get_ref()) {
                    self.err(
                        g,
                        "supervisor.group".into(),
                        format!("supervisor: group \"{}\" is not defined", g.get_ref()),
                    );
                }
            }
            Supervisor {
                rules,
                drives,
                approval: s.approval.as_ref().map(|p| self.path(p.get_ref())),
                key: s.key.as_ref().map(|p| self.path(p.get_ref())),
                group: s.group.as_ref().map(|g| g.get_ref().clone()),
            }
        });
        self.unique("task", &raw.task.iter().map(|t| &t.name).collect::<Vec<_>>());
        let tasks: Vec<TaskConfig> =
            raw.task.iter().enumerate().map(|(i, t)| self.task(i, t, &group_names, &program_names)).collect();

        if self.errors.is_empty() {
            Ok(Cell {
                file: file.to_path_buf(),
                station,
                links,
                devices,
                axes,
                groups,
                supervisor,
                tasks,
                programs,
                tools,
            })
        } else {
            self.errors.sort_by_key(|(o, _)| *o);
            Err(self.errors.into_iter().map(|(_, e)| e).collect())
        }
    }

    fn station(&mut self, raw: &RawCell) -> Station {
        let s = &raw.station;
        if s.name.get_ref().is_empty() {
            self.err(&s.name, "station.name".into(), "station: name must not be empty".into());
        }
        let listen = match &s.listen {
            None => DEFAULT_LISTEN.parse::<SocketAddr>().ok(),
            Some(l) => {
                let parsed = l.get_ref().parse::<SocketAddr>().ok();
                if parsed.is_none() {
                    self.err(
                        l,
                        "station.listen".into(),
                        format!(
                            "station: listen ({:?}) must be an address and port like {DEFAULT_LISTEN}",
                            l.get_ref()
                        ),
                    );
                }
                parsed
            }
        };
        let fallback = SocketAddr::from(([127, 0, 0, 1], 8080));
        for o in &s.origins {
            let text = o.get_ref();
            let authority = text.strip_prefix("http://").or_else(|| text.strip_prefix("https://"));
            let authority = authority.map(|a| a.strip_suffix('/').unwrap_or(a));
            if !authority.is_some_and(|a| !a.is_empty() && !a.contains(['/', '?', '#', '@', ' '])) {
                self.err(
                    o,
                    "station.origins".into(),
                    format!(
                        "station: origin {text:?} must be scheme://host[:port], like http://station.lab:8080"
                    ),
                );
            }
        }
        let program_check_time = match &s.program_check_time {
            None => DEFAULT_PROGRAM_CHECK_TIME,
            Some(t) => {
                let v = *t.get_ref();
                if v.is_finite() && v > 0.0 && v <= 600.0 {
                    Duration::from_secs_f64(v)
                } else {
                    self.err(
                        t,
                        "station.program_check_time".into(),
                        format!("station: program_check_time ({v}) must be in (0, 600] seconds"),
                    );
                    DEFAULT_PROGRAM_CHECK_TIME
                }
            }
        };
        Station {
            name: s.name.get_ref().clone(),
            listen: listen.unwrap_or(fallback),
            data_dir: self.path(s.data_dir.as_ref().map_or("data", |d| d.get_ref().as_str())),
            origins: s.origins.iter().map(|o| o.get_ref().clone()).collect(),
            program_check_time,
        }
    }

    fn link(&mut self, i: usize, l: &super::raw::RawLink) -> Link {
        let name = l.name.get_ref();
        let uri = l.uri.get_ref();
        let problem = match l.kind {
            LinkKind::Serial | LinkKind::PtySim if uri.is_empty() || uri.contains("://") => {
                Some("must be a device path such as /dev/ttyUSB0 or /tmp/motus/ps1a")
            }
            LinkKind::Can
                if !["socketcand://", "socketcan://", "slcan://"].iter().any(|s| uri.starts_with(s))
                    || uri.split_once("://").is_some_and(|(_, rest)| rest.is_empty()) =>
            {
                Some("must be socketcand://HOST:PORT/CHANNEL, socketcan://IFACE or slcan://PATH?bitrate=N")
            }
            LinkKind::Powerlink
                if uri.is_empty()
                    || (uri.contains("://") && !udp_uri_ok(uri) && !mem_uri_ok(uri)) =>
            {
                Some("must be udp://HOST:PORT, mem://NAME (a segment inside this process) or a network interface name")
            }
            _ => None,
        };
        if let Some(p) = problem {
            self.err(&l.uri, format!("link[{i}].uri"), format!("link \"{name}\": uri ({uri:?}) {p}"));
        }
        Link { name: name.clone(), kind: l.kind, uri: uri.clone() }
    }

    fn device(&mut self, i: usize, d: &RawDevice, links: &HashMap<String, LinkKind>) -> Device {
        let name = d.name.get_ref().clone();
        let kind = *d.kind.get_ref();
        match &d.link {
            Some(l) => match links.get(l.get_ref()) {
                None => self.err(
                    l,
                    format!("device[{i}].link"),
                    format!("device \"{name}\": link \"{}\" is not defined", l.get_ref()),
                ),
                Some(lk) if !kind.accepts_link(Some(*lk)) => self.err(
                    l,
                    format!("device[{i}].link"),
                    format!(
                        "device \"{name}\": a {} device needs {}, but link \"{}\" is {}",
                        kind.as_str(),
                        kind.link_hint(),
                        l.get_ref(),
                        lk.as_str()
                    ),
                ),
                Some(_) => {}
            },
            None if !kind.accepts_link(None) => self.err(
                &d.kind,
                format!("device[{i}].link"),
                format!(
                    "device \"{name}\": a {} device needs {} (key `link` missing)",
                    kind.as_str(),
                    kind.link_hint()
                ),
            ),
            None => {}
        }
        let address = match (kind.address_range(), &d.address) {
            (Some((lo, hi)), Some(a)) => {
                let v = *a.get_ref();
                if v < lo || v > hi {
                    self.err(
                        a,
                        format!("device[{i}].address"),
                        format!(
                            "device \"{name}\": address ({v}) must be in {lo}..={hi} for {}",
                            kind.as_str()
                        ),
                    );
                }
                u32::try_from(v).ok()
            }
            (Some((lo, hi)), None) => {
                self.err(
                    &d.name,
                    format!("device[{i}].address"),
                    format!("device \"{name}\": a {} device needs an address ({lo}..={hi})", kind.as_str()),
                );
                None
            }
            (None, Some(a)) => {
                self.err(
                    a,
                    format!("device[{i}].address"),
                    format!("device \"{name}\": a {} device takes no address", kind.as_str()),
                );
                None
            }
            (None, None) => None,
        };
        let baud = d.baud.as_ref().and_then(|b| {
            let v = *b.get_ref();
            let serial = d.link.as_ref().and_then(|l| links.get(l.get_ref())).is_some_and(|k| k.is_serial());
            if !(1..=4_000_000).contains(&v) {
                self.err(
                    b,
                    format!("device[{i}].baud"),
                    format!("device \"{name}\": baud ({v}) must be in 1..=4000000"),
                );
            } else if !serial {
                self.err(
                    b,
                    format!("device[{i}].baud"),
                    format!("device \"{name}\": baud applies only to serial devices"),
                );
            }
            u32::try_from(v).ok()
        });
        Device {
            name,
            kind,
            link: d.link.as_ref().map(|l| l.get_ref().clone()),
            address,
            simulate: d.simulate || kind == DeviceKind::SimAxis,
            baud,
        }
    }

    fn duplicate_addresses(&mut self, devices: &[RawDevice]) {
        let mut seen: HashSet<(String, i64)> = HashSet::new();
        for (i, d) in devices.iter().enumerate() {
            if let (Some(l), Some(a)) = (&d.link, &d.address) {
                if !seen.insert((l.get_ref().clone(), *a.get_ref())) {
                    self.err(
                        a,
                        format!("device[{i}].address"),
                        format!(
                            "device \"{}\": address {} is already used on link \"{}\"",
                            d.name.get_ref(),
                            a.get_ref(),
                            l.get_ref()
                        ),
                    );
                }
            }
        }
    }

    fn duplicate_joints(&mut self, axes: &[RawAxis]) {
        let mut seen: HashSet<(String, i64)> = HashSet::new();
        for (i, a) in axes.iter().enumerate() {
            let index = a.index.as_ref().map_or(0, |x| *x.get_ref());
            if !seen.insert((a.device.get_ref().clone(), index)) {
                let at = a.index.as_ref().map_or(a.device.span(), |x| x.span());
                let offset = at.start;
                let e = self.loc.error(
                    offset,
                    format!("axis[{i}].index"),
                    format!(
                        "axis \"{}\": index {index} of device \"{}\" is already used by another axis",
                        a.name.get_ref(),
                        a.device.get_ref()
                    ),
                );
                self.errors.push((offset, e));
            }
        }
    }

    fn axis(&mut self, i: usize, a: &RawAxis, devices: &HashMap<String, DeviceKind>) -> AxisConfig {
        let name = a.name.get_ref().clone();
        let device = a.device.get_ref().clone();
        let index = a.index.as_ref().map_or(0, |x| *x.get_ref());
        match devices.get(&device) {
            None => self.err(
                &a.device,
                format!("axis[{i}].device"),
                format!("axis \"{name}\": device \"{device}\" is not defined"),
            ),
            Some(k) => {
                let n = i64::from(k.axis_count());
                if index < 0 || index >= n {
                    let at = a.index.as_ref().map_or(a.device.span(), |x| x.span()).start;
                    let e = self.loc.error(
                        at,
                        format!("axis[{i}].index"),
                        format!(
                            "axis \"{name}\": index ({index}) must be in 0..{n} for a {} device",
                            k.as_str()
                        ),
                    );
                    self.errors.push((at, e));
                }
            }
        }
        let si = self.finite(&a.scale, "axis", &name, "scale", i);
        let offset = a.offset.as_ref().map_or(0.0, |o| *o.get_ref());
        let scale = match Scale::with_offset(a.unit.kind(), si, offset) {
            Ok(s) => s,
            Err(e) => {
                let at = if si == 0.0 || !si.is_finite() {
                    &a.scale
                } else {
                    a.offset.as_ref().unwrap_or(&a.scale)
                };
                let key = if std::ptr::eq(at, &a.scale) { "scale" } else { "offset" };
                self.err(at, format!("axis[{i}].{key}"), format!("axis \"{name}\": {key}: {e}"));
                Scale::HUNDREDTH_MM
            }
        };
        let min = self.finite(&a.limits.min, "axis", &name, "limits.min", i);
        let max = self.finite(&a.limits.max, "axis", &name, "limits.max", i);
        if min.is_finite() && max.is_finite() && min >= max {
            self.err(
                &a.limits.min,
                format!("axis[{i}].limits.min"),
                format!("axis \"{name}\": limits.min ({min}) must be below limits.max ({max})"),
            );
        }
        let limits = Limits { min, max };
        let max_velocity = self.positive(&a.max_velocity, "axis", &name, "max_velocity", i);
        let max_acceleration = self.positive(&a.max_acceleration, "axis", &name, "max_acceleration", i);
        let machine_ok =
            min.is_finite() && max.is_finite() && min < max && max_velocity > 0.0 && max_acceleration > 0.0;
        // No `student` table: students cannot move the axis (fail closed). Student limits are
        // checked against valid machine limits only (else the machine limits' own error says
        // what to fix first).
        let student = match &a.student {
            Some(s) if machine_ok => Some(self.student(i, &name, s, limits, max_velocity, max_acceleration)),
            Some(_) => Some(StudentLimits { limits, max_velocity, max_acceleration }),
            None => None,
        };
        AxisConfig {
            name,
            device,
            index: u32::try_from(index).unwrap_or(0),
            unit: a.unit,
            scale,
            limits,
            max_velocity,
            max_acceleration,
            student,
        }
    }

    fn student(
        &mut self,
        i: usize,
        name: &str,
        s: &RawStudent,
        m: Limits,
        mv: f64,
        ma: f64,
    ) -> StudentLimits {
        let mut bound =
            |v: &Option<Spanned<f64>>, key: &str, lo: f64, hi: f64, default: f64, what: &str| -> f64 {
                let Some(v) = v else { return default };
                let x = *v.get_ref();
                if !x.is_finite() || x < lo || x > hi {
                    self.err(
                        v,
                        format!("axis[{i}].student.{key}"),
                        format!("axis \"{name}\": student.{key} ({x}) must be within {what}"),
                    );
                }
                x
            };
        let min =
            bound(&s.min, "min", m.min, m.max, m.min, &format!("the machine limits {} ..= {}", m.min, m.max));
        let max =
            bound(&s.max, "max", m.min, m.max, m.max, &format!("the machine limits {} ..= {}", m.min, m.max));
        let max_velocity = bound(
            &s.max_velocity,
            "max_velocity",
            f64::MIN_POSITIVE,
            mv,
            mv,
            &format!("0 < v <= max_velocity ({mv})"),
        );
        let max_acceleration = bound(
            &s.max_acceleration,
            "max_acceleration",
            f64::MIN_POSITIVE,
            ma,
            ma,
            &format!("0 < a <= max_acceleration ({ma})"),
        );
        if min >= max {
            if let Some(at) = s.min.as_ref().or(s.max.as_ref()) {
                self.err(
                    at,
                    format!("axis[{i}].student.min"),
                    format!("axis \"{name}\": student.min ({min}) must be below student.max ({max})"),
                );
            }
        }
        StudentLimits { limits: Limits { min, max }, max_velocity, max_acceleration }
    }

    fn groups(&mut self, raw: &RawCell, axes: &HashSet<String>) -> Vec<Group> {
        let mut owner: HashMap<String, String> = HashMap::new();
        let mut out = Vec::new();
        for (i, g) in raw.group.iter().enumerate() {
            let name = g.name.get_ref().clone();
            let (lo, hi) = g.kind.axis_count();
            let n = g.axes.get_ref().len();
            if n < lo || n > hi {
                let want = if lo == hi { format!("{lo}") } else { format!("{lo} to {hi}") };
                self.err(
                    &g.axes,
                    format!("group[{i}].axes"),
                    format!("group \"{name}\": a {} group needs {want} axes, found {n}", g.kind.as_str()),
                );
            }
            for (j, a) in g.axes.get_ref().iter().enumerate() {
                let an = a.get_ref();
                if !axes.contains(an) {
                    self.err(
                        a,
                        format!("group[{i}].axes[{j}]"),
                        format!("group \"{name}\": axis \"{an}\" is not defined"),
                    );
                } else if let Some(other) = owner.insert(an.clone(), name.clone()) {
                    self.err(
                        a,
                        format!("group[{i}].axes[{j}]"),
                        format!("group \"{name}\": axis \"{an}\" already belongs to group \"{other}\""),
                    );
                }
            }
            let camera = g.camera.as_ref().and_then(|c| self.camera(c, i, &name));
            out.push(Group {
                name,
                kind: g.kind,
                axes: g.axes.get_ref().iter().map(|a| a.get_ref().clone()).collect(),
                camera,
            });
        }
        out
    }

    /// A group's camera: `"simulated"`, or a plain `http://` URL with a host (the station
    /// fetches it; TLS to cameras is not spoken).
    fn camera(&mut self, raw: &Spanned<String>, i: usize, group: &str) -> Option<Camera> {
        let text = raw.get_ref().trim();
        if text == "simulated" {
            return Some(Camera::Simulated);
        }
        let host = text.strip_prefix("http://").map(|rest| rest.split('/').next().unwrap_or(""));
        match host {
            Some(h) if !h.is_empty() && !h.contains(['@', ' ']) => Some(Camera::Http(text.to_string())),
            _ => {
                self.err(
                    raw,
                    format!("group[{i}].camera"),
                    format!(
                        "group \"{group}\": camera {text:?} is neither \"simulated\" nor an http://host[:port]/path URL \
                         (an MJPEG stream or a JPEG image; https and credentials in the URL are not supported)"
                    ),
                );
                None
            }
        }
    }

    /// The tool table: numbers 1-99999, each once; diameters finite and not negative; lengths
    /// finite.
    fn tools(&mut self, raw: &RawCell) -> Vec<ToolConfig> {
        let mut out = Vec::new();
        let mut seen = HashSet::new();
        for (i, t) in raw.tool.iter().enumerate() {
            let n = *t.number.get_ref();
            let number = match u32::try_from(n) {
                Ok(k @ 1..=99_999) => k,
                _ => {
                    self.err(
                        &t.number,
                        format!("tool[{i}].number"),
                        format!("tool[{i}]: number {n} is not 1-99999"),
                    );
                    continue;
                }
            };
            if !seen.insert(number) {
                self.err(&t.number, format!("tool[{i}].number"), format!("tool T{number} is listed twice"));
            }
            let d = *t.diameter_mm.get_ref();
            if !(d.is_finite() && d >= 0.0) {
                self.err(
                    &t.diameter_mm,
                    format!("tool[{i}].diameter_mm"),
                    format!("tool T{number}: diameter_mm ({d}) must be a number >= 0"),
                );
            }
            let l = *t.length_mm.get_ref();
            if !l.is_finite() {
                self.err(
                    &t.length_mm,
                    format!("tool[{i}].length_mm"),
                    format!("tool T{number}: length_mm ({l}) must be a number"),
                );
            }
            out.push(ToolConfig {
                number,
                diameter_mm: d,
                length_mm: l,
                comment: t.comment.clone().unwrap_or_default(),
            });
        }
        out
    }

    fn programs(&mut self, raw: &RawCell, groups: &HashSet<String>) -> Vec<Program> {
        let mut out = Vec::new();
        for (i, p) in raw.program.iter().enumerate() {
            let name = p.name.get_ref().clone();
            let file = self.path(p.file.get_ref());
            if !(self.exists)(&file) {
                self.err(
                    &p.file,
                    format!("program[{i}].file"),
                    format!("program \"{name}\": file {} does not exist", file.display()),
                );
            }
            if let Some(g) = &p.group {
                if !groups.contains(g.get_ref()) {
                    self.err(
                        g,
                        format!("program[{i}].group"),
                        format!("program \"{name}\": group \"{}\" is not defined", g.get_ref()),
                    );
                }
            }
            out.push(Program { name, file, group: p.group.as_ref().map(|g| g.get_ref().clone()) });
        }
        out
    }

    fn task(
        &mut self,
        i: usize,
        t: &RawTask,
        groups: &HashSet<String>,
        programs: &HashSet<String>,
    ) -> TaskConfig {
        let name = t.name.get_ref().clone();
        let ms = *t.period_ms.get_ref();
        let period = if ms.is_finite() && (MIN_PERIOD_MS..=MAX_PERIOD_MS).contains(&ms) {
            Duration::from_secs_f64(ms / 1000.0)
        } else {
            self.err(
                &t.period_ms,
                format!("task[{i}].period_ms"),
                format!(
                    "task \"{name}\": period_ms ({ms}) must be between {MIN_PERIOD_MS} and {MAX_PERIOD_MS}"
                ),
            );
            Duration::from_millis(1)
        };
        let kind = *t.kind.get_ref();
        if let Some(g) = &t.group {
            if !groups.contains(g.get_ref()) {
                self.err(
                    g,
                    format!("task[{i}].group"),
                    format!("task \"{name}\": group \"{}\" is not defined", g.get_ref()),
                );
            }
        } else if kind == TaskKind::Motion {
            self.err(
                &t.kind,
                format!("task[{i}].group"),
                format!("task \"{name}\": a motion task needs `group`"),
            );
        }
        if let Some(p) = &t.program {
            if kind != TaskKind::Program {
                self.err(
                    p,
                    format!("task[{i}].program"),
                    format!("task \"{name}\": only a program task takes `program`"),
                );
            } else if !programs.contains(p.get_ref()) {
                self.err(
                    p,
                    format!("task[{i}].program"),
                    format!("task \"{name}\": program \"{}\" is not defined", p.get_ref()),
                );
            }
        } else if kind == TaskKind::Program {
            self.err(
                &t.kind,
                format!("task[{i}].program"),
                format!("task \"{name}\": a program task needs `program`"),
            );
        }
        let overrun_limit = match &t.overrun_limit {
            None => DEFAULT_OVERRUN_LIMIT,
            Some(o) => {
                let v = *o.get_ref();
                if !(1..=1000).contains(&v) {
                    self.err(
                        o,
                        format!("task[{i}].overrun_limit"),
                        format!("task \"{name}\": overrun_limit ({v}) must be in 1..=1000"),
                    );
                }
                u32::try_from(v).unwrap_or(DEFAULT_OVERRUN_LIMIT)
            }
        };
        TaskConfig {
            name,
            period,
            kind,
            group: t.group.as_ref().map(|g| g.get_ref().clone()),
            program: t.program.as_ref().map(|p| p.get_ref().clone()),
            overrun_limit,
        }
    }
}

/// `mem://NAME`: an in-process POWERLINK segment (letters, digits, `-`, `_`, `.`).
fn mem_uri_ok(uri: &str) -> bool {
    uri.strip_prefix("mem://").is_some_and(|n| {
        !n.is_empty() && n.chars().all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'))
    })
}

/// `udp://HOST:PORT` with a parseable port.
fn udp_uri_ok(uri: &str) -> bool {
    uri.strip_prefix("udp://")
        .and_then(|rest| rest.split('?').next())
        .and_then(|hp| hp.rsplit_once(':'))
        .is_some_and(|(h, p)| !h.is_empty() && p.parse::<u16>().is_ok())
}
