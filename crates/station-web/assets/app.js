// Motus station HMI: vanilla JS, no build step, served by the station itself.
// Live state arrives on the WebSocket /api/ws (20 frames/s); commands go to the JSON API
// with the session cookie and the X-CSRF-Token header.
'use strict';

// Group ids and kinds come from GET /api/groups (the station's cell names them): the HMI
// never names a group itself.
const S = {};
function resetState() {
  Object.assign(S, {
    session: null, ws: null, signals: [], picked: new Set(['x.position', 'y.position']),
    plot: [], axes: [], axisIds: '', groups: [], program: null, frames: 0, lastRateAt: performance.now(),
    slot: null, slots: [], reservations: [], lastFrame: null, jogTimers: {}, alarmKey: null,
    preview: null, exec: { run: 0, next: 0, points: [], busy: false, at: 0 }, overrideBusy: false,
  });
}
resetState();
const PLOT_SECONDS = 10;
const $ = (id) => document.getElementById(id);

function el(tag, attrs, ...kids) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (k === 'on') { for (const [ev, f] of Object.entries(v)) e.addEventListener(ev, f); }
    else if (k === 'text') e.textContent = v;
    else if (v !== undefined && v !== null && v !== false) e.setAttribute(k, v === true ? '' : v);
  }
  for (const k of kids) e.append(k);
  return e;
}

function say(text, isError) {
  const m = $('message');
  m.textContent = text || '';
  m.className = 'message' + (isError ? ' error' : '');
}

// Bumped at every login and logout: the answer to a request of an earlier session is dropped
// (a late 401 must not log out the next user; late data must not fill the emptied panels).
let epoch = 0;

async function api(method, path, body) {
  const mine = epoch;
  const headers = {};
  if (body !== undefined) headers['Content-Type'] = 'application/json';
  if (method !== 'GET' && S.session) headers['X-CSRF-Token'] = S.session.csrf_token;
  const r = await fetch(path, {
    method, headers, credentials: 'same-origin',
    body: body === undefined ? undefined : JSON.stringify(body),
  });
  let data = null;
  try { data = await r.json(); } catch (_) { data = null; }
  if (mine !== epoch) { const e = new Error('the session changed'); e.stale = true; throw e; }
  if (!r.ok) {
    const d = data && data.detail;
    const text = d && typeof d === 'object' ? (d.message || JSON.stringify(d)) : (d || r.statusText);
    const err = new Error(`${r.status} ${(data && data.error) || ''}: ${text}`);
    err.status = r.status; err.data = data;
    if (r.status === 401 && path !== '/api/login') showLogin();
    throw err;
  }
  return data;
}

async function act(label, f) {
  try { const r = await f(); say(label + ': ok'); return r; }
  catch (e) { if (!e.stale) say(label + ': ' + e.message, true); return null; }
}

const fmt = (v, d = 4) => (typeof v === 'number' ? v.toFixed(d) : '-');
const hhmm = (ms) => new Date(ms).toLocaleTimeString([], { hour: '2-digit', minute: '2-digit' });

// ---------- session ----------
// Logged out: only the login form shows; the live stream is closed and every panel emptied,
// so nothing of the previous session stays on the screen.
function showLogin() {
  epoch++;
  stopAllJogs(true);
  const ws = S.ws;
  S.session = null; S.ws = null; // the closing socket's handlers see they are stale
  if (ws) { try { ws.close(); } catch (_) {} }
  clearPanels();
  resetState();
  document.querySelectorAll('[data-session]').forEach((e) => { e.hidden = true; });
  $('login-user').value = ''; $('login-password').value = '';
  $('login-panel').hidden = false;
}

function clearPanels() {
  for (const id of ['axes-rows', 'arm-sliders', 'pantilt-groups', 'alarm-rows', 'reservation-rows', 'slot-list',
    'predicted-rows', 'program-errors', 'task-rows', 'audit-rows', 'user-rows', 'signal-picks', 'camera',
    'juggler-program']) $(id).replaceChildren();
  for (const id of ['station-name', 'mode-note', 'who', 'message', 'slot-status', 'rules-name', 'rules-fp',
    'program-line-text', 'robot-pose', 'robot-group']) $(id).textContent = '';
  $('safe-badge').textContent = 'SafeToRun ?'; $('safe-badge').className = 'badge unknown';
  $('safe-text').textContent = '?'; $('diagnosis').textContent = '-'; $('juggler-current').textContent = '-';
  $('program-state').textContent = 'idle'; $('program-percent').textContent = '0'; $('program-line').textContent = '0';
  $('program-progress').value = 0; $('frame-rate').textContent = '0';
  $('program-feed').textContent = '0';
  for (const id of ['plot', 'scene', 'robot-map', 'program-preview']) { const c = $(id); c.getContext('2d').clearRect(0, 0, c.width, c.height); }
  for (const id of ['robot-panel', 'pantilt-panel', 'arm-panel', 'juggler-box']) $(id).hidden = true;
  // What the previous user typed goes too (their program, the rules draft, a new password).
  for (const id of ['program-name', 'program-text', 'program-file', 'jog-fraction', 'rules-text', 'new-user', 'new-password', 'mdi-line']) {
    const e = $(id); e.value = e.defaultValue || '';
  }
}

async function loadSession() {
  try { S.session = await api('GET', '/api/session'); }
  catch (_) { showLogin(); return; }
  document.querySelectorAll('[data-session]').forEach((e) => { e.hidden = false; });
  $('login-panel').hidden = true;
  $('who').textContent = `${S.session.user} (${S.session.role})`;
  $('station-name').textContent = S.session.station;
  const admin = S.session.role === 'admin';
  document.querySelectorAll('.admin-only').forEach((e) => { e.hidden = !admin; });
  S.slot = S.session.slot; S.slots = S.session.slots || [];
  buildMachinePick();
  applyMode();
  await Promise.all([loadReservations(), loadGroups(), loadCamera(), loadAlarms()]);
  if (admin) { loadAudit(); loadUsers(); }
  connect();
}

// A reservation's resource for people: a machine (group id), or the whole cell.
function resourceName(station) {
  return S.session && station === S.session.station ? 'whole cell' : station;
}

// The slots running now that are mine (the whole cell's or machines').
function mySlots() {
  return S.session ? S.slots.filter((r) => r.user === S.session.user) : [];
}

function canCommand() {
  if (!S.session) return false;
  if (S.session.role === 'admin') return true;
  if (S.session.role !== 'student') return false;
  return mySlots().length > 0;
}

// The booking choice: the whole cell or one machine.
function buildMachinePick() {
  const pick = $('book-machine');
  const was = pick.value;
  pick.replaceChildren(el('option', { value: '', text: 'the whole cell' }),
    ...(S.session.machines || []).map((m) => el('option', { value: m, text: `machine ${m}` })));
  if ([...pick.options].some((o) => o.value === was)) pick.value = was;
  pick.onchange = () => loadReservations();
}

function applyMode() {
  const can = canCommand();
  document.querySelectorAll('button.cmd, input.cmd, #axes-rows button, #axes-rows input, #robot-map, #pantilt-groups input, #arm-sliders input')
    .forEach((b) => { if (b.tagName === 'CANVAS') b.dataset.disabled = can ? '' : '1'; else b.disabled = !can; });
  $('estop-btn').disabled = !S.session || S.session.role === 'viewer';
  const note = $('mode-note');
  if (!S.session) { note.textContent = ''; return; }
  if (can) {
    note.textContent = S.session.role === 'admin' ? 'Admin: full control'
      : `Your slot: you have control of ${mySlots().map((r) => resourceName(r.station)).join(', ')}`;
    note.className = '';
  } else {
    const why = S.session.role === 'viewer' ? 'viewer role'
      : S.slot ? `slot held by ${S.slot.user}` : 'no slot of yours now: book a machine below';
    note.textContent = `Read-only (${why})`; note.className = 'readonly-note';
  }
  const st = $('slot-status');
  st.textContent = S.slots.length
    ? `Slots running: ${S.slots.map((r) => `${resourceName(r.station)} by ${r.user} until ${hhmm(r.end)}`).join('; ')}`
    : 'No slot running now';
}

// ---------- reservations ----------
async function loadReservations() {
  try { S.reservations = await api('GET', '/api/reservations'); } catch (_) { return; }
  const rows = $('reservation-rows'); rows.replaceChildren();
  for (const r of S.reservations) {
    const mine = S.session && (r.user === S.session.user || S.session.role === 'admin');
    rows.append(el('tr', { 'data-testid': `reservation-${r.id}` },
      el('td', { text: r.id }), el('td', { text: resourceName(r.station) }), el('td', { text: r.user }), el('td', { text: new Date(r.start).toLocaleString() }),
      el('td', { text: hhmm(r.end) }),
      el('td', {}, mine && Date.now() < r.end ? el('button', { text: 'Cancel', 'data-testid': `cancel-${r.id}`,
        on: { click: () => act('Cancel', () => api('DELETE', `/api/reservations/${r.id}`)).then(refreshSlot) } }) : '')));
  }
  // The machine's line: join it when the machine is busy now; it is yours as soon as it frees.
  let queues = {}; try { queues = await api('GET', '/api/queues'); } catch (_) { /* shown empty */ }
  const picked = $('book-machine').value;
  const line = (picked && queues[picked]) || [];
  const place = line.findIndex((w) => S.session && w.user === S.session.user);
  const busy = picked && S.slots.some((r) => r.station === picked || r.station === S.session.station);
  const join = $('queue-join');
  join.hidden = !picked || !busy || place >= 0 || !S.session || S.session.role === 'viewer';
  join.textContent = `Join the line for ${picked}`;
  join.onclick = () => act('Join the line', () => api('POST', `/api/machines/${encodeURIComponent(picked)}/queue`)).then(refreshSlot);
  $('queue-status').textContent = place >= 0 ? `You are number ${place + 1} in the line for ${picked}: it is yours as soon as it is free.`
    : line.length ? `${line.length} waiting for ${picked}.` : '';
  const list = $('slot-list'); list.replaceChildren();
  const now = Date.now(); const half = 30 * 60 * 1000;
  const slots = [[now, Math.ceil((now + half) / half) * half]];
  for (let i = 0; i < 8; i++) { const s = slots[slots.length - 1][1]; slots.push([s, s + half]); }
  // A machine's slot is taken by its own bookings and the whole cell's; the whole cell's by any.
  const machine = $('book-machine').value;
  const clashes = (r) => !machine || r.station === machine || r.station === S.session.station;
  slots.forEach(([a, b], i) => {
    const taken = S.reservations.find((r) => r.start < b && a < r.end && clashes(r));
    const label = i === 0 ? `Now - ${hhmm(b)}` : `${hhmm(a)} - ${hhmm(b)}`;
    list.append(el('li', {}, el('button', {
      text: taken ? `${label} (${taken.user})` : label, class: taken ? 'taken' : '', 'data-testid': `book-slot-${i}`,
      disabled: !!taken || !S.session || S.session.role === 'viewer',
      on: { click: () => act('Book', () => api('POST', '/api/reservations',
        machine ? { start: a, end: b, machine } : { start: a, end: b })).then(refreshSlot) },
    })));
  });
}

async function refreshSlot() {
  try { S.session = await api('GET', '/api/session'); S.slot = S.session.slot; S.slots = S.session.slots || []; } catch (_) { return; }
  applyMode(); loadReservations();
}

// ---------- axes ----------
function buildAxes(axes) {
  const rows = $('axes-rows'); rows.replaceChildren();
  for (const a of axes) {
    const jogBtn = (dir, label) => {
      const b = el('button', { text: label, 'data-testid': `jog-${dir > 0 ? 'plus' : 'minus'}-${a.id}` });
      const start = (ev) => { ev.preventDefault(); startJog(a.id, dir); };
      b.addEventListener('pointerdown', start);
      for (const ev of ['pointerup', 'pointerleave', 'pointercancel']) b.addEventListener(ev, () => stopJog(a.id));
      return b;
    };
    const target = el('input', { type: 'number', step: 'any', value: '0', 'data-testid': `move-target-${a.id}`, id: `move-target-${a.id}` });
    rows.append(el('tr', { 'data-testid': `axis-${a.id}` },
      el('td', { text: `${a.name} [${a.unit}]` }), el('td', { text: a.device, class: 'small' }),
      el('td', { class: 'num', id: `pos-${a.id}`, 'data-testid': `axis-pos-${a.id}` }),
      el('td', { class: 'num', id: `vel-${a.id}`, 'data-testid': `axis-vel-${a.id}`, 'data-group': a.group || '' }),
      el('td', { id: `state-${a.id}`, 'data-testid': `axis-state-${a.id}` }),
      el('td', { id: `fault-${a.id}`, class: 'error' }),
      el('td', {}, jogBtn(-1, '-'), ' ', jogBtn(1, '+')),
      el('td', {}, target, el('button', { text: 'Go', 'data-testid': `move-go-${a.id}`,
        on: { click: () => act(`Move ${a.id}`, () => api('POST', `/api/axes/${a.id}/move`,
          { target: Number(target.value), speed: a.default_speed })) } })),
      el('td', {}, el('button', { text: 'Home', 'data-testid': `home-${a.id}`, on: { click: () => act(`Home ${a.id}`, () => api('POST', `/api/axes/${a.id}/home`)) } }),
        el('button', { text: 'Stop', 'data-testid': `stop-${a.id}`, on: { click: () => act(`Stop ${a.id}`, () => api('POST', `/api/axes/${a.id}/stop`)) } }))));
  }
  buildArm(axes);
  applyMode();
}

function jogOnce(id, dir) {
  const a = S.axes.find((x) => x.id === id); if (!a) return Promise.resolve();
  const f = Math.min(1, Math.max(0.05, Number($('jog-fraction').value) || 0.5));
  return api('POST', `/api/axes/${id}/jog`, { direction: dir, speed: a.limits.max_speed * f })
    .catch((e) => { if (e.stale) return; say(`Jog ${id}: ${e.message}`, true); stopJog(id, true); });
}
function startJog(id, dir) {
  stopJog(id, true);
  jogOnce(id, dir);
  S.jogTimers[id] = setInterval(() => jogOnce(id, dir), 200); // dead-man: repeat within 0.5 s
}
function stopJog(id, quiet) {
  if (S.jogTimers[id]) {
    clearInterval(S.jogTimers[id]); delete S.jogTimers[id];
    if (!quiet) api('POST', `/api/axes/${id}/stop`).catch(() => {});
  }
}
// Releasing the button is not the only way a hold ends: the window loses focus, the tab is
// hidden, the user logs out. The station stops a jog that is not renewed anyway (dead-man).
function stopAllJogs(quiet) { for (const id of Object.keys(S.jogTimers || {})) stopJog(id, quiet); }

function renderAxes(axes) {
  S.axes = axes;
  const ids = axes.map((a) => a.id).join(',');
  if (ids !== S.axisIds) { S.axisIds = ids; buildAxes(axes); }
  for (const a of axes) {
    $(`pos-${a.id}`).textContent = fmt(a.position);
    $(`vel-${a.id}`).textContent = fmt(a.velocity);
    $(`state-${a.id}`).textContent = [a.enabled ? 'on' : 'off', a.homed ? 'homed' : 'not homed', a.moving ? 'moving' : 'stopped'].join(', ');
    $(`fault-${a.id}`).textContent = a.fault || '';
  }
}

// ---------- safety ----------
function renderSafety(s) {
  const badge = $('safe-badge');
  badge.textContent = s.safe_to_run ? 'SafeToRun' : (s.estop ? 'E-STOP' : 'NOT SAFE');
  badge.className = 'badge ' + (s.safe_to_run ? 'ok' : 'bad');
  $('safe-text').textContent = s.safe_to_run ? 'true' : `false${s.held ? ' (held)' : ''}${s.estop ? ' (E-stop)' : ''}`;
  $('diagnosis').textContent = s.diagnosis || '-';
  $('rules-name').textContent = s.rules_name; $('rules-fp').textContent = s.rules_fingerprint;
  const rows = $('predicted-rows'); rows.replaceChildren();
  for (const p of s.predicted) rows.append(el('tr', {}, el('td', { text: p.axis }), el('td', { class: 'num', text: fmt(p.stop_position) }), el('td', { class: 'num', text: fmt(p.distance) })));
}

// ---------- program ----------
function renderProgram(p) {
  $('program-state').textContent = p.state + (p.message ? ` (${p.message})` : '');
  $('program-progress').value = p.progress;
  $('program-percent').textContent = Math.round(p.progress * 100);
  $('program-line').textContent = p.line;
  $('program-line-text').textContent = p.line_text;
  $('program-feed').textContent = Math.round(p.feed);
  // The station's settings, unless the user is changing them right now.
  if (!S.overrideBusy && document.activeElement !== $('program-override')) {
    $('program-override').value = p.override_percent; $('program-override-value').textContent = Math.round(p.override_percent);
  }
  // The station's single-block setting, unless the user's change has not reached it yet
  // (a status fetched before the change would undo the click).
  const wanted = S.singleBlockWanted;
  if (wanted && (p.single_block === wanted.on || Date.now() > wanted.until)) S.singleBlockWanted = null;
  if (!S.singleBlockWanted) $('program-single-block').checked = p.single_block;
  pollExecuted(p);
}

// The executed path, fetched by cursor while a program runs (and once after it ended).
async function pollExecuted(p) {
  const active = ['running', 'held', 'block_stop'].includes(p.state);
  const now = performance.now();
  if (S.exec.busy || (!active && S.exec.settled) || now - S.exec.at < 200) return;
  S.exec.busy = true; S.exec.at = now;
  try {
    const b = await api('GET', `/api/programs/path?run=${S.exec.run}&cursor=${S.exec.next}`);
    if (b.run !== S.exec.run) S.exec.points = [];
    S.exec.run = b.run; S.exec.next = b.next; S.exec.points.push(...b.points);
    S.exec.settled = !active && b.points.length === 0;
    drawPreview(p.xyz);
  } catch (_) { /* the next frame asks again */ } finally { S.exec.busy = false; }
}

async function loadPreview(id) {
  try { S.preview = (await api('GET', `/api/programs/${id}/preview`)).points; } catch (e) { S.preview = null; say(e.message, true); }
  drawPreview(null);
}

// Top view (X right, Y up) of the checked program and of the executed path, scaled to fit.
function drawPreview(tool) {
  const c = $('program-preview'); const g = c.getContext('2d');
  g.clearRect(0, 0, c.width, c.height);
  const prev = S.preview || []; const done = S.exec.points;
  c.dataset.points = prev.length; c.dataset.executed = done.length;
  const all = prev.concat(done); if (!all.length) return;
  let [x0, y0, x1, y1] = [Infinity, Infinity, -Infinity, -Infinity];
  for (const [x, y] of all) { x0 = Math.min(x0, x); y0 = Math.min(y0, y); x1 = Math.max(x1, x); y1 = Math.max(y1, y); }
  const k = Math.min((c.width - 20) / Math.max(x1 - x0, 1e-3), (c.height - 20) / Math.max(y1 - y0, 1e-3));
  const X = (x) => 10 + (x - x0) * k, Y = (y) => c.height - 10 - (y - y0) * k;
  const line = (pts, color, width) => {
    g.strokeStyle = color; g.lineWidth = width; g.beginPath();
    pts.forEach(([x, y], i) => (i ? g.lineTo(X(x), Y(y)) : g.moveTo(X(x), Y(y)))); g.stroke();
  };
  line(prev, '#999', 1); line(done, '#d62728', 2);
  if (tool) { g.fillStyle = '#1f77b4'; g.fillRect(X(tool[0]) - 3, Y(tool[1]) - 3, 6, 6); }
}

function showCheck(check) {
  const ul = $('program-errors'); ul.replaceChildren();
  for (const e of check.errors) ul.append(el('li', { text: `${e.line}:${e.col}: ${e.message}` }));
  if (!check.errors.length) ul.append(el('li', { text: 'check: no errors', class: 'ok' }));
}

// ---------- plot ----------
function buildPicks() {
  const box = $('signal-picks'); box.replaceChildren();
  // The station's signals, not names the HMI guesses: the first two when none picked is there.
  if (!S.signals.some((s) => S.picked.has(s.id))) S.picked = new Set(S.signals.slice(0, 2).map((s) => s.id));
  for (const s of S.signals) {
    const cb = el('input', { type: 'checkbox', 'data-testid': `pick-${s.id}` });
    cb.checked = S.picked.has(s.id);
    cb.addEventListener('change', () => { if (cb.checked) S.picked.add(s.id); else S.picked.delete(s.id); });
    box.append(el('label', { class: 'small' }, cb, ` ${s.id}`));
  }
}

const COLORS = ['#1f77b4', '#d62728', '#2ca02c', '#ff7f0e', '#9467bd', '#8c564b', '#e377c2', '#17becf'];
function drawPlot() {
  const c = $('plot'); const g = c.getContext('2d');
  g.clearRect(0, 0, c.width, c.height);
  if (!S.plot.length) return;
  const tEnd = S.plot[S.plot.length - 1].t; const tStart = tEnd - PLOT_SECONDS;
  const idx = S.signals.map((s, i) => [s.id, i]).filter(([id]) => S.picked.has(id));
  let lo = Infinity, hi = -Infinity;
  for (const smp of S.plot) for (const [, i] of idx) { const v = smp.values[i]; if (v === null || v === undefined) continue; if (v < lo) lo = v; if (v > hi) hi = v; }
  if (!isFinite(lo)) return;
  if (hi - lo < 1e-6) { hi += 0.5; lo -= 0.5; }
  const X = (t) => ((t - tStart) / PLOT_SECONDS) * (c.width - 50) + 45;
  const Y = (v) => c.height - 10 - ((v - lo) / (hi - lo)) * (c.height - 20);
  g.fillStyle = '#555'; g.font = '11px sans-serif';
  g.fillText(hi.toFixed(3), 2, 12); g.fillText(lo.toFixed(3), 2, c.height - 4);
  idx.forEach(([id, i], k) => {
    g.strokeStyle = COLORS[k % COLORS.length]; g.beginPath();
    let gap = true; // no value yet (null): the line starts again after it
    S.plot.forEach((smp) => {
      const v = smp.values[i]; if (v === null || v === undefined) { gap = true; return; }
      const x = X(smp.t), y = Y(v); if (gap) g.moveTo(x, y); else g.lineTo(x, y); gap = false;
    });
    g.stroke(); g.fillStyle = g.strokeStyle; g.fillText(id, 60 + k * 120, 12);
  });
}

// ---------- scene & robot ----------
function drawScene(sc) {
  const c = $('scene'); const g = c.getContext('2d');
  g.clearRect(0, 0, c.width, c.height); g.lineWidth = 2; g.font = '12px sans-serif'; g.fillStyle = '#333';
  if (sc.gantry) { // top view 200x160 at (10,20), z bar beside it
    const [[x, y, z], [xm, ym, zm]] = sc.gantry; const W = 180, H = 150, ox = 10, oy = 25;
    g.fillText('gantry (top view)', ox, 15); g.strokeStyle = '#888'; g.strokeRect(ox, oy, W, H);
    const px = ox + (x / xm) * W, py = oy + H - (y / ym) * H;
    g.strokeStyle = '#1f77b4'; g.beginPath(); g.moveTo(px, oy); g.lineTo(px, oy + H); g.stroke();
    g.fillStyle = '#d62728'; g.fillRect(px - 5, py - 5, 10, 10);
    g.strokeStyle = '#888'; g.strokeRect(ox + W + 8, oy, 10, H); g.fillStyle = '#2ca02c';
    g.fillRect(ox + W + 8, oy, 10, (z / zm) * H); g.fillStyle = '#333';
  }
  if (sc.pan_tilt) { // pan as a pointer, tilt as its length
    const [pan, tilt] = sc.pan_tilt; const cx = 280, cy = 100, r = 50;
    g.fillText('pan-tilt', 250, 15); g.strokeStyle = '#888'; g.beginPath(); g.arc(cx, cy, r, 0, 2 * Math.PI); g.stroke();
    const len = r * (0.4 + 0.6 * Math.cos(tilt));
    g.strokeStyle = '#ff7f0e'; g.beginPath(); g.moveTo(cx, cy); g.lineTo(cx + len * Math.sin(pan), cy - len * Math.cos(pan)); g.stroke();
  }
  if (sc.arm) { // planar chain from the base
    const [q, L] = sc.arm; let x = 450, y = 260, a = -Math.PI / 2; const k = 300;
    g.fillStyle = '#333'; g.fillText('arm', 430, 15); g.strokeStyle = '#9467bd'; g.beginPath(); g.moveTo(x, y);
    q.forEach((qi, i) => { a += qi; x += Math.cos(a) * L[i] * k; y += Math.sin(a) * L[i] * k; g.lineTo(x, y); });
    g.stroke(); g.fillRect(x - 3, y - 3, 6, 6);
  }
  if (sc.robot) {
    const [rx, ry, th] = sc.robot.pose;
    g.fillStyle = '#333'; g.fillText(`robot x=${rx.toFixed(2)} y=${ry.toFixed(2)} th=${th.toFixed(2)}`, 10, 200 + 90);
  }
  for (const [id, p, lo, hi] of sc.juggler || []) g.fillText(`${id}: ${fmt(p)} [${lo}, ${hi}]`, 220, 200);
}

function robotFrame() {
  const c = $('robot-map'); const b = (S.lastFrame && S.lastFrame.scene.robot && S.lastFrame.scene.robot.bounds) || [-2, -1.5, 2, 1.5];
  const sx = c.width / (b[2] - b[0]), sy = c.height / (b[3] - b[1]); const s = Math.min(sx, sy);
  return { c, b, s, X: (x) => (x - b[0]) * s, Y: (y) => c.height - (y - b[1]) * s };
}

function drawRobot(r) {
  const { c, X, Y, s } = robotFrame(); const g = c.getContext('2d');
  g.clearRect(0, 0, c.width, c.height);
  g.strokeStyle = '#ddd'; for (let i = -2; i <= 2; i++) { g.beginPath(); g.moveTo(X(i), 0); g.lineTo(X(i), c.height); g.stroke(); g.beginPath(); g.moveTo(0, Y(i)); g.lineTo(c.width, Y(i)); g.stroke(); }
  g.strokeStyle = '#1f77b4'; g.beginPath(); r.path.forEach(([x, y], i) => { if (i) g.lineTo(X(x), Y(y)); else g.moveTo(X(x), Y(y)); }); g.stroke();
  if (r.target) { g.strokeStyle = '#2ca02c'; g.beginPath(); g.arc(X(r.target[0]), Y(r.target[1]), 6, 0, 2 * Math.PI); g.stroke(); }
  const [x, y, th] = r.pose; const R = 0.15 * s;
  g.fillStyle = '#d62728'; g.beginPath();
  for (let k = 0; k < 3; k++) { const a = th + k * 2 * Math.PI / 3; const rr = k ? R * 0.6 : R; g.lineTo(X(x) + rr * Math.cos(a), Y(y) - rr * Math.sin(a)); }
  g.closePath(); g.fill();
  $('robot-pose').textContent = `x=${x.toFixed(3)} m, y=${y.toFixed(3)} m, theta=${th.toFixed(3)} rad`;
}

function robotClick(ev) {
  const g = groupsOfKind('robot')[0]; if (!g) return;
  const { c, b, s } = robotFrame();
  if (c.dataset.disabled === '1') { say('Read-only: no slot of yours', true); return; }
  const rect = c.getBoundingClientRect();
  const px = (ev.clientX - rect.left) * (c.width / rect.width), py = (ev.clientY - rect.top) * (c.height / rect.height);
  const x = px / s + b[0], y = (c.height - py) / s + b[1];
  const robot = S.lastFrame && S.lastFrame.scene && S.lastFrame.scene.robot;
  const th = robot ? robot.pose[2] : 0;
  act(`Robot ${g.id} go-to`, () => api('POST', `/api/groups/${encodeURIComponent(g.id)}`, { action: 'go_to', targets: [x, y, th] }));
}

// ---------- groups (robot, pan-tilt, arm, juggler), as the station names them ----------
const groupsOfKind = (kind) => S.groups.filter((g) => g.kind === kind);

async function loadGroups() {
  try { S.groups = await api('GET', '/api/groups'); } catch (_) { S.groups = []; }
  const robot = groupsOfKind('robot')[0];
  $('robot-panel').hidden = !robot; $('robot-group').textContent = robot ? robot.id : '';
  buildPanTilt(); buildJuggler(); buildArm(S.axes);
}

// One target row per pan-tilt group: one input per member axis, in the group's order.
function buildPanTilt() {
  const box = $('pantilt-groups'); box.replaceChildren();
  const groups = groupsOfKind('pan_tilt'); $('pantilt-panel').hidden = !groups.length;
  for (const g of groups) {
    const inputs = g.axes.map((id, i) => el('input', { type: 'number', step: '0.1', value: i === 0 ? '0.5' : '0.2',
      id: `pantilt-target-${id}`, 'data-testid': `pantilt-target-${id}` }));
    box.append(el('fieldset', { class: 'group-box', 'data-testid': `pantilt-${g.id}` }, el('legend', { text: g.id }),
      ...g.axes.map((id, i) => el('label', { text: `${id} (rad) ` }, inputs[i])),
      el('button', { text: 'Go', class: 'cmd', 'data-testid': `pantilt-go-${g.id}`, on: { click: () => act(`Pan-tilt ${g.id}`,
        () => api('POST', `/api/groups/${encodeURIComponent(g.id)}`, { action: 'go_to', targets: inputs.map((x) => Number(x.value)) })) } })));
  }
  applyMode();
}

// The juggler's programs (a student's program is guarded by the supervisor like any motion).
function buildJuggler() {
  const g = S.groups.find((x) => x.programs && x.programs.length); $('juggler-box').hidden = !g;
  if (!g) return;
  const sel = $('juggler-program'); const keep = sel.value; sel.replaceChildren();
  for (const p of g.programs) sel.append(el('option', { value: p, text: p }));
  if (g.programs.includes(keep)) sel.value = keep;
  $('juggler-current').textContent = g.program || '-';
}

// One slider per joint of each arm group, and its "Move joints" button.
function buildArm(axes) {
  const box = $('arm-sliders'); box.replaceChildren();
  const groups = groupsOfKind('arm'); $('arm-panel').hidden = !groups.length;
  for (const g of groups) {
    const sliders = [];
    const rows = [];
    for (const id of g.axes) {
      const a = (axes || []).find((x) => x.id === id); if (!a) continue;
      const out = el('span', { text: fmt(a.position, 2), 'data-testid': `arm-value-${id}` });
      const r = el('input', { type: 'range', min: a.limits.min, max: a.limits.max, step: '0.01', value: a.position, id: `arm-${id}`, 'data-testid': `arm-${id}` });
      r.addEventListener('input', () => { out.textContent = Number(r.value).toFixed(2); });
      sliders.push(r);
      rows.push(el('div', {}, el('label', { text: `${id} ` }), r, ' ', out));
    }
    if (sliders.length !== g.axes.length) continue; // axes not known yet: built again with them
    box.append(el('fieldset', { class: 'group-box', 'data-testid': `arm-group-${g.id}` }, el('legend', { text: g.id }), ...rows,
      el('button', { text: 'Move joints', class: 'cmd', 'data-testid': `arm-go-${g.id}`, on: { click: () => act(`Arm ${g.id}`,
        () => api('POST', `/api/groups/${encodeURIComponent(g.id)}`, { action: 'go_to', targets: sliders.map((x) => Number(x.value)) })) } })));
  }
  applyMode();
}

// ---------- cyclic tasks ----------
async function loadTasks() {
  if (!S.session) return;
  let tasks = [];
  try { tasks = await api('GET', '/api/tasks'); } catch (_) { return; }
  const rows = $('task-rows'); rows.replaceChildren();
  for (const t of tasks) {
    rows.append(el('tr', {}, el('td', { text: t.name }), el('td', { class: 'num', text: `${t.period_us / 1000} ms` }),
      el('td', { text: t.state, class: t.state === 'running' ? '' : 'error' }),
      el('td', { class: 'num', text: t.lateness_us.join(' / ') }), el('td', { class: 'num', text: t.overruns }),
      el('td', { class: 'num', text: t.cpu_percent.toFixed(1) })));
  }
}

// ---------- alarms, audit, users, camera ----------
// The list arrives in every frame (20/s) but is redrawn only when an alarm came, went, was
// cleared or acknowledged: a button rebuilt under the pointer between press and release
// would never receive its click. The Ack click is delegated to the table (wire()).
function renderAlarms(list) {
  list = list || [];
  const key = JSON.stringify(list.map((a) => [a.id, a.cleared_at, a.acknowledged ? a.acknowledged.by : null]))
    + (S.session ? S.session.role : '');
  if (key === S.alarmKey) return;
  S.alarmKey = key;
  const rows = $('alarm-rows'); rows.replaceChildren();
  for (const a of list) {
    rows.append(el('tr', { 'data-testid': `alarm-${a.code}`, 'data-alarm-id': a.id }, el('td', { text: hhmm(a.raised_at) }), el('td', { text: a.code }),
      el('td', { text: a.source }), el('td', { text: a.message + (a.cleared_at ? ' (cleared)' : '') }),
      el('td', {}, a.acknowledged ? `ack ${a.acknowledged.by}` : el('button', { text: 'Ack', 'data-testid': `ack-${a.id}`,
        'data-ack': a.id, disabled: !S.session || S.session.role === 'viewer' }))));
  }
}
async function loadAlarms() { try { renderAlarms((await api('GET', '/api/alarms')).active); } catch (_) {} }

async function loadAudit() {
  let list; try { list = await api('GET', '/api/audit?limit=100'); } catch (_) { return; }
  const rows = $('audit-rows'); rows.replaceChildren();
  for (const { entry: e } of list) {
    rows.append(el('tr', {}, el('td', { text: new Date(e.time).toLocaleTimeString() }), el('td', { text: e.user }),
      el('td', { text: e.action }), el('td', { text: e.target }),
      el('td', { text: e.outcome.result + (e.outcome.message ? `: ${e.outcome.message}` : ''), class: e.outcome.result === 'ok' ? '' : 'error' })));
  }
}

async function loadUsers() {
  let list; try { list = await api('GET', '/api/users'); } catch (_) { return; }
  const rows = $('user-rows'); rows.replaceChildren();
  for (const u of list) {
    rows.append(el('tr', {}, el('td', { text: u.name }), el('td', { text: u.role }), el('td', {},
      el('button', { text: 'End session', on: { click: () => act(`End session of ${u.name}`, () => api('POST', `/api/sessions/${encodeURIComponent(u.name)}/end`)).then(loadReservations) } }),
      el('button', { text: 'Delete', on: { click: () => act(`Delete ${u.name}`, () => api('DELETE', `/api/users/${encodeURIComponent(u.name)}`)).then(loadUsers) } }))));
  }
}

async function loadCamera() {
  let r, groups;
  try { r = await api('GET', '/api/camera'); groups = await api('GET', '/api/groups'); } catch (_) { return; }
  const box = $('camera'); box.replaceChildren();
  // The machines' cameras, relayed by the station (no route to the cameras needed; a stream
  // ends with the session). One live picture at a time, and only when asked for: a browser
  // keeps six connections per station, and every picture costs the station and the browser.
  const cams = groups.filter(g => g.camera);
  if (cams.length) {
    const img = el('img', { alt: 'machine camera', 'data-testid': 'camera-view', hidden: true });
    const caption = el('figcaption', { class: 'small', text: 'Pick a machine to watch it live.' });
    const mark = (id) => { for (const b of picks.children) b.setAttribute('aria-pressed', String(b.dataset.group === id)); };
    const show = (g) => {
      img.hidden = false;
      img.src = `/api/groups/${encodeURIComponent(g.id)}/camera.mjpg`;
      caption.textContent = `Camera of ${g.id} (${g.kind}), live through the station`;
      mark(g.id);
    };
    const off = () => { img.removeAttribute('src'); img.hidden = true; caption.textContent = 'Camera off.'; mark(null); };
    const picks = el('div', { class: 'camera-picks' }, ...cams.map(g =>
      el('button', { text: g.id, 'data-group': g.id, 'data-testid': `camera-pick-${g.id}`, on: { click: () => show(g) } })),
      el('button', { text: 'Camera off', 'data-testid': 'camera-off', on: { click: off } }));
    box.append(picks, el('figure', { class: 'camera' }, img, caption));
  }
  if (r.url) {
    const isImg = /\.(jpe?g|png|mjpe?g|gif)(\?|$)|mjpg|snapshot/i.test(r.url);
    box.append(isImg ? el('img', { src: r.url, alt: 'camera', 'data-testid': 'camera-external' }) : el('iframe', { src: r.url, title: 'camera', 'data-testid': 'camera-external' }));
  } else if (!cams.length) box.append(el('p', { class: 'small', text: 'No camera configured; the live view above shows the simulated machines.' }));
}

// ---------- WebSocket ----------
function connect() {
  if (S.ws || !S.session) return;
  const ws = new WebSocket(`${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/api/ws`);
  S.ws = ws;
  ws.onmessage = (ev) => {
    if (S.ws !== ws) return; // a frame of a closed (logged-out) stream
    const f = JSON.parse(ev.data);
    if (f.type === 'hello') { S.signals = f.signals; buildPicks(); return; }
    if (f.type === 'logout') { say('Session ended', true); showLogin(); return; }
    if (f.type !== 'state') return;
    S.lastFrame = f; S.frames++;
    renderAxes(f.axes); renderSafety(f.safety); renderProgram(f.program); renderAlarms(f.alarms);
    const key = (l) => (l || []).map((r) => `${r.id}:${r.user}`).join(',');
    const changed = key(f.slots) !== key(S.slots);
    S.slot = f.slot || null; S.slots = f.slots || [];
    if (changed) { applyMode(); loadReservations(); }
    for (const s of f.samples) S.plot.push(s);
    if (S.plot.length) { const t0 = S.plot[S.plot.length - 1].t - PLOT_SECONDS; let i = 0; while (i < S.plot.length && S.plot[i].t < t0) i++; if (i) S.plot.splice(0, i); }
    drawPlot(); drawScene(f.scene); if (f.scene.robot) drawRobot(f.scene.robot);
    const now = performance.now();
    if (now - S.lastRateAt >= 1000) { $('frame-rate').textContent = (S.frames * 1000 / (now - S.lastRateAt)).toFixed(1); S.frames = 0; S.lastRateAt = now; }
  };
  ws.onclose = () => { if (S.ws !== ws) return; S.ws = null; if (S.session) setTimeout(connect, 1000); };
}

// ---------- wiring ----------
function wire() {
  $('login-form').addEventListener('submit', async (ev) => {
    ev.preventDefault(); $('login-error').textContent = '';
    epoch++;
    try {
      const r = await api('POST', '/api/login', { user: $('login-user').value, password: $('login-password').value });
      S.session = { csrf_token: r.csrf_token }; $('login-password').value = '';
      await loadSession();
    } catch (e) { $('login-error').textContent = e.message; }
  });
  $('logout-btn').addEventListener('click', async () => {
    stopAllJogs(false);
    try { await api('POST', '/api/logout'); } catch (_) { /* the session is gone either way */ }
    showLogin();
  });
  window.addEventListener('blur', () => stopAllJogs(false));
  document.addEventListener('visibilitychange', () => { if (document.hidden) stopAllJogs(false); });
  $('alarm-rows').addEventListener('click', (ev) => {
    const b = ev.target.closest('button[data-ack]'); if (!b || b.disabled) return;
    act('Acknowledge', () => api('POST', `/api/alarms/${b.dataset.ack}/ack`)).then(loadAlarms);
  });
  $('estop-btn').addEventListener('click', () => act('E-STOP', () => api('POST', '/api/estop')));
  $('reset-btn').addEventListener('click', () => act('Reset', () => api('POST', '/api/reset')));
  $('program-file').addEventListener('change', async (ev) => {
    const f = ev.target.files[0]; if (!f) return;
    $('program-text').value = await f.text(); $('program-name').value = f.name;
  });
  $('program-upload').addEventListener('click', async () => {
    const r = await act('Upload', () => api('POST', '/api/programs', { name: $('program-name').value, text: $('program-text').value }));
    if (r) { S.program = r.program.id; showCheck(r.check); loadPreview(S.program); }
  });
  $('program-override').addEventListener('input', () => { $('program-override-value').textContent = $('program-override').value; });
  $('program-override').addEventListener('change', async () => {
    S.overrideBusy = true;
    try { await act('Override', () => api('POST', '/api/programs/override', { percent: Number($('program-override').value) })); }
    finally { S.overrideBusy = false; }
  });
  $('program-single-block').addEventListener('change', () => {
    const on = $('program-single-block').checked;
    S.singleBlockWanted = { on, until: Date.now() + 3000 };
    // Refused (act says why): the next status shows the station's setting again.
    act('Single block', () => api('POST', '/api/programs/single-block', { on }))
      .then((r) => { if (r === null) S.singleBlockWanted = null; });
  });
  $('mdi-run').addEventListener('click', () => {
    S.exec.settled = false;
    act('MDI', () => api('POST', '/api/mdi', { line: $('mdi-line').value })).catch(() => {});
  });
  $('program-run').addEventListener('click', () => {
    if (!S.program) { say('Upload a program first', true); return; }
    S.exec.settled = false;
    act('Run', () => api('POST', `/api/programs/${S.program}/run`)).catch(() => {});
  });
  $('program-hold').addEventListener('click', () => act('Hold', () => api('POST', '/api/programs/hold')));
  $('program-resume').addEventListener('click', () => act('Resume', () => api('POST', '/api/programs/resume')));
  $('program-stop').addEventListener('click', () => act('Stop', () => api('POST', '/api/programs/stop')));
  $('robot-map').addEventListener('click', robotClick);
  $('juggler-run').addEventListener('click', async () => {
    const g = S.groups.find((x) => x.programs && x.programs.length); if (!g) return;
    await act('Juggler program', () => api('POST', `/api/groups/${g.id}`, { action: 'run', program: $('juggler-program').value }));
    await loadGroups();
  });
  $('rules-upload').addEventListener('click', () => act('Rules', () => api('PUT', '/api/safety/rules', { toml: $('rules-text').value })));
  $('audit-refresh').addEventListener('click', loadAudit);
  $('user-form').addEventListener('submit', (ev) => {
    ev.preventDefault();
    act('Add user', () => api('POST', '/api/users', { name: $('new-user').value, password: $('new-password').value, role: $('new-role').value }))
      .then((r) => { if (r) { $('new-user').value = ''; $('new-password').value = ''; } loadUsers(); });
  });
  setInterval(() => { if (S.session && S.session.role === 'admin') loadAudit(); }, 5000);
  setInterval(loadTasks, 2000);
}

wire();
loadSession();
