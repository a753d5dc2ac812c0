//! Machines as bookable resources, on the real station machine: two students book two
//! machines of one cell for the same time and each commands only their own; a machine's slot
//! and a whole-cell slot never overlap; the end of one student's slot makes their machine
//! safe and homed and leaves the other machine's motion alone.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use common::web::{wait_for, Env, WebClient, ADMIN_PW, STUDENT_PW};
use reqwest::{Method, StatusCode};
use serde_json::{json, Value};

/// Generous liveness time-out for motion on a loaded host (seconds).
const MOTION: f64 = 30.0;

/// The test cell with a second machine: `bench`, the axis `w` (with student limits).
fn two_machines() -> Env {
    Env::with_cell(|t| {
        let edited = t.replacen(
            "max_acceleration = 1.0\n\n[[group]]",
            "max_acceleration = 1.0\nstudent = { min = 0.0, max = 0.3, max_velocity = 0.08 }\n\n\
             [[group]]\nname = \"bench\"\nkind = \"axes\"\naxes = [\"w\"]\n\n[[group]]",
            1,
        );
        assert_ne!(edited, t);
        edited
    })
}

async fn book(c: &WebClient, env: &Env, machine: Option<&str>) -> (StatusCode, Value) {
    let now = env.now().0;
    let mut body = json!({ "start": now, "end": now + 30 * 60 * 1000 });
    if let Some(m) = machine {
        body["machine"] = json!(m);
    }
    c.post("/api/reservations", body).await
}

async fn at_rest_at(c: &WebClient, axis: &str, target: f64) -> bool {
    wait_for(MOTION, || async {
        let a = c.axis(axis).await;
        (a["position"].as_f64().unwrap() - target).abs() < 1e-5 && a["moving"] == false
    })
    .await
}

#[tokio::test]
async fn two_students_work_on_two_machines_of_one_cell_at_the_same_time() {
    let env = two_machines();
    let s1 = env.login("student", STUDENT_PW).await;
    let s2 = env.login("student2", STUDENT_PW).await;
    let admin = env.login("admin", ADMIN_PW).await;
    let (_, groups) = s1.get("/api/groups").await;
    let ids: Vec<&str> = groups.as_array().unwrap().iter().map(|g| g["id"].as_str().unwrap()).collect();
    assert_eq!(ids, ["bench", "cnc"]);
    assert_eq!(groups[0]["kind"], "axes");

    // Two machines, one time: both booked.
    let (st, r1) = book(&s1, &env, Some("cnc")).await;
    assert_eq!(st, StatusCode::OK, "{r1}");
    assert_eq!(r1["station"], "cnc");
    let (st, r2) = book(&s2, &env, Some("bench")).await;
    assert_eq!(st, StatusCode::OK, "{r2}");
    // The same machine twice, or the whole cell over a machine's slot: 409.
    let (st, e) = book(&s2, &env, Some("cnc")).await;
    assert_eq!(st, StatusCode::CONFLICT, "{e}");
    let (st, e) = book(&admin, &env, None).await;
    assert_eq!(st, StatusCode::CONFLICT, "{e}");
    assert!(e["detail"].to_string().contains("student"), "{e}");
    // A machine that does not exist: 400, naming the machines.
    let (st, e) = book(&s2, &env, Some("lathe")).await;
    assert_eq!(st, StatusCode::BAD_REQUEST, "{e}");
    assert!(e["detail"].as_str().unwrap().contains("bench, cnc"), "{e}");

    let (_, session) = s1.get("/api/session").await;
    assert_eq!(session["my_slots"], json!(["cnc"]));
    assert_eq!(session["machines"], json!(["bench", "cnc"]));
    assert_eq!(session["slots"].as_array().unwrap().len(), 2);
    assert_eq!(session["can_command"], true);
    let (_, list) = s1.get("/api/reservations").await;
    let machines: Vec<&str> =
        list.as_array().unwrap().iter().map(|r| r["station"].as_str().unwrap()).collect();
    assert_eq!(machines.len(), 2);
    assert!(machines.contains(&"cnc") && machines.contains(&"bench"), "{list}");

    // Each commands their own machine, in parallel, and only their own.
    let (st, e) = s1.post("/api/axes/x/move", json!({ "target": 0.05, "speed": 0.05 })).await;
    assert_eq!(st, StatusCode::OK, "{e}");
    let (st, e) = s2.post("/api/axes/w/move", json!({ "target": 0.02, "speed": 0.05 })).await;
    assert_eq!(st, StatusCode::OK, "{e}");
    let (st, e) = s1.post("/api/axes/w/move", json!({ "target": 0.1, "speed": 0.05 })).await;
    assert_eq!(st, StatusCode::FORBIDDEN, "{e}");
    assert_eq!(e["detail"]["reason"]["station"], "bench", "{e}");
    assert_eq!(e["detail"]["reason"]["holder"], "student2", "{e}");
    let (st, e) = s2.post("/api/axes/y/move", json!({ "target": 0.1, "speed": 0.05 })).await;
    assert_eq!(st, StatusCode::FORBIDDEN, "{e}");
    assert_eq!(e["detail"]["reason"]["holder"], "student", "{e}");
    assert!(at_rest_at(&s1, "x", 0.05).await);
    assert!(at_rest_at(&s2, "w", 0.02).await);
    // The audit names the machine.
    let audit = env.audit_of("student", "command.axis.move");
    assert!(audit.iter().any(|(t, k, _)| t.starts_with("cnc/x move") && k == "ok"), "{audit:?}");

    // Student 2 sets w moving slowly; student 1 ends their slot: the CNC is made safe and
    // homed, w keeps its motion (another student's machine).
    let (st, e) = s2.post("/api/axes/w/move", json!({ "target": 0.25, "speed": 0.02 })).await;
    assert_eq!(st, StatusCode::OK, "{e}");
    let (st, e) = s1.req(Method::DELETE, &format!("/api/reservations/{}", r1["id"]), None).await;
    assert_eq!(st, StatusCode::OK, "{e}");
    assert!(
        wait_for(MOTION, || async {
            let a = s1.axis("x").await;
            a["homed"] == true && a["position"].as_f64().unwrap().abs() < 1e-5 && a["moving"] == false
        })
        .await,
        "the CNC homed after its slot"
    );
    assert!(at_rest_at(&s2, "w", 0.25).await, "w reached its target: not stopped by the other slot's end");
    // Student 1 has no slot now; student 2 still commands the bench.
    let (st, _) = s1.post("/api/axes/x/move", json!({ "target": 0.05, "speed": 0.05 })).await;
    assert_eq!(st, StatusCode::FORBIDDEN);
    let (st, e) = s2.post("/api/axes/w/move", json!({ "target": 0.1, "speed": 0.05 })).await;
    assert_eq!(st, StatusCode::OK, "{e}");
    let cleanups = env.audit_of("station", "cleanup");
    assert!(cleanups.iter().any(|(t, k, _)| t.starts_with("cnc/reservation:") && k == "ok"), "{cleanups:?}");
}

#[tokio::test]
async fn a_whole_cell_slot_covers_every_machine_and_blocks_machine_bookings() {
    let env = two_machines();
    let s1 = env.login("student", STUDENT_PW).await;
    let s2 = env.login("student2", STUDENT_PW).await;
    let (st, r) = book(&s1, &env, None).await;
    assert_eq!(st, StatusCode::OK, "{r}");
    let (st, e) = book(&s2, &env, Some("bench")).await;
    assert_eq!(st, StatusCode::CONFLICT, "{e}");
    let (st, e) = s1.post("/api/axes/w/move", json!({ "target": 0.02, "speed": 0.05 })).await;
    assert_eq!(st, StatusCode::OK, "{e}");
    let (st, e) = s1.post("/api/axes/x/move", json!({ "target": 0.02, "speed": 0.05 })).await;
    assert_eq!(st, StatusCode::OK, "{e}");
    let (st, e) = s2.post("/api/axes/w/move", json!({ "target": 0.1, "speed": 0.05 })).await;
    assert_eq!(st, StatusCode::FORBIDDEN, "{e}");
    assert!(at_rest_at(&s1, "w", 0.02).await && at_rest_at(&s1, "x", 0.02).await);
}

#[tokio::test]
async fn a_student_in_a_machines_queue_gets_it_when_it_frees() {
    let env = two_machines();
    let s1 = env.login("student", STUDENT_PW).await;
    let s3 = env.login("student2", STUDENT_PW).await;
    let (st, r1) = book(&s1, &env, Some("cnc")).await;
    assert_eq!(st, StatusCode::OK, "{r1}");
    // The CNC is busy: student 2 waits in its line (joining twice keeps the place).
    let (st, q) = s3.post0("/api/machines/cnc/queue").await;
    assert_eq!(st, StatusCode::OK, "{q}");
    assert_eq!(q["place"], 1);
    assert_eq!(s3.post0("/api/machines/cnc/queue").await.1["place"], 1);
    let (_, queues) = s1.get("/api/queues").await;
    assert_eq!(queues["cnc"][0]["user"], "student2", "{queues}");
    let (st, _) = s3.post("/api/axes/x/move", json!({ "target": 0.05, "speed": 0.05 })).await;
    assert_eq!(st, StatusCode::FORBIDDEN);
    // An unknown machine's line: 404.
    assert_eq!(s3.post0("/api/machines/lathe/queue").await.0, StatusCode::NOT_FOUND);

    // Student 1 ends their slot: after the clean-up, student 2 has the CNC at once.
    let (st, e) = s1.req(Method::DELETE, &format!("/api/reservations/{}", r1["id"]), None).await;
    assert_eq!(st, StatusCode::OK, "{e}");
    assert!(
        wait_for(MOTION, || async {
            let (_, s) = s3.get("/api/session").await;
            s["my_slots"] == json!(["cnc"])
        })
        .await,
        "the queue's first student got the machine"
    );
    let (_, queues) = s1.get("/api/queues").await;
    assert!(queues["cnc"].as_array().into_iter().flatten().next().is_none(), "{queues}");
    let (st, e) = s3.post("/api/axes/x/move", json!({ "target": 0.05, "speed": 0.05 })).await;
    assert_eq!(st, StatusCode::OK, "{e}");
    let granted = env.audit_of("station", "queue.granted");
    assert!(granted.iter().any(|(t, k, _)| t.starts_with("cnc to student2") && k == "ok"), "{granted:?}");
    // The instant slot lasts 15 minutes.
    let (_, list) = s3.get("/api/reservations").await;
    let mine = list.as_array().unwrap().iter().find(|r| r["user"] == "student2").unwrap().clone();
    let length = mine["end"].as_i64().unwrap() - mine["start"].as_i64().unwrap();
    assert_eq!(length, 15 * 60 * 1000, "{mine}");

    // A free machine is given at once; leaving a line is allowed.
    let (st, q) = s1.post0("/api/machines/bench/queue").await;
    assert_eq!(st, StatusCode::OK, "{q}");
    let (_, s) = s1.get("/api/session").await;
    assert_eq!(s["my_slots"], json!(["bench"]), "{s}");
    let (st, q) = s1.req(Method::DELETE, "/api/machines/cnc/queue", None).await;
    assert_eq!(st, StatusCode::OK, "{q}");
    assert_eq!(q["left"], false);
}
