#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
//! G-code programs on the real station (demo cell): a check runs off the web runtime within
//! its budget while the station stays responsive, the pool refuses checks beyond its
//! capacity (503 at once); a program's path is checked against the machine travel for
//! everyone and against the student limits for students, before it runs (refusals audited
//! with the program's demands, nothing moves); students see, check and run only their own
//! and published programs, viewers neither check nor run.

mod common;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use common::Client;
use serde_json::{json, Value};

/// One demo cell at a time within this binary under `cargo test` (three at once overload a
/// 2-core host); under nextest each test is a process and the `station` test group of
/// `.config/nextest.toml` bounds them.
static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn serial() -> std::sync::MutexGuard<'static, ()> {
    ONE_AT_A_TIME.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

fn now_ms() -> i64 {
    i64::try_from(std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap().as_millis())
        .unwrap()
}

fn audit(admin: &Client, user: &str, action: &str) -> Vec<Value> {
    let v = admin.ok("GET", &format!("/api/audit?user={user}&action_prefix={action}&limit=500"), Value::Null);
    v.as_array().unwrap().iter().map(|r| r["entry"].clone()).collect()
}

fn upload(c: &Client, name: &str, text: &str) -> (String, Value) {
    let r = c.ok("POST", "/api/programs", json!({ "name": name, "text": text }));
    (r["program"]["id"].as_str().unwrap().to_owned(), r["check"].clone())
}

fn book(c: &Client) -> i64 {
    let now = now_ms();
    let r = c.ok("POST", "/api/reservations", json!({ "start": now - 1000, "end": now + 30 * 60 * 1000 }));
    r["id"].as_i64().unwrap()
}

fn add_user(admin: &Client, name: &str, role: &str) -> Client {
    let password = format!("{name}-password-1");
    admin.ok("POST", "/api/users", json!({ "name": name, "password": password, "role": role }));
    Client::login(&admin.addr, name, &password)
}

/// Homes the gantry (x, y, z): programs run only on a homed gantry.
fn home_gantry(admin: &Client) {
    for axis in ["x", "y", "z"] {
        admin.home(axis);
    }
}

/// A station with its gantry homed and the student's slot booked: (station, admin, student).
fn booked_station() -> (common::Station, Client, Client) {
    let st = common::station();
    let admin = Client::login(&st.addr, "admin", "admin-password-1");
    let student = Client::login(&st.addr, "student", "student-password-1");
    book(&student);
    home_gantry(&admin);
    (st, admin, student)
}

/// The runner's status once `done` holds for it (a liveness bound of 30 s).
fn wait_status(c: &Client, what: &str, done: impl Fn(&Value) -> bool) -> Value {
    let t0 = Instant::now();
    loop {
        let s = c.ok("GET", "/api/programs/status", Value::Null);
        if done(&s) {
            return s;
        }
        assert!(t0.elapsed() < Duration::from_secs(30), "waiting for {what}: {s}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn wait_program(c: &Client, state: &str) -> Value {
    let t0 = Instant::now();
    loop {
        let s = c.ok("GET", "/api/programs/status", Value::Null);
        if s["state"] == state {
            return s;
        }
        assert!(t0.elapsed() < Duration::from_secs(60), "program not {state}: {s}");
        std::thread::sleep(Duration::from_millis(50));
    }
}

fn percentile(sorted: &[Duration], p: f64) -> Duration {
    let i = ((sorted.len() as f64 - 1.0) * p).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

/// Counts the WebSocket's messages until `done` (a current-thread runtime of its own).
fn ws_count(addr: &str, cookie: &str, done: &AtomicBool, frames: &std::sync::atomic::AtomicU64) {
    use futures_util::StreamExt;
    use tokio_tungstenite::tungstenite::client::IntoClientRequest;
    let rt = tokio::runtime::Builder::new_current_thread().enable_all().build().unwrap();
    rt.block_on(async {
        let mut req = format!("ws://{addr}/api/ws").into_client_request().unwrap();
        req.headers_mut().insert("Cookie", cookie.parse().unwrap());
        let (mut ws, _) = tokio_tungstenite::connect_async(req).await.unwrap();
        while !done.load(Ordering::Relaxed) {
            if let Ok(Some(m)) = tokio::time::timeout(Duration::from_millis(200), ws.next()).await {
                if m.unwrap().is_text() {
                    frames.fetch_add(1, Ordering::Relaxed);
                }
            }
        }
    });
}

/// An endless loop of heavy expressions: it would run for hours.
const ENDLESS: &str = "G21 G90\n#1 = 0\no100 while [1]\n\
#1 = [[#1 + 1] MOD 1000]\n\
#2 = [SIN[#1] * COS[#1] + SQRT[ABS[#1]] + EXP[[#1 MOD 10] / 10] + ATAN[#1]/[1 + #1]]\n\
#3 = [[#2 * #2 + LN[1 + ABS[#2]]] / [1 + SQRT[1 + #1 * #1]] + [#1 MOD 7] ** 2]\n\
#4 = [[#3 + #2] * [#3 - #2] / [1 + ABS[#3 * #2]] + FIX[#1 / 3] + FUP[#1 / 7]]\n\
o100 endwhile\nM2\n";

/// Acceptance point 3 of issue 18.
#[test]
fn a_check_that_would_take_hours_stops_at_its_budget_and_the_station_stays_responsive() {
    let _serial = serial();
    let st = common::station();
    let admin = Client::login(&st.addr, "admin", "admin-password-1");
    let student = Client::login(&st.addr, "student", "student-password-1");
    book(&student);
    let capacity = motus_station_machine::StationOptions::default().program_checks.capacity();

    // Latency of the session and E-stop routes, from their own thread, over the checks.
    let done = Arc::new(AtomicBool::new(false));
    let probe = {
        let (done, addr) = (Arc::clone(&done), st.addr.clone());
        let (cookie, csrf) = (admin.cookie.clone(), admin.csrf.clone());
        std::thread::spawn(move || {
            let probe = Client { addr, cookie, csrf };
            let (mut session, mut estop) = (Vec::new(), Vec::new());
            while !done.load(Ordering::Relaxed) {
                let t = Instant::now();
                let (s, _) = probe.call("GET", "/api/session", Value::Null);
                session.push(t.elapsed());
                assert_eq!(s, 200);
                let t = Instant::now();
                let (s, _) = probe.call("POST", "/api/estop", Value::Null);
                estop.push(t.elapsed());
                assert_eq!(s, 200);
                std::thread::sleep(Duration::from_millis(20));
            }
            (session, estop)
        })
    };

    // The WebSocket's frames, counted by their own thread: a baseline before the checks,
    // then the rate over the checks.
    let ws_frames = Arc::new(std::sync::atomic::AtomicU64::new(0));
    let ws = {
        let (done, frames, addr, cookie) =
            (Arc::clone(&done), Arc::clone(&ws_frames), st.addr.clone(), admin.cookie.clone());
        std::thread::spawn(move || ws_count(&addr, &cookie, &done, &frames))
    };
    let baseline_from = (Instant::now(), ws_frames.load(Ordering::Relaxed));
    std::thread::sleep(Duration::from_secs(3));
    let baseline = (ws_frames.load(Ordering::Relaxed) - baseline_from.1) as f64
        / baseline_from.0.elapsed().as_secs_f64();

    // Fill the pool: one endless check per worker and queue place, each in its own upload.
    let started = Instant::now();
    let frames_at_start = ws_frames.load(Ordering::Relaxed);
    let mut uploads = Vec::new();
    for k in 0..capacity {
        let c = Client { addr: st.addr.clone(), cookie: student.cookie.clone(), csrf: student.csrf.clone() };
        uploads.push(std::thread::spawn(move || {
            let t = Instant::now();
            let r = upload(&c, &format!("endless-{k}.ngc"), ENDLESS);
            (r, t.elapsed())
        }));
        std::thread::sleep(Duration::from_millis(300));
    }
    // Beyond the capacity: the upload stands, its check is refused at once; so is an
    // explicit check (503).
    let t = Instant::now();
    let (extra, check) = upload(&student, "one-more.ngc", ENDLESS);
    assert!(check["errors"][0]["message"].as_str().unwrap().starts_with("not checked: busy"), "{check}");
    let (status, body) = student.call("POST", &format!("/api/programs/{extra}/check"), Value::Null);
    let refused_in = t.elapsed();
    assert_eq!(status, 503, "{body}");
    assert_eq!(body["error"], "busy", "{body}");
    assert!(refused_in < Duration::from_secs(2), "refused at once, not after {refused_in:?}");

    let results: Vec<_> = uploads.into_iter().map(|u| u.join().unwrap()).collect();
    let checks_took = started.elapsed();
    let during = (ws_frames.load(Ordering::Relaxed) - frames_at_start) as f64 / checks_took.as_secs_f64();
    done.store(true, Ordering::Relaxed);
    let (mut session, mut estop) = probe.join().unwrap();
    ws.join().unwrap();
    eprintln!("WebSocket: {baseline:.1} frames/s before the checks, {during:.1} frames/s during {checks_took:?} of checks");
    // Liveness, not a rate threshold: the frames keep coming while the checks run (the rate
    // against the baseline is printed above; both follow the host's load).
    assert!(during > 1.0, "the WebSocket stalled: {during:.1} vs {baseline:.1} frames/s");
    // The first check: a worker took it at once and stopped it at the budget (3 s by
    // default), with the clear error, at a line of the loop.
    let ((first_id, first), first_took) = &results[0];
    let e = &first["errors"][0];
    let message = e["message"].as_str().unwrap();
    eprintln!("first check: {first_took:?}: {}:{}: {message}", e["line"], e["col"]);
    assert!(message.starts_with("check stopped after 3."), "{message}");
    assert!(message.contains("the program is too long or does not end"), "{message}");
    assert!((3..=8).contains(&e["line"].as_u64().unwrap()), "{e}");
    assert!(*first_took < Duration::from_secs(10), "{first_took:?}");
    for ((_, check), took) in &results[1..] {
        let m = check["errors"][0]["message"].as_str().unwrap();
        assert!(
            m.starts_with("check stopped after 3.") || m.starts_with("not checked: busy"),
            "{m} ({took:?})"
        );
    }
    // The result is kept: checking again answers at once, with the same error.
    let t = Instant::now();
    let again = student.ok("POST", &format!("/api/programs/{first_id}/check"), Value::Null);
    assert!(t.elapsed() < Duration::from_secs(2), "{:?}", t.elapsed());
    assert_eq!(again["errors"][0]["message"], e["message"]);
    // Every check is audited with its outcome; so is the refused one.
    let checks = audit(&admin, "student", "command.check_program");
    assert!(
        checks.iter().any(|c| c["target"].as_str().unwrap().contains("endless-0.ngc")
            && c["outcome"]["result"] == "error"
            && c["outcome"]["message"].as_str().unwrap().contains("check stopped after")),
        "{checks:?}"
    );
    assert!(
        checks.iter().any(|c| c["target"].as_str().unwrap().contains(&extra)
            && c["outcome"]["message"].as_str().unwrap().contains("503 busy")),
        "{checks:?}"
    );

    // The station answered all along.
    for (name, v) in [("GET /api/session", &mut session), ("POST /api/estop", &mut estop)] {
        v.sort();
        let (p50, p99, max) = (percentile(v, 0.5), percentile(v, 0.99), *v.last().unwrap());
        eprintln!(
            "{name} during {checks_took:?} of checks: {} requests, p50 {p50:?}, p99 {p99:?}, max {max:?}",
            v.len()
        );
        assert!(v.len() >= 10, "{name}: only {} requests in {checks_took:?}", v.len());
        assert!(max < Duration::from_secs(2), "{name}: {max:?}");
    }
    admin.ok("POST", "/api/reset", Value::Null);
}

#[test]
fn a_program_cannot_take_a_student_beyond_the_limits_and_nothing_moves() {
    let _serial = serial();
    let (_st, admin, student) = booked_station();
    let x0 = student.axis("x")["position"].as_f64().unwrap();

    // X 500 mm = 0.5 m is inside the student range of x ([0, 0.55] m), but F1000000 (16.7 m/s)
    // is far beyond its 0.08 m/s: refused by the lab before it runs.
    let (fast, check) = upload(&student, "fast.ngc", "G21 G90\nG1 X500 F1000000\nM2\n");
    assert_eq!(check["errors"], json!([]), "{check}");
    let x = check["demands"].as_array().unwrap().iter().find(|d| d[0] == "x").unwrap()[1].clone();
    assert_eq!(x["range"], json!([0.5, 0.5]), "{x}");
    assert!((x["speed"].as_f64().unwrap() - 1_000_000.0 / 60_000.0).abs() < 1e-9, "{x}");
    let (status, body) = student.call("POST", &format!("/api/programs/{fast}/run"), Value::Null);
    assert_eq!(status, 403, "{body}");
    assert_eq!(body["detail"]["reason"]["reason"], "motion_limit", "{body}");
    // 580 mm is within the machine travel (0.6 m) but beyond the student range: refused with
    // the position reason.
    let (far, _) = upload(&student, "far.ngc", "G21 G90\nG0 X10\nG1 X580 F600\nM2\n");
    let (status, body) = student.call("POST", &format!("/api/programs/{far}/run"), Value::Null);
    assert_eq!(status, 403, "{body}");
    assert_eq!(body["detail"]["reason"]["reason"], "position_limit", "{body}");
    let message = body["detail"]["message"].as_str().unwrap();
    assert!(message.contains("x:") && message.contains("student range [0, 0.55]"), "{message}");
    // Beyond the machine travel: refused for everyone, admin too, with the axis, the position
    // and the line, before it runs.
    let beyond = "G21 G90\nG1 X100 F600\nG1 X700\nM2\n";
    let (out, check) = upload(&student, "out.ngc", beyond);
    assert_eq!(check["errors"][0]["line"], 3, "{check}");
    let m = check["errors"][0]["message"].as_str().unwrap();
    assert!(m.contains("axis x would reach 0.7 m, outside the machine travel [0, 0.6] m"), "{m}");
    let (status, body) = student.call("POST", &format!("/api/programs/{out}/run"), Value::Null);
    assert_eq!(status, 400, "{body}");
    assert!(body["detail"]["message"].as_str().unwrap().starts_with("3:1: axis x would reach 0.7"), "{body}");
    let (admins, _) = upload(&admin, "admin-out.ngc", beyond);
    let (status, body) = admin.call("POST", &format!("/api/programs/{admins}/run"), Value::Null);
    assert_eq!(status, 400, "{body}");
    // In inches: X 30 in = 0.762 m, beyond the machine too.
    let (inch, check) = upload(&admin, "inch.ngc", "G20 G90\nG1 X30 F10\nM2\n");
    assert!(check["errors"][0]["message"].as_str().unwrap().contains("would reach 0.762"), "{check}");
    assert_eq!(admin.call("POST", &format!("/api/programs/{inch}/run"), Value::Null).0, 400);

    // Nothing moved, nothing ran.
    let s = student.ok("GET", "/api/programs/status", Value::Null);
    assert_eq!(s["state"], "idle", "{s}");
    let scene = student.ok("GET", "/api/scene", Value::Null);
    assert_eq!(scene["gantry"][0], json!([0.0, 0.0, 0.0]), "{scene}");
    assert_eq!(student.axis("x")["position"].as_f64().unwrap(), x0);
    // Each refusal is audited with the program and its demands or its error.
    let runs = audit(&admin, "student", "command.run_program");
    let denied = |id: &str, text: &str| {
        runs.iter().any(|r| {
            let target = r["target"].as_str().unwrap();
            target.contains(&format!("({id})"))
                && r["outcome"]["result"] == "denied"
                && r["outcome"]["message"].as_str().unwrap().contains(text)
        })
    };
    assert!(denied(&fast, "exceeds the student limit"), "{runs:?}");
    assert!(denied(&far, "student range [0, 0.55]"), "{runs:?}");
    assert!(
        runs.iter()
            .any(|r| r["target"].as_str().unwrap().contains(&format!("({fast}) demands: x [0.5, 0.5] v "))),
        "{runs:?}"
    );
    assert!(
        runs.iter().any(|r| r["target"].as_str().unwrap().contains(&format!("({out})"))
            && r["outcome"]["result"] == "error"
            && r["outcome"]["message"].as_str().unwrap().contains("machine travel")),
        "{runs:?}"
    );
    let admin_runs = audit(&admin, "admin", "command.run_program");
    assert!(
        admin_runs.iter().any(|r| r["outcome"]["message"].as_str().unwrap_or("").contains("0.7 m")),
        "{admin_runs:?}"
    );

    // A program inside the student limits runs, and moves the (simulated) gantry.
    let (ok, check) = upload(&student, "inside.ngc", "G21 G90\nG1 X50 Y20 F1200\nG1 X0 Y0\nM2\n");
    assert_eq!(check["errors"], json!([]), "{check}");
    student.ok("POST", &format!("/api/programs/{ok}/run"), Value::Null);
    let t0 = Instant::now();
    let mut moved = false;
    let mut axis_moved = 0.0f64;
    loop {
        let s = student.ok("GET", "/api/programs/status", Value::Null);
        let g = student.ok("GET", "/api/scene", Value::Null)["gantry"][0][0].as_f64().unwrap();
        moved |= g > 0.0;
        axis_moved = axis_moved.max(student.axis("x")["position"].as_f64().unwrap());
        if s["state"] == "done" {
            break;
        }
        assert!(s["state"] == "running", "{s}");
        assert!(t0.elapsed() < Duration::from_secs(30), "{s}");
        std::thread::sleep(Duration::from_millis(20));
    }
    assert!(moved, "the run moved the gantry in the scene");
    // The booked machine's axis x itself went out towards X 50 mm (0.05 m) and came back.
    assert!(axis_moved > 0.02, "axis x reached {axis_moved} m");
    let x_end = student.wait_axis("x", Duration::from_secs(10), "back and still", |a| a["moving"] == false);
    assert!(x_end["position"].as_f64().unwrap().abs() < 1e-4, "{x_end}");
    assert!(audit(&admin, "student", "command.run_program").iter().any(|r| r["target"]
        .as_str()
        .unwrap()
        .contains(&format!("({ok})"))
        && r["outcome"]["result"] == "ok"));
}

#[test]
fn students_see_check_and_run_their_own_and_published_programs_viewers_neither() {
    let _serial = serial();
    let st = common::station();
    let admin = Client::login(&st.addr, "admin", "admin-password-1");
    let student = Client::login(&st.addr, "student", "student-password-1");
    let student2 = add_user(&admin, "student2", "student");
    let viewer = add_user(&admin, "viewer", "viewer");
    let names = |c: &Client| -> Vec<String> {
        let v = c.ok("GET", "/api/programs", Value::Null);
        v.as_array().unwrap().iter().map(|p| p["name"].as_str().unwrap().to_owned()).collect()
    };
    let inside = "G21 G90\nG1 X20 Y10 F1200\nG1 X0 Y0\nM2\n";
    let (public, _) = upload(&admin, "public.ngc", inside);
    let (secret, _) = upload(&admin, "secret.ngc", inside);
    // Only an admin publishes (audited).
    let reservation = book(&student);
    home_gantry(&admin);
    let (mine, _) = upload(&student, "mine.ngc", inside);
    assert_eq!(student.call("POST", &format!("/api/programs/{mine}/publish"), Value::Null).0, 403);
    let p = admin.ok("POST", &format!("/api/programs/{public}/publish"), Value::Null);
    assert_eq!(p["published"], true);
    assert!(audit(&admin, "admin", "publish_program").iter().any(|e| e["outcome"]["result"] == "ok"));
    assert!(audit(&admin, "student", "publish_program").iter().any(|e| e["outcome"]["result"] == "denied"));

    let mut all = names(&admin);
    all.sort();
    assert_eq!(all, ["mine.ngc", "public.ngc", "secret.ngc"]);
    let mut own = names(&student);
    own.sort();
    assert_eq!(own, ["mine.ngc", "public.ngc"]);
    assert_eq!(names(&student2), ["public.ngc"]);
    assert_eq!(names(&viewer), ["public.ngc"]);

    // Someone else's program: not found (the name does not leak), audited.
    for id in [&mine, &secret] {
        for what in ["check", "run"] {
            let (status, body) = student2.call("POST", &format!("/api/programs/{id}/{what}"), Value::Null);
            assert_eq!(status, 404, "student2 {what} {id}: {body}");
        }
    }
    let (status, _) = student.call("POST", &format!("/api/programs/{secret}/check"), Value::Null);
    assert_eq!(status, 404);
    assert!(audit(&admin, "student2", "command.check_program")
        .iter()
        .any(|e| e["outcome"]["result"] == "denied"));
    assert!(audit(&admin, "student2", "command.run_program")
        .iter()
        .any(|e| e["outcome"]["result"] == "denied"));
    // A viewer neither checks nor runs, published or not.
    for id in [&public, &mine] {
        for what in ["check", "run"] {
            let (status, body) = viewer.call("POST", &format!("/api/programs/{id}/{what}"), Value::Null);
            assert_eq!(status, 403, "viewer {what} {id}: {body}");
        }
    }
    assert!(audit(&admin, "viewer", "command.check_program")
        .iter()
        .any(|e| e["outcome"]["result"] == "denied"));

    // The slot holder runs their own program and the published one.
    for id in [&mine, &public] {
        assert_eq!(
            student.ok("POST", &format!("/api/programs/{id}/check"), Value::Null)["errors"],
            json!([])
        );
        student.ok("POST", &format!("/api/programs/{id}/run"), Value::Null);
        wait_program(&student, "done");
    }

    // The slot ends: the student's programs go, the published one stays; student2 books the
    // station and runs it.
    admin.ok("DELETE", &format!("/api/reservations/{reservation}"), Value::Null);
    let t0 = Instant::now();
    while names(&admin).contains(&"mine.ngc".to_owned()) {
        assert!(t0.elapsed() < Duration::from_secs(20), "slot cleanup");
        std::thread::sleep(Duration::from_millis(100));
    }
    assert_eq!(names(&admin).len(), 2);
    std::thread::sleep(Duration::from_millis(50));
    let now = now_ms();
    student2.ok("POST", "/api/reservations", json!({ "start": now, "end": now + 30 * 60 * 1000 }));
    let t0 = Instant::now();
    loop {
        let (status, body) = student2.call("POST", &format!("/api/programs/{public}/run"), Value::Null);
        if status == 200 {
            break;
        }
        // The end-of-slot cleanup may still be homing the machine.
        assert!(t0.elapsed() < Duration::from_secs(30), "{status} {body}");
        std::thread::sleep(Duration::from_millis(200));
    }
    wait_program(&student2, "done");
    assert!(audit(&admin, "student2", "command.run_program").iter().any(|e| e["outcome"]["result"] == "ok"));
}

/// The runner on the booked machine: a preview of the checked program, the executed path
/// drawn from the gantry's set-points, the feed override seen in the executed feed, single
/// block, MDI, and the server's limits (students at most 100 %, no jog of a gantry axis the
/// program drives, the E-stop ends the run); every command audited.
#[test]
fn the_runner_drives_the_gantry_with_override_single_block_mdi_preview_and_path() {
    let _serial = serial();
    let (_st, admin, student) = booked_station();
    // A square of 40 mm at 1200 mm/min (20 mm/s, within the student's 80 mm/s).
    let square = "G21 G90 F1200\nG1 X40\nG1 Y40\nG1 X0\nG1 Y0\nM2\n";
    let (id, check) = upload(&student, "square.ngc", square);
    assert_eq!(check["errors"], json!([]), "{check}");
    let preview = student.ok("GET", &format!("/api/programs/{id}/preview"), Value::Null);
    let pts: Vec<Vec<f64>> = serde_json::from_value(preview["points"].clone()).unwrap();
    assert_eq!(
        pts,
        vec![vec![0.0; 3], vec![40.0, 0.0, 0.0], vec![40.0, 40.0, 0.0], vec![0.0, 40.0, 0.0], vec![0.0; 3]]
    );

    // Students stay at or below 100 % (refused and audited), admins may go to 200 %.
    let (code, body) = student.call("POST", "/api/programs/override", json!({ "percent": 150.0 }));
    assert_eq!(code, 403, "{body}");
    let (code, body) = admin.call("POST", "/api/programs/override", json!({ "percent": 250.0 }));
    assert_eq!(code, 400, "{body}");
    student.ok("POST", "/api/programs/override", json!({ "percent": 100.0 }));

    student.ok("POST", &format!("/api/programs/{id}/run"), Value::Null);
    let feed_near = |f: f64| move |s: &Value| (s["feed"].as_f64().unwrap_or(0.0) - f).abs() < 1.0;
    let at_100 = wait_status(&student, "the programmed feed", feed_near(1200.0));
    assert!((at_100["feed"].as_f64().unwrap() - 1200.0).abs() < 1.0, "{at_100}");
    // The gantry axis the program drives refuses a jog meanwhile.
    let (code, body) = student.call("POST", "/api/axes/x/jog", json!({ "direction": 1.0, "speed": 0.01 }));
    assert_eq!(code, 409, "{body}");
    assert!(body["detail"].as_str().unwrap().contains("driven by the running program"), "{body}");
    student.ok("POST", "/api/programs/override", json!({ "percent": 50.0 }));
    let at_50 = wait_status(&student, "half the feed", feed_near(600.0));
    assert!((at_50["feed"].as_f64().unwrap() - 600.0).abs() < 1.0, "{at_50}");
    assert_eq!(at_50["override_percent"], 50.0);
    student.ok("POST", "/api/programs/override", json!({ "percent": 100.0 }));
    wait_program(&student, "done");
    // The executed path went round the square, on the gantry's axes.
    let path = student.ok("GET", "/api/programs/path?run=0&cursor=0", Value::Null);
    let pts: Vec<Vec<f64>> = serde_json::from_value(path["points"].clone()).unwrap();
    let corner = |x: f64, y: f64| pts.iter().any(|p| (p[0] - x).abs() < 0.2 && (p[1] - y).abs() < 0.2);
    assert!(corner(40.0, 0.0) && corner(40.0, 40.0) && corner(0.0, 40.0), "{path}");
    let more = student.ok(
        "GET",
        &format!("/api/programs/path?run={}&cursor={}", path["run"], path["next"]),
        Value::Null,
    );
    assert_eq!(more["points"], json!([]), "{more}");

    // Single block: a stop after each block, resume (cycle start) for the next.
    student.ok("POST", "/api/programs/single-block", json!({ "on": true }));
    student.ok("POST", &format!("/api/programs/{id}/run"), Value::Null);
    let first = wait_program(&student, "block_stop");
    let x = student.wait_axis("x", Duration::from_secs(10), "at the first corner", |a| a["moving"] == false);
    assert!((x["position"].as_f64().unwrap() - 0.04).abs() < 1e-4, "{x} {first}");
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(student.ok("GET", "/api/programs/status", Value::Null)["state"], "block_stop");
    student.ok("POST", "/api/programs/resume", Value::Null);
    let y = student.wait_axis("y", Duration::from_secs(10), "at the second corner", |a| {
        (a["position"].as_f64().unwrap() - 0.04).abs() < 1e-4 && a["moving"] == false
    });
    assert_eq!(student.ok("GET", "/api/programs/status", Value::Null)["state"], "block_stop", "{y}");
    student.ok("POST", "/api/programs/single-block", json!({ "on": false }));
    student.ok("POST", "/api/programs/resume", Value::Null);
    wait_program(&student, "done");

    // MDI: one line, checked like a program (travel, student limits), then executed.
    student.ok("POST", "/api/mdi", json!({ "line": "G1 X12 Y7 F600" }));
    wait_program(&student, "done");
    let x = student.wait_axis("x", Duration::from_secs(10), "at X 12", |a| a["moving"] == false);
    assert!((x["position"].as_f64().unwrap() - 0.012).abs() < 1e-4, "{x}");
    // Held and resumed like a program (authorised again from the line's own check).
    student.ok("POST", "/api/mdi", json!({ "line": "G1 X30 F300" }));
    wait_status(&student, "the MDI line moving", |s| {
        s["program"] == "MDI" && s["feed"].as_f64().unwrap_or(0.0) > 0.0
    });
    student.ok("POST", "/api/programs/hold", Value::Null);
    wait_program(&student, "held");
    student.ok("POST", "/api/programs/resume", Value::Null);
    wait_program(&student, "done");
    let x = student.wait_axis("x", Duration::from_secs(10), "at X 30", |a| a["moving"] == false);
    assert!((x["position"].as_f64().unwrap() - 0.030).abs() < 1e-4, "{x}");
    let (code, body) = student.call("POST", "/api/mdi", json!({ "line": "G1 X700 F600" }));
    assert_eq!(code, 400, "beyond the machine travel: {body}");
    let (code, body) = student.call("POST", "/api/mdi", json!({ "line": "G1 X10\nG1 X20" }));
    assert_eq!(code, 400, "one line only: {body}");
    let (code, body) = student.call("POST", "/api/mdi", json!({ "line": "G1 X10" }));
    assert_eq!(code, 400, "no feed: {body}");
    assert!(body["detail"].to_string().contains("1:"), "{body}");

    // The E-stop ends a run at once; nothing moves on.
    student.ok("POST", &format!("/api/programs/{id}/run"), Value::Null);
    wait_status(&student, "the run moving", |s| {
        s["state"] == "running" && s["feed"].as_f64().unwrap_or(0.0) > 0.0
    });
    student.ok("POST", "/api/estop", Value::Null);
    let stopped = wait_program(&student, "stopped");
    assert!(stopped["message"].as_str().unwrap().contains("emergency stop"), "{stopped}");
    let x = student.wait_axis("x", Duration::from_secs(10), "halted", |a| a["moving"] == false);
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(student.axis("x")["position"], x["position"], "nothing moves after the E-stop");
    student.ok("POST", "/api/reset", Value::Null);

    let audited = |user: &str, action: &str, result: &str| {
        audit(&admin, user, action).iter().any(|r| r["outcome"]["result"] == result)
    };
    assert!(audited("student", "command.program_override", "denied"));
    assert!(audited("student", "command.program_override", "ok"));
    assert!(audited("student", "command.program_single_block", "ok"));
    assert!(audited("student", "command.mdi", "ok"));
    assert!(audited("student", "command.mdi", "error"));
}

/// The cell's tool table serves the station's programs (T, M6, G43 H): the demo's drilling
/// program checks and runs on the gantry, its Z net of the drill's 20 mm; a tool the table
/// does not have is refused at its line.
#[test]
fn programs_use_the_cells_tool_table() {
    let _serial = serial();
    let st = common::station();
    let admin = Client::login(&st.addr, "admin", "admin-password-1");
    home_gantry(&admin);
    let drill = std::fs::read_to_string(st.dir.path().join("programs/drill-plate.ngc")).unwrap();
    let (id, check) = upload(&admin, "drill-plate.ngc", &drill);
    assert_eq!(check["errors"], json!([]), "{check}");
    let z = check["demands"].as_array().unwrap().iter().find(|d| d[0] == "z").unwrap()[1].clone();
    // Z-5 of G54 (60 mm up) with the 20 mm drill: the spindle nose at 75 mm; Z10 at 90 mm.
    let [lo, hi]: [f64; 2] = serde_json::from_value(z["range"].clone()).unwrap();
    assert!((lo - 0.075).abs() < 1e-9 && (hi - 0.090).abs() < 1e-9, "{z}");
    admin.ok("POST", &format!("/api/programs/{id}/run"), Value::Null);
    wait_program(&admin, "done");
    let z = admin.wait_axis("z", Duration::from_secs(10), "still", |a| a["moving"] == false);
    assert!((z["position"].as_f64().unwrap() - 0.090).abs() < 1e-4, "{z}");
    let (_, check) = upload(&admin, "t9.ngc", "G21 G90\nT9 M6\nM2\n");
    assert_eq!(check["errors"][0]["line"], 2, "{check}");
    assert!(check["errors"][0]["message"].as_str().unwrap().contains("tool 9 not found"), "{check}");
}
