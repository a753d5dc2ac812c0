#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use std::path::Path;
use std::time::Duration;

use super::*;

/// A small valid cell; line numbers below are counted by hand from this text
/// (line 1 is `[station]`).
const BASE: &str = r#"[station]
name = "test"

[[link]]
name = "ttyA"
kind = "pty-sim"
uri = "/tmp/motus/a"

[[link]]
name = "can"
kind = "can"
uri = "socketcand://127.0.0.1:29536/can0"

[[device]]
name = "m1"
kind = "ps1a"
link = "ttyA"
address = 1
simulate = true

[[device]]
name = "w1"
kind = "cia402"
link = "can"
address = 2

[[axis]]
name = "x"
device = "m1"
unit = "m"
scale = 1e-5
limits = { min = 0.0, max = 0.5 }
max_velocity = 0.1
max_acceleration = 1.0
student = { max = 0.4, max_velocity = 0.05 }

[[axis]]
name = "w"
device = "w1"
unit = "rad"
scale = 0.001
limits = { min = -100.0, max = 100.0 }
max_velocity = 10.0
max_acceleration = 100.0

[[group]]
name = "g"
kind = "gantry"
axes = ["x", "w"]

[[task]]
name = "fast"
period_ms = 1
kind = "motion"
group = "g"

[[task]]
name = "slow"
period_ms = 100
kind = "trace"
"#;

fn parse(text: &str) -> Result<Cell, ConfigErrors> {
    parse_with(Path::new("cell.toml"), text, &|_| true)
}

fn one_error(text: &str) -> ConfigError {
    let errs = parse(text).expect_err("must fail").0;
    assert_eq!(errs.len(), 1, "{errs:?}");
    errs.into_iter().next().unwrap()
}

/// 1-based line of the first line containing `needle`.
fn line_of(text: &str, needle: &str) -> usize {
    text.lines().position(|l| l.contains(needle)).unwrap() + 1
}

#[test]
fn base_cell_is_valid_and_converted() {
    let cell = parse(BASE).unwrap();
    assert_eq!(cell.station.name, "test");
    assert_eq!(cell.station.listen.to_string(), "127.0.0.1:8080");
    assert_eq!(cell.station.data_dir, Path::new("data"));
    assert_eq!(cell.links.len(), 2);
    assert_eq!(cell.link("can").unwrap().kind, LinkKind::Can);
    let m1 = cell.device("m1").unwrap();
    assert_eq!((m1.kind, m1.address, m1.simulate), (DeviceKind::Ps1a, Some(1), true));
    let x = cell.axis("x").unwrap();
    assert_eq!(x.limits, Limits { min: 0.0, max: 0.5 });
    // Student: max given (0.4), min defaults to the machine's 0.0, velocity 0.05 given,
    // acceleration defaults to the machine's 1.0.
    assert_eq!(x.student.unwrap().limits, Limits { min: 0.0, max: 0.4 });
    assert_eq!(x.student.unwrap().max_velocity, 0.05);
    assert_eq!(x.student.unwrap().max_acceleration, 1.0);
    assert_eq!(x.scale.si_per_unit(), 1e-5);
    assert_eq!(cell.axes_of_device("w1")[0].name, "w");
    let classes = cell.task_classes();
    assert_eq!(classes.len(), 2);
    assert_eq!(classes[0].period, Duration::from_millis(1));
    assert_eq!(classes[0].tasks, vec!["fast".to_string()]);
    assert_eq!(classes[1].period, Duration::from_millis(100));
    assert_eq!(classes[0].overrun_limit, DEFAULT_OVERRUN_LIMIT);
}

#[test]
fn unknown_key_names_file_line_column_and_key() {
    let text = BASE.replace("max_velocity = 10.0", "max_velocity = 10.0\nspeed = 3");
    let e = one_error(&text);
    assert_eq!(e.line, line_of(&text, "speed = 3"));
    assert_eq!(e.column, 1);
    assert_eq!(e.key, "axis[1].speed");
    assert!(e.message.contains("unknown field `speed`"), "{}", e.message);
    assert!(
        e.to_string().starts_with(&format!("cell.toml:{}:1: axis[1].speed: unknown field", e.line)),
        "{e}"
    );
}

#[test]
fn unknown_key_in_inline_table_and_unknown_kind() {
    let text = BASE
        .replace("limits = { min = -100.0, max = 100.0 }", "limits = { min = -100.0, max = 100.0, mid = 0 }");
    let e = one_error(&text);
    assert_eq!(e.key, "axis[1].limits.mid");
    assert_eq!(e.line, line_of(&text, "mid = 0"));

    let text = BASE.replace("kind = \"cia402\"", "kind = \"cia403\"");
    let e = one_error(&text);
    assert_eq!(e.key, "device[1].kind");
    assert_eq!(e.line, line_of(&text, "cia403"));
    // `kind = "cia403"`: the value starts at column 8.
    assert_eq!(e.column, 8);
    assert!(e.message.contains("unknown variant `cia403`"), "{}", e.message);
}

#[test]
fn syntax_error_points_at_line() {
    let text = BASE.replace("scale = 0.001", "scale = = 0.001");
    let e = one_error(&text);
    assert_eq!(e.line, line_of(&text, "scale = = 0.001"));
}

#[test]
fn min_above_max_points_at_min() {
    let text = BASE.replace("limits = { min = 0.0, max = 0.5 }", "limits = { min = 10, max = 5 }");
    let e = one_error(&text);
    let line = line_of(&text, "min = 10");
    // `limits = { min = 10`: the 10 is at column 18 (1-based).
    assert_eq!((e.line, e.column), (line, 18));
    assert_eq!(e.key, "axis[0].limits.min");
    assert_eq!(
        e.to_string(),
        format!("cell.toml:{line}:18: axis \"x\": limits.min (10) must be below limits.max (5)")
    );
}

#[test]
fn dangling_references_are_reported_together_in_file_order() {
    let text = BASE
        .replace("link = \"can\"", "link = \"can9\"")
        .replace("axes = [\"x\", \"w\"]", "axes = [\"x\", \"q\"]");
    let errs = parse(&text).unwrap_err().0;
    assert_eq!(errs.len(), 2, "{errs:?}");
    assert_eq!(errs[0].key, "device[1].link");
    assert!(errs[0].message.contains("link \"can9\" is not defined"));
    assert_eq!(errs[1].key, "group[0].axes[1]");
    assert_eq!(errs[1].line, line_of(&text, "\"q\""));
    assert!(errs[0].line < errs[1].line);
}

#[test]
fn duplicate_names_addresses_and_wrong_link_kinds() {
    let text = BASE.replace("name = \"w1\"", "name = \"m1\"");
    let errs = parse(&text).unwrap_err().0;
    assert!(errs.iter().any(|e| e.key == "device[1].name" && e.message.contains("used twice")), "{errs:?}");

    let text = BASE.replace("link = \"can\"\naddress = 2", "link = \"ttyA\"\naddress = 1");
    let errs = parse(&text).unwrap_err().0;
    // cia402 on a pty, and (second check) not a duplicate address since the first fails?
    // Both are reported: wrong link kind and address 1 already used on ttyA.
    assert!(
        errs.iter().any(|e| e.key == "device[1].link" && e.message.contains("needs a can link")),
        "{errs:?}"
    );
    assert!(
        errs.iter().any(|e| e.key == "device[1].address" && e.message.contains("already used")),
        "{errs:?}"
    );

    let text = BASE.replace("address = 2", "address = 200");
    let e = one_error(&text);
    assert_eq!(e.key, "device[1].address");
    assert!(e.message.contains("1..=127"), "{}", e.message);
}

#[test]
fn student_limits_outside_machine_limits() {
    let text = BASE.replace(
        "student = { max = 0.4, max_velocity = 0.05 }",
        "student = { max = 0.6, max_velocity = 0.5 }",
    );
    let errs = parse(&text).unwrap_err().0;
    assert_eq!(errs.len(), 2, "{errs:?}");
    assert_eq!(errs[0].key, "axis[0].student.max");
    assert_eq!(errs[1].key, "axis[0].student.max_velocity");
}

#[test]
fn positive_periods_speeds_and_scale() {
    let text = BASE.replace("period_ms = 100", "period_ms = 0");
    assert_eq!(one_error(&text).key, "task[1].period_ms");
    let text = BASE.replace("max_velocity = 10.0", "max_velocity = -1.0");
    assert_eq!(one_error(&text).key, "axis[1].max_velocity");
    let text = BASE.replace("scale = 0.001", "scale = 0.0");
    assert_eq!(one_error(&text).key, "axis[1].scale");
    let text = BASE.replace("scale = 0.001", "scale = nan");
    assert!(parse(&text).is_err());
}

#[test]
fn group_sizes_and_task_requirements() {
    let text = BASE.replace("kind = \"gantry\"", "kind = \"omni\"");
    let e = one_error(&text);
    assert_eq!(e.key, "group[0].axes");
    assert!(e.message.contains("needs 3 axes, found 2"), "{}", e.message);

    let text = BASE.replace("kind = \"motion\"\ngroup = \"g\"", "kind = \"motion\"");
    assert_eq!(one_error(&text).key, "task[0].group");

    let text = BASE.replace("kind = \"trace\"", "kind = \"program\"");
    assert_eq!(one_error(&text).key, "task[1].program");
}

#[test]
fn axis_index_must_fit_device() {
    let text = BASE.replace("device = \"w1\"", "device = \"w1\"\nindex = 1");
    let e = one_error(&text);
    assert_eq!(e.key, "axis[1].index");
    assert!(e.message.contains("0..1"), "{}", e.message);
}

#[test]
fn program_check_time_defaults_and_is_bounded() {
    assert_eq!(parse(BASE).unwrap().station.program_check_time, super::DEFAULT_PROGRAM_CHECK_TIME);
    let text = BASE.replace("name = \"test\"", "name = \"test\"\nprogram_check_time = 0.5");
    assert_eq!(parse(&text).unwrap().station.program_check_time, std::time::Duration::from_millis(500));
    for bad in ["0", "-1", "601", "nan"] {
        let text = BASE.replace("name = \"test\"", &format!("name = \"test\"\nprogram_check_time = {bad}"));
        assert_eq!(one_error(&text).key, "station.program_check_time", "{bad}");
    }
}

#[test]
fn listen_address_and_missing_files() {
    let text = BASE.replace("name = \"test\"", "name = \"test\"\nlisten = \"localhost\"");
    assert_eq!(one_error(&text).key, "station.listen");

    let text = format!(
        "{BASE}\n[supervisor]\nrules = \"rules.toml\"\n\n[[program]]\nname = \"p\"\nfile = \"p.ngc\"\n"
    );
    let errs = parse_with(Path::new("dir/cell.toml"), &text, &|_| false).unwrap_err().0;
    assert_eq!(errs.len(), 2);
    assert_eq!(errs[0].key, "supervisor.rules");
    assert!(errs[0].message.contains("dir/rules.toml"), "{}", errs[0].message);
    assert_eq!(errs[1].key, "program[0].file");
}

#[test]
fn supervisor_files_resolve_relative_to_the_cell_and_drives_must_exist() {
    let text = format!(
        "{BASE}\n[supervisor]\nrules = \"rules.toml\"\ndrives = \"data/drives.toml\"\napproval = \"data/a.approved\"\nkey = \"/etc/motus/admin.key\"\n"
    );
    let cell = parse_with(Path::new("dir/cell.toml"), &text, &|_| true).unwrap();
    let sup = cell.supervisor.unwrap();
    assert_eq!(sup.rules, Path::new("dir/rules.toml"));
    assert_eq!(sup.drives.as_deref(), Some(Path::new("dir/data/drives.toml")));
    assert_eq!(sup.approval.as_deref(), Some(Path::new("dir/data/a.approved")));
    assert_eq!(sup.key.as_deref(), Some(Path::new("/etc/motus/admin.key")));
    // Without `drives`: none.
    let plain = format!("{BASE}\n[supervisor]\nrules = \"rules.toml\"\n");
    assert_eq!(parse(&plain).unwrap().supervisor.unwrap().drives, None);
    // A named drive-parameter file must exist (the approval may not exist yet).
    let errs = parse_with(Path::new("dir/cell.toml"), &text, &|p| !p.ends_with("drives.toml")).unwrap_err().0;
    assert_eq!(errs.len(), 1, "{errs:?}");
    assert_eq!(errs[0].key, "supervisor.drives");
    assert!(errs[0].message.contains("dir/data/drives.toml"), "{}", errs[0].message);
    assert_eq!(errs[0].line, line_of(&text, "drives = "));
}

#[test]
fn load_reports_unreadable_file() {
    let errs = load(Path::new("/nonexistent/cell.toml")).unwrap_err();
    assert!(errs.to_string().starts_with("/nonexistent/cell.toml:0:0: cannot read"), "{errs}");
}

#[test]
fn missing_field_and_wrong_type_name_the_table_and_key() {
    let text = BASE.replace("uri = \"/tmp/motus/a\"\n", "");
    let e = one_error(&text);
    assert_eq!(e.key, "link[0]");
    assert_eq!(e.line, 4, "points at the [[link]] header");
    assert!(e.message.contains("missing field `uri`"), "{}", e.message);

    let text = BASE.replace("simulate = true", "simulate = \"yes\"");
    let e = one_error(&text);
    assert_eq!(e.key, "device[0].simulate");
    assert_eq!((e.line, e.column), (line_of(&text, "simulate = \"yes\""), 12));
}

#[test]
fn station_origins_are_scheme_host_port() {
    let text = BASE.replace(
        "name = \"test\"",
        "name = \"test\"\norigins = [\"http://station.lab:8080\", \"https://lab.example.org/\"]",
    );
    let cell = parse_with(Path::new("cell.toml"), &text, &|_| true).unwrap();
    assert_eq!(cell.station.origins, ["http://station.lab:8080", "https://lab.example.org/"]);
    assert!(parse_with(Path::new("cell.toml"), BASE, &|_| true).unwrap().station.origins.is_empty());
    for bad in ["station.lab:8080", "http://", "http://a/b", "ftp://a"] {
        let text = BASE.replace("name = \"test\"", &format!("name = \"test\"\norigins = [{bad:?}]"));
        assert_eq!(one_error(&text).key, "station.origins", "{bad}");
    }
}

#[test]
fn powerlink_links_take_udp_mem_or_an_interface() {
    let cell =
        |uri: &str| format!("{BASE}\n[[link]]\nname = \"epl\"\nkind = \"powerlink\"\nuri = \"{uri}\"\n");
    for ok in ["udp://127.0.0.1:24000", "mem://juggler-1", "eth0"] {
        parse(&cell(ok)).unwrap_or_else(|e| panic!("{ok}: {e:?}"));
    }
    for bad in ["mem://", "mem://a b", "tcp://127.0.0.1:1"] {
        let e = one_error(&cell(bad));
        assert!(e.to_string().contains("mem://NAME"), "{bad}: {e}");
    }
}

#[test]
fn the_tool_table_is_read_and_checked() {
    let good = format!(
        "{BASE}\n[[tool]]\nnumber = 1\ndiameter_mm = 6.0\nlength_mm = 20.0\ncomment = \"6 mm drill\"\n\n\
         [[tool]]\nnumber = 2\ndiameter_mm = 10\nlength_mm = 35.5\n"
    );
    let cell = parse(&good).unwrap();
    assert_eq!(
        cell.tools,
        vec![
            ToolConfig { number: 1, diameter_mm: 6.0, length_mm: 20.0, comment: "6 mm drill".into() },
            ToolConfig { number: 2, diameter_mm: 10.0, length_mm: 35.5, comment: String::new() },
        ]
    );
    assert!(parse(BASE).unwrap().tools.is_empty(), "a cell without tools has an empty table");
    let bad = format!(
        "{BASE}\n[[tool]]\nnumber = 1\ndiameter_mm = -6.0\nlength_mm = 20.0\n\n\
         [[tool]]\nnumber = 1\ndiameter_mm = 6\nlength_mm = 0\n\n[[tool]]\nnumber = 0\ndiameter_mm = 6\nlength_mm = 0\n"
    );
    let errs = parse(&bad).expect_err("must fail").0;
    let texts: Vec<String> = errs.iter().map(|e| format!("{}: {}", e.key, e.message)).collect();
    assert_eq!(
        texts,
        [
            "tool[0].diameter_mm: tool T1: diameter_mm (-6) must be a number >= 0",
            "tool[1].number: tool T1 is listed twice",
            "tool[2].number: tool[2]: number 0 is not 1-99999",
        ],
        "{errs:?}"
    );
    assert_eq!(errs[0].line, line_of(&bad, "diameter_mm = -6.0"));
}
