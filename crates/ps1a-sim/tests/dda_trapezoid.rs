//! Acceptance 5: the simulated DDA position-versus-time of a move matches the theoretical
//! trapezoid computed independently here (from DS, the cycle, the speed value and the
//! acceleration number, with the formulas of `specs/ps1a.md` and our documented
//! acceleration mapping) within 1 unit at every DDA cycle.
#![allow(clippy::panic, clippy::unwrap_used, clippy::indexing_slicing)]

use motus_ps1a_protocol::*;
use motus_ps1a_sim::{MachineConfig, Module};
use std::time::Duration;

/// Closed-form trapezoid (or triangle) from rest over distance `d` >= 0.
fn theory(t: f64, d: f64, v: f64, a: f64) -> f64 {
    let (t_acc, t_flat) = if d >= v * v / a { (v / a, (d - v * v / a) / v) } else { ((d / a).sqrt(), 0.0) };
    let vp = a * t_acc;
    let total = 2.0 * t_acc + t_flat;
    if t <= 0.0 {
        0.0
    } else if t < t_acc {
        0.5 * a * t * t
    } else if t < t_acc + t_flat {
        0.5 * a * t_acc * t_acc + vp * (t - t_acc)
    } else if t < total {
        let td = total - t;
        d - 0.5 * a * td * td
    } else {
        d
    }
}

fn homed_module(p: Parameters) -> Module {
    let mut m = Module::power_on(p, true, MachineConfig::default(), 5_000.0, Duration::ZERO);
    let mut now = Duration::ZERO;
    let step = p.tvz.period();
    m.handle(&Command::ControlByte { control: ControlByte(ControlByte::POWER_STAGE) }, now);
    m.handle(&Command::Home, now);
    while m.in_motion() {
        now += step;
        m.advance_to(now);
    }
    assert!(!m.report().low.has(LowStatus::AFTER_RESET), "homing clears the reset flag");
    m
}

fn check(ds: u8, tvz: DdaCycle, speed: u16, acc: u8, start: u32, target: u32) {
    let p = Parameters { ds, tvz, max_position: U24::MAX, ..Parameters::default() };
    let mut m = homed_module(p);
    let period = tvz.period();
    let mut now = Duration::from_secs(100);
    m.advance_to(now);
    let a = Acceleration::new(acc).unwrap();
    m.handle(&Command::SetSpeed { speed, acceleration: a }, now);
    m.handle(&Command::MoveAbsolute { target: U24::new(start).unwrap() }, now);
    while m.in_motion() {
        now += period;
        m.advance_to(now);
    }
    let x0 = m.commanded_position();
    assert!((x0 - f64::from(start)).abs() < 1e-6);
    // Independent numbers: v = V*DS/256/T, a = A*DS/256/T^2.
    let t = tvz.seconds();
    let v_units = f64::from(speed) * f64::from(ds) / 256.0 / t;
    let a_units = f64::from(acc) * f64::from(ds) / 256.0 / (t * t);
    let d = f64::from(target) - f64::from(start);
    m.handle(&Command::MoveAbsolute { target: U24::new(target).unwrap() }, now);
    let mut k = 0u32;
    let mut worst = 0.0f64;
    while m.in_motion() {
        now += period;
        k += 1;
        m.advance_to(now);
        let expected = x0 + d.signum() * theory(f64::from(k) * t, d.abs(), v_units, a_units);
        let got = m.commanded_position().round();
        worst = worst.max((got - expected).abs());
        assert!((got - expected).abs() <= 1.0, "cycle {k}: DDA {got} vs theory {expected}");
        assert!(k < 10_000_000);
    }
    assert_eq!(m.report().position.get(), target);
    eprintln!("ds={ds} tvz={tvz:?} V={speed} A={acc} {start}->{target}: {k} cycles, worst deviation {worst:.3} units");
}

#[test]
fn trapezoid_default_parameters() {
    check(39, DdaCycle::Ms1_54, 1000, 8, 0, 100_000);
}

#[test]
fn triangle_short_move() {
    check(39, DdaCycle::Ms1_54, 5000, 2, 1000, 3000);
}

#[test]
fn backwards_other_cycles() {
    check(200, DdaCycle::Ms4_20, 300, 10, 50_000, 1_234);
    check(17, DdaCycle::Ms2_10, 65535, 1, 10, 400_000);
    check(128, DdaCycle::Ms2_66, 1, 1, 500, 520);
}
