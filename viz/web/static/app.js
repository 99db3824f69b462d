// posed live view: draws what the robot's Zenoh topics carry (poses, status, fall events). Written for
// posed; no library, nothing fetched from a network. State for tests and curious users: window.posedView.
"use strict";

const TOKEN = new URLSearchParams(location.search).get("token");
const withToken = (url) => TOKEN ? url + (url.includes("?") ? "&" : "?") + "token=" + encodeURIComponent(TOKEN) : url;

const BONES = [ // [from, to, side] between the fitted joints (camera axes, metres, mid-hip origin)
  ["left_shoulder", "right_shoulder", "c"], ["left_hip", "right_hip", "c"], ["mid_hip", "mid_shoulder", "c"],
  ["left_shoulder", "left_elbow", "l"], ["left_elbow", "left_wrist", "l"],
  ["right_shoulder", "right_elbow", "r"], ["right_elbow", "right_wrist", "r"],
  ["left_hip", "left_knee", "l"], ["left_knee", "left_ankle", "l"],
  ["right_hip", "right_knee", "r"], ["right_knee", "right_ankle", "r"]];
const SIDE_COLOUR = {l: "#ff8c00", r: "#00a0ff", c: "#3cdc3c"};
const CHART = [ // [angle, colour, dash]
  ["theta_hp_l", "#1f5fa8", []], ["theta_hp_r", "#1f5fa8", [7, 5]],
  ["theta_kn_l", "#7b3294", []], ["theta_kn_r", "#7b3294", [7, 5]], ["theta_tr", "#333333", [2, 3]]];
// the words for a fall's states: the server's (viz.series.STATE_WORDS, the same as the report and the plots)
let STATE_WORDS = {falling: "fall", on_floor: "on the floor", alarm: "ALARM", recovered: "got up"};
const ANKLE_HEIGHT = 0.08, WINDOW_S = 60, GAP_S = 3;

const view = window.posedView = {
  connected: false, poses: 0, drawn: 0, lastPose: null, status: null, fpsText: "",
  events: {}, acked: {}, history: [], labels: {}, yaw: -35, pitch: 20, zoom: 1.0, lastGood: null, floorNote: "",
  showAllEvents: false, showAllHistory: false, robotState: null, streamLost: null, stale: false, paused: null,
  // posed web '*': a card per robot; the robot whose live parts are shown, and why (its card was clicked: "hash";
  // "default"); which robots' poses were drawn since it was chosen
  cards: {}, unlisted: 0, maxRobots: 0, selected: null, selectedBy: null, poseRobots: {}};
const angleLog = []; // {time_unix, angles}
Object.defineProperty(view, "angleSamples", {get: () => angleLog.length});   // for tests: the chart's samples

// ------------------------------------------------------------------ 3D skeleton
const sk = document.getElementById("skeleton"), g = sk.getContext("2d");

function fitCanvas(cv, ctx, heightOf) {  // draw at the width the canvas is shown at (a phone too), sharp on HiDPI
  const dpr = window.devicePixelRatio || 1, w = Math.max(240, Math.round(cv.clientWidth || 640)), h = heightOf(w);
  if (cv.width !== Math.round(w * dpr) || cv.height !== Math.round(h * dpr)) {
    cv.width = Math.round(w * dpr); cv.height = Math.round(h * dpr);
  }
  cv.style.height = h + "px";
  ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
  return [w, h];
}

const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
const unit = (a) => { const n = Math.hypot(a[0], a[1], a[2]) || 1; return a.map((v) => v / n); };
const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];

function worldPoints(pose) {
  // camera frame (x right, y down, z away) -> world (x right, up, z away from the camera, level with the floor):
  // gravity and the floor are the robot's fall detector's (status.floor) when it has them; a level camera and
  // a floor under the lowest joint otherwise (said on the canvas)
  const j = Object.assign({}, pose.joints);
  if (j.left_shoulder && j.right_shoulder)
    j.mid_shoulder = j.left_shoulder.map((v, i) => (v + j.right_shoulder[i]) / 2);
  const fl = view.status && view.status.floor;
  const down = fl ? unit(fl.down) : [0, 1, 0];
  const ez = unit([-down[2] * down[0], -down[2] * down[1], 1 - down[2] * down[2]]);  // camera z, level
  const ex = cross(down, ez);
  const out = {};
  if (fl && fl.below_camera_m !== null && pose.root) {
    for (const [k, p] of Object.entries(j)) {
      const abs = p.map((v, i) => v + pose.root[i]);
      out[k] = [dot(ex, p), fl.below_camera_m - dot(down, abs), dot(ez, p)];
    }
    view.floorNote = `floor: the fall detector's, ${fl.below_camera_m.toFixed(2)} m below the camera` +
      ` (${fl.height_from || "?"}); camera tilt ${Math.round(fl.tilt_deg)}° (${fl.tilt_from || "?"})`;
  } else {
    let lowest = Infinity;
    for (const p of Object.values(j)) lowest = Math.min(lowest, -dot(down, p));
    for (const [k, p] of Object.entries(j)) out[k] = [dot(ex, p), -dot(down, p) - lowest + ANKLE_HEIGHT, dot(ez, p)];
    view.floorNote = "floor: under the lowest joint (" + (!fl ? "no fall detector geometry" :
      fl.below_camera_m === null ? "the fall detector has not learned it yet" : "the person's position is unknown") + ")";
  }
  return out;
}

function project(p, w, h) {
  const yaw = view.yaw * Math.PI / 180, pitch = view.pitch * Math.PI / 180;
  let x = p[0], y = p[1] - 0.9, z = p[2];                              // orbit about a point 0.9 m up
  [x, z] = [x * Math.cos(yaw) - z * Math.sin(yaw), x * Math.sin(yaw) + z * Math.cos(yaw)];
  [y, z] = [y * Math.cos(pitch) - z * Math.sin(pitch), y * Math.sin(pitch) + z * Math.cos(pitch)];
  const d = 3.4 / view.zoom, f = h * 1.1;
  const depth = Math.max(0.1, d + z);
  return [w / 2 + f * x / depth, h * 0.55 - f * y / depth];
}

function drawSkeleton() {
  const [w, h] = fitCanvas(sk, g, (w) => Math.round(w * 0.75));
  g.fillStyle = "#1e1e1e"; g.fillRect(0, 0, w, h);
  g.lineWidth = 1; g.strokeStyle = "#444";
  for (let a = -2; a <= 2.001; a += 0.5) {  // floor grid, 4 m x 4 m, 0.5 m squares
    line(project([a, 0, -2], w, h), project([a, 0, 2], w, h));
    line(project([-2, 0, a], w, h), project([2, 0, a], w, h));
  }
  const pose = view.lastPose;
  const note = document.getElementById("pose-note");
  const paused = view.status && view.status.paused;
  if (paused && !view.stale) {  // paused for privacy: the person asked not to be watched, so no body is drawn,
    g.fillStyle = "#bbb"; g.font = "15px sans-serif";   // not even the last one from before the pause
    const why = pausedText(paused);
    g.fillText(why.length > 70 ? why.slice(0, 69) + "…" : why, 16, 26);
    note.textContent = "";
    return;
  }
  const fitted = pose && pose.ok && Object.keys(pose.joints).length;
  const shown = fitted ? pose : view.lastGood;
  if (view.stale && shown) {  // posed is not heard from: the last skeleton in grey, with its age
    g.fillStyle = "#ff8a80"; g.font = "bold 15px sans-serif";
    g.fillText("NOT LIVE: posed is not heard from", 16, 26);
    g.fillStyle = "#bbb"; g.font = "14px sans-serif";
    g.fillText(`grey: the last pose, received ${ageText(view.robotState && view.robotState.pose_at)}`, 16, 48);
    note.textContent = "not live";
    drawBones(worldPoints(shown), false, w, h);
    return;
  }
  if (!fitted) {  // say why, and keep the last fitted skeleton in grey
    g.fillStyle = "#bbb"; g.font = "15px sans-serif";
    const nw = view.status && view.status.not_watching;
    const why = nw ? "posed is not watching: " + nw.reason :
      pose ? "no fit: " + (pose.reason || "no person") : "waiting for poses…";
    g.fillText(why.length > 70 ? why.slice(0, 69) + "…" : why, 16, 26);
    if (shown && pose) g.fillText(`grey: the last fit, ${Math.max(0, pose.time_unix - shown.time_unix).toFixed(1)} s ago`, 16, 48);
    note.textContent = "";
    if (!shown) return;
  }
  drawBones(worldPoints(shown), fitted, w, h);
  if (!fitted) return;
  view.drawn += 1;
  note.textContent = `turned ${Math.round(view.yaw)}°, tilted ${Math.round(view.pitch)}°; joints the camera did ` +
    "not see this frame are left out";
}

function drawBones(pts, colour, w, h) {  // colour false: grey (an old fit, or posed not heard from)
  g.lineCap = "round";
  for (const [a, b, s] of BONES) {
    if (!pts[a] || !pts[b]) continue;
    g.strokeStyle = colour ? SIDE_COLOUR[s] : "#777"; g.lineWidth = 5; g.setLineDash(s === "r" ? [10, 7] : []);
    line(project(pts[a], w, h), project(pts[b], w, h));
  }
  g.setLineDash([]); g.fillStyle = colour ? "#eee" : "#999";
  for (const [k, p] of Object.entries(pts)) {
    if (k === "mid_shoulder") continue;
    const [u, v] = project(p, w, h); g.beginPath(); g.arc(u, v, 4, 0, 2 * Math.PI); g.fill();
  }
  g.fillStyle = "#999"; g.font = "12px sans-serif"; g.fillText(view.floorNote, 16, h - 12);
}

function line(a, b) { g.beginPath(); g.moveTo(a[0], a[1]); g.lineTo(b[0], b[1]); g.stroke(); }

let drag = null;
sk.addEventListener("pointerdown", (e) => { drag = [e.clientX, e.clientY]; sk.setPointerCapture(e.pointerId); });
sk.addEventListener("pointerup", () => { drag = null; });
sk.addEventListener("pointermove", (e) => {
  if (!drag) return;
  view.yaw += (e.clientX - drag[0]) * 0.5;
  view.pitch = Math.max(-10, Math.min(89, view.pitch + (e.clientY - drag[1]) * 0.5));
  drag = [e.clientX, e.clientY]; drawSkeleton();
});
sk.addEventListener("wheel", (e) => {
  e.preventDefault(); view.zoom = Math.max(0.3, Math.min(4, view.zoom * (e.deltaY < 0 ? 1.1 : 0.9))); drawSkeleton();
}, {passive: false});
for (const b of document.querySelectorAll("[data-view]")) b.addEventListener("click", () => {
  [view.yaw, view.pitch] = {front: [0, 5], side: [-90, 5], top: [0, 89]}[b.dataset.view]; drawSkeleton();
});

// ------------------------------------------------------------------ angles
const ch = document.getElementById("chart"), c2 = ch.getContext("2d");
const label = (n) => view.labels[n] || "";   // plain names come with the first message; never a symbol

function drawChart() {
  // wide: the legend at the right; narrow (a phone): under the plot in two columns, fewer time labels
  const narrow = (ch.clientWidth || 900) < 560, rows = Math.ceil(CHART.length / 2);
  const legendH = narrow ? 18 * rows + 6 : 0;
  const [w, h] = fitCanvas(ch, c2, (w) => narrow ? 190 + legendH : Math.max(200, Math.min(300, Math.round(w * 0.3))));
  const L = narrow ? 38 : 46, R = narrow ? 10 : 190, T = 10, B = 28 + legendH;
  c2.clearRect(0, 0, w, h);
  const now = angleLog.length ? angleLog[angleLog.length - 1].time_unix : Date.now() / 1000;
  let lo = -10, hi = 120;
  for (const s of angleLog) for (const [n] of CHART) {
    const v = s.angles[n]; if (v !== null && v !== undefined) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
  }
  const X = (t) => L + (w - L - R) * (1 - (now - t) / WINDOW_S), Y = (v) => T + (h - T - B) * (hi - v) / (hi - lo);
  c2.strokeStyle = "#ddd"; c2.lineWidth = 1; c2.fillStyle = "#555"; c2.font = "11px sans-serif";
  for (let v = Math.ceil(lo / 30) * 30; v <= hi; v += 30) {
    c2.beginPath(); c2.moveTo(L, Y(v)); c2.lineTo(w - R, Y(v)); c2.stroke(); c2.fillText(v + "°", 8, Y(v) + 4);
  }
  for (let s = 0; s <= WINDOW_S; s += narrow ? 20 : 10) c2.fillText(s ? `-${s} s` : "now", X(now - s) - 12, h - legendH - 8);
  view.legend = CHART.map(([n]) => label(n)).filter((t) => t);   // what the legend says (for tests and users)
  CHART.forEach(([n, colour, dash], i) => {
    c2.strokeStyle = colour; c2.setLineDash(dash); c2.lineWidth = 2; c2.beginPath();
    let pen = false, prev = -Infinity;
    for (const s of angleLog) {
      const v = s.angles[n], gap = s.time_unix - prev > GAP_S;   // nothing came (posed off): a gap, not a line
      prev = s.time_unix;
      if (v === null || v === undefined || now - s.time_unix > WINDOW_S) { pen = false; continue; }
      if (pen && !gap) c2.lineTo(X(s.time_unix), Y(v)); else c2.moveTo(X(s.time_unix), Y(v));
      pen = true;
    }
    c2.stroke();
    // legend: plain names, same line style (none until the names arrived)
    const lx = narrow ? 8 + (i % 2) * (w - 8) / 2 : w - R + 10;
    const ly = narrow ? h - legendH + 12 + 18 * Math.floor(i / 2) : T + 14 + 20 * i;
    if (label(n)) {
      c2.beginPath(); c2.moveTo(lx, ly); c2.lineTo(lx + 26, ly); c2.stroke();
      c2.setLineDash([]); c2.fillStyle = "#222"; c2.fillText(label(n), lx + 32, ly + 4);
    }
  });
  c2.setLineDash([]);
}

function showEvidence(pose) {  // what the last fit used: "2D landmarks + BlazePose 3D, assumed lens" (the hub's words)
  if (pose.ok && pose.evidence) setText("st-evidence", pose.evidence.replace(/^3D from: /, ""));
}

function showAnglesNow(pose) {  // none while paused for privacy (a pose of before the pause is not "now")
  if (view.status && view.status.paused) { document.getElementById("angles-now").innerHTML = ""; return; }
  const rows = Object.entries(pose.angles).map(([n, v]) =>
    `<tr><th>${label(n)}</th><td>${v === null ? "not seen" : Math.round(v) + "°"}</td></tr>`);
  document.getElementById("angles-now").innerHTML = rows.join("");
}

// ------------------------------------------------------------------ status, events, history
const ZONE = Intl.DateTimeFormat().resolvedOptions().timeZone;
const pad = (n) => String(n).padStart(2, "0");
// Every time on the page is on the robot's clock, in the robot's zone (its status's time_zone), as the report,
// `posed events` and `posed plot history` show them: a carer abroad reads the time it happened at home. Until
// the status says (or for an old daemon), this browser's zone; the headings name the zone either way.
let viewZone = ZONE;
function setZone(zone) {  // the robot's IANA zone; false when this browser does not know it (kept as it was)
  if (typeof zone !== "string" || !zone || zone === viewZone) return false;
  try { new Intl.DateTimeFormat("en-GB", {timeZone: zone}); } catch (e) { return false; }
  viewZone = zone;
  return true;
}
function partsOf(d, zone) {  // {year, month, day, hour, minute, second, timeZoneName: "GMT+01:00"} of a Date in viewZone (or zone)
  const f = new Intl.DateTimeFormat("en-GB", {timeZone: zone || viewZone, year: "numeric", month: "2-digit",
    day: "2-digit", hour: "2-digit", minute: "2-digit", second: "2-digit", hourCycle: "h23",
    timeZoneName: "longOffset"});
  const o = {};
  for (const p of f.formatToParts(d)) o[p.type] = p.value;
  return o;
}
function zoneText() {  // "Europe/Berlin, UTC+01:00": the zone every time on the page is shown in
  const off = partsOf(new Date()).timeZoneName.replace("GMT", "") || "+00:00";
  return `${viewZone}, UTC${off}`;
}

function toDate(t) {  // an ISO time (UTC unless it says otherwise), or unix seconds
  if (t === null || t === undefined || t === "") return null;
  const d = typeof t === "number" ? new Date(t * 1000) : new Date(/[zZ]|[+-]\d\d:?\d\d$/.test(t) ? t : t + "Z");
  return isNaN(d) ? null : d;
}

function localTime(t, zone) {  // ISO 8601 in the page's zone (the robot's), as every other posed view writes times: 2026-12-02 19:42:47
  const d = toDate(t);
  if (!d) return t === null || t === undefined || t === "" ? "–" : String(t);
  const o = partsOf(d, zone);
  return `${o.year}-${o.month}-${o.day} ${o.hour}:${o.minute}:${o.second}`;
}
function robotTime(t, robot) {  // every robot: a time of another robot in its own zone, named; else localTime
  const c = view.everyRobot && robot && view.cards[robot], zone = c && zoneOf(c.time_zone);
  if (!zone || zone === viewZone) return localTime(t);
  const d = toDate(t);
  return d ? `${localTime(t, zone)} (${zone})` : localTime(t);
}

function setText(id, text) { document.getElementById(id).textContent = text; }

function showStatus(s) {
  if (view.everyRobot && s.robot !== view.shownRobot) return;   // another robot's: never shown as this one's
  view.status = s;
  if (setZone(s.time_zone) && view.history) showHistory();   // times drawn so far are drawn again below
  view.fpsText = s.fps === null ? "–" : s.fps.toFixed(1);
  setText("st-state", s.state); setText("st-fps", view.fpsText);
  setText("st-latency", s.latency_p95_ms === null ? "–" : Math.round(s.latency_p95_ms) + " ms");
  setText("st-camera", s.camera || "–"); setText("st-drops", s.drops); setText("st-restarts", s.restarts);
  const nw = s.not_watching;
  if (s.paused) {   // paused for privacy: no body, no angles now, no minute of angles from before the pause
    angleLog.length = 0;
    document.getElementById("angles-now").innerHTML = "";
  }
  if (Boolean(s.paused) !== Boolean(view.paused)) { view.paused = s.paused; requestDraw(); }
  setText("st-watching", s.paused ? pausedText(s.paused).replace(/^Watching paused/, "no: paused") :
    nw ? `NO: ${nw.reason}` + (nw.since_known ? `, since ${sinceText(nw.since_unix)}` : "") :
    s.state === "starting" ? "not yet (starting)" : "yes");
  document.getElementById("st-watching").className = nw ? "warn" : "";
  showPresence(s.presence);
  const restored = s.restored_open || [];
  document.getElementById("st-restored-row").hidden = !restored.length;
  setText("st-restored", restored.map((r) => `${r.id.slice(0, 8)}: ` +
    (r.alarm ? "alarm sent" : `alarm due ${clockText(r.due_unix)}`)).join("; "));
  showLiveness();
  if (view.events && Object.keys(view.events).length) showEvents();
  const storage = document.getElementById("storage");   // the state directory fails: fall events not on disk
  storage.hidden = !s.storage;
  if (s.storage) storage.textContent = "The robot cannot store fall events on its disk: " +
    (s.storage.unstored_events || 0) + " kept in memory and in " + (s.storage.fallback || "its fallback file") +
    " (" + (s.storage.reason || "the state directory fails") + "). Fix: " + (s.storage.fix || "check its disk") + ".";
}

function showPresence(p) {  // "last seen 14:02 (12 min ago)", "in view"; absent: in red (the server's words)
  document.getElementById("st-person-row").hidden = !p;
  setText("st-person", p ? p.text : "–");
  document.getElementById("st-person").className = p && p.absent ? "warn" : "";
}

function showBus(bus) {  // the page cannot reach the robot's bus: say so, never show an empty history as all well
  const el = document.getElementById("bus");
  if (!bus || bus.connected !== false) { el.hidden = true; return; }
  el.hidden = false;
  el.textContent = "Not connected to the robot: " + (bus.reason || "no answer") +
    ". Falls are NOT shown here until this is fixed. Fix: " + (bus.fix || "check the Zenoh configuration") + ".";
}

function showAlive(alive) {
  const el = document.getElementById("alive");
  el.textContent = alive === null ? "robot: ?" : alive ? "robot: up" : "robot: GONE";
  el.className = "pill" + (alive ? "" : alive === false ? " bad" : " off");
}

// ------------------------------------------------------------------ is posed watching: the server's verdict
let clockSkew = 0;   // this browser's clock minus the server's (s): ages are told on the server's clock
const serverNow = () => Date.now() / 1000 - clockSkew;
function clockText(t, zone) {  // HH:MM:SS in the page's zone (the robot's; or zone, a valid IANA zone)
  const d = toDate(t);
  if (!d) return "–";
  const o = partsOf(d, zone);
  return `${o.hour}:${o.minute}:${o.second}`;
}
function sinceText(t, zone) {  // HH:MM:SS, with the date when it is not today (the robot's day)
  const d = toDate(t);
  if (!d) return "–";
  const o = partsOf(d, zone), n = partsOf(new Date(), zone);
  return o.year === n.year && o.month === n.month && o.day === n.day ? clockText(t, zone) :
    `${o.year}-${o.month}-${o.day} ${o.hour}:${o.minute}:${o.second}`;
}
function ageText(t) {  // "at 22:31:24, 35 s ago"
  if (t === null || t === undefined) return "never";
  const a = Math.max(0, Math.round(serverNow() - t));
  return `at ${clockText(t)}, ` + (a < 120 ? `${a} s ago` : a < 7200 ? `${Math.round(a / 60)} min ago` :
    `${(a / 3600).toFixed(1)} h ago`);
}

function hmText(t, zone) {  // HH:MM in the page's zone (the robot's; or zone), with the date when not today
  const d = toDate(t);
  if (!d) return "–";
  const o = partsOf(d, zone), n = partsOf(new Date(), zone);
  return (o.year === n.year && o.month === n.month && o.day === n.day ? "" : `${o.year}-${o.month}-${o.day} `) +
    `${o.hour}:${o.minute}`;
}
function pausedText(p, zone) {  // "Watching paused for privacy by voice until 15:42" (the status's privacy)
  return "Watching paused for privacy" + (p.by ? ` by ${p.by}` : "") +
    (p.until_unix === null || p.until_unix === undefined ? "" : ` until ${hmText(p.until_unix, zone)}`);
}

function showRobot(r) {
  if (!r) return;
  view.robotState = r;
  if (typeof r.now_unix === "number") clockSkew = Date.now() / 1000 - r.now_unix;
  showLiveness();
}

function showLiveness() {  // the red bar, the "live" badge, and everything stale greyed with its age
  const r = view.robotState || {state: "waiting"}, robot = view.shownRobot || "the robot";
  let text = "";
  if (view.streamLost !== null) {
    text = `This page lost its connection to posed web at ${clockText(view.streamLost)} — falls are NOT shown ` +
      "here until it is back.";
  } else if (r.state === "down" && r.why === "gone") {
    text = `posed on ${robot} is not running since ${clockText(r.since_unix)} — falls are NOT being detected.`;
  } else if (r.state === "down" && r.why === "starting") {
    text = `posed on ${robot} is starting again (not running since ${clockText(r.since_unix)}) — falls are NOT ` +
      "being detected yet.";
  } else if (r.state === "down" && r.why === "silent") {
    text = r.last_heard_unix ? `posed on ${robot} has sent nothing since ${clockText(r.since_unix)} (stopped or ` +
      "stuck) — falls are NOT being detected." : `posed on ${robot} has not been heard from since this page opened ` +
      `at ${clockText(r.since_unix)} — falls are NOT being detected.`;
  }   // a bus this side cannot reach: the bus banner says it, with the reason and the fix
  const bar = document.getElementById("down");
  bar.hidden = !text; bar.textContent = text;
  const live = view.streamLost === null && view.connected && r.state === "up";
  // posed runs and is heard from, but sees nothing (camera ended, lost, blind; a stage failing): said as loudly
  const nw = live && view.status && view.status.not_watching;
  const paused = live && view.status && view.status.paused;   // asked for: a plain banner, not an alarm
  const pbar = document.getElementById("paused");
  pbar.hidden = !paused;
  pbar.textContent = paused ? pausedText(paused) : "";
  const pr = live && view.status && view.status.presence, absent = pr && pr.absent ? pr : null;
  const abar = document.getElementById("absent");   // the absence notice: the person may have fallen out of view
  abar.hidden = !absent;
  abar.textContent = absent ? `${robot}: person ${absent.text}` : "";
  const wbar = document.getElementById("watching");
  wbar.hidden = !nw;
  wbar.textContent = nw ? `posed on ${robot} is running but NOT WATCHING ` + (nw.since_known ?
    `since ${sinceText(nw.since_unix)}` : `(already when this view started, ${clockText(nw.since_unix)})`) +
    `: ${nw.reason} — a fall would NOT be detected.` : "";
  const waiting = view.streamLost === null && r.state === "waiting";
  const conn = document.getElementById("conn");
  conn.textContent = nw ? "live, NOT WATCHING" : paused ? "live, paused" : live ? "live" :
    view.streamLost !== null ? "NOT LIVE: reconnecting…" : waiting ? "waiting for the robot…" : "NOT LIVE";
  conn.className = "pill" + (paused && !nw ? " paused" : live && !nw ? "" : waiting ? " off" : " bad");
  view.live = live;
  view.stale = !live && !waiting;
  document.body.classList.toggle("stale", view.stale);
  setText("st-age", view.stale ? (r.status_at ? `not live: last status ${ageText(r.status_at)}` : "not live: no status") : "");
  setText("angles-age", view.stale ? (r.pose_at ? `not live: last pose ${ageText(r.pose_at)}` : "not live") : "");
  const none = document.getElementById("events-none");
  if (none) none.textContent = view.stale ? "none received since this page opened — and none can arrive while " +
    "posed is not heard from" : "none since this page opened";
}


const EVENTS_SHOWN = 6, HISTORY_SHOWN = 15;   // the newest; the rest behind "show all", always counted

// which robot an event is from: named on every entry and row (a page may list several robots' events)
const robotText = (robot) => robot ? `robot ${esc(robot)} · ` : "";

function showRobotName() {  // "r1", or "every robot (skeleton and pipeline: r1)"
  setText("robot", view.everyRobot ? `every robot` + (view.shownRobot ? ` (skeleton and pipeline: ${view.shownRobot})` : "")
    : view.shownRobot || "");
}

function fallsById() {  // [{id, msgs (in order), first, last (unix s)}], the newest event first
  const by = {};
  for (const e of Object.values(view.events)) (by[e.id] = by[e.id] || []).push(e);
  const when = (m) => { const d = toDate(m.wall_time); return d ? d.getTime() / 1000 : 0; };
  return Object.entries(by).map(([id, msgs]) => {
    msgs.sort((a, b) => a.t_detect - b.t_detect);
    return {id, msgs, first: when(msgs[0]), last: when(msgs[msgs.length - 1])};
  }).sort((a, b) => b.first - a.first);
}

const esc = (t) => String(t).replace(/[&<>"']/g, (c) => ({"&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&#39;"})[c]);

const CLOCK_NOTES = {  // restored.clock: why the restored alarm was raised at once (docs/falls.md)
  behind: "alarm raised at once: the clock was stepped back, so how long ago the fall was is unknown",
  beyond_horizon: "alarm raised at once: the fall was more than a day ago by this clock and nobody had " +
    "acknowledged it (posed was down that long, or the clock was stepped forward)",
};

function caveats(msgs, id) {  // a fall taken back after a restart, an alarm raised with no camera frame
  const out = [];
  const r = msgs.map((m) => m.restored).find((x) => x);
  if (r) out.push(`posed restarted during this fall and took it back at ${clockText(r.at_unix)}` +
    (r.last_state ? ` (last seen: ${r.last_state})` : ""));
  if (r && CLOCK_NOTES[r.clock]) out.push(CLOCK_NOTES[r.clock]);
  const open = ((view.status && view.status.restored_open) || []).find((o) => o.id === id && !o.alarm);
  if (open && !msgs.some((m) => m.state === "alarm" || m.state === "recovered"))
    out.push(`ALARM due at ${clockText(open.due_unix)} unless the person is seen up`);
  const blind = msgs.find((m) => typeof m.without_frames_s === "number");
  if (blind) out.push(`${STATE_WORDS.alarm || "ALARM"} raised with no camera frame for ` +
    `${Math.round(blind.without_frames_s)} s: the camera had stopped, the person was not seen`);
  return out;
}

function showEvents() {
  const falls = fallsById(), ul = document.getElementById("events");
  view.shownEvents = falls.map((f) => f.id);
  const alarm = document.getElementById("alarm");
  if (!falls.length) {  // none (left): the page says so, never an old list
    if (!document.getElementById("events-none")) {
      ul.innerHTML = '<li id="events-none" class="note"></li>'; showLiveness();
    }
    alarm.hidden = true; alarm.textContent = "";
    fleetChanged();
    return;
  }
  ul.innerHTML = "";
  const open = falls.filter((f) => !view.acked[f.id]).length;
  const shown = view.showAllEvents ? falls : falls.slice(0, EVENTS_SHOWN);
  for (const f of shown) {
    const li = document.createElement("li");
    li.innerHTML = `<span class="fall">${f.msgs.map((m) => STATE_WORDS[m.state] || m.state).join(" → ")}</span>
      <span class="note">${robotTime(f.msgs[0].wall_time, f.msgs[0].robot)} · ${robotText(f.msgs[0].robot)}${f.id.slice(0, 8)}</span> ` +
      caveats(f.msgs, f.id).map((c) => `<div class="caveat">${esc(c)}</div>`).join("");
    li.dataset.eventId = f.id;
    if (view.acked[f.id]) {
      const by = ackedBy(f.id);
      li.insertAdjacentHTML("beforeend", `<span class="ok">acknowledged ✓${by ? " by " + esc(by) : ""}</span>`);
    } else {
      const b = document.createElement("button");
      b.className = "ack"; b.textContent = "Acknowledge"; b.dataset.eventId = f.id;
      b.addEventListener("click", () => acknowledge(f.id, b));
      li.appendChild(b);
    }
    ul.appendChild(li);
  }
  const hidden = falls.slice(shown.length);
  if (hidden.length || view.showAllEvents && falls.length > EVENTS_SHOWN) {
    const li = document.createElement("li");
    li.className = "note more";
    const openHidden = hidden.filter((f) => !view.acked[f.id]).length;
    li.textContent = hidden.length ? `${hidden.length} earlier event(s)` + (openHidden ? `, ${openHidden} not acknowledged` : "") + " " : "";
    const b = document.createElement("button");
    b.textContent = view.showAllEvents ? "show the newest only" : "show all";
    b.addEventListener("click", () => { view.showAllEvents = !view.showAllEvents; showEvents(); });
    li.appendChild(b); ul.appendChild(li);
  }
  alarm.hidden = open === 0;
  alarm.textContent = open ? `${open} fall event(s) not acknowledged` : "";
  fleetChanged();
}

const byInput = document.getElementById("ack-by");
try { byInput.value = localStorage.getItem("posed.ackBy") || ""; } catch (err) { /* storage off: ask again */ }

function ackedBy(id) {  // who acknowledged the event's messages, as the robot's journal says
  const names = view.history.filter((m) => m.id === id && m.acked_at && m.acked_by).map((m) => m.acked_by);
  return [...new Set(names)].join(", ");
}

async function acknowledge(id, button) {
  button.disabled = true; button.textContent = "acknowledging…";
  const by = byInput.value.trim();
  try { localStorage.setItem("posed.ackBy", by); } catch (err) { /* storage off */ }
  try {
    const r = await fetch(withToken("/api/ack"), {method: "POST", headers: {"Content-Type": "application/json",
      "X-Posed": "ack"}, body: JSON.stringify(by ? {id, by} : {id})});
    const body = await r.json();
    if (r.ok && body.confirmed) { view.acked[id] = true; showEvents(); loadHistory(); return; }
    button.textContent = r.status === 409 ? body.error : "not confirmed — retry"; button.disabled = r.status === 409;
  } catch (err) {
    button.textContent = "failed — retry"; button.disabled = false;
  }
}

function historyRows(events) {  // the robot's stored messages, one row per event, the newest first
  const by = {};
  for (const e of events) (by[e.id] = by[e.id] || []).push(e);
  return Object.entries(by).map(([id, msgs]) => {
    const first = toDate(msgs[0].wall_time), acked = msgs.map((m) => m.acked_at);
    const words = (ms) => ms.map((m) => STATE_WORDS[m.state] || m.state).join(" → ");
    return {id, robot: msgs[0].robot, time: msgs[0].wall_time, at: first ? first.getTime() : 0, states: words(msgs),
            acked: acked.every((a) => a) ? Math.max(...acked) : null,
            by: [...new Set(msgs.filter((m) => m.acked_at && m.acked_by).map((m) => m.acked_by))].join(", "),
            notOpen: words(msgs.filter((m) => !m.acked_at)), caveats: caveats(msgs, id),
            open: acked.filter((a) => !a).length, count: msgs.length};
  }).sort((a, b) => b.at - a.at);
}

let historyAsked = 0, historyBusy = false, historyAgain = false;
async function loadHistory() {
  // one request at a time, and one more after it when asked meanwhile: a burst of event messages (a robot back
  // on the bus with a backlog) is a few reads of the robot's journal, never one per message
  if (historyBusy) { historyAgain = true; return; }
  historyBusy = true; historyAgain = false;
  const mine = ++historyAsked;
  view.historyLoads = (view.historyLoads || 0) + 1;
  try {
    const r = await fetch(withToken("/api/history"));
    const body = await r.json();
    if (mine !== historyAsked) return;
    view.history = body.events || [];
    view.historyCut = r.ok && body.truncated ? body.limit : null;
    showHistory(r.ok ? null : body.error || r.status);
    showEvents();
  } catch (err) { /* the next refresh tries again */
  } finally {
    historyBusy = false;
    if (historyAgain) setTimeout(loadHistory, 1000);
  }
}

function showHistory(error) {
  const t = document.getElementById("history"), more = document.getElementById("history-more");
  more.innerHTML = "";
  if (error) { t.innerHTML = `<tr><td class="note">${error}</td></tr>`; return; }
  if (!view.history.length) { t.innerHTML = '<tr><td class="note">no fall events stored</td></tr>'; return; }
  const rows = historyRows(view.history);
  view.historyRows = rows.map((x) => x.id);
  const cut = document.getElementById("history-cut");   // the robot sent its newest messages only: said
  cut.hidden = !view.historyCut;
  cut.textContent = view.historyCut ? `Only the newest ${view.historyCut} stored messages are shown (since ` +
    `${localTime(view.history[0].wall_time)}); earlier falls of the last 7 days are not listed here.` : "";
  const shown = view.showAllHistory ? rows : rows.slice(0, HISTORY_SHOWN);
  t.innerHTML = `<tr><th>started (${zoneText()})</th><th>event</th><th>what happened</th><th>acknowledged</th></tr>` +
    shown.map((e) => `<tr><td>${robotTime(e.time, e.robot)}</td><td>${robotText(e.robot)}${e.id.slice(0, 8)}</td><td>${e.states}` +
      e.caveats.map((c) => `<div class="caveat">${esc(c)}</div>`).join("") + `</td>
      <td>${e.acked ? robotTime(e.acked, e.robot) + (e.by ? " by " + esc(e.by) : "") : e.open < e.count ?
        `<span class="warn">${e.notOpen} not acknowledged</span>` + (e.by ? ` (the rest by ${esc(e.by)})` : "") :
        "no"}</td></tr>`).join("");
  if (rows.length > HISTORY_SHOWN) {
    const open = rows.slice(shown.length).filter((e) => !e.acked).length;
    more.textContent = view.showAllHistory ? "" : `${rows.length - shown.length} earlier event(s)` +
      (open ? `, ${open} not acknowledged ` : " ");
    const b = document.createElement("button");
    b.textContent = view.showAllHistory ? "show the newest only" : "show all";
    b.addEventListener("click", () => { view.showAllHistory = !view.showAllHistory; showHistory(null); });
    more.appendChild(b);
  }
}

// ------------------------------------------------------------------ every robot: a card each, one followed
// posed web '*': a card per robot (up or gone and since when, watching or why not, falls not acknowledged, its
// last pose's time in its own zone, frames per second); the skeleton, the angles and the pipeline card are one
// robot's: the one whose card was clicked (kept in the address, #robot=ID, so a reload keeps it), else the one
// with an unacknowledged alarm, else the first by id. The server sends this page that robot's poses only.
function hashRobot() {
  const m = /(?:^#|&)robot=([^&]*)/.exec(location.hash);
  if (!m) return null;
  try { return decodeURIComponent(m[1]) || null; } catch (err) { return null; }
}

function openFalls() {  // {robot: {open, alarm, first}}: events not acknowledged; the earliest alarm's and fall's start
  const out = {};
  for (const f of fallsById()) {
    const r = f.msgs[0].robot;
    if (view.acked[f.id] || !r) continue;
    const o = out[r] = out[r] || {open: 0, alarm: Infinity, first: Infinity};
    o.open += 1; o.first = Math.min(o.first, f.first);
    if (f.msgs.some((m) => m.state === "alarm")) o.alarm = Math.min(o.alarm, f.first);
  }
  return out;
}

function defaultRobot() {  // the server's rule too (viz.web.hub Hub._default_robot)
  const open = openFalls(), ids = Object.keys(view.cards).sort();
  let best = null;
  for (const r of ids) {
    const o = open[r];
    if (!o) continue;
    const key = o.alarm < Infinity ? [0, o.alarm] : [1, o.first];
    if (!best || key[0] < best[0] || key[0] === best[0] && key[1] < best[1]) best = [...key, r];
  }
  return best ? best[2] : ids.length ? ids[0] : null;
}

function follow(robot, by) {  // show robot's live parts: its own stream, nothing of the one before
  view.selectedBy = by;
  if (robot === view.selected) { showCards(); return; }
  view.selected = view.shownRobot = robot;
  view.lastPose = null; view.lastGood = null; view.status = null; view.robotState = null; view.poses = 0;
  view.poseRobots = {}; angleLog.length = 0;
  for (const id of ["st-state", "st-fps", "st-latency", "st-camera", "st-drops", "st-restarts", "st-evidence",
    "st-watching"]) setText(id, "–");
  showPresence(null);
  setText("st-poses", 0); document.getElementById("angles-now").innerHTML = "";
  showRobotName(); showCards(); requestDraw();
  connect();
}

function fleetChanged() {  // cards, events or acknowledgements changed: the cards again, and the default robot
  if (!view.everyRobot) return;
  const asked = hashRobot();
  if (asked) { if (asked !== view.selected || view.selectedBy !== "hash") follow(asked, "hash"); else showCards(); return; }
  const d = defaultRobot();
  if (d !== null && d !== view.selected) follow(d, "default"); else { view.selectedBy = "default"; showCards(); }
}
window.addEventListener("hashchange", fleetChanged);

const zoneOk = {};
function zoneOf(zone) {  // the robot's IANA zone when this browser knows it, else the page's
  if (typeof zone !== "string" || !zone) return viewZone;
  if (!(zone in zoneOk)) {
    try { new Intl.DateTimeFormat("en-GB", {timeZone: zone}); zoneOk[zone] = true; } catch (err) { zoneOk[zone] = false; }
  }
  return zoneOk[zone] ? zone : viewZone;
}

const DOWN_WORDS = {gone: "not running (its Zenoh liveliness token went away)", silent: "sends nothing (stopped or stuck)",
  starting: "starting again", bus: "this side has no bus"};

function cardParts(c, open) {  // [pill, its class, watching line, whether it watches, falls, pose line, open, presence]
  const zone = zoneOf(c.time_zone), since = sinceText(c.since_unix, zone);
  let pill = "up", cls = "", watch, watching = false;
  if (c.state === "up" && c.paused) {   // asked for: said plainly, never as a fault
    pill = "paused"; cls = " paused"; watch = pausedText(c.paused, zone);
  } else if (c.state === "up") {
    const nw = c.not_watching;
    watching = c.watching !== false;
    watch = !watching && nw ? `NOT WATCHING: ${nw.reason}` + (nw.since_known ? `, since ${sinceText(nw.since_unix, zone)}` : "") :
      c.status === "starting" ? "not watching yet (starting)" : c.watching ? "watching" : "no status yet";
  } else if (c.state === "waiting") {
    pill = "waiting…"; cls = " off"; watch = "not heard from yet";
  } else {
    pill = c.why === "starting" ? `starting (down since ${since})` : c.why === "bus" ? "NO BUS" : `GONE since ${since}`;
    cls = " bad"; watch = "falls NOT detected: " + (DOWN_WORDS[c.why] || "not heard from");
  }
  const n = open ? open.open : 0;
  const falls = n ? `${n} fall event(s) not acknowledged` : "no fall event open";
  const pose = (c.pose_unix === null || c.pose_unix === undefined ? "no pose yet" :
    `last pose ${sinceText(c.pose_unix, zone)}`) + ` (${zone})` +
    (c.fps === null || c.fps === undefined ? "" : ` · ${c.fps.toFixed(1)} fps`);
  const person = c.state === "up" && c.presence ? c.presence : null;
  return [pill, cls, watch, watching, falls, pose, n, person];
}

const cardEls = new Map();   // robot -> its card's button, kept while the robot is listed (a click is never lost to a redraw)
function showCards() {
  const box = document.getElementById("robots");
  box.hidden = !view.everyRobot;
  if (!view.everyRobot) return;
  const open = openFalls(), list = document.getElementById("robot-cards");
  const ids = Object.keys(view.cards).sort();
  if (view.selected && !view.cards[view.selected]) ids.unshift(view.selected);   // asked for, not on the bus
  for (const [id, el] of cardEls) if (!ids.includes(id)) { el.remove(); cardEls.delete(id); }
  ids.forEach((id, i) => {
    const c = view.cards[id] || {robot: id, state: "absent"};
    let b = cardEls.get(id);
    if (!b) {
      b = document.createElement("button");
      b.addEventListener("click", () => { location.hash = "robot=" + encodeURIComponent(id); });
      cardEls.set(id, b);
    }
    if (list.children[i] !== b) list.insertBefore(b, list.children[i] || null);
    const parts = c.state === "absent" ? null : cardParts(c, open[id]);
    const paused = parts && c.state === "up" && c.paused;
    b.className = "robot-card" + (id === view.selected ? " selected" : "") +
      (paused ? " paused" : parts && parts[3] ? "" : " down");
    b.dataset.robot = id; b.dataset.state = paused ? "paused" : c.state;
    b.setAttribute("aria-pressed", id === view.selected ? "true" : "false");
    let html;
    if (c.state === "absent") {
      html = `<div class="rc-head"><b>${esc(id)}</b> <span class="pill off">not on the bus</span></div>` +
        '<div class="note">chosen in this page\'s address; no message from it since the page opened</div>';
    } else {
      const [pill, cls, watch, watching, falls, pose, n, person] = parts;
      html = `<div class="rc-head"><b>${esc(id)}</b> <span class="pill${cls}">${esc(pill)}</span></div>` +
        `<div class="rc-watch${watching || paused ? "" : " warn"}">${esc(watch)}</div>` +
        (person ? `<div class="rc-person${person.absent ? " warn" : ""}">person ${esc(person.text)}</div>` : "") +
        `<div class="rc-falls${n ? " warn" : ""}">${esc(falls)}</div><div class="rc-pose note">${esc(pose)}</div>`;
    }
    if (b.posedHtml !== html) { b.innerHTML = html; b.posedHtml = html; }
  });
  const note = document.getElementById("robots-note");
  note.textContent = (ids.length ? "" : "no robot heard from on the bus yet. ") +
    (view.unlisted ? `${view.unlisted} more robot(s) on the bus are not listed: this page lists at most ` +
      `${view.maxRobots}. ` : "") +
    (view.selectedBy === "hash" ? "Following the robot you chose (kept in the address)." :
      ids.length ? "Following " + (openFalls()[view.selected] ? "the robot with a fall not acknowledged" :
        "the first robot") + " until you click a card." : "");
}

function takeCards(m) {  // a snapshot's cards (all), or a cards message (the changed ones)
  if (m.type === "snapshot") view.cards = {};
  for (const c of m.cards || []) view.cards[c.robot] = c;
  for (const id of m.forget || []) delete view.cards[id];
  view.unlisted = m.unlisted || 0; view.maxRobots = m.max_robots || 0;
}

// ------------------------------------------------------------------ the stream
function onMessage(m) {
  if (m.type === "snapshot") {
    view.labels = m.labels || {}; view.everyRobot = m.robot === "*"; view.shownRobot = m.shown_robot || null;
    if (view.everyRobot) {
      view.selected = view.shownRobot; view.selectedBy = hashRobot() ? "hash" : "default"; takeCards(m);
    }
    view.poseRobots = {};
    showRobotName();
    if (m.state_words) STATE_WORDS = m.state_words;
    view.streamLost = null;
    angleLog.length = 0;   // a snapshot again (a reconnect, or a resync after this page fell behind): its minute
    for (const a of m.angles) angleLog.push(a);
    if (m.status) showStatus(m.status);
    view.events = {};   // the server's list replaces this page's: what it forgot is gone here too
    for (const e of m.events) view.events[e.id + "/" + e.state] = e;
    view.acked = {};
    for (const id of m.acked) view.acked[id] = true;
    showAlive(m.alive); showBus(m.bus); showRobot(m.robot_state);
    if (m.pose) {
      view.lastPose = m.pose; if (m.pose.ok) view.lastGood = m.pose; showEvidence(m.pose); showAnglesNow(m.pose); drawSkeleton();
    }
    showEvents(); drawChart();
  } else if (view.everyRobot && "robot" in m && (m.robot || null) !== view.shownRobot &&
             ["pose", "status", "alive", "robot"].includes(m.type)) {
    // another robot's live part (from a stream of before a selection changed): never shown as this one's
  } else if (m.type === "pose") {
    view.poseRobots[m.robot] = (view.poseRobots[m.robot] || 0) + 1;
    view.poses += 1; view.lastPose = m; setText("st-poses", view.poses);
    if (m.ok && Object.keys(m.joints).length) view.lastGood = m;
    showEvidence(m);
    angleLog.push({time_unix: m.time_unix, angles: m.angles});
    while (angleLog.length && angleLog[0].time_unix < m.time_unix - WINDOW_S) angleLog.shift();
    showAnglesNow(m);
    requestDraw();
  } else if (m.type === "status") {
    showStatus(m);
  } else if (m.type === "event") {
    // a new state of an acknowledged event is a new message: the robot needs it acknowledged too
    view.events[m.id + "/" + m.state] = m; delete view.acked[m.id]; requestEvents(); loadHistory();
  } else if (m.type === "forget") {  // the server no longer holds them: acknowledged and older than the window
    const gone = new Set(m.ids);
    for (const k of Object.keys(view.events)) if (gone.has(view.events[k].id)) delete view.events[k];
    for (const id of m.ids) delete view.acked[id];
    requestEvents();
  } else if (m.type === "acked") {
    if (m.confirmed) view.acked[m.id] = true; requestEvents();
  } else if (m.type === "alive") {
    showAlive(m.alive);
  } else if (m.type === "bus") {
    showBus(m); loadHistory();
  } else if (m.type === "robot") {
    showRobot(m); if (view.stale) requestDraw();
  } else if (m.type === "cards") {
    takeCards(m); fleetChanged();
  }
}

let eventsPending = false;
function requestEvents() {  // the fall list drawn once for a burst of messages (a backlog), not once each
  if (eventsPending) return;
  eventsPending = true;
  setTimeout(() => { eventsPending = false; showEvents(); }, 0);
}

let drawPending = false;
function requestDraw() {
  if (drawPending) return;
  drawPending = true;
  const draw = () => { drawPending = false; drawSkeleton(); drawChart(); };
  if (document.hidden) setTimeout(draw, 0); else requestAnimationFrame(draw);
}

let es = null;
function connect() {  // the stream; a page of every robot names the robot it follows (its live parts only)
  if (es) es.close();
  const robot = view.selected || hashRobot();
  es = new EventSource(withToken("/stream" + (robot ? "?robot=" + encodeURIComponent(robot) : "")));
  es.onopen = () => { view.connected = true; showLiveness(); };
  es.onerror = () => {  // the server is gone (or restarting): nothing here is live until the next snapshot
    view.connected = false;
    if (view.streamLost === null) view.streamLost = serverNow();
    showLiveness(); requestDraw();
  };
  es.onmessage = (ev) => onMessage(JSON.parse(ev.data));
}

drawSkeleton(); drawChart(); connect(); loadHistory();
setInterval(loadHistory, 20000);
setInterval(() => { showLiveness(); if (view.stale) drawSkeleton(); }, 1000);   // the ages go on
window.addEventListener("resize", requestDraw);
