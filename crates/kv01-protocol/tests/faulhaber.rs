//! Faulhaber request parsing by hand from `specs/faulhaber.md` §1.1-§1.5.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

use motus_kv01_protocol::faulhaber::{Command, ControllerError, Query, Reply, Request, RequestError};

fn cmd(s: &str) -> Command {
    Request::parse(s).unwrap().command
}

#[test]
fn spec_examples() {
    // §1.1: `v500` = `V500` = `V 500`.
    for s in ["v500", "V500", "V 500"] {
        assert_eq!(cmd(s), Command::Velocity(500));
    }
    assert_eq!(cmd("POS"), Command::Query(Query::Position));
    assert_eq!(cmd("GN"), Command::Query(Query::Velocity));
    assert_eq!(cmd("gu"), Command::Query(Query::Pwm));
    assert_eq!(cmd("EN"), Command::Enable);
    assert_eq!(cmd("DIPROG"), Command::DisableProgram);
    assert_eq!(cmd("ENPROG"), Command::EnableProgram);
    assert_eq!(cmd("ANSW2"), Command::AnswerMode(2));
    assert_eq!(cmd("SOR 0"), Command::VelocitySource(0));
    assert_eq!(cmd("HO"), Command::Home(None));
    assert_eq!(cmd("HO -5"), Command::Home(Some(-5)));
    assert_eq!(cmd("LA 1000"), Command::LoadAbsolute(1000));
    assert_eq!(cmd("LR-1000"), Command::LoadRelative(-1000));
    assert_eq!(cmd("M"), Command::Move);
    assert_eq!(cmd("np 1000"), Command::NotifyPosition(Some(1000)));
    assert_eq!(cmd("NPOFF"), Command::NotifyPositionOff);
    assert_eq!(cmd("GADV1"), Command::AnalogInput(1));
    assert_eq!(cmd("EEPSAV"), Command::EepSave);
    assert_eq!(cmd("GST"), Command::Query(Query::Status));
    assert_eq!(cmd("OST"), Command::Query(Query::OperationStatus));
    assert_eq!(cmd("VER"), Command::Query(Query::Version));
    // §1.2: node prefix (EPICS `0GST`, `1POS`; manual `3V100`).
    let r = Request::parse("3V100").unwrap();
    assert_eq!((r.node, r.velocity()), (Some(3), Some(100)));
    assert_eq!(Request::parse("0GST").unwrap().node, Some(0));
    assert_eq!(r.to_string(), "3V100");
    assert_eq!(Request::parse(" v -0320 ").unwrap().to_string(), "V-320");
    // Not in the typed subset.
    assert_eq!(cmd("gprogseq1"), Command::Unknown("GPROGSEQ1".into()));
    assert_eq!(cmd("NET"), Command::Unknown("NET".into()));
}

#[test]
fn errors() {
    assert_eq!(Request::parse(""), Err(RequestError::Empty));
    assert_eq!(Request::parse("  7 "), Err(RequestError::Empty));
    assert!(matches!(Request::parse("V5X"), Err(RequestError::Syntax(_))));
    assert!(matches!(Request::parse("-5"), Err(RequestError::Syntax(_))));
    assert!(matches!(Request::parse("V--5"), Err(RequestError::Syntax(_))));
    assert!(matches!(Request::parse("V-"), Err(RequestError::Syntax(_))));
    assert!(matches!(Request::parse("EN\r"), Err(RequestError::Syntax(_))));
    assert!(matches!(Request::parse("é"), Err(RequestError::Syntax(_))));
    assert_eq!(Request::parse("256V1"), Err(RequestError::NodeOutOfRange));
    assert_eq!(Request::parse("V"), Err(RequestError::MissingArgument("V")));
    assert_eq!(Request::parse("EN1"), Err(RequestError::UnexpectedArgument("EN")));
    assert_eq!(Request::parse("V2147483648"), Err(RequestError::ArgumentOutOfRange("V")));
    assert_eq!(Request::parse("V-2147483648").unwrap().velocity(), Some(i32::MIN));
    assert_eq!(
        Request::parse("V5X").unwrap_err().controller_reply(),
        Reply::Error(ControllerError::UnknownCommand)
    );
    assert_eq!(
        Request::parse("V").unwrap_err().controller_reply(),
        Reply::Error(ControllerError::InvalidParameter)
    );
}

#[test]
fn replies() {
    assert_eq!(Reply::parse("98956"), Reply::Value(98956));
    assert_eq!(Reply::parse("OK"), Reply::Ok);
    assert_eq!(Reply::parse("Flash defect"), Reply::FlashDefect);
    assert_eq!(Reply::parse("p"), Reply::PositionReached);
    assert_eq!(Reply::parse("Unknown command"), Reply::Error(ControllerError::UnknownCommand));
    assert_eq!(Reply::parse("Command not available"), Reply::Error(ControllerError::CommandNotAvailable));
    assert_eq!(
        Reply::parse("Overtemperature - drive disabled"),
        Reply::Error(ControllerError::Overtemperature)
    );
    // The manual's en dash is not what the controller sends: kept as text.
    assert!(matches!(Reply::parse("Overtemperature \u{2013} drive disabled"), Reply::Text(_)));
}

#[test]
fn serde_forms() {
    let r = Request::parse("3V-5").unwrap();
    let json = serde_json::to_string(&r).unwrap();
    assert_eq!(json, r#"{"node":3,"cmd":"velocity","arg":-5}"#);
    assert_eq!(serde_json::from_str::<Request>(&json).unwrap(), r);
    let json = serde_json::to_string(&Request::parse("POS").unwrap()).unwrap();
    assert_eq!(json, r#"{"cmd":"query","arg":"position"}"#);
    assert_eq!(serde_json::to_string(&Reply::Value(7)).unwrap(), r#""7""#);
}
