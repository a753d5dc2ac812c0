#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
//! Supervisor on the juggler rule set, figures computed by hand from
//! specs/juggler-safety.md. Horizon at age 0: Tp 0.0096 + lease 0.0008 = 0.0104 s.
//! Reach at rest (a H^2/2 + (aH)^2/(2b)):
//!   arm:      500000*0.0104^2/2 = 27.04, 5200^2/3.2e6 = 8.45   -> +-35.49
//!   vertical: 1e6*0.0104^2/2 = 54.08,    10400^2/2.6e6 = 41.6  -> +-95.68
//!   thrower:  2e6*0.0104^2/2 = 108.16,   20800^2/4e6 = 108.16  -> +-216.32

use motus_safety::supervisor::DataProblem;
use motus_safety::*;
use std::time::Duration;

fn rules() -> RuleSet {
    RuleSet::from_toml(JUGGLER_TOML).unwrap()
}

/// Order: arm_left, vertical_left, arm_right, vertical_right, thrower.
fn at(pos: [f64; 5], cycle: u64) -> Vec<Option<Sample>> {
    pos.iter().map(|p| Some(Sample { position: *p, speed: 0.0, cycle, homed: true })).collect()
}

fn input(samples: &[Option<Sample>], cycle: u64, mode: Mode) -> CycleInput<'_> {
    CycleInput { now: Duration::from_micros(400 * cycle), cycle, mode, samples, params_ok: true }
}

const SAFE: [f64; 5] = [-500.0, 1000.0, -500.0, 10_000.0, -7100.0];

#[test]
fn juggler_parameters_loaded_as_in_the_spec() {
    let r = rules();
    let a = r.axes();
    assert_eq!(a.len(), 5);
    assert_eq!((a[0].limits.min, a[0].limits.max), (-1000.0, 1000.0)); // corrected signs
    assert_eq!(a[0].acceleration.up, 500_000.0);
    assert_eq!(a[0].braking.down, 1_600_000.0);
    assert_eq!((a[1].limits.min, a[1].limits.max), (-1000.0, 20_000.0));
    assert_eq!(a[1].braking.up, 1_300_000.0);
    assert_eq!(a[1].oversize.up, 500.0);
    assert_eq!((a[4].limits.min, a[4].limits.max), (-7600.0, 3400.0));
    assert_eq!(a[4].acceleration.down, 2_000_000.0);
    assert_eq!(a[4].from_raw(-71_000), -7100.0);
    assert_eq!(r.config().supervisor.reaction_time, 0.0096);
    assert_eq!(r.rules().len(), 10); // 5 limits + arms + 2 thrower + 2 rod mount
}

#[test]
fn safe_at_rest_grants_a_lease_and_feeder() {
    let mut s = Supervisor::new(rules());
    let smp = at(SAFE, 10);
    let d = s.evaluate(&input(&smp, 10, Mode::Normal));
    assert!(d.safe_to_run(), "{:?}", d.diagnosis());
    assert!(d.home_ok() && d.all_modules_ok() && d.params_ok());
    // thrower at -7100, reach -7316.32..-6883.68 inside (-7400, -6800)
    assert_eq!(d.interlock("feeder_enable"), Some(true));
    let lease = d.lease().unwrap();
    assert_eq!(lease.expires(), Duration::from_micros(4000 + 800));
    assert!(lease.is_valid(Duration::from_micros(4799)));
    assert!(!lease.is_valid(Duration::from_micros(4800)));
    let r = s.reaches()[0];
    assert!((r.hi - (-500.0 + 35.49)).abs() < 1e-6, "{r:?}");
    let r = s.reaches()[4];
    assert!((r.lo - (-7100.0 - 216.32)).abs() < 1e-6, "{r:?}");
}

#[test]
fn feeder_off_when_thrower_elsewhere() {
    let mut s = Supervisor::new(rules());
    let mut p = SAFE;
    p[4] = -7200.0; // reach -7416.32 < -7400
    let smp = at(p, 1);
    let d = s.evaluate(&input(&smp, 1, Mode::Normal));
    assert!(d.safe_to_run());
    assert_eq!(d.interlock("feeder_enable"), Some(false));
}

#[test]
fn arms_pass_first_failing_rule_with_figures() {
    let mut s = Supervisor::new(rules());
    // Verticals 3000 / 3500 (cups overlap); arm_left 300: hi 335.49 < 380 -> rule holds.
    let smp = at([300.0, 3000.0, 360.0, 3500.0, -7100.0], 5);
    assert!(s.evaluate(&input(&smp, 5, Mode::Normal)).safe_to_run());
    // Both arms at 360: hi 395.49 >= 380 -> region margins 380 - 395.49 = -15.49.
    // Collision gap: 3500 - 95.68 - 500 - (3000 + 95.68 + 500) = -691.36.
    let smp = at([360.0, 3000.0, 360.0, 3500.0, -7100.0], 6);
    let d = s.evaluate(&input(&smp, 6, Mode::Normal));
    assert!(!d.safe_to_run());
    assert!(d.lease().is_none());
    let Some(Diagnosis::Rule { rule, findings }) = d.diagnosis() else { panic!("{:?}", d.diagnosis()) };
    assert_eq!(rule, "arms_pass");
    assert_eq!(findings.len(), 3);
    assert_eq!(findings[0].condition, "collision(vertical_left, vertical_right)");
    assert!((findings[0].margin + 691.36).abs() < 1e-6);
    assert_eq!(findings[1].condition, "region(arm_left, 380.0, 1000.0)");
    assert!((findings[1].margin + 15.49).abs() < 1e-6);
    let text = d.diagnosis().unwrap().to_string();
    assert!(text.starts_with("rule arms_pass failed: collision(vertical_left, vertical_right) margin -691.4 [vertical_left at 3000.0, reach 2904.3..3095.7]"), "{text}");
}

#[test]
fn limits_rule_named_first() {
    let mut s = Supervisor::new(rules());
    let mut p = SAFE;
    p[0] = 970.0; // hi 1005.49 > 1000
    p[2] = 970.0;
    let smp = at(p, 1);
    let d = s.evaluate(&input(&smp, 1, Mode::Normal));
    let Some(Diagnosis::Rule { rule, findings }) = d.diagnosis() else { panic!() };
    assert_eq!(rule, "limits_arm_left");
    assert!((findings[0].margin + 5.49).abs() < 1e-6);
}

#[test]
fn speed_toward_a_limit_counts() {
    let mut s = Supervisor::new(rules());
    // vertical_right at 19000 moving up at 100000 units/s (10 m/s):
    // s1 = 19000 + 1040 + 54.08 = 20094.08 > 20000 -> limits fail.
    let mut smp = at(SAFE, 1);
    smp[3] = Some(Sample { position: 19_000.0, speed: 100_000.0, cycle: 1, homed: true });
    let d = s.evaluate(&input(&smp, 1, Mode::Normal));
    let Some(Diagnosis::Rule { rule, .. }) = d.diagnosis() else { panic!() };
    assert_eq!(rule, "limits_vertical_right");
    // Same speed downward at 19000 is fine.
    smp[3] = Some(Sample { position: 19_000.0, speed: -100_000.0, cycle: 1, homed: true });
    assert!(s.evaluate(&input(&smp, 1, Mode::Normal)).safe_to_run());
}

#[test]
fn stale_missing_nan_future() {
    let mut s = Supervisor::new(rules());
    let smp = at(SAFE, 10);
    // age 3 allowed, age 4 stale
    assert!(s.evaluate(&input(&smp, 13, Mode::Normal)).safe_to_run());
    let d = s.evaluate(&input(&smp, 14, Mode::Normal));
    assert!(!d.safe_to_run() && !d.all_modules_ok());
    assert_eq!(
        d.diagnosis(),
        Some(&Diagnosis::Data { axis: "arm_left".into(), problem: DataProblem::Stale { age: 4, max: 3 } })
    );
    let mut m = at(SAFE, 10);
    m[2] = None;
    let d = s.evaluate(&input(&m, 10, Mode::Homing));
    assert!(!d.safe_to_run());
    assert_eq!(d.diagnosis().unwrap().to_string(), "axis arm_right: no data");
    let mut n = at(SAFE, 10);
    n[1].as_mut().unwrap().speed = f64::NAN;
    let d = s.evaluate(&input(&n, 10, Mode::Normal));
    assert_eq!(d.diagnosis().unwrap().to_string(), "axis vertical_left: position or speed not a number");
    let d = s.evaluate(&input(&smp, 9, Mode::Normal));
    assert!(matches!(
        d.diagnosis(),
        Some(Diagnosis::Data { problem: DataProblem::FromFuture { cycle: 10 }, .. })
    ));
    // short (missing slots) sample list
    let d = s.evaluate(&input(&smp[..3], 10, Mode::Normal));
    assert!(!d.safe_to_run());
}

#[test]
fn older_sample_widens_the_horizon() {
    let mut s = Supervisor::new(rules());
    let smp = at(SAFE, 10);
    s.evaluate(&input(&smp, 13, Mode::Normal));
    // age 3 cycles: H = 0.0104 + 0.0012 = 0.0116: arm reach 500000*0.0116^2/2 = 33.64,
    // 5800^2/3.2e6 = 10.5125 -> 44.1525
    let r = s.reaches()[0];
    assert!((r.hi - (-500.0 + 44.1525)).abs() < 1e-6, "{r:?}");
}

#[test]
fn params_not_ok_blocks() {
    let mut s = Supervisor::new(rules());
    let smp = at(SAFE, 1);
    let mut i = input(&smp, 1, Mode::Normal);
    i.params_ok = false;
    let d = s.evaluate(&i);
    assert!(!d.safe_to_run() && !d.params_ok());
    assert_eq!(d.diagnosis(), Some(&Diagnosis::ParamsNotApproved));
}

#[test]
fn homing_mode() {
    let mut s = Supervisor::new(rules());
    let mut smp = at(SAFE, 1);
    // arm_right un-homed, at a meaningless position inside the collision zone.
    smp[2] = Some(Sample { position: 800.0, speed: 150.0, cycle: 1, homed: false });
    let d = s.evaluate(&input(&smp, 1, Mode::Normal));
    assert!(!d.safe_to_run() && !d.home_ok());
    assert_eq!(d.diagnosis().unwrap().to_string(), "axes not homed: arm_right");
    // Homing mode: leaves on arm_right skipped, speed 150 <= 200 allowed; feeder off.
    let d = s.evaluate(&input(&smp, 1, Mode::Homing));
    assert!(d.safe_to_run(), "{:?}", d.diagnosis());
    assert!(!d.home_ok());
    assert_eq!(d.interlock("feeder_enable"), Some(false));
    // Too fast.
    smp[2].as_mut().unwrap().speed = -250.0;
    let d = s.evaluate(&input(&smp, 1, Mode::Homing));
    assert!(matches!(d.diagnosis(), Some(Diagnosis::HomingTooFast { speed, .. }) if *speed == -250.0));
    // Homed axes are still supervised in homing mode.
    smp[2].as_mut().unwrap().speed = 0.0;
    smp[0] = Some(Sample { position: 990.0, speed: 0.0, cycle: 1, homed: true });
    let d = s.evaluate(&input(&smp, 1, Mode::Homing));
    assert!(matches!(d.diagnosis(), Some(Diagnosis::Rule { rule, .. }) if rule == "limits_arm_left"));
}

#[test]
fn config_errors_name_the_problem() {
    let swapped = JUGGLER_TOML.replacen(
        "limits = { min = -1000, max = 1000 }",
        "limits = { min = 1000, max = -1000 }",
        1,
    );
    let e = RuleSet::from_toml(&swapped).unwrap_err().to_string();
    assert_eq!(e, "axis \"arm_left\": impossible limits: min 1000 >= max -1000");

    let unknown = JUGGLER_TOML.replace("expr = \"limits(thrower)\"", "expr = \"limits(axis9)\"");
    let e = RuleSet::from_toml(&unknown).unwrap_err().to_string();
    assert_eq!(e, "rule \"limits_thrower\": unknown axis \"axis9\"");

    let mismatch =
        JUGGLER_TOML.replace("expr = \"limits(thrower)\"", "expr = \"collision(arm_left, vertical_left)\"");
    let e = RuleSet::from_toml(&mismatch).unwrap_err().to_string();
    assert!(e.contains("unit mismatch: collision(arm_left, vertical_left): 0.1deg vs 0.1mm"), "{e}");

    let suffix = JUGGLER_TOML.replace("expr = \"limits(thrower)\"", "expr = \"below(arm_left, 5mm)\"");
    let e = RuleSet::from_toml(&suffix).unwrap_err().to_string();
    assert!(e.contains("unit mismatch: value 5mm on axis \"arm_left\""), "{e}");

    let region = JUGGLER_TOML.replace("region(arm_left, 620, 1000)", "region(arm_left, 1000, 620)");
    let e = RuleSet::from_toml(&region).unwrap_err().to_string();
    assert!(e.contains("min must be < max"), "{e}");

    let brake = JUGGLER_TOML.replacen(
        "braking = { up = 2_000_000, down = 2_000_000 }",
        "braking = { up = 2_000_000, down = -1 }",
        1,
    );
    let e = RuleSet::from_toml(&brake).unwrap_err().to_string();
    assert_eq!(e, "axis \"thrower\": braking.down must be > 0 (got -1)");

    let unit = JUGGLER_TOML.replacen("unit = \"0.1deg\"", "unit = \"grad\"", 1);
    let e = RuleSet::from_toml(&unit).unwrap_err().to_string();
    assert!(e.contains("arm_left") && e.contains("unknown unit \"grad\""), "{e}");

    let syntax = JUGGLER_TOML.replace("expr = \"limits(thrower)\"", "expr = \"limits(thrower) &&\"");
    let e = RuleSet::from_toml(&syntax).unwrap_err().to_string();
    assert!(e.starts_with("rule \"limits_thrower\": at offset 18:"), "{e}");
}

#[test]
fn unit_suffixes_and_seed_position_syntax() {
    // 38deg on a 0.1deg axis = 380 units; 50cm on a 0.1mm axis = 5000 units.
    let t = JUGGLER_TOML.replace(
        "region(vertical_left, 5000, 6000) || below(arm_left, 920)",
        "region(vertical_left, 50cm, 0.6m) || position(1) < 92deg",
    );
    let r = RuleSet::from_toml(&t).unwrap();
    let lines = r.canonical_lines();
    let rod = lines.iter().find(|(k, _)| k.ends_with("arm_left_vs_rod_mount")).unwrap();
    assert_eq!(rod.1, "(region(vertical_left, 5000.0, 6000.0) || position(arm_left) < 920.0)");
}
