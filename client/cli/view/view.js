// fulcrum view: draws a Fulcrum world on a canvas. Shapes come from /api/describe (the
// DescribeWorld reply as Protobuf JSON, shapes in body frames); poses from frames: in live mode
// Server-Sent Events from /events, in replay mode /api/replay/frame?tick=N. A frame is
//   {tick, hash, bodies, awake, full, destroyed: [[index, generation]...],
//    b: [[index, generation, x, y, angle, awake]...]}.
// The view transform is exposed as window.fulcrumView for tests and the console.
"use strict";

const $ = (id) => document.getElementById(id);
const canvas = $("canvas");
const ctx = canvas.getContext("2d");
const params = new URLSearchParams(location.search);

const colors = {
  background: "#1d2026",
  grid: "#262a31",
  static: "#7d8595",
  dynamic: "#4f9de8",
  kinematic: "#e8a04f",
  particle: "#5fcf8a",
  joint: "#f2d24b",
  drag: "#ff6e6e",
};
const typeColor = {
  BODY_TYPE_STATIC: colors.static,
  BODY_TYPE_KINEMATIC: colors.kinematic,
  BODY_TYPE_DYNAMIC: colors.dynamic,
  BODY_TYPE_PARTICLE: colors.particle,
};

// --- State ---------------------------------------------------------------------------------

const state = {
  mode: null,             // "live" or "replay"
  world: null,            // live: the world id shown
  bodies: new Map(),      // index -> {gen, x, y, angle, awake}
  shapes: new Map(),      // "index:gen" -> {type, shapes: [Shape JSON]}
  joints: [],             // DescribedJoint JSON
  tick: null,
  hash: "",
  describing: null,       // the /api/describe request in flight
  describeAgain: null,    // a describe queued behind it
  events: null,           // live: the EventSource
  drag: null,             // {joint, target: [x, y]} while a body is dragged
  replay: null,           // replay: /api/info's replay object
  playing: false,
};

// World (m, y up) to canvas (CSS px, y down): px = ox + x * scale, py = oy - y * scale.
const view = { scale: 30, ox: 0, oy: 0, fitted: false };
const toCanvas = (x, y) => [view.ox + x * view.scale, view.oy - y * view.scale];
const toWorld = (px, py) => [(px - view.ox) / view.scale, (view.oy - py) / view.scale];

function showError(message) { $("error").textContent = message || ""; }

async function api(path, options) {
  const res = await fetch(path, options);
  const body = await res.json();
  if (!res.ok) throw new Error(body.error || res.statusText);
  return body;
}
const post = (path) => api(path, { method: "POST" });

// --- Frames and descriptions ---------------------------------------------------------------

function applyFrame(f) {
  if (f.full) state.bodies.clear();
  for (const [index, gen] of f.destroyed) {
    const b = state.bodies.get(index);
    if (b && b.gen === gen) state.bodies.delete(index);
  }
  let unknown = false;
  for (const [index, gen, x, y, angle, awake] of f.b) {
    state.bodies.set(index, { gen, x, y, angle, awake: awake === 1 });
    if (!state.shapes.has(index + ":" + gen)) unknown = true;
  }
  state.tick = f.tick;
  state.hash = f.hash;
  $("tick").textContent = f.tick;
  $("hash").textContent = f.hash;
  $("counts").textContent = `bodies ${f.bodies}  awake ${f.awake}`;
  if (unknown || f.destroyed.length > 0) describe();
  requestDraw();
}

// Fetches the shapes of every body (again when bodies appear that the page does not know).
function describe() {
  if (state.describing) {
    // The request in flight may have left before the change its caller knows of (an edit, a
    // new drag joint): describe once more after it.
    if (!state.describeAgain) {
      state.describeAgain = state.describing.then(() => {
        state.describeAgain = null;
        return describe();
      });
    }
    return state.describeAgain;
  }
  const path = state.mode === "live" ? `/api/describe?world=${state.world}` : "/api/describe";
  state.describing = api(path)
    .then((d) => {
      state.shapes.clear();
      // A description at least as new as the last frame is the world as it is: edits made
      // while a world is paused change it without a frame (frames come with ticks).
      const current = state.tick === null || Number(d.tick) >= state.tick;
      if (current) state.bodies.clear();
      for (const b of d.bodies || []) {
        state.shapes.set(b.handle.index + ":" + b.handle.generation,
                         { type: b.body.type, shapes: b.body.shapes || [] });
        if (current || !state.bodies.has(b.handle.index)) {
          state.bodies.set(b.handle.index, { gen: b.handle.generation,
                                             x: b.body.position.x, y: b.body.position.y,
                                             angle: b.body.angle, awake: b.body.awake });
        }
      }
      state.joints = d.joints || [];
      if (!view.fitted) fit();
      requestDraw();
    })
    .catch((e) => showError("describe: " + e.message))
    .finally(() => { state.describing = null; });
  return state.describing;
}

// --- Drawing -------------------------------------------------------------------------------

let drawQueued = false;
function requestDraw() {
  if (drawQueued) return;
  drawQueued = true;
  requestAnimationFrame(() => { drawQueued = false; draw(); });
}

function resize() {
  const dpr = window.devicePixelRatio || 1;
  canvas.width = Math.round(canvas.clientWidth * dpr);
  canvas.height = Math.round(canvas.clientHeight * dpr);
  ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
  requestDraw();
}

// The world box of every described shape, at the bodies' current poses.
function worldBounds() {
  let lo = [Infinity, Infinity], hi = [-Infinity, -Infinity];
  const add = (x, y, r) => {
    lo = [Math.min(lo[0], x - r), Math.min(lo[1], y - r)];
    hi = [Math.max(hi[0], x + r), Math.max(hi[1], y + r)];
  };
  forEachShape((body, shape, xf) => {
    for (const [x, y, r] of shapePoints(shape)) { const p = xf(x, y); add(p[0], p[1], r); }
  });
  return lo[0] <= hi[0] ? { lo, hi } : null;
}

function fit() {
  const bounds = worldBounds();
  if (!bounds) return;
  const w = canvas.clientWidth, h = canvas.clientHeight;
  const sx = (bounds.hi[0] - bounds.lo[0]) || 1, sy = (bounds.hi[1] - bounds.lo[1]) || 1;
  view.scale = 0.9 * Math.min(w / sx, h / sy);
  view.ox = w / 2 - view.scale * (bounds.lo[0] + bounds.hi[0]) / 2;
  view.oy = h / 2 + view.scale * (bounds.lo[1] + bounds.hi[1]) / 2;
  view.fitted = true;
  requestDraw();
}

const v = (p) => [p ? p.x || 0 : 0, p ? p.y || 0 : 0];

// Points with radii that bound a shape (local frame), for fitting the view.
function shapePoints(s) {
  if (s.circle) return [[...v(s.circle.center), s.circle.radius]];
  if (s.capsule) return [[...v(s.capsule.center1), s.capsule.radius],
                         [...v(s.capsule.center2), s.capsule.radius]];
  if (s.segment) return [[...v(s.segment.point1), 0], [...v(s.segment.point2), 0]];
  if (s.polygon) return s.polygon.vertices.map((p) => [...v(p), s.polygon.radius || 0]);
  return [];
}

// Calls fn(body, shape, xf) for every shape, xf mapping body-local points to world points.
function forEachShape(fn) {
  for (const [index, body] of state.bodies) {
    const described = state.shapes.get(index + ":" + body.gen);
    if (!described) continue;
    const c = Math.cos(body.angle), s = Math.sin(body.angle);
    const xf = (x, y) => [body.x + c * x - s * y, body.y + s * x + c * y];
    for (const shape of described.shapes) fn({ ...body, type: described.type }, shape, xf);
  }
}

// A closed path of the shape in canvas coordinates (segments: an open path).
function shapePath(shape, xf) {
  const k = view.scale;
  ctx.beginPath();
  if (shape.circle) {
    const [x, y] = toCanvas(...xf(...v(shape.circle.center)));
    ctx.arc(x, y, shape.circle.radius * k, 0, 2 * Math.PI);
  } else if (shape.capsule) {
    // Two half circles joined by straight sides.
    const a = toCanvas(...xf(...v(shape.capsule.center1)));
    const b = toCanvas(...xf(...v(shape.capsule.center2)));
    const r = shape.capsule.radius * k;
    const t = Math.atan2(b[1] - a[1], b[0] - a[0]);
    ctx.arc(b[0], b[1], r, t - Math.PI / 2, t + Math.PI / 2);
    ctx.arc(a[0], a[1], r, t + Math.PI / 2, t + 3 * Math.PI / 2);
    ctx.closePath();
  } else if (shape.polygon) {
    // Rounded by `radius`: each corner an arc between the offset edges.
    const pts = shape.polygon.vertices.map((p) => toCanvas(...xf(...v(p))));
    const r = (shape.polygon.radius || 0) * k;
    const n = pts.length;
    if (r <= 0) {
      pts.forEach((p, i) => (i ? ctx.lineTo(...p) : ctx.moveTo(...p)));
    } else {
      for (let i = 0; i < n; ++i) {
        const p = pts[i], prev = pts[(i + n - 1) % n], next = pts[(i + 1) % n];
        // Outward normals of the two edges at p. Canvas y is down, so the counter-clockwise
        // polygon runs the other way here: the outward normal of edge d is (-dy, dx) / |d|,
        // and the corner's arc turns with decreasing angle (anticlockwise = true).
        const n1 = normal(prev, p), n2 = normal(p, next);
        ctx.arc(p[0], p[1], r, Math.atan2(n1[1], n1[0]), Math.atan2(n2[1], n2[0]), true);
      }
    }
    ctx.closePath();
  } else if (shape.segment) {
    ctx.moveTo(...toCanvas(...xf(...v(shape.segment.point1))));
    ctx.lineTo(...toCanvas(...xf(...v(shape.segment.point2))));
  }
}

function normal(a, b) {
  const dx = b[0] - a[0], dy = b[1] - a[1], len = Math.hypot(dx, dy) || 1;
  return [-dy / len, dx / len];
}

function draw() {
  const w = canvas.clientWidth, h = canvas.clientHeight;
  ctx.fillStyle = colors.background;
  ctx.fillRect(0, 0, w, h);
  drawAxes(w, h);
  ctx.lineJoin = "round";
  forEachShape((body, shape, xf) => {
    const color = typeColor[body.type] || colors.dynamic;
    // Sleeping bodies (and static ones, which never wake) dimmed.
    const dim = body.type !== "BODY_TYPE_STATIC" && !body.awake;
    ctx.globalAlpha = dim ? 0.45 : 1;
    shapePath(shape, xf);
    if (shape.segment) {
      ctx.strokeStyle = color;
      ctx.lineWidth = 2;
      ctx.stroke();
    } else {
      ctx.fillStyle = color;
      ctx.fill();
      ctx.strokeStyle = "rgba(0, 0, 0, 0.35)";
      ctx.lineWidth = 1;
      ctx.stroke();
      // A radius line shows a round shape turning.
      if (shape.circle) {
        const c = toCanvas(...xf(...v(shape.circle.center)));
        const e = toCanvas(...xf(shape.circle.center ? (shape.circle.center.x || 0) +
                                 shape.circle.radius : shape.circle.radius,
                                 shape.circle.center ? shape.circle.center.y || 0 : 0));
        ctx.beginPath();
        ctx.moveTo(...c);
        ctx.lineTo(...e);
        ctx.stroke();
      }
    }
  });
  ctx.globalAlpha = 1;
  drawJoints();
  if (state.drag && state.drag.anchor) {
    ctx.strokeStyle = colors.drag;
    ctx.lineWidth = 2;
    ctx.beginPath();
    ctx.moveTo(...toCanvas(...state.drag.anchor()));
    ctx.lineTo(...toCanvas(...state.drag.target));
    ctx.stroke();
  }
}

function drawAxes(w, h) {
  ctx.strokeStyle = colors.grid;
  ctx.lineWidth = 1;
  ctx.beginPath();
  ctx.moveTo(0, view.oy); ctx.lineTo(w, view.oy);
  ctx.moveTo(view.ox, 0); ctx.lineTo(view.ox, h);
  ctx.stroke();
}

// Joints as lines from anchor A to anchor B at the bodies' current poses.
function drawJoints() {
  ctx.strokeStyle = colors.joint;
  ctx.fillStyle = colors.joint;
  ctx.lineWidth = 1.5;
  for (const j of state.joints) {
    if (j.type === "JOINT_TYPE_TARGET" && state.drag && state.drag.joint ===
        j.handle.index + ":" + j.handle.generation) continue;  // drawn from the pointer
    const a = anchor(j.bodyA, j.localAnchorA), b = anchor(j.bodyB, j.localAnchorB);
    if (!a || !b) continue;
    // Motor joints hold an offset in local_anchor_a, target and curve joints a world point.
    const pa = j.type === "JOINT_TYPE_MOTOR" ? anchor(j.bodyA, null)
             : (j.type === "JOINT_TYPE_TARGET" || j.type === "JOINT_TYPE_CURVE") ? v(j.anchorA) : a;
    const ca = toCanvas(...pa), cb = toCanvas(...b);
    ctx.beginPath();
    ctx.moveTo(...ca);
    ctx.lineTo(...cb);
    ctx.stroke();
    for (const p of [ca, cb]) { ctx.beginPath(); ctx.arc(p[0], p[1], 2.5, 0, 2 * Math.PI); ctx.fill(); }
  }
}

function anchor(handle, local) {
  const body = state.bodies.get(handle.index);
  if (!body || body.gen !== handle.generation) return null;
  const [x, y] = v(local);
  const c = Math.cos(body.angle), s = Math.sin(body.angle);
  return [body.x + c * x - s * y, body.y + s * x + c * y];
}

// --- Live mode -----------------------------------------------------------------------------

// The world picker's options: the server's worlds now (asked again when the picker is opened).
async function listWorlds() {
  const worlds = await api("/api/worlds");
  const select = $("world");
  select.innerHTML = "";
  for (const w of worlds) {
    const o = document.createElement("option");
    o.value = w.id;
    o.textContent = `${w.id} ${w.name} (${w.bodies} bodies)`;
    select.appendChild(o);
  }
  if (state.world) select.value = state.world;
  return worlds;
}

async function startLive() {
  for (const el of document.querySelectorAll(".live")) el.classList.remove("hidden");
  const worlds = await listWorlds();
  const select = $("world");
  const wanted = Number(params.get("world")) || (worlds[0] && worlds[0].id);
  if (!wanted) { showError("no worlds on the server (create one: fulcrum create)"); return; }
  select.value = wanted;
  select.onchange = () => openWorld(Number(select.value));
  select.onfocus = () => listWorlds().catch((e) => showError(e.message));
  $("run").onclick = () => post(`/api/run?world=${state.world}`).catch((e) => showError(e.message));
  $("pause").onclick = () => post(`/api/pause?world=${state.world}`).catch((e) => showError(e.message));
  $("step").onclick = () => post(`/api/step?world=${state.world}`)
    .then((r) => { $("steptime").textContent = `step ${r.stepMs.toFixed(3)} ms`; })
    .catch((e) => showError(e.message));
  setInterval(pollStatus, 1000);
  openWorld(wanted);
}

function openWorld(id) {
  if (state.events) state.events.close();
  state.world = id;
  state.bodies.clear();
  state.shapes.clear();
  state.joints = [];
  view.fitted = false;
  showError("");
  history.replaceState(null, "", `?world=${id}`);
  describe();
  const events = new EventSource(`/events?world=${id}`);
  events.onmessage = (e) => applyFrame(JSON.parse(e.data));
  events.addEventListener("end", (e) => { showError("stream ended: " + JSON.parse(e.data)); events.close(); });
  events.onerror = () => showError("lost the event stream (fulcrum view stopped?)");
  state.events = events;
}

async function pollStatus() {
  if (!state.world) return;
  try {
    const s = await api(`/api/status?world=${state.world}`);
    // Edits on a paused world (another client's, or a drag) change it between frames.
    if (s.tick === state.tick && s.hash !== state.hash) {
      state.hash = s.hash;
      $("hash").textContent = s.hash;
      describe();
    }
    const perTick = s.stepMsPerTick === null ? "" : `  step ${s.stepMsPerTick.toFixed(3)} ms/tick`;
    $("verdict").textContent = s.mode === "real_time" ? "running" : "paused";
    $("steptime").textContent = perTick.trim();
  } catch (e) {
    showError(e.message);
  }
}

// --- Replay mode ---------------------------------------------------------------------------

async function startReplay(info) {
  state.replay = info;
  for (const el of document.querySelectorAll(".replay")) el.classList.remove("hidden");
  const seek = $("seek");
  seek.min = info.startTick;
  seek.max = info.endTick;
  seek.value = info.startTick;
  if (info.firstDivergentTick !== null) {
    const f = (info.firstDivergentTick - info.startTick) / Math.max(1, info.endTick - info.startTick);
    const mark = $("divergence");
    mark.style.left = `calc(${(f * 100).toFixed(3)}% - 1px)`;
    mark.style.display = "block";
    $("verdict").textContent = `diverges at tick ${info.firstDivergentTick}`;
    $("verdict").title = info.detail;
  } else {
    $("verdict").textContent = `verified: ${info.endTick - info.startTick} ticks match`;
  }
  seek.oninput = () => { state.playing = false; $("play").textContent = "play"; showTick(Number(seek.value)); };
  $("back").onclick = () => showTick(Math.max(info.startTick, state.tick - 1));
  $("forward").onclick = () => showTick(Math.min(info.endTick, state.tick + 1));
  $("play").onclick = () => {
    state.playing = !state.playing;
    $("play").textContent = state.playing ? "pause" : "play";
    if (state.playing) play();
  };
  await showTick(info.startTick);
}

// One frame request at a time; a newer wish replaces a waiting one.
let wanted = null, fetching = false;
async function showTick(tick) {
  wanted = tick;
  if (fetching) return;
  fetching = true;
  try {
    while (wanted !== null) {
      const t = wanted;
      wanted = null;
      const f = await api(`/api/replay/frame?tick=${t}`);
      applyFrame(f);
      $("seek").value = f.tick;
      $("hash").textContent = f.hash + (f.diverged ? ` (file: ${f.recordedHash})` : "");
      $("hash").style.color = f.diverged ? "#ff8a80" : "";
      await state.describing;
    }
  } catch (e) {
    showError(e.message);
  } finally {
    fetching = false;
  }
}

async function play() {
  const dt = 1000 * (state.replay.dt || 1 / 60);
  while (state.playing && state.tick < state.replay.endTick) {
    const started = performance.now();
    await showTick(state.tick + 1);
    await new Promise((r) => setTimeout(r, Math.max(0, dt - (performance.now() - started))));
  }
  state.playing = false;
  $("play").textContent = "play";
}

// --- Pointer: pan, zoom, drag a body -------------------------------------------------------

let pan = null;
canvas.addEventListener("wheel", (e) => {
  e.preventDefault();
  const [x, y] = toWorld(e.offsetX, e.offsetY);
  view.scale *= Math.exp(-e.deltaY * 0.0015);
  view.ox = e.offsetX - x * view.scale;
  view.oy = e.offsetY + y * view.scale;
  requestDraw();
}, { passive: false });

canvas.addEventListener("pointerdown", async (e) => {
  canvas.setPointerCapture(e.pointerId);
  const [x, y] = toWorld(e.offsetX, e.offsetY);
  if (state.mode === "live" && e.button === 0) {
    try {
      const r = await post(`/api/drag/start?world=${state.world}&x=${x}&y=${y}`);
      if (r.joint) {
        state.drag = { joint: r.joint, target: [x, y], anchor: null };
        await describe();  // the new joint's local anchor
        const j = state.joints.find((j) => j.handle.index + ":" + j.handle.generation === r.joint);
        if (j && state.drag) state.drag.anchor = () => anchor(j.bodyB, j.localAnchorB) || state.drag.target;
        return;
      }
    } catch (err) {
      showError(err.message);
    }
  }
  pan = { x: e.offsetX, y: e.offsetY };
});

let moveInFlight = false;
canvas.addEventListener("pointermove", (e) => {
  if (pan) {
    view.ox += e.offsetX - pan.x;
    view.oy += e.offsetY - pan.y;
    pan = { x: e.offsetX, y: e.offsetY };
    requestDraw();
  } else if (state.drag) {
    state.drag.target = toWorld(e.offsetX, e.offsetY);
    requestDraw();
    if (moveInFlight) return;  // the next move sends the newest target
    moveInFlight = true;
    const [x, y] = state.drag.target;
    post(`/api/drag/move?world=${state.world}&joint=${state.drag.joint}&x=${x}&y=${y}`)
      .catch((err) => showError(err.message))
      .finally(() => { moveInFlight = false; });
  }
});

function endPointer() {
  pan = null;
  if (!state.drag) return;
  const joint = state.drag.joint;
  state.drag = null;
  post(`/api/drag/end?world=${state.world}&joint=${joint}`)
    .then(() => describe())
    .catch((err) => showError(err.message));
  requestDraw();
}
canvas.addEventListener("pointerup", endPointer);
canvas.addEventListener("pointercancel", endPointer);

$("fit").onclick = fit;
// The canvas changes size with the window and with the header (which wraps as its readouts
// grow): its bitmap follows, or the drawing would be stretched off the view transform.
new ResizeObserver(resize).observe(canvas);

// --- Start ---------------------------------------------------------------------------------

// For tests and the console: the view transform and what is drawn.
window.fulcrumView = {
  toCanvas, toWorld, view,
  ready: () => state.tick !== null && state.shapes.size > 0 && view.fitted && !state.describing &&
    !state.describeAgain,
  tick: () => state.tick,
  hash: () => state.hash,
  bodies: () => [...state.bodies].map(([index, b]) => ({
    index, ...b, type: (state.shapes.get(index + ":" + b.gen) || {}).type })),
  showTick: (t) => showTick(t),
};

(async () => {
  resize();
  try {
    const info = await api("/api/info");
    state.mode = info.mode;
    if (info.mode === "replay") await startReplay(info.replay);
    else await startLive();
  } catch (e) {
    showError(e.message);
  }
})();
