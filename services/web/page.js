// The board's page: frames over a WebSocket (/ws), the light under the
// visitor's drag, wheel and keys (the same mapping as `rt-client live`), and
// the board's status (/status). One request in flight at a time.
"use strict";

const W = 480, H = 360, FRAME_BYTES = W * H * 3;
const EL_MIN = -0.4, EL_MAX = Math.PI / 2 - 0.05, D_MIN = 1.5, D_MAX = 200;
const DRAG_RAD_PER_PX = 0.01, KEY_STEP = 5 * Math.PI / 180, ZOOM = 1.1, AUTO_RAD_PER_S = 0.6;
const RAW_MIN = -(2 ** 23), RAW_MAX = 2 ** 23; // [min, max)
const TAU = 2 * Math.PI;

const $ = (id) => document.getElementById(id);
const canvas = $("frame"), ctx = canvas.getContext("2d");
const image = ctx.createImageData(W, H);
image.data.fill(255);

const state = window.rtPage = {
  framesDrawn: 0, lightRaw: null, targetRaw: null, connected: false, lastError: null,
};

// ---- The light ----

// Round to nearest, ties to even: as the model's Light::from_world does.
function roundEven(v) {
  const f = Math.floor(v), r = v - f;
  return r > 0.5 ? f + 1 : r < 0.5 ? f : (f % 2 === 0 ? f : f + 1);
}
const toRaw = (p) => p.map((v) => roundEven(v * 1024));

function clamped(o) {
  return {
    az: ((o.az % TAU) + TAU) % TAU,
    el: Math.min(EL_MAX, Math.max(EL_MIN, o.el)),
    d: Math.min(D_MAX, Math.max(D_MIN, o.d)),
  };
}
function orbitFromWorld(x, y, z) {
  const dy = y - 1, d = Math.hypot(x, dy, z);
  return clamped({ az: Math.atan2(z, x), el: d > 0 ? Math.asin(dy / d) : 0, d });
}
function position(o) {
  const h = o.d * Math.cos(o.el);
  return [h * Math.cos(o.az), 1 + o.d * Math.sin(o.el), h * Math.sin(o.az)];
}
const INITIAL = orbitFromWorld(3, 4, -2);

let orbit = INITIAL;
let fixedRaw = null;  // from ?light=, sent exactly until the visitor moves the light
let auto = false, autoAt = 0;

function parseQuery() {
  const q = new URLSearchParams(location.search).get("light");
  if (q === null) return;
  const num = /^\s*[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?\s*$/;
  const parts = q.split(",");
  const raw = parts.length === 3 && parts.every((s) => num.test(s)) ? toRaw(parts.map(Number)) : null;
  if (raw && raw.every((r) => Number.isFinite(r) && r >= RAW_MIN && r < RAW_MAX)) {
    fixedRaw = raw;
  } else {
    setError(`Ignoring ?light=${q}: expected X,Y,Z in world units, each in [-8192, 8192). Using the initial light.`, "notice");
  }
}

function targetRaw() {
  return fixedRaw ? fixedRaw.slice() : toRaw(position(orbit));
}
function updateTarget() {
  state.targetRaw = targetRaw();
  showRtspUrl();
}

// Any movement of the light: leave the exact query light for the orbit.
function move(f) {
  if (fixedRaw) {
    orbit = orbitFromWorld(...fixedRaw.map((r) => r / 1024));
    fixedRaw = null;
  }
  const o = { ...orbit };
  f(o);
  if ([o.az, o.el, o.d].every(Number.isFinite)) orbit = clamped(o);
  updateTarget();
}

function setAuto(on) {
  if (on !== auto) move(() => {});
  auto = on;
  autoAt = performance.now();
  $("orbit").checked = on;
  showRtspUrl();
}

function reset() {
  fixedRaw = null;
  orbit = INITIAL;
  setAuto(false);
  updateTarget();
}

function savePng() {
  canvas.toBlob((blob) => {
    if (!blob) return;
    const a = document.createElement("a");
    a.href = URL.createObjectURL(blob);
    a.download = "frame.png";
    document.body.append(a);
    a.click();
    a.remove();
    setTimeout(() => URL.revokeObjectURL(a.href), 1000);
  }, "image/png");
}

// ---- Input ----

// One pointer drags the light around the sphere; two (a pinch on a touch
// screen) bring it closer or farther as they spread or close.
let dragId = null, dragX = 0, dragY = 0;
const touches = new Map();  // pointerId -> {x, y}, while two are down
let pinchGap = 0;
const gap = () => { const [a, b] = [...touches.values()]; return Math.hypot(a.x - b.x, a.y - b.y); };
canvas.addEventListener("pointerdown", (e) => {
  if (e.pointerType === "mouse" && e.button !== 0) return;
  canvas.focus({ preventScroll: true });
  canvas.setPointerCapture(e.pointerId);
  e.preventDefault();
  if (e.pointerType === "touch") {
    touches.set(e.pointerId, { x: e.clientX, y: e.clientY });
    if (touches.size === 2) { dragId = null; pinchGap = gap(); return; }
  }
  dragId = e.pointerId; dragX = e.clientX; dragY = e.clientY;
});
canvas.addEventListener("pointermove", (e) => {
  if (touches.has(e.pointerId)) touches.set(e.pointerId, { x: e.clientX, y: e.clientY });
  if (touches.size === 2) {
    const g = gap();
    if (pinchGap > 0 && g > 0) move((o) => { o.d *= pinchGap / g; });
    pinchGap = g;
    return;
  }
  if (e.pointerId !== dragId) return;
  const dx = e.clientX - dragX, dy = e.clientY - dragY;
  dragX = e.clientX; dragY = e.clientY;
  if (dx || dy) move((o) => { o.az += dx * DRAG_RAD_PER_PX; o.el -= dy * DRAG_RAD_PER_PX; });
});
const endDrag = (e) => {
  touches.delete(e.pointerId);
  if (touches.size < 2) pinchGap = 0;
  if (e.pointerId === dragId) dragId = null;
};
canvas.addEventListener("pointerup", endDrag);
canvas.addEventListener("pointercancel", endDrag);
canvas.addEventListener("wheel", (e) => {
  e.preventDefault();
  const per = e.deltaMode === 1 ? 3 : e.deltaMode === 2 ? 1 : 100;
  const notches = -e.deltaY / per; // wheel up (away from the user): closer
  if (notches) move((o) => { o.d /= ZOOM ** notches; });
}, { passive: false });

const KEYS = {
  ArrowLeft: () => move((o) => { o.az -= KEY_STEP; }),
  ArrowRight: () => move((o) => { o.az += KEY_STEP; }),
  ArrowUp: () => move((o) => { o.el += KEY_STEP; }),
  ArrowDown: () => move((o) => { o.el -= KEY_STEP; }),
  PageUp: () => move((o) => { o.d /= ZOOM; }),
  PageDown: () => move((o) => { o.d *= ZOOM; }),
  " ": () => setAuto(!auto),
  r: reset,
  R: reset,
  p: savePng,
  P: savePng,
};
// Keys move the light only while the picture has focus (a click or Tab
// gives it), so they never take the page's scrolling or a form's keys.
canvas.addEventListener("keydown", (e) => {
  if (e.ctrlKey || e.metaKey || e.altKey) return;
  const f = KEYS[e.key];
  if (!f) return;
  e.preventDefault();
  if (!e.repeat || e.key.startsWith("Arrow") || e.key.startsWith("Page")) f();
});

$("orbit").addEventListener("change", (e) => setAuto(e.target.checked));
$("reset").addEventListener("click", reset);
$("save").addEventListener("click", savePng);
$("rate").addEventListener("change", () => { showRtspUrl(); pump(); });

// ---- Display ----

function fmt(raw) {
  const s = (raw / 1024).toFixed(3).replace(/\.?0+$/, "");
  return s === "-0" ? "0" : s;
}

let conn = "";
function setConn(text, bad) {
  const el = $("conn");
  if (text !== conn) { el.textContent = conn = text; }
  el.classList.toggle("bad", !!bad);
}
function setError(text, where = "conn") {
  state.lastError = text;
  if (where === "conn") setConn(text, true);
  else { $(where).textContent = text; $(where).hidden = false; }
}

let rtspPort = 8554;
function showRtspUrl() {
  const rate = $("rate").value;
  const raw = state.lightRaw || state.targetRaw;
  let url = `rtsp://${location.hostname}:${rtspPort}/`;
  url += auto || !raw ? "orbit" : `light/${raw.map(fmt).join(",")}`;
  if (rate !== "max") url += `?fps=${rate}`;
  const field = $("rtsp-url");
  if (field.value !== url) field.value = url;
}
$("copy").addEventListener("click", async () => {
  const field = $("rtsp-url");
  try {
    if (!navigator.clipboard) throw new Error("no clipboard");
    await navigator.clipboard.writeText(field.value);
    $("copy").textContent = "Copied";
    setTimeout(() => { $("copy").textContent = "Copy"; }, 1500);
  } catch {
    field.focus();
    field.select();
  }
});

const drawTimes = [];
function showFps() {
  const now = performance.now();
  while (drawTimes.length && now - drawTimes[0] > 1000) drawTimes.shift();
  $("fps-drawn").textContent = String(drawTimes.length);
}

// ---- Frames ----

let ws = null, retry = null, timer = null;
// Reconnecting: 1 s after the first failure, doubling to 30 s, each wait
// drawn from 70-130% of that so that many pages do not come back at once.
const RETRY_FIRST_MS = 1000, RETRY_MAX_MS = 30000, SLOW_FRAME_MS = 5000;
let backoff = RETRY_FIRST_MS;
let inFlight = null;  // { raw, at } of the request whose frame is awaited
let lastSent = -Infinity;

function interval() {
  const r = $("rate").value;
  return r === "max" ? 0 : 1000 / Number(r);
}

// Send the next request when the socket is free and the rate allows.
function pump() {
  clearTimeout(timer);
  timer = null;
  if (!ws || ws.readyState !== WebSocket.OPEN || inFlight) return;
  // A hidden tab asks for nothing (the board renders for visible pages);
  // it asks again when shown (visibilitychange).
  if (document.hidden) return;
  const now = performance.now();
  const wait = lastSent + interval() - now;
  if (wait > 0) { timer = setTimeout(pump, wait); return; }
  if (auto) {
    const dt = (now - autoAt) / 1000;
    autoAt = now;
    move((o) => { o.az += AUTO_RAD_PER_S * dt; });
  }
  const raw = targetRaw();
  const msg = new DataView(new ArrayBuffer(12));
  raw.forEach((v, i) => msg.setInt32(i * 4, v, false));
  ws.send(msg.buffer);
  inFlight = { raw, at: now };
  lastSent = now;
}

function draw(buf) {
  const src = new Uint8Array(buf), dst = image.data;
  for (let i = 0, j = 0; i < FRAME_BYTES; i += 3, j += 4) {
    dst[j] = src[i]; dst[j + 1] = src[i + 1]; dst[j + 2] = src[i + 2];
  }
  ctx.putImageData(image, 0, 0);
  const now = performance.now();
  state.framesDrawn += 1;
  state.lightRaw = inFlight.raw;
  drawTimes.push(now);
  $("frames-drawn").textContent = String(state.framesDrawn);
  $("rtt").textContent = (now - inFlight.at).toFixed(0);
  const light = $("light");
  light.dataset.raw = inFlight.raw.join(",");
  light.textContent = `(${inFlight.raw.map(fmt).join(", ")})`;
  showFps();
  showRtspUrl();
  inFlight = null;
  backoff = RETRY_FIRST_MS;
  if (state.connected) setConn("Connected");
}

function connect() {
  retry = null;
  setConn("Connecting…");
  const proto = location.protocol === "https:" ? "wss:" : "ws:";
  const sock = ws = new WebSocket(`${proto}//${location.host}/ws`);
  sock.binaryType = "arraybuffer";
  sock.onopen = () => {
    state.connected = true;
    setConn("Connected");
    inFlight = null;
    pump();
  };
  sock.onmessage = (e) => {
    if (sock !== ws) return;
    const n = e.data instanceof ArrayBuffer ? e.data.byteLength : null;
    if (n !== FRAME_BYTES || !inFlight) {
      setError(n === null ? "Error: the board sent a text message instead of a frame; reconnecting."
        : `Error: a frame of ${n} bytes (expected ${FRAME_BYTES}); reconnecting.`);
      sock.close(4000, "bad frame");
      closed(sock, null);
      return;
    }
    draw(e.data);
    pump();
  };
  sock.onclose = (e) => closed(sock, e);
}

// Why a connection that never opened failed: the WebSocket API does not
// say, so ask the board for its status: an answer means the board is there
// and refused the viewer (every web place taken, 503).
async function whyRefused() {
  try {
    const ctl = new AbortController();
    const t = setTimeout(() => ctl.abort(), 3000);
    const r = await fetch("/status", { cache: "no-store", signal: ctl.signal });
    clearTimeout(t);
    return r.ok ? "every viewer place on the board is taken" : `the board answered HTTP ${r.status}`;
  } catch {
    return "the board is unreachable (check its power, cable and address)";
  }
}

async function closed(sock, e) {
  if (sock !== ws) return;
  const opened = state.connected;
  ws = null;
  state.connected = false;
  inFlight = null;
  clearTimeout(timer);
  const wait = Math.round(backoff * (0.7 + 0.6 * Math.random()));
  backoff = Math.min(RETRY_MAX_MS, backoff * 2);
  if (e) {
    let why = `Connection closed (code ${e.code}${e.reason ? `: ${e.reason}` : ""})`;
    if (!opened) why = `No viewer connection: ${await whyRefused()}`;
    const later = document.hidden ? "when this tab is shown again" : `in ${(wait / 1000).toFixed(1)} s`;
    setError(`${why}. Retrying ${later}…`);
  }
  if (document.hidden) return;  // visibilitychange reconnects
  if (!retry) retry = setTimeout(connect, wait);
}

document.addEventListener("visibilitychange", () => {
  if (document.hidden) return;
  if (!ws && !retry) connect();
  else pump();
});

// A frame asked for long ago and not here: say so (the board may be busy
// with other viewers, or the path slow) rather than show a frozen picture.
function watchFrame() {
  if (!inFlight || !state.connected) return;
  const waited = performance.now() - inFlight.at;
  if (waited > SLOW_FRAME_MS) setConn(`Waiting for the board's frame (${(waited / 1000).toFixed(0)} s)…`, true);
}

// ---- Board status ----

let prev = null, statusBusy = false;
function hms(s) {
  s = Math.floor(s);
  const h = Math.floor(s / 3600), m = Math.floor(s / 60) % 60;
  return `${h}:${String(m).padStart(2, "0")}:${String(s % 60).padStart(2, "0")}`;
}
async function status() {
  showFps();
  watchFrame();
  if (statusBusy) return;
  statusBusy = true;
  const note = $("status-note");
  try {
    const ctl = new AbortController();
    const t = setTimeout(() => ctl.abort(), 3000);
    const r = await fetch("/status", { cache: "no-store", signal: ctl.signal });
    clearTimeout(t);
    if (!r.ok) throw new Error(`HTTP ${r.status}`);
    const s = await r.json();
    const now = performance.now();
    $("status-uptime").textContent = hms(s.uptime_s);
    $("status-renderer").textContent = s.renderer;
    $("status-link").textContent = s.link;
    if (prev && now > prev.at) {
      const dt = (now - prev.at) / 1000;
      $("status-fps-rendered").textContent = ((s.frames_rendered - prev.rendered) / dt).toFixed(1);
      $("status-fps-sent").textContent = ((s.frames_sent - prev.sent) / dt).toFixed(1);
    }
    prev = { at: now, rendered: s.frames_rendered, sent: s.frames_sent };
    const v = s.viewers || {};
    $("status-viewers").textContent = `web ${v.web} of ${v.web_max}, seed ${v.seed}, RTSP ${v.rtsp}`;
    if (Number.isInteger(s.rtsp_port) && s.rtsp_port !== rtspPort) { rtspPort = s.rtsp_port; showRtspUrl(); }
    note.textContent = "";
  } catch {
    prev = null;
    note.textContent = "Board status unavailable; trying again every second.";
  } finally {
    statusBusy = false;
  }
}

parseQuery();
updateTarget();
connect();
status();
setInterval(status, 1000);
