// The web Guest: watches the lab, and drives it once admitted. What it
// sends is built in protocol.js; the Host judges all of it as it judges
// `vl guest`'s.
"use strict";

const $ = (id) => document.getElementById(id);

// Words for what the Host says, as `vl guest` puts them: the operator's
// actions among the events the lab's net enables (the rest are the Host's).
const ACTIONS = {
  mount: "mount an experiment", define: "define the run", start: "start a run",
  command: "drive", stop: "stop the run",
};
const ENDINGS = {
  goal_reached: "goal reached", stopped: "stopped by the operator",
  time_limit: "time limit passed", operator_left: "the operator left",
  fault: "the robot faulted", emergency_stop: "emergency stop",
  operator_silent: "the operator went silent", robot_lost: "the camera lost the robot",
  held_back: "held back by the safety layer", slot_ended: "the operator's slot ended",
  kicked: "ended by an administrator",
};
const DEVICES = { online: "online", offline: "not answering", absent: "none" };
// The colours the desktop window draws with (legend.js, from the Host).
const COLOUR = Object.fromEntries(LEGEND.map((m) => [m.id, m.colour]));
// What the page draws, in the legend under the camera view.
const DRAWN = ["robot", "trail", "path", "goal", "force"];
const ROLES = { operator: "driving", observer: "watching" };

// Everything the page knows, one place (read by the tests as window.vl).
const vl = {
  socket: null, link: "connecting", role: null, session: null, resume: null,
  wanted: "observer", login: {}, user: null, lineAfterWelcome: false, experiments: [], lab: null, scene: null, state: null,
  status: null, definition: null, forecast: null, planned: null, goal: null, waypoints: [], controller: null,
  feedback: null, trail: [], running: false, lastEvent: 0, sentEvent: 0,
  lastCommandAt: 0, summary: null, error: null, rttMs: null,
  frame: null, frames: 0, image: null, keys: new Set(), stick: { v: 0, w: 0 },
  gamepad: null, queue: null, waiting: 0, controlEnded: null, lastRun: null, sent: [],
  feedbackAt: null, frameAt: null, stopUnsent: false,
};
window.vl = vl;

// A page an LMS launched (LTI) carries its person's session, and what the
// course's link asks for: it logs in with the session, no password.
function meta(name) {
  const m = document.querySelector(`meta[name="${name}"]`);
  return m ? m.content : null;
}
const launched = meta("vl-session");
if (launched) {
  vl.login = { session: launched };
  if (meta("vl-drives") === "yes") vl.wanted = "operator";
  const assignment = meta("vl-assignment");
  if (assignment) { text("assignment", `Your course asks for ${assignment}.`); show("assignment", true); }
  const goal = (meta("vl-goal") || "").split(",").map(Number);
  if (goal.length === 2 && goal.every(Number.isFinite)) { $("goal-x").value = goal[0]; $("goal-y").value = goal[1]; }
  const roster = meta("vl-roster");
  // Posted, the session in the form's body: a link's query would leave it
  // in the history, logs and the referrer.
  if (roster) { $("roster").action = roster; $("roster-session").value = launched; show("roster", true); }
  show("login", false);
}

// ---- the link ---------------------------------------------------------

function url() {
  const scheme = location.protocol === "https:" ? "wss:" : "ws:";
  return `${scheme}//${location.host}/`;
}

let retry = 250;
function connect() {
  const socket = new WebSocket(url());
  socket.binaryType = "arraybuffer";
  vl.socket = socket;
  vl.link = "connecting";
  socket.onopen = () => {
    retry = 250;
    send(VL.guest.hello(vl.wanted, vl.login, vl.resume));
  };
  socket.onmessage = (event) => {
    if (typeof event.data === "string") {
      let message;
      try { message = JSON.parse(event.data); } catch { return; }
      take(message);
    } else {
      takeFrame(event.data);
    }
    render();
  };
  socket.onclose = () => {
    if (vl.socket !== socket) return;
    // Refused at the door: knocking again would be refused again.
    if (vl.link === "refused") return;
    vl.link = "closed";
    vl.running = false;
    render();
    setTimeout(connect, retry);
    retry = Math.min(retry * 2, 4000);
  };
}

function send(message) {
  if (!vl.socket || vl.socket.readyState !== WebSocket.OPEN) return false;
  vl.socket.send(JSON.stringify(message));
  if (message.type !== "ping" && message.type !== "pong" && message.type !== "command") {
    vl.sent.push(message.type);
  }
  return true;
}

// Says hello again as `role`: a new connection, so the old role is let go.
function rejoin(role) {
  vl.wanted = role;
  if (role === "observer") vl.resume = null;
  const old = vl.socket;
  vl.socket = null;
  if (old) {
    if (old.readyState === WebSocket.OPEN) old.send(JSON.stringify(VL.guest.bye()));
    old.onclose = null;
    old.close();
  }
  connect();
}

// How old what the Host measured is now: the time since it arrived, and
// half a round trip on the way (the Host's clocks are its own).
function ageMs(arrivedAt) {
  if (arrivedAt === null) return null;
  return performance.now() - arrivedAt + (vl.rttMs === null ? 0 : vl.rttMs / 2);
}

// ---- what the Host says -----------------------------------------------

function take(m) {
  switch (m.type) {
    case "welcome":
      vl.link = "open"; vl.role = m.role; vl.session = m.session; vl.user = m.user || null;
      vl.slotEnds = m.slot_s ? performance.now() + m.slot_s * 1000 : null;
      vl.experiments = m.experiments || []; vl.resume = m.resume || null;
      vl.scene = m.scene || null; vl.lab = null;
      // Told someone drives: wait in line for control, as `vl guest` does.
      if (vl.lineAfterWelcome && m.role === "observer") send(VL.guest.queue());
      vl.lineAfterWelcome = false;
      // A Host started again counts anew: forget what it said.
      vl.feedback = null; vl.frame = null; vl.feedbackAt = null; vl.frameAt = null;
      vl.image = null;
      clearError();
      break;
    case "role":
      vl.role = m.role; if (m.resume) vl.resume = m.resume;
      vl.slotEnds = m.role === "operator" && m.slot_s ? performance.now() + m.slot_s * 1000 : null;
      if (m.role === "operator") vl.queue = null;
      vl.controlEnded = m.role === "observer" ? m.ended || null : null;
      break;
    case "queue":
      vl.queue = m.position ? m : null; vl.waiting = m.length || 0;
      if (vl.queue) vl.controlEnded = null;
      clearError();
      break;
    case "mounted":
      vl.lab = m; vl.definition = null; vl.planned = null; vl.goal = null; vl.waypoints = [];
      vl.controller = null; $("controller-file").value = "";
      vl.forecast = null; vl.trail = []; vl.summary = null;
      break;
    case "state": {
      vl.state = m;
      // Who joins during a run hears no `started`: the net says it runs,
      // and says when it no longer does (a `done` missed is no run forever).
      const marking = m.marking || [];
      const running = marking.includes("execute.running");
      if (running && !vl.running) { vl.running = true; vl.trail = []; vl.summary = null; }
      if (!running && !marking.includes("execute.stopping")) vl.running = false;
      break;
    }
    case "status": vl.status = m; vl.lastRun = m.last_run || null; break;
    case "planned":
      // A plan through points since clicked again is no longer the one wanted.
      if (vl.waypoints.length && !(vl.goal && m.goal.x_mm === vl.goal.x_mm && m.goal.y_mm === vl.goal.y_mm)) break;
      vl.planned = m.path; vl.goal = m.goal; clearError(); break;
    case "defined": vl.definition = m; vl.planned = null; clearError(); break;
    case "controller_taken": vl.controller = m; clearError(); break;
    case "forecast": vl.forecast = m; break;
    case "started":
      vl.running = true; vl.lastEvent = m.event; vl.sentEvent = m.event;
      vl.trail = []; vl.summary = null; clearError();
      break;
    case "feedback": takeFeedback(m); break;
    case "done": vl.running = false; vl.summary = m.summary; break;
    case "error":
      vl.error = { code: m.code, message: m.message, at: performance.now() };
      if (m.code === "operator_taken" && vl.wanted === "operator" && vl.link !== "open") {
        // Watch meanwhile, and take a place in line.
        vl.lineAfterWelcome = true;
        rejoin("observer");
      } else if (m.code === "unauthorized" || m.code === "too_many_attempts") {
        if (vl.link !== "open") vl.link = "refused";
      }
      break;
    case "ping": send(VL.guest.pong(m.t)); break;
    case "pong": vl.rttMs = performance.now() - m.t; break;
    case "bye": break;
  }
}

function takeFeedback(m) {
  if (vl.feedback && m.event < vl.feedback.event && vl.running) return;
  vl.feedback = m;
  vl.feedbackAt = performance.now();
  if (vl.running) {
    vl.lastEvent = Math.max(vl.lastEvent, m.event);
    const last = vl.trail[vl.trail.length - 1];
    if (!last || Math.hypot(last.x_mm - m.pose.x_mm, last.y_mm - m.pose.y_mm) > 2) {
      vl.trail.push({ x_mm: m.pose.x_mm, y_mm: m.pose.y_mm });
      if (vl.trail.length > 5000) vl.trail.shift();
    }
    drive();
    rumble(m.force);
  }
}

// The force the obstacles push back with, felt in a gamepad that rumbles
// (the browser's Gamepad API has no force-feedback stick).
let rumbledAt = 0;
function rumble(force) {
  const pad = vl.gamepad;
  if (!force || vl.role !== "operator" || !pad || !pad.vibrationActuator) return;
  const strength = Math.min(1, Math.hypot(force[0], force[1]));
  const now = performance.now();
  if (strength < 0.05 || now - rumbledAt < 100) return;
  rumbledAt = now;
  pad.vibrationActuator.playEffect("dual-rumble", {
    duration: 120, strongMagnitude: strength, weakMagnitude: strength / 2,
  }).catch(() => {});
}

function takeFrame(buffer) {
  const f = VL.frame(buffer);
  if (!f || (vl.frame && f.seq <= vl.frame.seq)) return;
  vl.frame = f;
  vl.frameAt = performance.now();
  vl.frames += 1;
  createImageBitmap(f.image).then((bitmap) => {
    if (vl.image) vl.image.close();
    vl.image = bitmap;
    draw();
  }, () => {});
}

function clearError() { vl.error = null; }

// ---- driving ----------------------------------------------------------

const KEYS = {
  ArrowUp: [1, 0], KeyW: [1, 0], ArrowDown: [-1, 0], KeyS: [-1, 0],
  ArrowLeft: [0, 1], KeyA: [0, 1], ArrowRight: [0, -1], KeyD: [0, -1],
};
// The stick's full throw: forward mm/s and turn rad/s.
const FULL_V = 200, FULL_W = 2.0;
// Commands go at most this often (event-based: and only after the
// feedback of the one before).
const COMMAND_EVERY_MS = 40;

function stick() {
  let v = 0, w = 0;
  for (const key of vl.keys) {
    const [dv, dw] = KEYS[key] || [0, 0];
    v += dv; w += dw;
  }
  const pad = vl.gamepad;
  if (pad && (Math.abs(pad.axes[1]) > 0.1 || Math.abs(pad.axes[0]) > 0.1)) {
    v = -pad.axes[1]; w = -pad.axes[0];
  }
  v = Math.max(-1, Math.min(1, v)); w = Math.max(-1, Math.min(1, w));
  vl.stick = { v, w };
  return { v: v * FULL_V, w: w * FULL_W };
}

// Sends the next command once the feedback of the last has come.
function drive() {
  if (!vl.running || vl.role !== "operator") return;
  // A run the user's controller drives, or one held still, takes none.
  if (runs("controller") || runs("hold")) return;
  const following = vl.definition && vl.definition.path && vl.definition.path.length > 1;
  const s = stick();
  // A followed path needs no commands; a command takes over while they come.
  if (following && s.v === 0 && s.w === 0) return;
  if (vl.sentEvent > vl.lastEvent) return;
  const now = performance.now();
  if (now - vl.lastCommandAt < COMMAND_EVERY_MS) return;
  vl.lastCommandAt = now;
  vl.sentEvent = vl.lastEvent + 1;
  send(VL.guest.command(vl.sentEvent, vl.lastEvent, s.v, s.w));
}

// The keys drive only the operator of a teleoperation lab; for everyone
// else they scroll and move between controls as usual.
function keysDrive() {
  return vl.role === "operator" && runs("teleoperate");
}
document.addEventListener("keydown", (e) => {
  if (KEYS[e.code] && keysDrive() && e.target.tagName !== "INPUT") {
    vl.keys.add(e.code); e.preventDefault(); drive(); render();
  }
});
document.addEventListener("keyup", (e) => {
  if (KEYS[e.code]) { vl.keys.delete(e.code); render(); }
});
window.addEventListener("blur", () => vl.keys.clear());
window.addEventListener("gamepadconnected", (e) => { vl.gamepad = e.gamepad; render(); });
window.addEventListener("gamepaddisconnected", () => { vl.gamepad = null; render(); });

// ---- the camera view --------------------------------------------------

const canvas = $("camera");
const ctx = canvas.getContext("2d");

// The floor, robot and camera to draw with: the mounted lab's, else the
// welcome's (the robot is drawn before anything is mounted).
function scene() { return vl.lab || vl.scene; }
function camera() { const s = scene(); return s && s.camera; }

function polyline(points, style, width, dash) {
  const cam = camera();
  if (!cam || points.length < 2) return;
  ctx.save();
  ctx.strokeStyle = style; ctx.lineWidth = width; ctx.setLineDash(dash || []);
  ctx.beginPath();
  points.forEach((p, i) => {
    const [x, y] = VL.toPixel(cam, p);
    if (i === 0) ctx.moveTo(x, y); else ctx.lineTo(x, y);
  });
  ctx.stroke();
  ctx.restore();
}

// The arena as its map describes it, where there is no camera image.
function drawArena(cam) {
  const arena = scene().arena;
  const shape = (points) => {
    ctx.beginPath();
    points.forEach((p, i) => {
      const [x, y] = VL.toPixel(cam, p);
      if (i === 0) ctx.moveTo(x, y); else ctx.lineTo(x, y);
    });
    ctx.closePath(); ctx.fill();
  };
  const box = (x, y, w, h) => shape([
    { x_mm: x, y_mm: y }, { x_mm: x + w, y_mm: y }, { x_mm: x + w, y_mm: y + h }, { x_mm: x, y_mm: y + h },
  ]);
  ctx.fillStyle = COLOUR.floor;
  box(0, 0, arena.width_mm, arena.height_mm);
  ctx.fillStyle = COLOUR.obstacle;
  for (const o of arena.obstacles) {
    if (o.shape === "rect") box(o.x_mm, o.y_mm, o.width_mm, o.height_mm);
    else if (o.shape === "polygon") shape(o.points);
    else if (o.shape === "circle") {
      const n = 48, ring = [];
      for (let i = 0; i < n; i++) {
        const a = (2 * Math.PI * i) / n;
        ring.push({ x_mm: o.x_mm + o.radius_mm * Math.cos(a), y_mm: o.y_mm + o.radius_mm * Math.sin(a) });
      }
      shape(ring);
    }
  }
}

function draw() {
  const cam = camera();
  const width = cam ? cam.width_px : (vl.image ? vl.image.width : 640);
  const height = cam ? cam.height_px : (vl.image ? vl.image.height : 480);
  if (canvas.width !== width) canvas.width = width;
  if (canvas.height !== height) canvas.height = height;
  ctx.fillStyle = "#20242a";
  ctx.fillRect(0, 0, width, height);
  if (vl.image) ctx.drawImage(vl.image, 0, 0, width, height);
  if (!cam) return;
  if (!vl.image) drawArena(cam);
  if (vl.definition && vl.definition.path) polyline(vl.definition.path, COLOUR.path, 3);
  if (vl.planned) polyline(vl.planned, COLOUR.path, 2, [6, 4]);
  polyline(vl.trail, COLOUR.trail, 2);
  const goal = (vl.definition && vl.definition.goal) || vl.goal;
  if (goal) {
    const [x, y] = VL.toPixel(cam, goal);
    ctx.strokeStyle = COLOUR.goal; ctx.lineWidth = 3;
    ctx.beginPath(); ctx.arc(x, y, 8, 0, 2 * Math.PI); ctx.stroke();
  }
  const waypoints = (vl.definition && vl.definition.waypoints) || vl.waypoints;
  ctx.fillStyle = COLOUR.goal; ctx.font = "13px sans-serif";
  waypoints.forEach((p, i) => {
    const [x, y] = VL.toPixel(cam, p);
    ctx.beginPath(); ctx.arc(x, y, 6, 0, 2 * Math.PI); ctx.stroke();
    ctx.fillText(String(i + 1), x + 8, y - 8);
  });
  if (vl.feedback) {
    const pose = vl.feedback.pose;
    const [x, y] = VL.toPixel(cam, pose);
    const r = scene().robot.radius_mm;
    const [hx, hy] = VL.toPixel(cam, {
      x_mm: pose.x_mm + r * Math.cos(pose.theta_rad),
      y_mm: pose.y_mm + r * Math.sin(pose.theta_rad),
    });
    const [ex] = VL.toPixel(cam, { x_mm: pose.x_mm + r, y_mm: pose.y_mm });
    ctx.strokeStyle = vl.feedback.limited ? COLOUR.force : COLOUR.robot; ctx.lineWidth = 2;
    ctx.beginPath(); ctx.arc(x, y, Math.abs(ex - x), 0, 2 * Math.PI); ctx.stroke();
    ctx.beginPath(); ctx.moveTo(x, y); ctx.lineTo(hx, hy); ctx.stroke();
  }
}

// The mounted experiment, as the Host's welcome declares it: what its
// run is made of and what the user defines decide the page's controls.
function mounted() {
  return (vl.lab && vl.experiments.find((e) => e.id === vl.lab.experiment)) || null;
}
function runs(component) {
  const e = mounted();
  return !!(e && e.run && e.run.components.includes(component));
}
// How many waypoints the mounted experiment visits, {min, max}; none.
function waypointBounds() {
  const e = mounted();
  return (e && (e.define || []).find((d) => d.kind === "waypoints")) || null;
}

// A click on the floor is a goal, or the next waypoint: the Host plans a
// path to it (through the waypoints before it).
canvas.addEventListener("click", (e) => {
  const cam = camera();
  if (!cam || vl.role !== "operator" || !enabled("define")) return;
  if (!runs("plan") && !runs("controller")) return;
  const box = canvas.getBoundingClientRect();
  const c = (e.clientX - box.left) * (canvas.width / box.width);
  const r = (e.clientY - box.top) * (canvas.height / box.height);
  const p = VL.toArena(cam, c, r);
  // The user's controller drives to the goal: nothing to plan.
  if (!runs("plan")) { vl.goal = p; return render(); }
  const bounds = waypointBounds();
  if (!bounds) return planTo(p);
  if (vl.waypoints.length >= bounds.max) return;
  vl.waypoints.push(p);
  // The plan through the points so far is no more: a new one is asked for
  // once the clicks pause (the Host plans one every quarter second).
  vl.planned = null; vl.goal = null;
  clearTimeout(vl.planLater);
  if (vl.waypoints.length >= bounds.min) {
    vl.planLater = setTimeout(() => planTo(p, vl.waypoints.slice(0, -1)), PLAN_PAUSE_MS);
  }
  render();
});
// How long the clicks on the floor pause before the points are planned.
const PLAN_PAUSE_MS = 400;

// Asks the Host for a path to `goal` (from a click or the goal's fields),
// through `through` first.
function planTo(goal, through) {
  vl.goal = goal;
  $("goal-x").value = Math.round(goal.x_mm); $("goal-y").value = Math.round(goal.y_mm);
  send(VL.guest.plan(goal, through));
  render();
}

// The force the obstacles push back with, over the stick.
function drawStick() {
  const c = $("stick"), g = c.getContext("2d");
  const m = c.width / 2;
  g.clearRect(0, 0, c.width, c.height);
  g.strokeStyle = "#888"; g.lineWidth = 1;
  g.beginPath(); g.arc(m, m, m - 4, 0, 2 * Math.PI); g.stroke();
  g.fillStyle = "#1e7fff";
  g.beginPath(); g.arc(m - vl.stick.w * (m - 10), m - vl.stick.v * (m - 10), 6, 0, 2 * Math.PI); g.fill();
  const force = vl.feedback && vl.feedback.force;
  if (force && Math.hypot(force[0], force[1]) > 0.01) {
    const tx = m + force[0] * (m - 8), ty = m - force[1] * (m - 8);
    g.strokeStyle = COLOUR.force; g.fillStyle = COLOUR.force; g.lineWidth = 3;
    g.beginPath(); g.moveTo(m, m); g.lineTo(tx, ty); g.stroke();
    const a = Math.atan2(ty - m, tx - m);
    g.beginPath(); g.moveTo(tx, ty);
    g.lineTo(tx - 10 * Math.cos(a - 0.4), ty - 10 * Math.sin(a - 0.4));
    g.lineTo(tx - 10 * Math.cos(a + 0.4), ty - 10 * Math.sin(a + 0.4));
    g.fill();
  }
}

// ---- the panel --------------------------------------------------------

function enabled(event) {
  return !!(vl.state && vl.state.enabled && vl.state.enabled.includes(event));
}

function text(id, value) {
  const el = $(id);
  if (el.textContent !== value) el.textContent = value;
}

function show(id, visible) { $(id).hidden = !visible; }

function labWords() {
  if (!vl.status) return "…";
  const s = vl.status;
  const lab = s.lab === "getting_ready" ? "getting ready: the robot drives back to its start" : "ready";
  return `robot ${DEVICES[s.robot] || s.robot}, camera ${DEVICES[s.camera] || s.camera}; lab ${lab}`;
}

function runWords() {
  // Held back or not is its own line (#held): text that changed length
  // here would move the buttons below it under the user's pointer.
  if (vl.running) return "a run is under way";
  if (vl.summary) {
    const s = vl.summary;
    return `last run: ${ENDINGS[s.reason] || s.reason} after ${s.seconds.toFixed(1)} s, ` +
      `${(s.distance_mm / 1000).toFixed(2)} m, ${s.collisions} contacts`;
  }
  const r = vl.lastRun;
  if (r && r.ended) {
    return `last run: ${ENDINGS[r.ended] || r.ended} (run ${r.run}, ${r.experiment}` +
      `${r.user ? `, driven by ${r.user}` : ""})`;
  }
  return "no run yet";
}

function netWords() {
  if (!vl.state) return "…";
  const can = (vl.state.enabled || []).filter((e) => ACTIONS[e]).map((e) => ACTIONS[e]);
  const lab = vl.lab ? `“${(mounted() || {}).title || vl.lab.experiment}” mounted` : "nothing mounted";
  return `${lab}; the lab's net lets the operator ${can.length ? can.join(", ") : "do nothing now"}`;
}

function forecastWords() {
  const f = vl.forecast;
  if (!f) return "";
  if (f.refusals && f.refusals.length) return "the twin refused this definition: define another";
  const runs = f.forecast.runs;
  const reached = runs.filter((r) => r.reached_goal).length;
  const mean = runs.reduce((s, r) => s + r.seconds, 0) / Math.max(runs.length, 1);
  return `tried on the lab's twin: ${reached} of ${runs.length} runs reach the goal, in ${mean.toFixed(1)} s`;
}

// What whoever looks at the page may do next, in a line.
function nextWords() {
  if (vl.link !== "open") return "";
  if (vl.role === "observer") {
    if (vl.queue) return "";
    const why = { slot_ended: "your slot ended", kicked: "an administrator ended your turn" };
    if (vl.controlEnded) return `You watch now: ${why[vl.controlEnded] || vl.controlEnded}, and the next in line drives. Ask for control to drive again.`;
    return "You watch. Ask for control to drive.";
  }
  if (!vl.lab) return "Next: mount an experiment below.";
  const navigation = runs("follow");
  const controls = runs("controller");
  const bounds = waypointBounds();
  if (vl.running) {
    if (controls) return "Your controller drives: Stop ends the run, STOP halts it at once.";
    return navigation ? "The robot follows the path: Stop ends the run, STOP halts it at once." :
      "Drive with the arrow keys or a gamepad: Stop ends the run, STOP halts it at once.";
  }
  if (vl.status && vl.status.lab === "getting_ready") return "Wait: the robot drives back to its start.";
  if (controls && !vl.definition) {
    return !vl.controller ? "Next: choose your controller's file (below the view)." :
      !vl.goal ? "Next: click the floor for its goal." : "Next: Define: the twin tries your controller first.";
  }
  const path = (vl.definition && vl.definition.path && vl.definition.path.length > 1) ||
    (controls && vl.definition);
  if (navigation && !vl.definition && bounds && !vl.planned) {
    return `Next: click the floor for each point to visit, in order (${bounds.min} to ${bounds.max}).`;
  }
  if (navigation && !vl.definition) {
    return vl.planned ? "Next: Define, to run along the planned path." :
      "Next: choose a goal (click the floor, or type it below the view).";
  }
  if (!vl.definition) return "Next: Define the run (no path: you drive), then Start.";
  if (path && !vl.forecast) return "The lab's twin tries the definition first…";
  if (vl.forecast && vl.forecast.refusals && vl.forecast.refusals.length) {
    return controls ? "Next: change your controller or its goal: the twin refused it (see why above)." :
      "Next: choose another goal: the twin refused this definition.";
  }
  return enabled("start") ? "Next: Start the run." : "";
}

// The mount buttons, made once per list of experiments (a button replaced
// under the pointer would lose its click, and the focus with it).
let mountsFor = null;
function mountButtons() {
  const key = vl.experiments.map((e) => e.id).join(",");
  if (key !== mountsFor) {
    mountsFor = key;
    $("mounts").replaceChildren(...vl.experiments.map((e) => {
      const b = document.createElement("button");
      b.textContent = e.title;
      b.dataset.experiment = e.id;
      b.onclick = () => send(VL.guest.mount(e.id));
      return b;
    }));
  }
  for (const b of $("mounts").children) {
    b.disabled = !enabled("mount") || (vl.lab && vl.lab.experiment === b.dataset.experiment);
  }
}

function render() {
  const operator = vl.role === "operator";
  const who = vl.user ? ` as ${vl.user}` : "";
  text("link", vl.link === "open" ? `connected${who} · ${ROLES[vl.role] || "…"}` :
    vl.link === "closed" ? "disconnected: connecting again…" :
    vl.link === "refused" ? (launched ? "not let in: open the lab from your course again" : "not let in: log in below") :
    "connecting…");
  $("link").className = vl.link === "open" ? "ok" : "bad";
  text("rtt", vl.rttMs === null ? "round trip …" : `round trip ${vl.rttMs.toFixed(0)} ms`);
  // An image is as old as the pose plus how much earlier the Host
  // captured it than it measured the pose (the two share its lab clock).
  const poseAge = vl.link === "open" ? ageMs(vl.feedbackAt) : null;
  const f0 = vl.feedback, fr = vl.frame;
  let imageAge = vl.link === "open" && vl.image ? ageMs(vl.frameAt) : null;
  if (imageAge !== null && poseAge !== null && f0 && fr) {
    imageAge = poseAge + Math.max(0, f0.t_ms - fr.captureMs);
  }
  const ms = (a) => (a === null ? "…" : `${a.toFixed(0)} ms`);
  text("age", (vl.image ? `image ${ms(imageAge)} old · ` : "no image · ") + `pose ${ms(poseAge)} old`);
  text("lab", labWords());
  text("net", netWords());
  text("run", runWords());
  text("forecast", forecastWords());
  const f = vl.feedback;
  text("pose", f ? `x ${f.pose.x_mm.toFixed(0)} mm, y ${f.pose.y_mm.toFixed(0)} mm, ` +
    `heading ${(f.pose.theta_rad * 180 / Math.PI).toFixed(0)}° (${f.source === "camera" ? "camera and wheels" : "wheels alone"})` : "…");
  text("held", f && f.limited ? "held back by the safety layer" : "");
  text("error", vl.error ? vl.error.message : "");
  show("error", !!vl.error);
  const left = vl.slotEnds && operator ? Math.max(0, (vl.slotEnds - performance.now()) / 1000) : null;
  text("slot", left === null ? "" :
    `your turn ends in ${Math.floor(left / 60)}:${String(Math.floor(left % 60)).padStart(2, "0")}`);
  const q = vl.queue;
  text("queue", q ? `you are number ${q.position} of ${q.length} in line` +
    (q.wait_s !== undefined && q.wait_s !== null ? `, at most ${Math.max(1, Math.ceil(q.wait_s / 60))} min to wait` :
      ": slots have no length here, so you drive when the operator leaves") :
    operator && vl.waiting ? `${vl.waiting} waiting for control after you` : "");
  text("next", nextWords());

  show("drive", !operator);
  show("line", vl.link === "open" && vl.role === "observer");
  text("line", vl.queue ? "Leave the line" : "Ask for control");
  show("operate", operator);
  mountButtons();
  show("goal-hint", operator && runs("plan") && !waypointBounds() && !vl.running);
  const bounds = waypointBounds();
  show("waypoints-hint", operator && !!bounds && !vl.running);
  text("waypoints-count", bounds ?
    `${vl.waypoints.length} of ${bounds.min} to ${bounds.max} points: click the floor for each, in order.` : "");
  $("plan").disabled = !enabled("define");
  const controls = runs("controller");
  show("controller-hint", operator && controls && !vl.running);
  text("controller-taken", !vl.controller ? "none sent yet" :
    `taken: ${vl.controller.bytes} bytes, SHA-256 ${vl.controller.sha256.slice(0, 12)}…` +
    (vl.goal ? "" : "; now click the floor for its goal"));
  $("define").disabled = !(controls ? vl.controller && vl.goal : vl.planned && vl.goal) || !enabled("define");
  $("start").disabled = !enabled("start") || (vl.status && vl.status.lab === "getting_ready");
  $("stop").disabled = !enabled("stop");
  show("keys", operator && runs("teleoperate"));
  text("gamepad", vl.gamepad ? `gamepad: ${vl.gamepad.id}` : "no gamepad (press a button on one to use it)");
  draw();
  drawStick();
}

// ---- controls ---------------------------------------------------------

// The forms submit nowhere: their buttons act (and the page's policy
// allows no inline handler to say so).
for (const form of document.querySelectorAll("form")) {
  form.addEventListener("submit", (e) => e.preventDefault());
}

// The form's login: an account, else the lab's token.
function login() {
  const user = $("user").value.trim();
  return user ? { user, password: $("password").value } : { token: $("token").value };
}
$("ask").onclick = () => { vl.login = login(); rejoin("operator"); };
$("look").onclick = () => { vl.login = login(); rejoin("observer"); };
$("line").onclick = () => send(vl.queue ? VL.guest.leave_queue() : VL.guest.queue());
$("watch").onclick = () => rejoin("observer");
$("define").onclick = () => {
  if (runs("controller") && vl.controller && vl.goal) {
    send(VL.guest.define(vl.goal, [], [], vl.controller.sha256));
  } else if (vl.planned && vl.goal) {
    send(VL.guest.define(vl.goal, vl.planned, waypointBounds() ? vl.waypoints : []));
  }
};
$("start").onclick = () => send(VL.guest.start());
$("stop").onclick = () => send(VL.guest.stop());
$("estop").onclick = () => {
  if (vl.link === "open" && send(VL.guest.emergency_stop())) return;
  const message = vl.link === "refused" ?
    (launched ? "STOP was not sent: the lab no longer knows this page's session. Open the lab from your course again." :
      "STOP was not sent: this lab lets only those who log in watch, and STOP is theirs. Log in below to watch.") :
    "STOP was not sent: the page has no link to the Host now (connecting again). " +
      "The Host holds the robot still while its operator's link is down.";
  vl.error = { code: "not_sent", at: performance.now(), message };
  render();
};
// The user's controller: its file, read here and sent in parts.
$("controller-file").onchange = async () => {
  const file = $("controller-file").files[0];
  if (!file) return;
  vl.controller = null;
  if (file.size > 2 * 1024 * 1024) {
    vl.error = { code: "too_large", at: performance.now(),
      message: `${file.name} is ${file.size} bytes: a controller may have at most 2 MiB` };
    return render();
  }
  const bytes = new Uint8Array(await file.arrayBuffer());
  for (const part of VL.guest.controller(bytes)) send(part);
  render();
};
$("clear-points").onclick = () => {
  clearTimeout(vl.planLater);
  vl.waypoints = []; vl.planned = null; vl.goal = null; render();
};
$("plan").onclick = () => {
  const x = parseFloat($("goal-x").value), y = parseFloat($("goal-y").value);
  if (Number.isFinite(x) && Number.isFinite(y)) planTo({ x_mm: x, y_mm: y });
};
// The legend of what the view draws, in the window's colours.
$("legend").replaceChildren(...LEGEND.filter((m) => DRAWN.includes(m.id)).map((m) => {
  const li = document.createElement("li");
  const swatch = document.createElement("span");
  swatch.style.background = m.colour;
  li.append(swatch, m.words);
  return li;
}));

// The Host's clock and the round trip, every 200 ms as `vl guest` does;
// the gamepad and the stick at the screen's pace.
setInterval(() => send(VL.guest.ping(performance.now())), 200);
setInterval(render, 250);
function tick() {
  const pads = navigator.getGamepads ? navigator.getGamepads() : [];
  vl.gamepad = Array.from(pads).find((p) => p) || null;
  if (vl.running) drive();
  requestAnimationFrame(tick);
}
requestAnimationFrame(tick);
window.addEventListener("beforeunload", () => send(VL.guest.bye()));
connect();
render();
