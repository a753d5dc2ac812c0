//! `GET /api/openapi.json`: the hand-written OpenAPI 3.0 document of every route.
//!
//! A test checks that every route of [`crate::server::router`] appears here and that every
//! operation listed here is served. There is no operation that sets SafeToRun.

use axum::Json;
use serde_json::{json, Map, Value};

/// Sets `o[k0][k1]... = v`, creating objects on the way (replaces non-objects).
fn set(o: &mut Value, keys: &[&str], v: Value) {
    let Some((last, path)) = keys.split_last() else { return };
    let mut cur = o;
    for k in path {
        if !cur.is_object() {
            *cur = json!({});
        }
        let Some(map) = cur.as_object_mut() else { return };
        cur = map.entry((*k).to_string()).or_insert_with(|| json!({}));
    }
    if !cur.is_object() {
        *cur = json!({});
    }
    if let Some(map) = cur.as_object_mut() {
        map.insert((*last).to_string(), v);
    }
}

fn r(name: &str) -> Value {
    json!({ "$ref": format!("#/components/schemas/{name}") })
}

fn arr(item: Value) -> Value {
    json!({ "type": "array", "items": item })
}

/// One operation: summary, request body schema, response schema; `csrf` adds the header
/// requirement and the 403 answer.
fn op(summary: &str, body: Option<Value>, response: Value, csrf: bool) -> Value {
    let mut o = json!({
        "summary": summary,
        "responses": {
            "200": { "description": "OK", "content": { "application/json": { "schema": response } } },
            "400": { "$ref": "#/components/responses/Error" },
            "401": { "$ref": "#/components/responses/Error" },
            "403": { "$ref": "#/components/responses/Error" },
        },
    });
    if let Some(b) = body {
        set(
            &mut o,
            &["requestBody"],
            json!({ "required": true, "content": { "application/json": { "schema": b } } }),
        );
    }
    if csrf {
        set(&mut o, &["parameters"], json!([{ "$ref": "#/components/parameters/Csrf" }]));
        set(&mut o, &["responses", "409"], json!({ "$ref": "#/components/responses/Error" }));
    }
    o
}

fn with_path_param(mut o: Value, name: &str, kind: &str) -> Value {
    let p = json!({ "name": name, "in": "path", "required": true, "schema": { "type": kind } });
    match o.get_mut("parameters").and_then(Value::as_array_mut) {
        Some(a) => a.push(p),
        None => set(&mut o, &["parameters"], json!([p])),
    }
    o
}

fn ok_schema() -> Value {
    json!({ "type": "object", "properties": { "ok": { "type": "boolean" } } })
}

fn paths() -> Value {
    let any = json!({ "type": "object" });
    let mut p = Map::new();
    let mut add = |path: &str, method: &str, o: Value| {
        let entry = p.entry(path.to_string()).or_insert_with(|| json!({}));
        set(entry, &[method], o);
    };
    add(
        "/",
        "get",
        json!({ "summary": "The web HMI (HTML)", "responses": { "200": { "description": "HTML" } } }),
    );
    add(
        "/app.js",
        "get",
        json!({ "summary": "HMI script", "responses": { "200": { "description": "JavaScript" } } }),
    );
    add(
        "/style.css",
        "get",
        json!({ "summary": "HMI style sheet", "responses": { "200": { "description": "CSS" } } }),
    );
    add(
        "/api/openapi.json",
        "get",
        json!({ "summary": "This document", "responses": { "200": { "description": "OpenAPI 3.0" } } }),
    );
    let mut login = op(
        "Log in: sets the session cookie, returns the CSRF token",
        Some(r("LoginRequest")),
        r("LoginResponse"),
        false,
    );
    set(&mut login, &["responses", "429"], json!({ "$ref": "#/components/responses/Error" }));
    add("/api/login", "post", login);
    add("/api/logout", "post", op("Log out", None, ok_schema(), true));
    add(
        "/api/session",
        "get",
        op("Current session, slot and whether I may command", None, r("Session"), false),
    );
    add(
        "/api/sessions/{user}/end",
        "post",
        with_path_param(
            op("Admin: end a user's sessions and running slot", None, any.clone(), true),
            "user",
            "string",
        ),
    );
    add("/api/axes", "get", op("Every axis", None, arr(r("AxisView")), false));
    for (verb, body, summary) in [
        ("jog", Some(r("JogRequest")), "Jog (dead-man: repeat within 0.5 s)"),
        ("move", Some(r("MoveRequest")), "Absolute move"),
        ("home", None, "Home"),
        ("stop", None, "Controlled stop"),
    ] {
        add(
            &format!("/api/axes/{{id}}/{verb}"),
            "post",
            with_path_param(op(summary, body, ok_schema(), true), "id", "string"),
        );
    }
    add(
        "/api/axes/{id}/parameters",
        "put",
        with_path_param(
            op("Admin: change axis limits", Some(r("AxisParameters")), ok_schema(), true),
            "id",
            "string",
        ),
    );
    add(
        "/api/estop",
        "post",
        op("Emergency stop of every axis (students and admins, any time)", None, ok_schema(), true),
    );
    add(
        "/api/reset",
        "post",
        op("Reset E-stop and supervisor latch (refused while SafeToRun is false)", None, ok_schema(), true),
    );
    add(
        "/api/safety",
        "get",
        op(
            "Supervisor state: SafeToRun (read-only), diagnosis, predicted distances",
            None,
            r("SafetyView"),
            false,
        ),
    );
    add(
        "/api/safety/rules",
        "put",
        op("Admin: replace the supervisor rules (TOML)", Some(r("RulesRequest")), any.clone(), true),
    );
    add(
        "/api/groups",
        "get",
        op("Axis groups (robot, pan-tilt, arm, gantry)", None, arr(r("GroupView")), false),
    );
    add(
        "/api/groups/{id}",
        "post",
        with_path_param(
            op(
                "Group command: go_to targets, stop, or run a program of the group's controller",
                Some(r("GroupAction")),
                ok_schema(),
                true,
            ),
            "id",
            "string",
        ),
    );
    add("/api/programs", "get", op("Stored programs", None, arr(r("ProgramInfo")), false));
    add(
        "/api/programs",
        "post",
        op("Upload a program (checked at once)", Some(r("UploadRequest")), any.clone(), true),
    );
    add("/api/programs/status", "get", op("Program runner status", None, r("ProgramStatus"), false));
    add("/api/programs/hold", "post", op("Feed hold", None, ok_schema(), true));
    add(
        "/api/programs/resume",
        "post",
        op("Resume after hold; cycle start after a single-block stop", None, ok_schema(), true),
    );
    add(
        "/api/programs/override",
        "post",
        op("Feed override 0-200 % (students at most 100)", Some(r("OverrideRequest")), ok_schema(), true),
    );
    add(
        "/api/programs/single-block",
        "post",
        op("Single block on/off", Some(r("SingleBlockRequest")), ok_schema(), true),
    );
    let mut path = op("The executed path since a cursor", None, r("ExecutedPath"), false);
    set(
        &mut path,
        &["parameters"],
        json!([{ "name": "run", "in": "query", "schema": { "type": "integer" } },
               { "name": "cursor", "in": "query", "schema": { "type": "integer" } }]),
    );
    add("/api/programs/path", "get", path);
    add(
        "/api/programs/{id}/preview",
        "get",
        with_path_param(
            op("Tool path of a checked program", None, r("ProgramPreview"), false),
            "id",
            "string",
        ),
    );
    add(
        "/api/mdi",
        "post",
        op("Check and execute one G-code line (MDI)", Some(r("MdiRequest")), ok_schema(), true),
    );
    add("/api/programs/stop", "post", op("Stop the program", None, ok_schema(), true));
    add(
        "/api/programs/{id}/check",
        "post",
        with_path_param(
            op("Check: errors with line:col, per-axis demands", None, r("ProgramCheck"), true),
            "id",
            "string",
        ),
    );
    add(
        "/api/programs/{id}/run",
        "post",
        with_path_param(op("Run a checked program", None, ok_schema(), true), "id", "string"),
    );
    add(
        "/api/programs/{id}/publish",
        "post",
        with_path_param(
            op("Publish a program to every student (admin)", None, r("ProgramInfo"), true),
            "id",
            "string",
        ),
    );
    add(
        "/api/programs/{id}/publish",
        "delete",
        with_path_param(op("Withdraw a publication (admin)", None, r("ProgramInfo"), true), "id", "string"),
    );
    add("/api/signals", "get", op("Traced signals", None, arr(any.clone()), false));
    let mut samples = op("Samples after a cursor", None, any.clone(), false);
    set(
        &mut samples,
        &["parameters"],
        json!([{ "name": "cursor", "in": "query", "schema": { "type": "integer" } }]),
    );
    add("/api/samples", "get", samples);
    let mut csv = op("The traced signals as CSV (t_s and one column per signal)", None, any.clone(), false);
    set(
        &mut csv,
        &["responses", "200", "content"],
        json!({ "text/csv": { "schema": { "type": "string" } } }),
    );
    add("/api/samples.csv", "get", csv.clone());
    let mut trace = op("The cyclic tasks' signals at full rate as CSV (404: none)", None, any.clone(), false);
    set(
        &mut trace,
        &["responses", "200", "content"],
        json!({ "text/csv": { "schema": { "type": "string" } } }),
    );
    add("/api/trace.csv", "get", trace);
    add(
        "/api/tasks",
        "get",
        op("Cyclic task classes: cycle time, jitter, overruns, CPU", None, arr(any.clone()), false),
    );
    add("/api/scene", "get", op("2-D scene of the machines", None, any.clone(), false));
    add("/api/camera", "get", op("External camera URL, if configured", None, any.clone(), false));
    let mut camera = with_path_param(
        op(
            "The group's camera as an MJPEG stream (simulated, or an HTTP camera relayed by the station); \
             404 without a camera, 503 beyond the stream bounds",
            None,
            any.clone(),
            false,
        ),
        "id",
        "string",
    );
    set(
        &mut camera,
        &["responses", "200", "content"],
        json!({ "multipart/x-mixed-replace": { "schema": { "type": "string", "format": "binary" } } }),
    );
    add("/api/groups/{id}/camera.mjpg", "get", camera);
    add(
        "/api/reservations",
        "get",
        op(
            "This station's reservations, the whole cell's and each machine's (query from, until: ms)",
            None,
            arr(r("Reservation")),
            false,
        ),
    );
    add(
        "/api/reservations",
        "post",
        op(
            "Book a slot of one machine (`machine`: a group id) or of the whole cell (409 on overlap: \
             a machine's slots never overlap each other or a whole-cell slot)",
            Some(r("BookRequest")),
            r("Reservation"),
            true,
        ),
    );
    add("/api/queues", "get", op("Every machine's queue: who waits, in order", None, any.clone(), false));
    add(
        "/api/machines/{id}/queue",
        "post",
        with_path_param(
            op(
                "Join the machine's queue (students for themselves): the first in line gets the machine for \
                 an instant slot as soon as it is free; answers the place",
                None,
                any.clone(),
                true,
            ),
            "id",
            "string",
        ),
    );
    add(
        "/api/machines/{id}/queue",
        "delete",
        with_path_param(op("Leave the machine's queue", None, any.clone(), true), "id", "string"),
    );
    add(
        "/api/reservations/{id}",
        "delete",
        with_path_param(op("Cancel or end a reservation", None, any.clone(), true), "id", "integer"),
    );
    add(
        "/api/audit",
        "get",
        op(
            "Admin: audit log (query user, action_prefix, outcome, since, until, limit)",
            None,
            arr(any.clone()),
            false,
        ),
    );
    add("/api/alarms", "get", op("Active alarms and history", None, any.clone(), false));
    add(
        "/api/alarms/{id}/ack",
        "post",
        with_path_param(op("Acknowledge an alarm", None, any.clone(), true), "id", "integer"),
    );
    add("/api/users", "get", op("Admin: users", None, arr(r("User")), false));
    add("/api/users", "post", op("Admin: add a user", Some(r("NewUser")), r("User"), true));
    add(
        "/api/users/{name}",
        "delete",
        with_path_param(op("Admin: delete a user", None, ok_schema(), true), "name", "string"),
    );
    add(
        "/api/ws",
        "get",
        json!({
            "summary": "WebSocket: a hello frame with the signals, then state frames at 20 Hz (axes, safety, program, alarms, slot, samples, scene); logged-in users only",
            "responses": { "101": { "description": "Switching protocols" }, "401": { "$ref": "#/components/responses/Error" } },
        }),
    );
    Value::Object(p)
}

fn schemas() -> Value {
    let num = json!({ "type": "number" });
    let s = json!({ "type": "string" });
    let b = json!({ "type": "boolean" });
    let limits = json!({ "type": "object", "properties": { "min": num, "max": num, "max_speed": num, "max_acceleration": num } });
    json!({
        "Error": { "type": "object", "required": ["error"], "properties": { "error": s, "detail": {} } },
        "LoginRequest": { "type": "object", "required": ["user", "password"], "properties": { "user": s, "password": s } },
        "LoginResponse": { "type": "object", "properties": { "user": s, "role": r("Role"), "csrf_token": s } },
        "Role": { "type": "string", "enum": ["viewer", "student", "admin"] },
        "Session": { "type": "object", "properties": {
            "user": s, "role": r("Role"), "csrf_token": s, "idle_expires": num, "absolute_expires": num,
            "station": s, "slot": r("Reservation"), "can_command": b, "now": num } },
        "AxisLimits": limits,
        "AxisView": { "type": "object", "properties": {
            "id": s, "name": s, "device": s, "group": s, "unit": s, "position": num, "velocity": num,
            "enabled": b, "homed": b, "moving": b, "fault": s, "limits": r("AxisLimits"),
            "acceleration": num, "default_speed": num } },
        "JogRequest": { "type": "object", "required": ["direction", "speed"], "properties": {
            "direction": { "type": "number", "enum": [-1, 1] }, "speed": num, "acceleration": num } },
        "MoveRequest": { "type": "object", "required": ["target", "speed"], "properties": {
            "target": num, "speed": num, "acceleration": num } },
        "AxisParameters": { "type": "object", "required": ["limits", "acceleration"], "properties": {
            "limits": r("AxisLimits"), "acceleration": num } },
        "SafetyView": { "type": "object", "readOnly": true, "properties": {
            "safe_to_run": { "type": "boolean", "readOnly": true }, "held": b, "estop": b, "diagnosis": s,
            "rules_name": s, "rules_fingerprint": s, "integrity_checks": num,
            "predicted": arr(json!({ "type": "object", "properties": { "axis": s, "stop_position": num, "distance": num } })) } },
        "RulesRequest": { "type": "object", "required": ["toml"], "properties": { "toml": s } },
        "GroupView": { "type": "object", "properties": {
            "id": s, "kind": { "type": "string", "enum": ["robot", "pan_tilt", "arm", "gantry", "juggler"] }, "axes": arr(s.clone()),
            "programs": arr(s.clone()), "program": { "type": "string", "nullable": true } } },
        "GroupAction": { "type": "object", "required": ["action"], "properties": {
            "action": { "type": "string", "enum": ["go_to", "stop", "run"] }, "targets": arr(num.clone()),
            "program": s } },
        "UploadRequest": { "type": "object", "required": ["name", "text"], "properties": { "name": s, "text": s } },
        "ProgramInfo": { "type": "object", "properties": {
            "id": s, "name": s, "owner": s, "size": num, "lines": num, "published": { "type": "boolean" } } },
        "ProgramCheck": { "type": "object", "properties": {
            "errors": arr(json!({ "type": "object", "properties": { "line": num, "col": num, "message": s } })),
            "demands": arr(json!({})) } },
        "ProgramStatus": { "type": "object", "properties": {
            "state": { "type": "string", "enum": ["idle", "running", "held", "block_stop", "done", "stopped"] },
            "program": s, "progress": num, "line": num, "line_text": s, "message": s,
            "xyz": { "type": "array", "items": num }, "feed": num, "override_percent": num,
            "single_block": b } },
        "OverrideRequest": { "type": "object", "required": ["percent"], "properties": { "percent": num } },
        "SingleBlockRequest": { "type": "object", "required": ["on"], "properties": { "on": b } },
        "MdiRequest": { "type": "object", "required": ["line"], "properties": { "line": s } },
        "ProgramPreview": { "type": "object", "properties": {
            "points": { "type": "array", "items": { "type": "array", "items": num } },
            "rapid": { "type": "array", "items": b }, "spacing_mm": num } },
        "ExecutedPath": { "type": "object", "properties": {
            "run": num, "from": num, "next": num,
            "points": { "type": "array", "items": { "type": "array", "items": num } } } },
        "BookRequest": { "type": "object", "required": ["start", "end"], "properties": {
            "start": num, "end": num, "user": s, "machine": s } },
        "Reservation": { "type": "object", "properties": {
            "id": num, "station": s, "user": s, "start": num, "end": num, "created": num, "ended_by": s, "cleaned": b } },
        "User": { "type": "object", "properties": { "name": s, "role": r("Role"), "created": num, "updated": num } },
        "NewUser": { "type": "object", "required": ["name", "password", "role"], "properties": {
            "name": s, "password": s, "role": r("Role") } },
    })
}

/// The OpenAPI document.
#[must_use]
pub fn document() -> Value {
    json!({
        "openapi": "3.0.3",
        "info": {
            "title": "Motus station API",
            "version": env!("CARGO_PKG_VERSION"),
            "description": "Session cookie `motus_session` (HttpOnly, SameSite=Strict, Secure unless configured off); every mutating request needs header X-CSRF-Token. Errors are JSON {error, detail}. SafeToRun is computed by the supervisor only: no operation sets it.",
        },
        "paths": paths(),
        "components": {
            "schemas": schemas(),
            "parameters": { "Csrf": { "name": "X-CSRF-Token", "in": "header", "required": true, "schema": { "type": "string" } } },
            "responses": { "Error": { "description": "Error", "content": { "application/json": { "schema": r("Error") } } } },
            "securitySchemes": { "session": { "type": "apiKey", "in": "cookie", "name": "motus_session" } },
        },
        "security": [{ "session": [] }],
    })
}

/// `GET /api/openapi.json` (public).
pub async fn handler() -> Json<Value> {
    Json(document())
}
