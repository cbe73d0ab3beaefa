// OpenNeRF viewer page: point cloud, cameras, open-vocabulary queries and renders.
// Plain ES2020 + hand-written WebGL2; no libraries, works offline. The HTTP API it
// talks to is listed in the README, section "The viewer" (GET /api/summary, /api/points, ...).
'use strict';
(function () {

// ======================================================================= state
const $ = (id) => document.getElementById(id);
const el = (tag, className, text) => Object.assign(document.createElement(tag), className ? { className } : {}, text ? { textContent: text } : {});

// Read by the headless-browser test (tests/browser/drive_viewer.cjs).
const state = window.viewerState = {
  ready: false,        // true once the points have been drawn the first time
  points: 0,           // points in the current cloud
  mode: 'captured',    // colour mode
  queryDone: 0,        // successful queries
  renderDone: 0,       // renders displayed in the side panel
  lastError: null,     // last error shown in the status line
  errors: 0,           // errors shown so far (lets a test stop waiting early)
  frames: 0,           // frames drawn
  fieldVersion: null,  // field_version of the points on screen
};

const app = {
  summary: null,
  classes: [],         // [{id, name, color: [r,g,b]}]
  hidden: new Set(),   // class ids hidden in class / error modes
  cameras: [],
  cloud: null,         // parsed /api/points
  query: null,         // last successful query: {text: what was sent, positives, quantity, lo, hi, values}
  up: [0, 0, 1],       // scene up axis
  center: [0, 0, 0],
  diag: 1,             // scene box diagonal
  loadingField: false,
  render: null,        // {job, done}: the render being polled
  lastRender: null,    // {job, url}: the render shown in the panel
};

const MODES = { captured: 0, class: 1, error: 2, uncertainty: 3, relevancy: 4 };
const CAMERA_COLOURS = { train: [0.35, 0.77, 1.0], heldout: [1.0, 0.62, 0.25], novel: [0.84, 0.48, 1.0] };

// ======================================================================= status line
// Errors go to the status line and viewerState, never to alert() or the console
// (the browser test counts console errors).
function setStatus(msg, isError = false) {
  $('status').textContent = msg;
  $('status').classList.toggle('error', isError);
}

function showError(msg) {
  state.lastError = msg;
  state.errors++;
  setStatus(msg, true);
}

// ======================================================================= HTTP
// Any non-2xx answer becomes an Error carrying the server's JSON `error` text.
async function api(path, opts) {
  const res = await fetch(path, opts).catch((e) => { throw new Error(`${path}: the server cannot be reached (${e.message})`); });
  if (res.ok) return res;
  const body = await res.json().catch(() => null);  // not JSON: report the status
  throw new Error(body && body.error ? body.error : `${path}: HTTP ${res.status}`);
}
const getJSON = async (path) => (await api(path)).json();
const postJSON = (path, body) => api(path, {
  method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify(body),
});

// ======================================================================= vector maths
// Vectors are plain [x, y, z] arrays; matrices are column-major Float32Array(16) as GL wants.
const add = (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
const scale = (a, s) => [a[0] * s, a[1] * s, a[2] * s];
const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
const length = (a) => Math.sqrt(dot(a, a));
const normalize = (a) => { const l = length(a); return l > 0 ? scale(a, 1 / l) : [0, 0, 0]; };

function perspective(fovy, aspect, near, far) {
  const f = 1 / Math.tan(fovy / 2), nf = 1 / (near - far);
  return new Float32Array([f / aspect, 0, 0, 0, 0, f, 0, 0, 0, 0, (far + near) * nf, -1, 0, 0, 2 * far * near * nf, 0]);
}

function multiply(a, b) {
  const out = new Float32Array(16);
  for (let c = 0; c < 4; c++) {
    for (let r = 0; r < 4; r++) for (let k = 0; k < 4; k++) out[c * 4 + r] += a[k * 4 + r] * b[c * 4 + k];
  }
  return out;
}

// ======================================================================= Turbo colour map
// Google's Turbo map via its published degree-5 polynomial fit (one polynomial per
// channel, evaluated with Horner's rule). Used for the GPU lookup texture and the colour bar.
const TURBO_COEFFS = [
  [0.13572138, 4.61539260, -42.66032258, 132.13108234, -152.94239396, 59.28637943],
  [0.09140261, 2.19418839, 4.84296658, -14.18503333, 4.27729857, 2.82956604],
  [0.10667330, 12.64194608, -60.58204836, 110.36276771, -89.90310912, 27.34824973],
];

function turbo(x) {
  const t = Math.min(1, Math.max(0, x));
  return TURBO_COEFFS.map((c) => {
    let v = c[5];
    for (let k = 4; k >= 0; k--) v = v * t + c[k];
    return Math.round(255 * Math.min(1, Math.max(0, v)));
  });
}

// ======================================================================= points format
// "ONPT" v1: positions f32[3n], colours u8[4n], predicted u16[n], truth u16[n], uncertainty f32[n].
function parsePoints(buf) {
  if (buf.byteLength < 16) throw new Error(`/api/points: ${buf.byteLength} bytes, shorter than the header`);
  const dv = new DataView(buf);
  const magic = String.fromCharCode(dv.getUint8(0), dv.getUint8(1), dv.getUint8(2), dv.getUint8(3));
  if (magic !== 'ONPT') throw new Error(`/api/points: bad magic "${magic}"`);
  const version = dv.getUint32(4, true);
  if (version !== 1) throw new Error(`/api/points: format version ${version}, this page reads 1`);
  const n = dv.getUint32(8, true);
  if (buf.byteLength !== 16 + 24 * n) throw new Error(`/api/points: ${buf.byteLength} bytes for ${n} points, expected ${16 + 24 * n}`);
  const uncertainty = new Float32Array(buf, 16 + 20 * n, n);
  return {
    n,
    fieldVersion: dv.getUint32(12, true),
    positions: new Float32Array(buf, 16, 3 * n),
    colours: new Uint8Array(buf, 16 + 12 * n, 4 * n),
    predicted: new Uint16Array(buf, 16 + 16 * n, n),
    truth: new Uint16Array(buf, 16 + 18 * n, n),
    // NaN ("no value") becomes -1: the shader tests a sign more reliably than isnan().
    uncertainty: Float32Array.from(uncertainty, (v) => (Number.isFinite(v) ? v : -1)),
  };
}

// ======================================================================= WebGL
const canvas = $('view');
let gl = null;
const glr = {};  // programs, buffers, textures, uniform locations

const POINT_VS = `#version 300 es
precision highp float;
precision highp int;
precision highp sampler2D;
layout(location = 0) in vec3 a_pos;
layout(location = 1) in vec4 a_rgb;
layout(location = 2) in uint a_pred;
layout(location = 3) in uint a_truth;
layout(location = 4) in float a_value;   // uncertainty or relevancy, -1 = none
uniform mat4 u_mvp;
uniform float u_size;
uniform int u_mode;                      // see MODES in viewer.js
uniform float u_threshold;
uniform sampler2D u_classes;             // N x 1: rgb = class colour, a = visible
uniform int u_nclasses;
uniform sampler2D u_turbo;               // 256 x 1 Turbo lookup
out vec3 v_col;
const vec3 GREY = vec3(0.45);
vec4 classInfo(uint id) {
  if (int(id) >= u_nclasses) return vec4(GREY, 1.0);   // 0xFFFF (none) or out of range
  return texelFetch(u_classes, ivec2(int(id), 0), 0);
}
vec3 turbo(float v) { return texture(u_turbo, vec2(clamp(v, 0.0, 1.0) * (255.0 / 256.0) + 0.5 / 256.0, 0.5)).rgb; }
void main() {
  vec3 col = a_rgb.rgb;
  bool visible = true;
  if (u_mode == 1) {
    vec4 c = classInfo(a_pred);
    col = c.rgb;
    visible = c.a > 0.5;
  } else if (u_mode == 2) {
    visible = classInfo(a_pred).a > 0.5 && classInfo(a_truth).a > 0.5;
    col = a_truth == 0xFFFFu ? GREY : (a_pred == a_truth ? vec3(0.2, 0.8, 0.3) : vec3(0.92, 0.2, 0.2));
  } else if (u_mode == 3) {
    col = a_value < 0.0 ? GREY : turbo(a_value);
  } else if (u_mode == 4) {
    col = a_value >= u_threshold ? turbo(a_value) : col * 0.55;
  }
  v_col = col;
  // A hidden point is moved outside the clip volume, so it is clipped away.
  gl_Position = visible ? u_mvp * vec4(a_pos, 1.0) : vec4(2.0, 2.0, 2.0, 1.0);
  gl_PointSize = u_size;
}`;

// Shared by points (u_round: cut the square sprite to a disc) and lines.
const COLOUR_FS = `#version 300 es
precision mediump float;
uniform bool u_round;
in vec3 v_col;
out vec4 o_col;
void main() {
  vec2 d = gl_PointCoord - 0.5;
  if (u_round && dot(d, d) > 0.25) discard;
  o_col = vec4(v_col, 1.0);
}`;

const LINE_VS = `#version 300 es
layout(location = 0) in vec3 a_pos;
layout(location = 1) in vec3 a_col;
uniform mat4 u_mvp;
out vec3 v_col;
void main() { v_col = a_col; gl_Position = u_mvp * vec4(a_pos, 1.0); }`;

function compileProgram(vsSrc, fsSrc) {
  const shader = (type, src) => {
    const s = gl.createShader(type);
    gl.shaderSource(s, src);
    gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(`shader: ${gl.getShaderInfoLog(s)}`);
    return s;
  };
  const p = gl.createProgram();
  gl.attachShader(p, shader(gl.VERTEX_SHADER, vsSrc));
  gl.attachShader(p, shader(gl.FRAGMENT_SHADER, fsSrc));
  gl.linkProgram(p);
  if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error(`program: ${gl.getProgramInfoLog(p)}`);
  const u = {};
  for (let i = 0; i < gl.getProgramParameter(p, gl.ACTIVE_UNIFORMS); i++) {
    const name = gl.getActiveUniform(p, i).name;
    u[name] = gl.getUniformLocation(p, name);
  }
  return { program: p, u };
}

function makeTexture(filter) {
  const t = gl.createTexture();
  gl.bindTexture(gl.TEXTURE_2D, t);
  for (const [k, v] of [[gl.TEXTURE_MIN_FILTER, filter], [gl.TEXTURE_MAG_FILTER, filter],
    [gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE], [gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE]]) gl.texParameteri(gl.TEXTURE_2D, k, v);
  return t;
}

function initGL() {
  // preserveDrawingBuffer keeps the last frame readable for screenshots.
  gl = canvas.getContext('webgl2', { preserveDrawingBuffer: true, antialias: false });
  if (!gl) return false;
  glr.points = compileProgram(POINT_VS, COLOUR_FS);
  glr.lines = compileProgram(LINE_VS, COLOUR_FS);

  // Point attributes, each in its own buffer so a new query only re-uploads the values.
  glr.pointVao = gl.createVertexArray();
  gl.bindVertexArray(glr.pointVao);
  const attrib = (loc, size, type, integer, normalized) => {
    const buf = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, buf);
    gl.enableVertexAttribArray(loc);
    if (integer) gl.vertexAttribIPointer(loc, size, type, 0, 0);
    else gl.vertexAttribPointer(loc, size, type, normalized, 0, 0);
    return buf;
  };
  glr.posBuf = attrib(0, 3, gl.FLOAT, false, false);
  glr.rgbBuf = attrib(1, 4, gl.UNSIGNED_BYTE, false, true);
  glr.predBuf = attrib(2, 1, gl.UNSIGNED_SHORT, true);
  glr.truthBuf = attrib(3, 1, gl.UNSIGNED_SHORT, true);
  glr.valueBuf = attrib(4, 1, gl.FLOAT, false, false);

  glr.lineVao = gl.createVertexArray();
  gl.bindVertexArray(glr.lineVao);
  glr.linePosBuf = attrib(0, 3, gl.FLOAT, false, false);
  glr.lineColBuf = attrib(1, 3, gl.FLOAT, false, false);
  glr.lineCount = 0;
  gl.bindVertexArray(null);

  glr.classTex = makeTexture(gl.NEAREST);
  glr.turboTex = makeTexture(gl.LINEAR);
  const lut = new Uint8Array(256 * 4);
  for (let i = 0; i < 256; i++) lut.set([...turbo(i / 255), 255], i * 4);
  gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA8, 256, 1, 0, gl.RGBA, gl.UNSIGNED_BYTE, lut);

  canvas.addEventListener('webglcontextlost', (e) => { e.preventDefault(); showError('the WebGL context was lost; reload the page'); });
  return true;
}

function uploadBuffer(buf, data) {
  gl.bindBuffer(gl.ARRAY_BUFFER, buf);
  gl.bufferData(gl.ARRAY_BUFFER, data, gl.STATIC_DRAW);
}

function uploadCloud(c) {
  for (const [buf, data] of [[glr.posBuf, c.positions], [glr.rgbBuf, c.colours], [glr.predBuf, c.predicted], [glr.truthBuf, c.truth]]) uploadBuffer(buf, data);
  uploadValues();
}

// The value attribute carries whichever scalar the colour mode shows.
function uploadValues() {
  const c = app.cloud;
  if (!c) return;
  const relevancy = app.query && app.query.values.length === c.n ? app.query.values : null;
  uploadBuffer(glr.valueBuf, state.mode === 'relevancy' && relevancy ? relevancy : c.uncertainty);
}

// Class colours and visibility as an N x 1 texture (N = largest id + 1), read by the
// point shader; ids missing from /api/classes stay grey and visible.
function uploadClassTexture() {
  const ids = app.classes.map((c) => c.id).filter((id) => Number.isInteger(id) && id >= 0 && id < 4096);
  const n = Math.max(1, ...ids.map((id) => id + 1));
  const data = new Uint8Array(n * 4);
  for (let i = 0; i < n; i++) data.set([115, 115, 115, 255], i * 4);
  for (const c of app.classes) {
    if (ids.includes(c.id)) data.set([...c.color.slice(0, 3), app.hidden.has(c.id) ? 0 : 255], c.id * 4);
  }
  gl.bindTexture(gl.TEXTURE_2D, glr.classTex);
  gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA8, n, 1, 0, gl.RGBA, gl.UNSIGNED_BYTE, data);
  glr.classCount = n;
}

// ======================================================================= orbit camera
const cam = { target: [0, 0, 0], dist: 1, yaw: 0, pitch: 0, fovy: (50 * Math.PI) / 180 };

// Two unit vectors spanning the plane perpendicular to `up` (x-like and y-like for +z up).
function horizontalBasis() {
  const u = app.up;
  const a = Math.abs(u[0]) < 0.9 ? [1, 0, 0] : [0, 1, 0];
  const e1 = normalize(sub(a, scale(u, dot(a, u))));
  return [e1, cross(u, e1)];
}

function cameraFrame() {
  const [e1, e2] = horizontalBasis();
  const cp = Math.cos(cam.pitch);
  const toEye = add(add(scale(e1, cp * Math.cos(cam.yaw)), scale(e2, cp * Math.sin(cam.yaw))), scale(app.up, Math.sin(cam.pitch)));
  const eye = add(cam.target, scale(toEye, cam.dist));
  const forward = scale(toEye, -1);
  const right = normalize(cross(forward, app.up));
  return { eye, forward, right, up: cross(right, forward) };
}

function viewProjection() {
  const { eye, forward: f, right: r, up: u } = cameraFrame();
  const view = new Float32Array([r[0], u[0], -f[0], 0, r[1], u[1], -f[1], 0, r[2], u[2], -f[2], 0,
    -dot(r, eye), -dot(u, eye), dot(f, eye), 1]);
  const aspect = canvas.clientWidth / Math.max(1, canvas.clientHeight);
  const near = Math.max(app.diag * 1e-4, cam.dist * 0.005);
  return multiply(perspective(cam.fovy, aspect, near, cam.dist + 2 * app.diag), view);
}

// Puts the orbit target at `p` without moving the eye: the view turns towards the point.
function lookAtPoint(p) {
  const eye = cameraFrame().eye;
  const d = sub(eye, p);
  const dist = length(d);
  if (dist < 1e-9) return;
  const [e1, e2] = horizontalBasis();
  const dir = scale(d, 1 / dist);
  cam.target = p;
  cam.dist = dist;
  cam.pitch = clampPitch(Math.asin(Math.max(-1, Math.min(1, dot(dir, app.up)))));
  cam.yaw = Math.atan2(dot(dir, e2), dot(dir, e1));
}

const clampPitch = (p) => Math.max(-1.55, Math.min(1.55, p));

function fitView() {
  cam.target = app.center.slice();
  cam.dist = (0.5 * app.diag) / Math.sin(cam.fovy / 2);
  cam.yaw = -Math.PI / 2 - 0.6;
  cam.pitch = 0.6;
  requestDraw();
}

// ======================================================================= mouse input
function installMouse() {
  let drag = null;
  canvas.addEventListener('contextmenu', (e) => e.preventDefault());
  canvas.addEventListener('pointerdown', (e) => {
    drag = { x: e.clientX, y: e.clientY, pan: e.button === 2 || e.button === 1 || e.shiftKey };
    canvas.setPointerCapture(e.pointerId);
  });
  canvas.addEventListener('pointermove', (e) => {
    if (!drag) return;
    const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
    drag.x = e.clientX;
    drag.y = e.clientY;
    if (drag.pan) {
      // World units per screen pixel at the target's depth.
      const perPx = (2 * cam.dist * Math.tan(cam.fovy / 2)) / Math.max(1, canvas.clientHeight);
      const f = cameraFrame();
      cam.target = add(cam.target, add(scale(f.right, -dx * perPx), scale(f.up, dy * perPx)));
    } else {
      cam.yaw -= dx * 0.008;
      cam.pitch = clampPitch(cam.pitch + dy * 0.008);
    }
    requestDraw();
  });
  for (const type of ['pointerup', 'pointercancel']) canvas.addEventListener(type, () => { drag = null; });
  canvas.addEventListener('wheel', (e) => {
    e.preventDefault();
    const lines = e.deltaMode === 1 ? 16 : e.deltaMode === 2 ? 400 : 1;
    cam.dist = Math.min(app.diag * 20, Math.max(app.diag * 1e-3, cam.dist * Math.exp(e.deltaY * lines * 0.0015)));
    requestDraw();
  }, { passive: false });
  canvas.addEventListener('dblclick', (e) => {
    const rect = canvas.getBoundingClientRect();
    const i = pickPoint(e.clientX - rect.left, e.clientY - rect.top);
    if (i < 0) { setStatus('no point under the cursor'); return; }
    const p = app.cloud.positions;
    lookAtPoint([p[3 * i], p[3 * i + 1], p[3 * i + 2]]);
    requestDraw();
  });
}

// Whether point i is drawn in the current mode (hidden classes drop out in class/error modes).
function pointVisible(i) {
  if (state.mode !== 'class' && state.mode !== 'error') return true;
  const c = app.cloud;
  if (app.hidden.has(c.predicted[i])) return false;
  return !(state.mode === 'error' && app.hidden.has(c.truth[i]));
}

// CPU pick: project every visible point; of those under the cursor's point disc the
// front-most wins, otherwise the nearest one on screen within 10 px.
function pickPoint(mx, my) {
  const c = app.cloud;
  if (!c || c.n === 0) return -1;
  const m = viewProjection();
  const w = canvas.clientWidth, h = canvas.clientHeight;
  const disc = Math.max(3, pointSize() / 2 + 1), radius = 10;
  let front = -1, frontDepth = Infinity, nearest = -1, nearestD2 = radius * radius;
  const p = c.positions;
  for (let i = 0; i < c.n; i++) {
    const x = p[3 * i], y = p[3 * i + 1], z = p[3 * i + 2];
    const cw = m[3] * x + m[7] * y + m[11] * z + m[15];
    if (cw <= 0) continue;  // behind the camera
    const sx = ((m[0] * x + m[4] * y + m[8] * z + m[12]) / cw + 1) * 0.5 * w;
    const sy = (1 - (m[1] * x + m[5] * y + m[9] * z + m[13]) / cw) * 0.5 * h;
    const d2 = (sx - mx) ** 2 + (sy - my) ** 2;
    if (d2 > nearestD2 && (d2 > disc * disc || cw >= frontDepth)) continue;
    if (!pointVisible(i)) continue;
    if (d2 <= disc * disc && cw < frontDepth) { front = i; frontDepth = cw; }
    if (d2 <= nearestD2) { nearest = i; nearestD2 = d2; }
  }
  return front >= 0 ? front : nearest;
}

// ======================================================================= camera frustums
function buildFrustums() {
  const pos = [], col = [];
  for (const c of app.cameras) {
    const R = c.rotation, t = c.position;
    if (!Array.isArray(R) || R.length !== 9 || !Array.isArray(t) || !(c.fx > 0) || !(c.fy > 0)) continue;
    // Depth chosen so the frustum's largest extent is about 5% of the scene diagonal.
    const s = (0.05 * app.diag) / Math.max(1, c.width / c.fx, c.height / c.fy);
    const world = (u, v) => {  // pixel (u, v) at depth s, camera -> world (R row-major)
      const x = ((u - c.cx) / c.fx) * s, y = ((v - c.cy) / c.fy) * s;
      return [0, 1, 2].map((r) => R[3 * r] * x + R[3 * r + 1] * y + R[3 * r + 2] * s + t[r]);
    };
    const W = c.width, H = c.height;
    const k = [world(0, 0), world(W, 0), world(W, H), world(0, H)];
    // A small triangle above the image's top edge (v = 0) tells which way is up.
    const tri = [world(0.3 * W, 0), world(0.5 * W, -0.25 * H), world(0.7 * W, 0)];
    const segs = [[t, k[0]], [t, k[1]], [t, k[2]], [t, k[3]], [k[0], k[1]], [k[1], k[2]], [k[2], k[3]], [k[3], k[0]],
      [tri[0], tri[1]], [tri[1], tri[2]]];
    const colour = CAMERA_COLOURS[c.kind] || CAMERA_COLOURS.novel;
    for (const [a, b] of segs) { pos.push(...a, ...b); col.push(...colour, ...colour); }
  }
  uploadBuffer(glr.linePosBuf, new Float32Array(pos));
  uploadBuffer(glr.lineColBuf, new Float32Array(col));
  glr.lineCount = pos.length / 3;
}

// Scene up: minus the mean of the cameras' y (down) axes; +z when there is no camera.
function sceneUp(cameras) {
  let s = [0, 0, 0];
  for (const c of cameras) if (Array.isArray(c.rotation) && c.rotation.length === 9) s = add(s, [c.rotation[1], c.rotation[4], c.rotation[7]]);
  return length(s) > 1e-6 ? normalize(scale(s, -1)) : [0, 0, 1];
}

// ======================================================================= drawing
let drawPending = false;
function requestDraw() {
  if (drawPending || !gl) return;
  drawPending = true;
  requestAnimationFrame(draw);
}

const pointSize = () => Number($('point-size').value);

function draw() {
  drawPending = false;
  const dpr = window.devicePixelRatio || 1;
  const w = Math.max(1, Math.round(canvas.clientWidth * dpr)), h = Math.max(1, Math.round(canvas.clientHeight * dpr));
  if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; }
  gl.viewport(0, 0, w, h);
  gl.clearColor(0.086, 0.094, 0.11, 1);
  gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
  gl.enable(gl.DEPTH_TEST);
  const mvp = viewProjection();

  const c = app.cloud;
  if (c && c.n > 0) {
    const { program, u } = glr.points;
    gl.useProgram(program);
    gl.uniformMatrix4fv(u.u_mvp, false, mvp);
    gl.uniform1f(u.u_size, pointSize() * dpr);
    gl.uniform1i(u.u_round, 1);
    gl.uniform1i(u.u_mode, MODES[state.mode]);
    gl.uniform1f(u.u_threshold, Number($('threshold').value));
    gl.uniform1i(u.u_nclasses, glr.classCount || 0);
    [[u.u_classes, glr.classTex], [u.u_turbo, glr.turboTex]].forEach(([loc, tex], unit) => {
      gl.activeTexture(gl.TEXTURE0 + unit);
      gl.bindTexture(gl.TEXTURE_2D, tex);
      gl.uniform1i(loc, unit);
    });
    gl.bindVertexArray(glr.pointVao);
    gl.drawArrays(gl.POINTS, 0, c.n);
  }
  if ($('show-cameras').checked && glr.lineCount > 0) {
    gl.useProgram(glr.lines.program);
    gl.uniformMatrix4fv(glr.lines.u.u_mvp, false, mvp);
    gl.uniform1i(glr.lines.u.u_round, 0);
    gl.bindVertexArray(glr.lineVao);
    gl.drawArrays(gl.LINES, 0, glr.lineCount);
  }
  gl.bindVertexArray(null);
  state.frames++;
  if (c && !state.ready) state.ready = true;
}

// ======================================================================= colour modes, legend, colour bar
function setMode(mode) {
  state.mode = mode;
  $('colour-mode').value = mode;
  uploadValues();
  updateColourBar();
  requestDraw();
}

// The select offers only the modes the data supports (summary flags, a query done).
function buildModeOptions() {
  const s = app.summary || {};
  const modes = ['captured', 'class'];
  if (s.has_truth) modes.push('error');
  if (s.has_uncertainty) modes.push('uncertainty');
  if (app.query) modes.push('relevancy');
  const sel = $('colour-mode');
  sel.replaceChildren(...modes.map((m) => new Option(m, m)));
  if (!modes.includes(state.mode)) state.mode = 'captured';
  sel.value = state.mode;
}

function buildLegend() {
  const counts = new Map();
  const c = app.cloud;
  if (c) for (let i = 0; i < c.n; i++) counts.set(c.predicted[i], (counts.get(c.predicted[i]) || 0) + 1);
  const items = app.classes.map((cls) => {
    const item = el('div', 'legend-item' + (app.hidden.has(cls.id) ? ' off' : ''));
    item.dataset.classId = String(cls.id);
    item.title = `${counts.get(cls.id) || 0} points predicted as ${cls.name}; click to hide or show`;
    const swatch = el('span', 'swatch');
    swatch.style.background = `rgb(${cls.color.slice(0, 3).join(',')})`;
    item.append(swatch, el('span', 'legend-name', cls.name));
    item.addEventListener('click', () => toggleClass(cls.id, item));
    return item;
  });
  $('legend').replaceChildren(...items);
}

function toggleClass(id, item) {
  if (app.hidden.has(id)) app.hidden.delete(id); else app.hidden.add(id);
  item.classList.toggle('off', app.hidden.has(id));
  uploadClassTexture();
  // Hiding acts in class and error modes; from captured colours, show classes.
  if (state.mode === 'captured') setMode('class'); else requestDraw();
}

const fmt = (x) => (typeof x !== 'number' || !Number.isFinite(x) ? '–' : Math.abs(x) >= 100 ? x.toFixed(0) : x.toFixed(3));

// Vertical bar: Turbo from bottom (0) to top (1); in relevancy mode the part below the
// threshold is drawn dark, as those points keep their captured colours.
function updateColourBar() {
  const bar = $('colour-bar');
  const rel = state.mode === 'relevancy' && app.query;
  if (!rel && state.mode !== 'uncertainty') { bar.hidden = true; return; }
  bar.hidden = false;
  const t = rel ? Number($('threshold').value) : 0;
  const cv = $('colour-bar-canvas');
  const ctx = cv.getContext('2d');
  for (let y = 0; y < cv.height; y++) {
    const v = 1 - y / (cv.height - 1);
    ctx.fillStyle = v >= t ? `rgb(${turbo(v).join(',')})` : '#3a3d44';
    ctx.fillRect(0, y, cv.width, 1);
  }
  const q = rel ? app.query : { quantity: 'uncertainty', lo: 0, hi: 1 };
  $('colour-bar-quantity').textContent = q.quantity;
  $('colour-bar-hi').textContent = fmt(q.hi);
  $('colour-bar-lo').textContent = fmt(q.lo);
  const cut = $('colour-bar-cut');
  cut.parentElement.hidden = !rel;
  cut.textContent = fmt(q.lo + t * (q.hi - q.lo));
  cut.style.top = `${(1 - t) * 100}%`;
}

// ======================================================================= queries
function describeQuery() {
  const q = app.query, t = Number($('threshold').value);
  let above = 0;
  for (let i = 0; i < q.values.length; i++) if (q.values[i] >= t) above++;
  setStatus(`"${q.positives.join('; ')}" (${q.quantity}): ${above} of ${q.values.length} points at or above the threshold`);
}

// keepThreshold: a re-run after the field changed keeps the user's threshold.
async function submitQuery(positives, negatives, keepThreshold) {
  if (!positives) { showError('type a class name or some text to query'); return; }
  if (!app.cloud) { showError('the points are not loaded yet'); return; }
  $('query-go').disabled = true;
  setStatus(`querying "${positives}"…`);
  try {
    const r = await (await postJSON('/api/query', { positives, negatives })).json();
    if (!Array.isArray(r.values) || r.values.length !== app.cloud.n) {
      throw new Error(`the query returned ${Array.isArray(r.values) ? r.values.length : 'no'} values for ${app.cloud.n} points`);
    }
    app.query = {
      text: { positives, negatives }, positives: Array.isArray(r.positives) ? r.positives : [positives],
      quantity: r.quantity || 'relevancy', lo: Number(r.lo), hi: Number(r.hi),
      values: Float32Array.from(r.values, (v) => (Number.isFinite(v) ? v : -1)),  // null -> below any threshold
    };
    if (!keepThreshold && Number.isFinite(r.threshold)) $('threshold').value = String(r.threshold);
    $('threshold-value').textContent = Number($('threshold').value).toFixed(2);
    buildModeOptions();
    setMode('relevancy');
    $('export-ply').disabled = false;
    describeQuery();
    state.queryDone++;
  } catch (e) {
    showError(`query: ${e.message}`);
  } finally {
    $('query-go').disabled = false;
  }
}

function onThreshold() {
  $('threshold-value').textContent = Number($('threshold').value).toFixed(2);
  updateColourBar();
  if (app.query) describeQuery();
  requestDraw();
}

// ======================================================================= renders
// Current WebGL view as an OpenCV camera: rotation columns right, down, forward.
function renderCamera(width) {
  const f = cameraFrame();
  const aspect = canvas.clientWidth / Math.max(1, canvas.clientHeight);
  const height = Math.max(1, Math.min(640, Math.round(width / aspect)));
  const focal = (height / 2) / Math.tan(cam.fovy / 2);
  const down = scale(f.up, -1);
  const rotation = [];
  for (let r = 0; r < 3; r++) rotation.push(f.right[r], down[r], f.forward[r]);
  return { rotation, position: f.eye, width, height, fx: focal, fy: focal, cx: width / 2, cy: height / 2 };
}

async function startRender() {
  const width = Number($('render-size').value);
  const body = { camera: renderCamera(width) };
  if (app.query) body.query = app.query.text;
  app.render = null;  // stops polling an earlier job (the server cancels it)
  $('render-progress').value = 0;
  $('render-cancel').disabled = false;
  setStatus('render requested…');
  try {
    const r = await (await postJSON('/api/render', body)).json();
    app.render = { job: r.job, done: false };
    setTimeout(() => pollRender(r.job), 250);
  } catch (e) {
    $('render-cancel').disabled = true;
    showError(`render: ${e.message}`);
  }
}

async function pollRender(job) {
  if (!app.render || app.render.job !== job) return;  // superseded or cancelled
  try {
    const s = await getJSON(`/api/render/${job}`);
    if (!app.render || app.render.job !== job) return;
    $('render-progress').value = Number(s.progress) || 0;
    if (s.state === 'done') { await showRender(job, s.images || ['rgb', 'depth'], s.depth_caption); return; }
    if (s.state === 'failed') throw new Error(s.error || 'the render failed');
    if (s.state === 'cancelled') { setStatus('render cancelled'); $('render-cancel').disabled = true; return; }
    setStatus(`rendering… ${Math.round(100 * (Number(s.progress) || 0))}%`);
    setTimeout(() => pollRender(job), 250);
  } catch (e) {
    $('render-cancel').disabled = true;
    showError(`render: ${e.message}`);
  }
}

function loadImage(img, url) {
  return new Promise((resolve, reject) => {
    img.onload = () => resolve();
    img.onerror = () => reject(new Error(`cannot load ${url}`));
    img.src = url;
  });
}

async function showRender(job, images, depthCaption) {
  const url = (name) => `/api/render/${job}/${name}.png`;
  const hasRel = images.includes('relevancy');
  const loads = [loadImage($('render-rgb'), url('rgb')), loadImage($('render-depth'), url('depth'))];
  const hasOpacity = images.includes('opacity');
  if (hasOpacity) loads.push(loadImage($('render-opacity'), url('opacity')));
  if (hasRel) loads.push(loadImage($('render-relevancy'), url('relevancy')));
  else $('render-relevancy').removeAttribute('src');
  await Promise.all(loads);
  if (!app.render || app.render.job !== job) return;
  $('render-relevancy-figure').hidden = !hasRel;
  $('render-opacity-figure').hidden = !hasOpacity;
  // The depth image's range and units (a robust range: 2nd to 98th percentile).
  $('render-depth-caption').textContent = depthCaption ? `depth: ${depthCaption}` : 'depth';
  $('render-depth-caption').title = depthCaption || '';
  $('render-panel').hidden = false;
  $('render-info').textContent = `${$('render-rgb').naturalWidth}×${$('render-rgb').naturalHeight}`;
  $('render-cancel').disabled = true;
  $('export-png').disabled = false;
  app.render.done = true;
  app.lastRender = { job, url: url('rgb') };
  setStatus(`render ${job} done`);
  state.renderDone++;
  requestDraw();  // the canvas narrowed to make room for the panel
}

async function cancelRender() {
  const r = app.render;
  if (!r || r.done) return;
  app.render = null;
  $('render-cancel').disabled = true;
  try {
    await api(`/api/render/${r.job}`, { method: 'DELETE' });
    setStatus('render cancelled');
  } catch (e) {
    showError(`cancel: ${e.message}`);
  }
}

// ======================================================================= exports
function download(href, filename) {
  const a = Object.assign(el('a'), { href, download: filename });
  document.body.append(a);
  a.click();
  a.remove();
}

async function exportPly() {
  if (!app.query) { showError('export: run a query first'); return; }
  const body = { ...app.query.text, threshold: Number($('threshold').value) };
  setStatus('exporting…');
  try {
    const res = await postJSON('/api/export', body);
    const m = /filename="?([^";]+)"?/.exec(res.headers.get('Content-Disposition') || '');
    const href = URL.createObjectURL(await res.blob());
    download(href, m ? m[1] : 'query.ply');
    setTimeout(() => URL.revokeObjectURL(href), 10000);
    setStatus(`exported ${m ? m[1] : 'query.ply'}`);
  } catch (e) {
    showError(`export: ${e.message}`);
  }
}

function exportPng() {
  const r = app.lastRender;
  if (!r) { showError('export: render a view first'); return; }
  download(r.url, `render-${r.job}.png`);
}

// ======================================================================= loading and training
function updateRunInfo() {
  const s = app.summary;
  const c = app.cloud;
  $('run-info').textContent = `${s.run} · ${c ? c.n : s.points} points (${s.point_source}) · field v${state.fieldVersion ?? s.field_version}`;
}

// Applies the summary's static parts: box, up axis, colour modes, default negatives.
function applySummary(s, cameras) {
  app.summary = s;
  const lo = (s.box && s.box.min) || [0, 0, 0], hi = (s.box && s.box.max) || [0, 0, 0];
  app.center = scale(add(lo, hi), 0.5);
  const diag = length(sub(hi, lo));
  app.diag = diag > 1e-6 ? diag : 1;  // a degenerate box (empty cloud) still gets a usable view
  app.cameras = cameras;
  app.up = sceneUp(cameras);
  $('query-negatives').value = s.default_negatives || '';
  $('query-text').placeholder = s.has_text_model ? 'class or text; a;b for several' : 'class name; a;b for several';
  buildModeOptions();
  buildFrustums();
  fitView();
}

// Fetches the points and classes (again after a training snapshot); the camera stays.
async function loadField() {
  if (app.loadingField) return;
  app.loadingField = true;
  try {
    const [classes, buf] = await Promise.all([getJSON('/api/classes'), api('/api/points').then((r) => r.arrayBuffer())]);
    const cloud = parsePoints(buf);
    app.classes = Array.isArray(classes.classes) ? classes.classes : [];
    app.cloud = cloud;
    state.points = cloud.n;
    state.fieldVersion = cloud.fieldVersion;
    uploadClassTexture();
    uploadCloud(cloud);
    buildLegend();
    updateRunInfo();
    if (cloud.n === 0) setStatus('the point cloud is empty');
    requestDraw();
    // Relevancy values belong to the old field: ask again with the same text.
    if (app.query) await submitQuery(app.query.text.positives, app.query.text.negatives, true);
  } finally {
    app.loadingField = false;
  }
}

function drawCurve(points) {
  const cv = $('curve');
  const dpr = window.devicePixelRatio || 1;
  cv.width = Math.round(cv.clientWidth * dpr);
  cv.height = Math.round(cv.clientHeight * dpr);
  const ctx = cv.getContext('2d');
  ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
  const W = cv.clientWidth, H = cv.clientHeight;
  ctx.clearRect(0, 0, W, H);
  ctx.font = '10px system-ui, sans-serif';
  ctx.fillStyle = '#8a909b';
  const pts = points.filter((p) => Number.isFinite(p.iteration) && Number.isFinite(p.psnr));
  if (pts.length === 0) { ctx.fillText('no PSNR values yet', 8, H / 2); return; }
  const x0 = pts[0].iteration, x1 = Math.max(pts[pts.length - 1].iteration, x0 + 1);
  let y0 = pts.reduce((m, p) => Math.min(m, p.psnr), Infinity), y1 = pts.reduce((m, p) => Math.max(m, p.psnr), -Infinity);
  if (y1 - y0 < 1e-6) { y0 -= 0.5; y1 += 0.5; }
  const L = 30, R = 6, T = 8, B = 16;  // plot margins for the labels
  const px = (x) => L + ((x - x0) / (x1 - x0)) * (W - L - R);
  const py = (y) => H - B - ((y - y0) / (y1 - y0)) * (H - T - B);
  ctx.strokeStyle = '#353a44';
  ctx.strokeRect(L, T, W - L - R, H - T - B);
  ctx.fillText(y1.toFixed(1), 2, T + 8);
  ctx.fillText(y0.toFixed(1), 2, H - B);
  ctx.fillText(String(x0), L, H - 4);
  const xl = String(x1);
  ctx.fillText(xl, W - R - ctx.measureText(xl).width, H - 4);
  ctx.fillText('PSNR', L + 4, T + 10);
  ctx.strokeStyle = '#4f9cf0';
  ctx.lineWidth = 1.5;
  ctx.beginPath();
  pts.forEach((p, i) => (i ? ctx.lineTo(px(p.iteration), py(p.psnr)) : ctx.moveTo(px(p.iteration), py(p.psnr))));
  ctx.stroke();
}

async function updateTraining(s) {
  $('training').hidden = !s.training;
  if (!s.training) return;
  $('iteration').textContent = s.iteration == null ? '' : `iteration ${s.iteration}`;
  const curve = await getJSON('/api/curve');
  drawCurve(Array.isArray(curve.points) ? curve.points : []);
}

// Every 2 s: a new field_version (training published a snapshot) reloads the points.
// It is compared with the summary's previous value, not the points header's, so a
// server whose two numbers differ does not reload forever.
let pollFailing = false;
async function pollSummary() {
  try {
    if (!app.cloud) {
      await loadAll();  // the first load failed: try again
    } else {
      const s = await getJSON('/api/summary');
      app.summary = s;
      if (s.field_version !== app.seenVersion) {
        app.seenVersion = s.field_version;
        setStatus(`field v${s.field_version}: reloading points…`);
        await loadField();
      }
      updateRunInfo();
      await updateTraining(s);
    }
    if (pollFailing) { pollFailing = false; setStatus('connected again'); }
  } catch (e) {
    if (!pollFailing) showError(`update: ${e.message}`);
    pollFailing = true;
  }
  setTimeout(pollSummary, 2000);
}

async function loadAll() {
  const summary = await getJSON('/api/summary');
  let cameras = [];
  try {
    const r = await getJSON('/api/cameras');
    cameras = Array.isArray(r.cameras) ? r.cameras : [];
  } catch (e) {
    showError(`cameras: ${e.message}`);  // the cloud is still worth showing
  }
  applySummary(summary, cameras);
  app.seenVersion = summary.field_version;
  await loadField();
  await updateTraining(summary);
}

// ======================================================================= start-up
function installControls() {
  const submit = () => submitQuery($('query-text').value.trim(), $('query-negatives').value.trim(), false);
  $('query-go').addEventListener('click', submit);
  for (const id of ['query-text', 'query-negatives']) {
    $(id).addEventListener('keydown', (e) => { if (e.key === 'Enter') { e.preventDefault(); submit(); } });
  }
  $('threshold').addEventListener('input', onThreshold);
  $('colour-mode').addEventListener('change', (e) => setMode(e.target.value));
  $('point-size').addEventListener('input', () => { $('point-size-value').textContent = $('point-size').value; requestDraw(); });
  $('show-cameras').addEventListener('change', requestDraw);
  $('reset-view').addEventListener('click', fitView);
  $('render-go').addEventListener('click', startRender);
  $('render-cancel').addEventListener('click', cancelRender);
  $('export-ply').addEventListener('click', exportPly);
  $('export-png').addEventListener('click', exportPng);
  $('render-close').addEventListener('click', () => { $('render-panel').hidden = true; requestDraw(); });
  new ResizeObserver(requestDraw).observe(canvas);
}

async function start() {
  installControls();
  try {
    if (!initGL()) throw new Error('WebGL2 is not available in this browser');
  } catch (e) {
    showError(`the viewer needs WebGL2: ${e.message}`);
    return;
  }
  installMouse();
  await loadAll().catch((e) => { pollFailing = true; showError(`loading: ${e.message}`); });
  setTimeout(pollSummary, 2000);
}

start();
})();
