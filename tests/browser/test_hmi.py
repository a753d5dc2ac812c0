#!/usr/bin/env python3
"""Browser test of the station web HMI on the real station (`motus demo`), in Debian's headless
Chromium driven by Playwright.

Every control of the HMI is clicked and its effect checked on the machine, through the JSON
API of a second (observer) administrator session, or on the page: the login form alone before
login; the group panels built from the cell's own group ids (`GET /api/groups`); adding a
student; home; jog (press and hold beyond the 0.5 s dead-man, release stops it); move; stop;
the robot map (go-to); the pan-tilt target; the arm joints; program upload/run/hold/resume/
stop and a run to the end; E-stop (every axis stops, motion refused), its alarm acknowledged
with the Ack button, reset; the juggler's programs and the supervisor's diagnosis; the audit
log; logout (the HMI hides, its WebSocket closes, the panels are emptied); a student who is
read-only without a slot, books one, commands the pan-tilt head in it, cancels it and logs out.

The station: `motus demo --listen 127.0.0.1:<free port>` started from $MOTUS_BIN (default
target/release/motus; the administrator password is read from its stdout), or a running
station at $MOTUS_HMI_URL with $MOTUS_HMI_ADMIN_PASSWORD. Screenshots go to $MOTUS_SCREENSHOTS
(default: a new temporary directory, printed), with the demo's log.

Run: python3 tests/browser/test_hmi.py (or `cargo test -p motus --test cli_demo_browser`).
Missing Chromium or Playwright is a failure, not a skip. Prints `N passed, M failed` and exits
non-zero on any failure; the script ends on its own timer ($MOTUS_BROWSER_DEADLINE seconds).
"""

import json
import math
import os
import re
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
import traceback
import urllib.error
import urllib.request

DEADLINE_S = float(os.environ.get("MOTUS_BROWSER_DEADLINE", "600"))
CHROMIUM = os.environ.get("MOTUS_CHROMIUM", "/usr/bin/chromium")
ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
MOTUS_BIN = os.environ.get("MOTUS_BIN", os.path.join(ROOT, "target", "release", "motus"))
SHOTS = os.environ.get("MOTUS_SCREENSHOTS") or tempfile.mkdtemp(prefix="motus-hmi-")
STUDENT = "hmi-student"
STUDENT_PASSWORD = "student-password-1"
# A program the demo's CNC accepts; ~24 s long at F1000 (time to run, hold, resume and stop).
LONG_PROGRAM = "G21 G90\nG0 X0 Y0\nG1 X100 Y0 F1000\nG1 X100 Y100\nG1 X0 Y100\nG1 X0 Y0\nM2\n"
SHORT_PROGRAM = "G21 G90\nG0 X0 Y0\nG1 X5 Y2 F3000\nG0 X0 Y0\nM2\n"


def _watchdog():
    sys.stderr.write(f"test_hmi: deadline of {DEADLINE_S} s reached, exiting\n")
    sys.stderr.flush()
    if STATION is not None:
        STATION.stop()
    os._exit(3)


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class ApiError(Exception):
    def __init__(self, status, body):
        super().__init__(f"HTTP {status}: {body}")
        self.status = status
        self.body = body


class Api:
    """An observer session on the JSON API (its own login; cookie and CSRF by hand)."""

    def __init__(self, url, user, password):
        self.url = url
        self.cookie = None
        self.csrf = None
        r = self.call("POST", "/api/login", {"user": user, "password": password})
        self.csrf = r["csrf_token"]

    def call(self, method, path, body=None):
        data = None if body is None else json.dumps(body).encode()
        req = urllib.request.Request(self.url + path, data=data, method=method)
        if data is not None:
            req.add_header("Content-Type", "application/json")
        if self.cookie:
            req.add_header("Cookie", self.cookie)
        if self.csrf and method != "GET":
            req.add_header("X-CSRF-Token", self.csrf)
        try:
            with urllib.request.urlopen(req, timeout=15) as r:
                set_cookie = r.headers.get("Set-Cookie")
                if set_cookie and self.cookie is None:
                    self.cookie = set_cookie.split(";")[0]
                raw = r.read()
                return json.loads(raw) if raw else None
        except urllib.error.HTTPError as e:
            raise ApiError(e.code, e.read().decode(errors="replace")) from None

    def get(self, path):
        return self.call("GET", path)

    def axes(self):
        return {a["id"]: a for a in self.get("/api/axes")}

    def axis(self, axis_id):
        return self.axes()[axis_id]

    def safety(self):
        return self.get("/api/safety")

    def program(self):
        return self.get("/api/programs/status")

    def alarms(self):
        return self.get("/api/alarms")["active"]


class Station:
    """`motus demo` on a free port (or the station at MOTUS_HMI_URL)."""

    def __init__(self):
        self.proc = None
        self.log = None
        self.started_here = False
        url = os.environ.get("MOTUS_HMI_URL")
        if url:
            self.url = url.rstrip("/")
            self.admin_password = os.environ.get("MOTUS_HMI_ADMIN_PASSWORD")
            if not self.admin_password:
                raise RuntimeError("MOTUS_HMI_URL needs MOTUS_HMI_ADMIN_PASSWORD")
            return
        if not os.path.exists(MOTUS_BIN):
            raise RuntimeError(f"{MOTUS_BIN} not found: cargo build --release -p motus (or set MOTUS_BIN)")
        port = free_port()
        os.makedirs(SHOTS, exist_ok=True)
        self.log = open(os.path.join(SHOTS, "demo.log"), "w")
        self.proc = subprocess.Popen([MOTUS_BIN, "demo", "--listen", f"127.0.0.1:{port}"],
                                     stdout=subprocess.PIPE, stderr=self.log, text=True)
        self.started_here = True
        self.url = f"http://127.0.0.1:{port}"
        self.admin_password = None
        for line in self.proc.stdout:  # the watchdog bounds this wait
            print(f"  demo: {line.rstrip()}")
            m = re.match(r"administrator login: user admin, password (\S+)", line.strip())
            if m:
                self.admin_password = m.group(1)
                break
        if not self.admin_password:
            raise RuntimeError(f"motus demo exited ({self.proc.poll()}) before printing the admin password")
        out = self.proc.stdout
        threading.Thread(target=lambda: [None for _ in out], daemon=True).start()

    def wait_ready(self):
        """Until the cell's axes and groups are served (the web server starts first)."""
        end = time.monotonic() + 60
        while True:
            try:
                api = Api(self.url, "admin", self.admin_password)
                if api.get("/api/axes") and api.get("/api/groups"):
                    return api
            except (OSError, ApiError):
                pass
            if self.proc is not None and self.proc.poll() is not None:
                raise RuntimeError(f"motus demo exited with {self.proc.returncode}")
            if time.monotonic() > end:
                raise RuntimeError("the station did not serve its cell within 60 s")
            time.sleep(0.5)

    def stop(self):
        if self.proc and self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(5)


STATION = None


# ---------------------------------------------------------------- helpers

def shot(page, name):
    os.makedirs(SHOTS, exist_ok=True)
    path = os.path.join(SHOTS, f"{name}.png")
    page.screenshot(path=path, full_page=True)
    print(f"  screenshot {path}")


def wait_until(what, fn, timeout=20.0, every=0.2):
    """Polls fn until it returns a truthy value (returned); fails with the last value."""
    end = time.monotonic() + timeout
    last = None
    while True:
        try:
            v = fn()
            if v:
                return v
            last = v
        except ApiError as e:
            last = e
        if time.monotonic() > end:
            raise AssertionError(f"timed out after {timeout} s waiting for {what} (last: {last})")
        time.sleep(every)


def near(a, b, tol):
    return abs(a - b) <= tol


def at_rest(a):
    return not a["moving"] and abs(a["velocity"]) < 1e-9


def page_number(page, testid):
    return float(page.get_by_test_id(testid).inner_text())


class T:
    """What the steps share."""

    def __init__(self, station, api, page, context):
        self.station = station
        self.api = api
        self.page = page
        self.context = context
        self.sockets = []
        self.page_errors = []
        self.groups = []
        page.on("websocket", lambda ws: self.sockets.append(ws))
        page.on("pageerror", lambda e: self.page_errors.append(str(e)))
        page.on("console", lambda m: m.type == "error" and print(f"  console: {m.text}"))

    def tid(self, testid):
        return self.page.get_by_test_id(testid)

    def group(self, kind):
        g = [g for g in self.groups if g["kind"] == kind]
        assert g, f"the station has no group of kind {kind}: {self.groups}"
        return g[0]

    def open_sockets(self):
        return [ws for ws in self.sockets if not ws.is_closed()]

    def group_post(self, click, group_id):
        """Clicks and returns the group command's response; it must name the cell's group."""
        with self.page.expect_response(lambda r: "/api/groups/" in r.url and r.request.method == "POST",
                                       timeout=30000) as info:  # liveness: a loaded host
            click()
        resp = info.value
        assert resp.url.endswith(f"/api/groups/{group_id}"), f"posted to {resp.url}, the cell's group is {group_id}"
        return resp

    def login(self, user, password):
        self.tid("login-user").fill(user)
        self.tid("login-password").fill(password)
        self.tid("login-submit").click()
        self.tid("who").filter(has_text=user).wait_for(timeout=30000)
        assert self.tid("login-panel").is_hidden()
        assert self.tid("app").is_visible()

    def logged_out_checks(self, name):
        """Only the login form; the stream closed and not reopened; every panel emptied."""
        page = self.page
        self.tid("login-panel").wait_for(state="visible", timeout=20000)
        for testid in ["app", "estop", "logout", "safe-badge", "who", "axes-rows", "robot-map"]:
            assert self.tid(testid).is_hidden(), f"{testid} still shows after logout"
        wait_until("the WebSocket to close", lambda: not self.open_sockets(), timeout=10)
        count = len(self.sockets)
        page.wait_for_timeout(2500)  # the HMI reconnects a lost stream after 1 s: not after logout
        assert len(self.sockets) == count and not self.open_sockets(), "a WebSocket was opened after logout"
        for rows in ["axes-rows", "alarm-rows", "reservation-rows", "arm-sliders", "pantilt-groups", "audit-rows"]:
            n = page.locator(f"[data-testid={rows}] > *").count()
            assert n == 0, f"{rows} still holds {n} rows after logout"
        assert self.tid("who").inner_text() == "" and self.tid("diagnosis").inner_text() == "-"
        assert "hmi-" not in page.locator("#program-name").input_value(), "the last user's program stays"
        r = page.request.get(self.station.url + "/api/session")
        assert r.status == 401, f"the browser's session still answers {r.status} after logout"
        shot(page, name)

    def reset_until_safe(self, tries=6):
        """Presses reset until SafeToRun. The supervised juggler on a loaded non-real-time host
        may be stopped again by a late cycle (its safety lease expires): reset again."""
        for i in range(tries):
            self.tid("reset").click()
            try:
                wait_until("SafeToRun after reset",
                           lambda: (s := self.api.safety()) and s["safe_to_run"] and not s["estop"], timeout=10)
                self.tid("safe-badge").filter(has_text=re.compile("^SafeToRun$")).wait_for(timeout=20000)
                return
            except Exception:  # noqa: BLE001 - not yet safe (AssertionError or a page time-out): again
                print(f"  not SafeToRun after reset {i + 1}: {self.api.safety()['diagnosis']}")
                if i + 1 == tries:
                    raise


# ---------------------------------------------------------------- steps

def step_login_form_only(t):
    page = t.page
    page.goto(t.station.url)
    t.tid("login-user").wait_for(timeout=20000)
    page.wait_for_timeout(500)
    for testid in ["app", "estop", "logout", "safe-badge", "axes-rows", "robot-map", "program-run", "alarm-rows"]:
        assert t.tid(testid).is_hidden(), f"{testid} shows before login"
    assert not t.sockets, "a WebSocket was opened before login"
    shot(page, "01-login-form-only")


def step_login_admin(t):
    page = t.page
    t.login("admin", t.station.admin_password)
    assert "Admin" in t.tid("mode-note").inner_text()
    axes = t.api.axes()
    # Live frames fill the axes table: a row per axis of the cell, positions shown.
    for a in axes:
        t.tid(f"axis-{a}").wait_for(timeout=30000)
    t.tid(f"axis-pos-{JOG_AXIS}").filter(has_text=re.compile(r"\d")).wait_for(timeout=30000)
    page.wait_for_function("() => Number(document.getElementById('frame-rate').textContent) >= 5", timeout=30000)
    assert len(t.open_sockets()) == 1, f"{len(t.open_sockets())} WebSockets open"
    # The group panels carry the cell's own group ids.
    t.groups = t.api.get("/api/groups")
    robot = t.group("robot")
    assert t.tid("robot-group").inner_text() == robot["id"]
    assert t.tid("robot-map").is_visible()
    for g in t.groups:
        if g["kind"] == "pan_tilt":
            assert t.tid(f"pantilt-go-{g['id']}").is_visible()
            for a in g["axes"]:
                assert t.tid(f"pantilt-target-{a}").is_visible()
        if g["kind"] == "arm":
            assert t.tid(f"arm-go-{g['id']}").is_visible()
            for a in g["axes"]:
                assert t.tid(f"arm-{a}").is_visible()
    print(f"  groups: {[(g['id'], g['kind']) for g in t.groups]}")
    shot(page, "02-logged-in")


CAMERA_COUNT_JS = """async (group) => {
    // The machine's camera stream read by the page itself (its session cookie), parts counted.
    const ctl = new AbortController();
    const r = await fetch(`/api/groups/${encodeURIComponent(group)}/camera.mjpg`, { signal: ctl.signal });
    if (!r.ok) return { status: r.status, parts: 0, seconds: 0 };
    const reader = r.body.getReader();
    const mark = new TextEncoder().encode('--motus-camera-frame');
    let parts = 0, match = 0;
    const t0 = performance.now();
    while (performance.now() - t0 < 3000) {
        const { value, done } = await reader.read();
        if (done) break;
        for (const b of value) {
            match = (b === mark[match]) ? match + 1 : (b === mark[0] ? 1 : 0);
            if (match === mark.length) { parts += 1; match = 0; }
        }
    }
    const seconds = (performance.now() - t0) / 1000;
    ctl.abort();
    return { status: r.status, parts, seconds };
}"""


def step_camera(t):
    page = t.page
    cams = [g for g in t.groups if g.get("camera")]
    assert cams, f"no group with a camera in {[g['id'] for g in t.groups]}"
    # A machine's camera on the page, when picked: a picture drawn by the station (320 x 240).
    t.tid(f"camera-pick-{cams[0]['id']}").click()
    page.wait_for_function(
        "() => { const i = document.querySelector('[data-testid=camera-view]'); return i && i.naturalWidth === 320; }",
        timeout=30000)
    t.tid(f"camera-pick-{cams[-1]['id']}").click()
    page.wait_for_function(
        f"() => document.querySelector('[data-testid=camera-view]').src.includes('/api/groups/{cams[-1]['id']}/')",
        timeout=10000)
    shot(page, "02b-camera")
    # Off again: the stream ends (the later steps run without it).
    t.tid("camera-off").click()
    page.wait_for_function("() => !document.querySelector('[data-testid=camera-view]').getAttribute('src')", timeout=10000)
    # Frames per second as a browser receives them: a figure for scripts/realtime.sh (the
    # station draws 15 a second; a loaded host may deliver fewer), and a liveness check here.
    r = page.evaluate(CAMERA_COUNT_JS, cams[0]["id"])
    assert r["status"] == 200, r
    fps = r["parts"] / max(r["seconds"], 1e-3)
    print(f"  camera of {cams[0]['id']}: {r['parts']} frames in {r['seconds']:.2f} s = {fps:.1f} frames/s in the browser")
    assert fps >= 2, f"{fps:.1f} frames/s"
    out = os.path.join(ROOT, "target", "realtime", "from-suite")
    os.makedirs(out, exist_ok=True)
    with open(os.path.join(out, "demo_browser.log"), "a", encoding="utf-8") as f:
        f.write(f"REALTIME suite.demo_browser.camera_fps {fps:.1f} fps\n")


def step_add_student(t):
    page = t.page
    page.locator("#new-user").fill(STUDENT)
    page.locator("#new-password").fill(STUDENT_PASSWORD)
    page.locator("#new-role").select_option("student")
    page.locator("#user-form button[type=submit]").click()
    wait_until("the student in GET /api/users",
               lambda: any(u["name"] == STUDENT and u["role"] == "student" for u in t.api.get("/api/users")))
    t.tid("user-rows").filter(has_text=STUDENT).wait_for(timeout=20000)
    assert page.locator("#new-password").input_value() == "", "the new user's password stays in the form"


HOME_AXES = ["x", "y", "z", "pan", "tilt", "linear2"]  # x, y, z: the gantry programs run on


def step_home(t):
    before = t.api.axes()
    print("  homed before: " + ", ".join(f"{a}={before[a]['homed']}" for a in HOME_AXES))
    if t.station.started_here:
        assert not all(before[a]["homed"] for a in HOME_AXES), "a fresh demo has unhomed axes"
    for a in HOME_AXES:
        t.tid(f"home-{a}").click()
    wait_until("every axis homed and at rest",
               lambda: all((x := t.api.axis(a))["homed"] and at_rest(x) for a in HOME_AXES), timeout=90)
    for a in HOME_AXES:
        t.page.get_by_test_id(f"axis-state-{a}").filter(has_text=re.compile(r"\bhomed")).wait_for(timeout=15000)


JOG_AXIS = "y"


def hold_jog(t, button, seconds):
    """Presses and holds a jog button; returns (the axis seen while still held, the HMI's jog
    responses as (seconds since the press, status), the last value of the page's message).
    Held `seconds` from the moment the axis is seen moving."""
    page = t.page
    jogs = []
    stops = []
    t0 = time.monotonic()

    def on_response(r):
        if "/jog" in r.url:
            jogs.append((round(time.monotonic() - t0, 2), r.status))
        if r.url.endswith(f"/api/axes/{JOG_AXIS}/stop"):
            stops.append(r.status)

    def refused():
        return t.tid("message").inner_text().startswith(f"Jog {JOG_AXIS}:")

    page.on("response", on_response)
    t.tid(button).hover()
    page.mouse.down()
    try:
        wait_until("the jog to start", lambda: t.api.axis(JOG_AXIS)["moving"], timeout=10)
        page.wait_for_timeout(int(seconds * 1000))  # from the start of the motion
        held = t.api.axis(JOG_AXIS)
        held["held_for"] = round(time.monotonic() - t0, 2)
    finally:
        # The release sends a stop at once (the lease would only end the jog 0.5 s later).
        # The HMI may have ended the jog before: with a stop when the button moved away from
        # under the pointer (pointerleave: the page's layout changed while it was held), or
        # by itself when the station refused a renewal (a lease that expired on a loaded
        # host; the page then says "Jog <axis>: ..."). Then the release has nothing to stop.
        page.mouse.up()
        deadline = time.monotonic() + 30
        while not stops and not refused() and time.monotonic() < deadline:
            page.wait_for_timeout(50)
        page.remove_listener("response", on_response)
    assert stops or refused(), "no stop request within 30 s of the release"
    assert all(st == 200 for st in stops), f"stop on release: {stops}"
    return held, jogs, t.tid("message").inner_text()


def renewal_gap(jogs, until):
    """The longest time without a jog response (the lease runs 0.5 s from each renewal)."""
    times = [s for s, _ in jogs] + [until]
    return max((b - a for a, b in zip(times, times[1:])), default=until)


def step_jog(t):
    page = t.page
    before = t.api.axis(JOG_AXIS)["position"]
    # Held well beyond the 0.5 s dead-man: the HMI renews the jog every 0.2 s, the axis keeps
    # going. On an overloaded host a renewal may reach the station late and the lease expire
    # (that is the dead-man doing its job): tried again then, a failure when renewals were
    # regular.
    for attempt in range(3):
        held, jogs, message = hold_jog(t, f"jog-plus-{JOG_AXIS}", 2.0)
        print(f"  jog responses while held (s, status): {jogs}")
        if held["moving"] and held["velocity"] > 0:
            break
        gap = renewal_gap(jogs, held["held_for"])
        assert gap > 0.45 and attempt < 2, \
            f"the held jog stopped after {held['held_for']} s at {held['position']:.4f} with renewals at most " \
            f"{gap:.2f} s apart (responses: {jogs}; message: {message!r})"
        print(f"  the jog stopped while held: a renewal came {gap:.2f} s late (host load); again")
        wait_until("the axis at rest", lambda: at_rest(t.api.axis(JOG_AXIS)), timeout=10)
    assert all(st == 200 for _, st in jogs), jogs
    assert held["position"] > before + 0.02, f"{before} -> {held['position']}"
    wait_until("the axis to stop on release", lambda: at_rest(t.api.axis(JOG_AXIS)), timeout=10)
    p1 = t.api.axis(JOG_AXIS)["position"]
    page.wait_for_timeout(1000)
    p2 = t.api.axis(JOG_AXIS)["position"]
    assert p1 == p2, f"still moving after the release: {p1} -> {p2}"
    t.tid(f"axis-state-{JOG_AXIS}").filter(has_text="stopped").wait_for(timeout=15000)
    wait_until("the page to show the position", lambda: near(page_number(page, f"axis-pos-{JOG_AXIS}"), p2, 1e-3), 10)
    print(f"  jog + {JOG_AXIS}: {before:.4f} -> {p2:.4f}")
    # And back: jog minus.
    stops = []
    on_stop = lambda r: stops.append(r.status) if r.url.endswith(f"/api/axes/{JOG_AXIS}/stop") else None
    page.on("response", on_stop)
    t.tid(f"jog-minus-{JOG_AXIS}").hover()
    page.mouse.down()
    try:
        wait_until("the jog minus to start", lambda: t.api.axis(JOG_AXIS)["velocity"] < 0, timeout=10)
        page.wait_for_timeout(600)
    finally:
        # A stop on release, or before it (pointerleave, see hold_jog).
        page.mouse.up()
        # (Playwright delivers responses to listeners only inside its own calls.)
        wait_until("a stop request", lambda: page.wait_for_timeout(20) or stops, timeout=30)
        page.remove_listener("response", on_stop)
    wait_until("the axis to stop on release", lambda: at_rest(t.api.axis(JOG_AXIS)), timeout=10)
    p3 = t.api.axis(JOG_AXIS)["position"]
    assert p3 < p2 - 0.005, f"jog minus: {p2} -> {p3}"
    shot(page, "03-jogged")


def step_move(t):
    t.tid("move-target-x").fill("0.1")
    t.tid("move-go-x").click()
    wait_until("x at 0.1", lambda: (a := t.api.axis("x")) and near(a["position"], 0.1, 1e-4) and at_rest(a), 30)
    wait_until("the page to show x at 0.1", lambda: near(page_number(t.page, "axis-pos-x"), 0.1, 1e-3), 10)


def step_stop(t):
    t.tid("move-target-x").fill("0.5")
    t.tid("move-go-x").click()
    wait_until("x moving past 0.12", lambda: (a := t.api.axis("x"))["moving"] and a["position"] > 0.12, 20)
    t.tid("stop-x").click()
    wait_until("x stopped", lambda: at_rest(t.api.axis("x")), 10)
    p = t.api.axis("x")["position"]
    assert 0.12 < p < 0.45, f"x stopped at {p}, the move went to 0.5"
    t.page.wait_for_timeout(1000)
    assert t.api.axis("x")["position"] == p
    print(f"  x stopped at {p:.4f}")


def step_robot_map(t):
    g = t.group("robot")
    target = (0.5, 0.3)
    robot = t.api.get("/api/scene")["robot"]
    b = robot["bounds"]
    canvas = t.tid("robot-map")
    canvas.scroll_into_view_if_needed()
    box = canvas.bounding_box()
    s = min(400 / (b[2] - b[0]), 300 / (b[3] - b[1]))  # the canvas is 400 x 300
    px, py = (target[0] - b[0]) * s, 300 - (target[1] - b[1]) * s
    wheels0 = {a: t.api.axis(a)["position"] for a in g["axes"]}
    resp = t.group_post(lambda: canvas.click(position={"x": px * box["width"] / 400, "y": py * box["height"] / 300}),
                        g["id"])
    body = resp.request.post_data_json
    assert body["action"] == "go_to" and near(body["targets"][0], target[0], 0.05) \
        and near(body["targets"][1], target[1], 0.05), body
    assert resp.status == 200, f"go-to refused: {resp.status} {resp.text()}"
    wait_until("the wheels to turn",
               lambda: any(abs(t.api.axis(a)["position"] - wheels0[a]) > 0.1 for a in g["axes"]), 10)
    wait_until("the robot at the clicked point",
               lambda: math.dist(t.api.get("/api/scene")["robot"]["pose"][:2], target) < 0.1, 60)
    shot(t.page, "04-robot-go-to")


def step_pan_tilt(t):
    g = t.group("pan_tilt")
    targets = [0.6, -0.3]
    for a, v in zip(g["axes"], targets):
        t.tid(f"pantilt-target-{a}").fill(str(v))
    resp = t.group_post(lambda: t.tid(f"pantilt-go-{g['id']}").click(), g["id"])
    assert resp.status == 200, f"{resp.status} {resp.text()}"
    assert resp.request.post_data_json == {"action": "go_to", "targets": targets}
    wait_until(f"{g['axes']} at {targets}",
               lambda: all(near((x := t.api.axis(a))["position"], v, 5e-3) and at_rest(x)
                           for a, v in zip(g["axes"], targets)), 30)


def step_arm(t):
    g = t.group("arm")
    want = {g["axes"][0]: 0.4, g["axes"][1]: -0.2}
    for a, v in want.items():
        t.tid(f"arm-{a}").fill(str(v))
        assert t.tid(f"arm-value-{a}").inner_text() == f"{v:.2f}"
    resp = t.group_post(lambda: t.tid(f"arm-go-{g['id']}").click(), g["id"])
    assert resp.status == 200, f"{resp.status} {resp.text()}"
    sent = resp.request.post_data_json["targets"]
    assert len(sent) == len(g["axes"]) and sent[0] == 0.4 and sent[1] == -0.2, sent
    wait_until(f"the arm at {want}",
               lambda: all(near((x := t.api.axis(a))["position"], v, 0.01) and not x["moving"]
                           for a, v in want.items()), 40)
    shot(t.page, "05-pan-tilt-and-arm")


def gantry(t):
    return tuple(t.api.get("/api/scene")["gantry"][0])


def set_range(t, testid, value):
    """Moves a slider as a user does: its value, then the input and change events."""
    t.tid(testid).evaluate("(e, v) => { e.value = v; e.dispatchEvent(new Event('input')); "
                           "e.dispatchEvent(new Event('change')); }", str(value))


def dataset_number(page, testid, key):
    return page.evaluate(f"() => Number(document.querySelector('[data-testid=\"{testid}\"]').dataset.{key})")


def cnc_feeds(t):
    """The traced executed feed (`cnc.feed`, mm/min) the station holds."""
    names = [s["id"] for s in t.api.get("/api/signals")]
    k = names.index("cnc.feed")
    return [row["values"][k] for row in t.api.get("/api/samples?cursor=0")["samples"] if row["values"][k] is not None]


def step_program(t):
    page = t.page
    t.tid("program-name").fill("hmi-long.ngc")
    t.tid("program-text").fill(LONG_PROGRAM)
    t.tid("program-upload").click()
    t.tid("program-errors").filter(has_text="no errors").wait_for(timeout=20000)
    # The preview of the checked program: its six moves drawn.
    page.wait_for_function("() => Number(document.getElementById('program-preview').dataset.points) >= 6",
                           timeout=15000)
    t.tid("pick-cnc.feed").check()
    p0 = gantry(t)
    x0 = t.api.axis("x")["position"]
    t.tid("program-run").click()
    wait_until("the program running", lambda: t.api.program()["state"] == "running", 10)
    page.wait_for_function("() => Number(document.getElementById('program-percent').textContent) > 0 && "
                           "document.getElementById('program-state').textContent.startsWith('running')",
                           timeout=10000)
    # The booked machine's gantry moves: its axes, and the scene drawn from them.
    wait_until("the gantry moving", lambda: gantry(t) != p0, 10)
    wait_until("axis x moving", lambda: t.api.axis("x")["position"] != x0, 10)
    # The executed path drawn over the preview, growing.
    page.wait_for_function("() => Number(document.getElementById('program-preview').dataset.executed) > 3",
                           timeout=15000)
    # The feed override: 50 % halves the executed feed, in the status and in the trace.
    wait_until("the feed at 1000 mm/min", lambda: abs(t.api.program()["feed"] - 1000) < 5, 20)
    set_range(t, "program-override", 50)
    wait_until("the override at 50 %", lambda: t.api.program()["override_percent"] == 50, 10)
    wait_until("the feed at 500 mm/min", lambda: abs(t.api.program()["feed"] - 500) < 5, 20)
    page.wait_for_function("() => Math.abs(Number(document.getElementById('program-feed').textContent) - 500) < 5",
                           timeout=10000)
    wait_until("both feeds in the trace", lambda: (f := cnc_feeds(t)) and any(abs(v - 1000) < 5 for v in f)
               and any(abs(v - 500) < 5 for v in f), 10)
    shot(page, "06-program-running")
    set_range(t, "program-override", 100)
    wait_until("the override back at 100 %", lambda: t.api.program()["override_percent"] == 100, 10)
    t.tid("program-hold").click()
    wait_until("the program held", lambda: t.api.program()["state"] == "held", 10)
    t.tid("program-state").filter(has_text="held").wait_for(timeout=15000)
    page.wait_for_timeout(500)  # the feed-hold deceleration
    p1 = gantry(t)
    page.wait_for_timeout(1000)
    assert gantry(t) == p1, "the gantry moves during the hold"
    t.tid("program-resume").click()
    wait_until("the program running again", lambda: t.api.program()["state"] == "running", 10)
    wait_until("the gantry moving again", lambda: gantry(t) != p1, 10)
    t.tid("program-stop").click()
    wait_until("the program stopped", lambda: t.api.program()["state"] == "stopped", 10)
    t.tid("program-state").filter(has_text="stopped").wait_for(timeout=15000)
    # Single block: a short one, stopping after each block until Cycle start.
    t.tid("program-name").fill("hmi-short.ngc")
    t.tid("program-text").fill(SHORT_PROGRAM)
    t.tid("program-upload").click()
    t.tid("program-errors").filter(has_text="no errors").wait_for(timeout=20000)
    t.tid("program-single-block").check()
    wait_until("single block on", lambda: t.api.program()["single_block"], 10)
    t.tid("program-run").click()
    stops = 0
    while True:
        # A liveness bound: beside CPU hogs the whole demo and Chromium share two cores.
        wait_until("a block stop or the end",
                   lambda: (p := t.api.program())["program"] == "hmi-short.ngc"
                   and p["state"] in ("block_stop", "done"), 60)
        if t.api.program()["state"] == "done":
            break
        stops += 1
        t.tid("program-state").filter(has_text="block_stop").wait_for(timeout=15000)
        wait_until("the gantry at rest at the block stop", lambda: at_rest(t.api.axis("x")), 10)
        p2 = gantry(t)
        page.wait_for_timeout(500)
        assert gantry(t) == p2 and t.api.program()["state"] == "block_stop", "single block did not stop"
        assert stops <= 5, "more block stops than blocks"
        t.tid("program-resume").click()
        wait_until("the stop left", lambda: t.api.program()["state"] != "block_stop" or gantry(t) != p2, 10)
    assert stops >= 2, f"{stops} block stops for three moves"
    t.tid("program-single-block").uncheck()
    wait_until("single block off", lambda: not t.api.program()["single_block"], 10)
    page.wait_for_function("() => document.getElementById('program-state').textContent.startsWith('done') && "
                           "document.getElementById('program-percent').textContent === '100'", timeout=10000)
    shot(page, "07-program-done")
    # MDI: one line, executed on the gantry.
    t.tid("mdi-line").fill("G1 X20 Y10 F1200")
    t.tid("mdi-run").click()
    wait_until("the MDI line done at X 20 Y 10",
               lambda: (p := t.api.program())["program"] == "MDI" and p["state"] == "done"
               and near(t.api.axis("x")["position"], 0.02, 1e-4) and near(t.api.axis("y")["position"], 0.01, 1e-4),
               60)


def step_estop_ack_reset(t):
    page = t.page
    t.tid("move-target-x").fill("0.55")
    t.tid("move-go-x").click()
    t.tid("move-target-pan").fill("-1.5")
    t.tid("move-go-pan").click()
    wait_until("x and pan moving", lambda: (a := t.api.axes())["x"]["moving"] and a["pan"]["moving"], 10)
    t.tid("estop").click()
    wait_until("the E-stop in /api/safety", lambda: t.api.safety()["estop"], 10)
    t.tid("safe-badge").filter(has_text="E-STOP").wait_for(timeout=20000)
    wait_until("every axis at rest", lambda: all(at_rest(a) for a in t.api.get("/api/axes")), 15)
    a = t.api.axes()
    assert a["x"]["position"] < 0.5 and a["pan"]["position"] > -1.45, "the moves ran to their targets"
    shot(page, "08-estop-all-stopped")
    # Motion is refused while the E-stop is pressed, and the HMI says why.
    t.tid("move-target-x").fill("0.2")
    t.tid("move-go-x").click()
    t.tid("message").filter(has_text=re.compile("emergency stop", re.I)).wait_for(timeout=15000)
    page.wait_for_timeout(500)
    assert at_rest(t.api.axis("x"))
    # The E-stop raised an alarm: acknowledge it with its Ack button (live frames keep coming).
    alarm = wait_until("the estop alarm",
                       lambda: next((x for x in t.api.alarms() if x["code"] == "estop" and not x["acknowledged"]),
                                    None), 10)
    ack = t.tid(f"ack-{alarm['id']}")
    ack.wait_for(timeout=20000)
    ack.click()
    wait_until("the alarm acknowledged by admin",
               lambda: any(x["id"] == alarm["id"] and (x["acknowledged"] or {}).get("by") == "admin"
                           for x in t.api.get("/api/alarms")["history"]), 10)
    page.locator(f"[data-alarm-id='{alarm['id']}']").filter(has_text="ack admin").wait_for(timeout=15000)
    shot(page, "09-alarm-acknowledged")
    t.reset_until_safe()
    # Cleared and acknowledged: no longer active, gone from the page.
    wait_until("the estop alarm inactive", lambda: all(x["id"] != alarm["id"] for x in t.api.alarms()), 10)
    page.locator(f"[data-alarm-id='{alarm['id']}']").wait_for(state="detached", timeout=20000)


def step_juggler(t):
    g = t.group("juggler")
    unsafe, safe, rule = "limit", "juggle", "limits_thrower"
    assert unsafe in g["programs"] and safe in g["programs"], g
    t.tid("juggler-program").select_option(unsafe)
    resp = t.group_post(lambda: t.tid("juggler-run").click(), g["id"])
    assert resp.status == 200, f"{resp.status} {resp.text()}"
    wait_until(f"the juggler running {unsafe}",
               lambda: next(x for x in t.api.get("/api/groups") if x["id"] == g["id"])["program"] == unsafe, 10)
    t.tid("juggler-current").filter(has_text=unsafe).wait_for(timeout=20000)
    for attempt in range(8):
        try:
            t.tid("diagnosis").filter(has_text=rule).wait_for(timeout=12000)
            break
        except Exception:  # noqa: BLE001 - stopped for another reason (a late cycle): reset, retry
            print(f"  stopped before the rule fired: {t.tid('diagnosis').inner_text()}")
            if attempt == 7:
                raise
            t.tid("reset").click()
    assert not t.api.safety()["safe_to_run"]
    assert t.tid("safe-text").inner_text().startswith("false")
    print(f"  diagnosis: {t.tid('diagnosis').inner_text()}")
    wait_until("the juggler's axes at rest",
               lambda: all(abs(t.api.axis(a)["velocity"]) < 1e-9 for a in g["axes"]), 10)
    shot(t.page, "10-supervisor-diagnosis")
    t.tid("juggler-program").select_option(safe)
    t.group_post(lambda: t.tid("juggler-run").click(), g["id"])
    wait_until(f"the juggler running {safe}",
               lambda: next(x for x in t.api.get("/api/groups") if x["id"] == g["id"])["program"] == safe, 10)
    t.reset_until_safe()


def step_audit(t):
    t.tid("audit-refresh").click()
    t.tid("audit-rows").filter(has_text="estop").wait_for(timeout=20000)
    assert any(e["entry"]["action"] == "command.estop" and e["entry"]["user"] == "admin"
               for e in t.api.get("/api/audit?limit=500")), "no estop by admin in the audit log"


def step_logout_admin(t):
    t.tid("logout").click()
    t.logged_out_checks("11-logged-out")


def step_student_books_and_commands(t):
    page = t.page
    t.login(STUDENT, STUDENT_PASSWORD)
    note = t.tid("mode-note")
    note.filter(has_text="Read-only").wait_for(timeout=20000)
    g = t.group("pan_tilt")
    assert t.tid(f"pantilt-go-{g['id']}").is_disabled() and t.tid(f"jog-plus-{JOG_AXIS}").is_disabled()
    shot(page, "12-student-read-only")
    t.tid("book-slot-0").click()
    now = lambda: time.time() * 1000  # noqa: E731
    res = wait_until("the student's reservation",
                     lambda: next((r for r in t.api.get("/api/reservations")
                                   if r["user"] == STUDENT and r["start"] <= now() < r["end"]), None), 10)
    note.filter(has_text="control").wait_for(timeout=20000)
    page.wait_for_timeout(1200)  # stays in control across the next live frames (the slot is in them)
    assert "Read-only" not in note.inner_text(), note.inner_text()
    assert t.tid(f"pantilt-go-{g['id']}").is_enabled()
    # In the slot, the student commands the pan-tilt head (within the student range).
    targets = [-0.4, 0.1]
    for a, v in zip(g["axes"], targets):
        t.tid(f"pantilt-target-{a}").fill(str(v))
    resp = t.group_post(lambda: t.tid(f"pantilt-go-{g['id']}").click(), g["id"])
    assert resp.status == 200, f"{resp.status} {resp.text()}"
    wait_until(f"{g['axes']} at {targets}",
               lambda: all(near((x := t.api.axis(a))["position"], v, 5e-3) and at_rest(x)
                           for a, v in zip(g["axes"], targets)), 30)
    shot(page, "13-student-slot")
    # Cancel (end early) the slot: control goes.
    t.tid(f"cancel-{res['id']}").click()
    wait_until("the reservation ended",
               lambda: all(r["id"] != res["id"] or r["end"] <= now() for r in t.api.get("/api/reservations")), 10)
    note.filter(has_text="Read-only").wait_for(timeout=20000)
    assert t.tid(f"pantilt-go-{g['id']}").is_disabled()


def step_logout_student(t):
    t.tid("logout").click()
    t.logged_out_checks("14-student-logged-out")


def step_no_script_errors(t):
    assert not t.page_errors, f"script errors: {t.page_errors}"


STEPS = [
    ("only the login form before login", step_login_form_only),
    ("log in as admin; group panels from /api/groups", step_login_admin),
    ("camera of a machine, relayed by the station", step_camera),
    ("add a student (users panel)", step_add_student),
    ("home", step_home),
    ("jog: press and hold, release stops", step_jog),
    ("move", step_move),
    ("stop", step_stop),
    ("robot map go-to", step_robot_map),
    ("pan-tilt target", step_pan_tilt),
    ("arm joints", step_arm),
    ("program preview/run/override/hold/resume/stop, single block, MDI", step_program),
    ("E-stop, alarm ack, reset", step_estop_ack_reset),
    ("juggler program and supervisor diagnosis", step_juggler),
    ("audit log", step_audit),
    ("logout (admin)", step_logout_admin),
    ("student: read-only, book, command, cancel", step_student_books_and_commands),
    ("logout (student)", step_logout_student),
    ("no script errors", step_no_script_errors),
]
FATAL = {"log in as admin; group panels from /api/groups"}  # nothing after it can run without it
# For working on one control: MOTUS_HMI_ONLY=home,jog runs the two login steps and the steps
# whose names contain one of the words.
if os.environ.get("MOTUS_HMI_ONLY"):
    _only = os.environ["MOTUS_HMI_ONLY"].split(",")
    STEPS = STEPS[:2] + [s for s in STEPS[2:] if any(w in s[0] for w in _only)]


def run():
    """Runs every step in one browser session; returns (passed, failed names)."""
    global STATION
    from playwright.sync_api import sync_playwright  # a missing package is a failure

    if not os.path.exists(CHROMIUM):
        raise RuntimeError(f"{CHROMIUM} not found: apt-get install -y --no-install-recommends chromium")
    print(f"screenshots in {SHOTS}")
    STATION = Station()
    passed, failed = 0, []
    try:
        api = STATION.wait_ready()
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=["--no-sandbox"])
            # The HMI's CSP forbids eval; Playwright's wait_for_function needs it.
            context = browser.new_context(viewport={"width": 1400, "height": 1000}, bypass_csp=True)
            page = context.new_page()
            # Generous liveness time-outs: the demo's cyclic threads take most of a 2-core host.
            page.set_default_timeout(30000)
            page.set_default_navigation_timeout(60000)
            t = T(STATION, api, page, context)
            for i, (name, fn) in enumerate(STEPS):
                t0 = time.monotonic()
                try:
                    fn(t)
                    passed += 1
                    print(f"ok   {name} ({time.monotonic() - t0:.1f} s)")
                except Exception as e:  # noqa: BLE001 - report, go on with the next control
                    failed.append(name)
                    print(f"FAIL {name} ({time.monotonic() - t0:.1f} s): {str(e).splitlines()[0] if str(e) else e!r}")
                    traceback.print_exc()
                    try:
                        shot(page, f"failed-{i + 1:02d}")
                    except Exception:  # noqa: BLE001
                        pass
                    if name in FATAL:
                        failed += [n for n, _ in STEPS[i + 1:]]
                        break
                sys.stdout.flush()
            browser.close()
    finally:
        STATION.stop()
    return passed, failed


def test_hmi():
    """pytest entry point."""
    passed, failed = run()
    assert not failed, f"browser steps failed: {failed}"


def main():
    timer = threading.Timer(DEADLINE_S, _watchdog)
    timer.daemon = True
    timer.start()
    try:
        passed, failed = run()
    except Exception:  # noqa: BLE001
        traceback.print_exc()
        passed, failed = 0, [n for n, _ in STEPS]
    if failed:
        print("failed: " + "; ".join(failed))
    print(f"{passed} passed, {len(failed)} failed")
    sys.stdout.flush()
    if STATION is not None:
        STATION.stop()
    os._exit(0 if not failed else 1)


if __name__ == "__main__":
    main()
