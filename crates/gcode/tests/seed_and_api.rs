//! The seed's additions (M-functions, EX parameters), machine-mm moves, streaming and
//! error positions; expected values worked out by hand from specs/cnc.md and the rules
//! in the crate docs.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use motus_gcode::{
    format_canon, interpret, interpret_with, Canon, ErrorKind, Interpreter, InterpreterConfig, MCodeDialect,
    MachineMove, Precision,
};

fn text(src: &str, cfg: InterpreterConfig) -> Vec<String> {
    interpret_with(src, cfg)
        .unwrap()
        .iter()
        .skip(5) // the set-up calls
        .map(|c| format_canon(&c.canon, Precision::Full))
        .collect()
}

#[test]
fn seed_example_program() {
    // The example of specs/cnc.md, with M2 added.
    let src = "N001 M63\nN005 G00 X100 Y100 F300\nN010 EXW60=3600 EXF61=100\nN020 M60\n\
               N030 G01 X110 Y110\nN040 M60\nN060 EXW60=1800 EXF61=60 EXF62=50.5\nN070 M60\nM2\n";
    let cfg = InterpreterConfig { async_m_functions: vec![63], ..InterpreterConfig::default() };
    let t = text(src, cfg);
    assert_eq!(
        &t[..9],
        &[
            "M_FUNCTION(63, ASYNC)",
            "SET_FEED_RATE(300)",
            "STRAIGHT_TRAVERSE(100, 100, 0, 0, 0, 0)",
            "EXTERNAL_PARAMETER(W, 60, 3600)",
            "EXTERNAL_PARAMETER(F, 61, 100)",
            "M_FUNCTION(60, SYNC)",
            "STRAIGHT_FEED(110, 110, 0, 0, 0, 0)",
            "M_FUNCTION(60, SYNC)",
            "EXTERNAL_PARAMETER(W, 60, 1800)",
        ]
    );
    assert!(t.contains(&"EXTERNAL_PARAMETER(F, 62, 50.5)".to_string()));
}

#[test]
fn m_function_runs_before_motion_of_its_block() {
    let t = text("G1 X1 F10 M61\nM2\n", InterpreterConfig::default());
    assert_eq!(t[..3], ["SET_FEED_RATE(10)", "M_FUNCTION(61, SYNC)", "STRAIGHT_FEED(1, 0, 0, 0, 0, 0)"]);
}

#[test]
fn ex_range_checks() {
    let e = interpret("EXB1=200\nM2\n").unwrap_err();
    assert_eq!((e.line, e.column), (1, 1));
    assert!(matches!(e.kind, ErrorKind::ExternalRange { array: 'B', .. }));
    let e = interpret("G0 X1\nEXW100=1\nM2\n").unwrap_err();
    assert_eq!(e.line, 2);
    assert!(interpret("EXL5=-2147483648 EXB0=-128\nM2\n").is_ok());
}

#[test]
fn machine_moves_are_mm_with_offsets() {
    // G20: X1 inch = 25.4 mm; G92 shifts by 2 inch in X: machine = (prog + g92) * 25.4.
    let calls = interpret("G20 G0 X1 Y0\nG92 X0\nG1 X1 F10\nG2 X3 Y0 I1 J0\nM2\n").unwrap();
    let moves: Vec<MachineMove> = calls.iter().filter_map(|c| c.machine).collect();
    match moves[1] {
        MachineMove::Feed { start, end, feed } => {
            assert!((start[0] - 25.4).abs() < 1e-12);
            assert!((end[0] - 50.8).abs() < 1e-12);
            assert!((feed - 254.0).abs() < 1e-12);
        }
        m => panic!("{m:?}"),
    }
    match moves[2] {
        MachineMove::Arc { centre, end, rotation, .. } => {
            assert!((centre[0] - 76.2).abs() < 1e-12, "{centre:?}");
            assert!((end[0] - 101.6).abs() < 1e-12);
            assert_eq!(rotation, -1);
        }
        m => panic!("{m:?}"),
    }
}

#[test]
fn streaming_yields_before_the_error() {
    let mut it = Interpreter::new("G0 X1\nG0 X2\nG1 X3\nM2\n");
    let mut ok = 0;
    let err = loop {
        match it.next().unwrap() {
            Ok(_) => ok += 1,
            Err(e) => break e,
        }
    };
    assert_eq!(ok, 5 + 2);
    assert_eq!((err.line, err.column), (3, 1));
    assert_eq!(err.to_string(), "3:1: Cannot do g1 with zero feed rate");
    assert_eq!(err.with_file("prog.ngc").to_string(), "prog.ngc:3:1: Cannot do g1 with zero feed rate");
    assert!(it.next().is_none());
}

#[test]
fn error_columns() {
    let e = interpret("G0 X1 (a (b))\nM2\n").unwrap_err();
    assert_eq!((e.line, e.column, e.kind), (1, 10, ErrorKind::NestedComment));
    let e = interpret("G0 X1\n  G1 X[1/0]\nM2\n").unwrap_err();
    assert_eq!((e.line, e.column, e.kind), (2, 6, ErrorKind::DivideByZero));
}

#[test]
fn endless_loop_is_caught() {
    let cfg = InterpreterConfig { max_steps: 1000, ..InterpreterConfig::default() };
    let e = interpret_with("o1 while [1]\no1 endwhile\nM2\n", cfg).unwrap_err();
    assert!(matches!(e.kind, ErrorKind::StepLimit(1000)));
}

#[test]
fn a_cancelled_interpreter_stops_at_its_next_line() {
    use motus_gcode::CancelFlag;
    let flag = CancelFlag::new();
    let cfg = InterpreterConfig { cancel: Some(flag.clone()), ..InterpreterConfig::default() };
    let src = "G21\n#1 = 0\no1 while [1]\nG1 X[#1] F100\n#1 = [#1 + 1]\no1 endwhile\nM2\n";
    let mut it = Interpreter::with_config(src, cfg);
    // Not cancelled: it runs, one move per loop.
    let moves = it.by_ref().filter_map(Result::ok).filter(|c| c.machine.is_some()).take(100).count();
    assert_eq!(moves, 100);
    let before = it.steps();
    flag.cancel();
    let e = it.next().unwrap().unwrap_err();
    assert_eq!(e.kind, ErrorKind::Cancelled(before + 1), "{e}");
    assert!((3..=6).contains(&e.line), "{e}: inside the loop");
    assert!(it.next().is_none(), "ended");
    // A flag set before the start stops the program before its first line.
    let flag = CancelFlag::new();
    flag.cancel();
    let cfg = InterpreterConfig { cancel: Some(flag), ..InterpreterConfig::default() };
    let e = interpret_with("G0 X1\nM2\n", cfg).unwrap_err();
    assert_eq!((e.line, e.kind), (1, ErrorKind::Cancelled(1)));
}

#[test]
fn program_end_optional() {
    let cfg = InterpreterConfig { require_program_end: false, ..InterpreterConfig::default() };
    let calls = interpret_with("G0 X1\n", cfg).unwrap();
    assert!(matches!(calls.last().unwrap().canon, Canon::StraightTraverse { .. }));
    assert!(interpret("G0 X1\n").is_err());
    // % delimited program: ends at the second %.
    assert!(interpret("%\nG0 X1\n%\nthis is not parsed\n").is_ok());
}

/// LinuxCNC's wording for an arc whose end radius differs, points included (the texts are
/// what `rs274` 2.9 printed for these programs).
#[test]
fn arc_radius_errors_read_as_linuxcnc_words_them() {
    let cases = [
        (
            "G21 G90 F100\nG18\nG2 X10 Z0 I0 K4\nM2\n",
            "Radius to end of arc differs from radius to start: start=(Z0.0000,X0.0000) center=(Z4.0000,X0.0000) end=(Z0.0000,X10.0000) r1=4.0000 r2=10.7703 abs_err=6.77 rel_err=62.8609%",
        ),
        (
            "G21 G90 F100\nG0 X0.123 Y1\nG2 X20.03 Y1 I10 J0\nM2\n",
            "Radius to end of arc differs from radius to start: start=(X0.1230,Y1.0000) center=(X10.1230,Y1.0000) end=(X20.0300,Y1.0000) r1=10.0000 r2=9.9070 abs_err=0.093 rel_err=0.9300%",
        ),
    ];
    for (prog, rs274) in cases {
        let e = motus_gcode::interpret(prog).unwrap_err();
        assert_eq!(e.kind.to_string(), rs274);
    }
}

#[test]
fn machine_moves_follow_the_coordinate_system_rotation() {
    // G55 at (100, 50) turned 90 degrees, G92 shifts 1 mm along the rotated X: program
    // (10, 0) is at machine (100, 50) + R90 (11, 0) = (100, 61); the arc's centre
    // (10, 5) + (1, 0) turns to (-5, 11).
    let src =
        "G21 G90\nG10 L2 P2 X100 Y50 R90\nG55\nG0 X0 Y0\nG92 X-1\nG1 X10 Y0 F100\nG3 X10 Y10 I0 J5\nM2\n";
    let calls = interpret(src).unwrap();
    let moves: Vec<MachineMove> = calls.iter().filter_map(|c| c.machine).collect();
    let close = |a: f64, b: f64| (a - b).abs() < 1e-9;
    let MachineMove::Feed { end, .. } = moves[1] else { panic!("{:?}", moves[1]) };
    assert!(close(end[0], 100.0) && close(end[1], 61.0), "{end:?}");
    let MachineMove::Arc { end, centre, .. } = moves[2] else { panic!("{:?}", moves[2]) };
    assert!(close(end[0], 90.0) && close(end[1], 61.0), "{end:?}");
    assert!(close(centre[0], 95.0) && close(centre[1], 61.0), "{centre:?}");
    // The canonical calls stay in the program's (unrotated) coordinates.
    assert!(calls.iter().any(|c| c.canon == Canon::SetXyRotation { degrees: 90.0 }));
    assert!(calls.iter().any(|c| matches!(c.canon, Canon::StraightFeed { end } if end[0] == 10.0)));
}

#[test]
fn m60_to_m68_follow_the_machine_dialect() {
    let src = "G0 X1\nM62 P1\nM66 P2 L3 Q1.5\nM67 E0 Q2.5\nM60\nM100 P1\nM2\n";
    // The seed's M-functions take P and Q words, not L or E.
    let seed = text(&src.replace(" L3", "").replace("E0 ", ""), InterpreterConfig::default());
    assert_eq!(
        seed[..6],
        [
            "STRAIGHT_TRAVERSE(1, 0, 0, 0, 0, 0)",
            "M_FUNCTION(62, SYNC)",
            "M_FUNCTION(66, SYNC)",
            "M_FUNCTION(67, SYNC)",
            "M_FUNCTION(60, SYNC)",
            "M_FUNCTION(100, SYNC)"
        ]
    );
    let cfg = InterpreterConfig { m_codes: MCodeDialect::LinuxCnc, ..InterpreterConfig::default() };
    let linuxcnc = text(src, cfg.clone());
    assert_eq!(
        linuxcnc[..7],
        [
            "STRAIGHT_TRAVERSE(1, 0, 0, 0, 0, 0)",
            "SET_MOTION_OUTPUT_BIT(1)",
            "WAIT(2, DIGITAL_INPUT, 3, 1.5)",
            "SET_MOTION_OUTPUT_VALUE(0,2.5)",
            "PALLET_SHUTTLE()",
            "PROGRAM_STOP()",
            "M_FUNCTION(100, SYNC)"
        ]
    );
    // An E word is only read in the LinuxCNC dialect.
    let e = interpret_with("M66 E1\nM2\n", InterpreterConfig::default()).unwrap_err();
    assert_eq!((e.column, e.kind), (5, ErrorKind::UnsupportedLetter('E')));
    // Refused here although the standalone rs274 accepts them: M67/M68 without a value
    // (LinuxCNC would send -1) and an M66 wait type outside 0..=4.
    for bad in ["M67 E1\nM2\n", "M68 E0\nM2\n", "M66 P1 L7 Q1\nM2\n"] {
        let e = interpret_with(bad, cfg.clone()).unwrap_err();
        assert!(matches!(e.kind, ErrorKind::BadIo(_)), "{bad}: {e}");
        assert_eq!(e.line, 1);
    }
}
