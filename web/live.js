// kinemesh live page: the deforming mesh (three.js), the skeleton overlay, stats and the
// mapping panel (handles on the mesh -> Kinect joints, saved with POST /rig).
import * as THREE from 'three';
import { OrbitControls } from './OrbitControls.js';
import { initCamera } from './camera.js';

const KINECT = ['HipCenter', 'Spine', 'ShoulderCenter', 'Head', 'ShoulderLeft', 'ElbowLeft',
  'WristLeft', 'HandLeft', 'ShoulderRight', 'ElbowRight', 'WristRight', 'HandRight', 'HipLeft',
  'KneeLeft', 'AnkleLeft', 'FootLeft', 'HipRight', 'KneeRight', 'AnkleRight', 'FootRight'];
const PARENT = [-1, 0, 1, 2, 2, 4, 5, 6, 2, 8, 9, 10, 0, 12, 13, 14, 0, 16, 17, 18];
// Diagram layout (metres, front view) when the rig has no rest skeleton.
const LAYOUT = [[0, .95], [0, 1.2], [0, 1.45], [0, 1.65], [.18, 1.42], [.42, 1.42], [.62, 1.42],
  [.7, 1.42], [-.18, 1.42], [-.42, 1.42], [-.62, 1.42], [-.7, 1.42], [.1, .9], [.11, .5],
  [.12, .1], [.14, .03], [-.1, .9], [-.11, .5], [-.12, .1], [-.14, .03]];
const MAGIC = 0x31464d4b, HEADER = 304;

const $ = (id) => document.getElementById(id);
// The server's per-run secret comes in the printed URL (?token=...): every request to the
// server carries it (POSTs and the WebSocket need it; off loopback the data GETs too).
const TOKEN = new URLSearchParams(location.search).get('token') || '';
const api = (p) => (TOKEN ? `${p}?token=${encodeURIComponent(TOKEN)}` : p);
const state = {
  frames: 0, seq: 0, inSeq: 0, times: [0, 0, 0], rig: null, handleSets: [], pending: null,
  recv: [], nv: 0, connected: false,
};
window.kmLive = state; // for the end-to-end test

// ---------------------------------------------------------------- scene
const canvas = $('canvas');
const renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(window.devicePixelRatio || 1);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x1d2024);
const camera = new THREE.PerspectiveCamera(35, 1, 0.01, 100);
const controls = new OrbitControls(camera, canvas);
scene.add(new THREE.HemisphereLight(0xffffff, 0x404050, 1.6));
const sun = new THREE.DirectionalLight(0xffffff, 1.8);
sun.position.set(1, 2, 3);
scene.add(sun);
const grid = new THREE.GridHelper(4, 20, 0x444444, 0x333333);
scene.add(grid);

const geom = new THREE.BufferGeometry();
const material = new THREE.MeshStandardMaterial({ vertexColors: true, roughness: 0.7, metalness: 0,
  side: THREE.DoubleSide });
const mesh = new THREE.Mesh(geom, material);
scene.add(mesh);

const skelGeom = new THREE.BufferGeometry();
skelGeom.setAttribute('position', new THREE.BufferAttribute(new Float32Array(19 * 2 * 3), 3));
const skel = new THREE.LineSegments(skelGeom, new THREE.LineBasicMaterial({ color: 0x33ff99,
  depthTest: false, transparent: true }));
skel.renderOrder = 2;
const jointGeom = new THREE.BufferGeometry();
jointGeom.setAttribute('position', new THREE.BufferAttribute(new Float32Array(20 * 3), 3));
const joints = new THREE.Points(jointGeom, new THREE.PointsMaterial({ color: 0xffee55, size: 6,
  sizeAttenuation: false, depthTest: false, transparent: true }));
joints.renderOrder = 3;
skel.visible = joints.visible = false;
scene.add(skel, joints);

function resize() {
  const w = canvas.clientWidth, h = canvas.clientHeight;
  renderer.setSize(w, h, false);
  camera.aspect = w / Math.max(1, h);
  camera.updateProjectionMatrix();
}
window.addEventListener('resize', resize);

// ---------------------------------------------------------------- mesh + rig
const BASE = [0.78, 0.72, 0.66], PENDING = [0.2, 0.85, 1.0];
const HANDLE_COLORS = [[1, .55, .1], [.9, .3, .5], [.5, .8, .2], [.6, .5, 1], [1, .85, .2],
  [.3, .7, .9]];

async function loadMesh() {
  const buf = await (await fetch(api('mesh'))).arrayBuffer();
  const dv = new DataView(buf);
  const nv = dv.getUint32(4, true), nf = dv.getUint32(8, true);
  state.nv = nv;
  const pos = new Float32Array(buf, 16, 3 * nv).slice();
  const idx = new Uint32Array(buf.slice(16 + 12 * nv, 16 + 12 * nv + 12 * nf));
  state.rest = pos.slice();
  // flags bit 0: the mesh's own vertex colours (a scan's), sRGB bytes, shown where no handle is
  // (the colour attribute is linear)
  state.base = null;
  if (dv.getUint32(12, true) & 1) {
    const c8 = new Uint8Array(buf, 16 + 12 * nv + 12 * nf, 4 * nv);
    const lin = (x) => (x <= 0.04045 ? x / 12.92 : ((x + 0.055) / 1.055) ** 2.4);
    state.base = new Float32Array(3 * nv);
    for (let i = 0; i < nv; ++i)
      for (let k = 0; k < 3; ++k) state.base[3 * i + k] = lin(c8[4 * i + k] / 255);
  }
  geom.setAttribute('position', new THREE.BufferAttribute(pos, 3));
  geom.setAttribute('color', new THREE.BufferAttribute(new Float32Array(3 * nv), 3));
  geom.setIndex(new THREE.BufferAttribute(idx, 1));
  geom.computeVertexNormals();
  geom.computeBoundingSphere();
  geom.computeBoundingBox();
  const bb = geom.boundingBox, c = bb.getCenter(new THREE.Vector3());
  const size = bb.getSize(new THREE.Vector3());
  const d = Math.max(size.y, size.x) * 2.2;
  controls.target.copy(c);
  camera.position.set(c.x, c.y, c.z + d);
  camera.near = d / 100; camera.far = d * 20;
  camera.updateProjectionMatrix();
  grid.position.y = bb.min.y;
  state.radiusScale = Math.max(size.x, size.y, size.z);
  // The radius slider is in metres (0..0.3, 8 cm by default) for a mesh of human size; a mesh
  // in other units (a scan in centimetres or millimetres, served as in its file when no
  // --units was given) gets the slider in the matching power of ten, so the default ball is
  // still about 8 cm of the character and not a single vertex (or the whole mesh).
  const k = 10 ** Math.round(Math.log10(Math.max(size.y, 1e-12) / 1.7));
  if (k !== 1 && Number.isFinite(k)) {
    const r = $('h-radius');
    r.max = String(0.3 * k); r.step = String(0.005 * k); r.value = String(0.08 * k);
    $('h-radius-v').textContent = (+r.value).toFixed(3);
  }
  recolor();
}

// Edits made while a reload is in flight win over it: the panel must never put back a handle
// the user has just removed (state.edits counts adds and removes).
async function loadRig() {
  const e0 = state.edits || 0;
  const rig = await (await fetch(api('rig'))).json();
  const hs = await (await fetch(api('handles'))).json();
  if ((state.edits || 0) !== e0) return;
  state.rig = rig;
  state.handleSets = hs.handles || [];
  renderHandles();
  drawDiagram();
  recolor();
}

function recolor() {
  const col = geom.getAttribute('color');
  if (!col) return;
  const a = col.array;
  if (state.base) a.set(state.base);
  else for (let i = 0; i < state.nv; ++i) a.set(BASE, 3 * i);
  state.handleSets.forEach((h, k) => {
    const c = HANDLE_COLORS[k % HANDLE_COLORS.length];
    for (const v of h.vertices) if (v < state.nv) a.set(c, 3 * v);
  });
  if (state.pending) for (const v of state.pending.preview) a.set(PENDING, 3 * v);
  col.needsUpdate = true;
}

// ---------------------------------------------------------------- frames
function onFrame(buf) {
  const dv = new DataView(buf);
  if (buf.byteLength < HEADER || dv.getUint32(0, true) !== MAGIC) return;
  const flags = dv.getUint32(4, true), nv = dv.getUint32(8, true);
  if (nv !== state.nv) return;
  state.seq = dv.getUint32(12, true);
  state.inSeq = dv.getUint32(16, true);
  state.times = [dv.getFloat32(20, true), dv.getFloat32(24, true), dv.getFloat32(28, true)];
  const lo = [0, 1, 2].map((k) => dv.getFloat32(36 + 4 * k, true));
  const hi = [0, 1, 2].map((k) => dv.getFloat32(48 + 4 * k, true));
  const J = new Float32Array(buf, 60, 60);
  const P = geom.getAttribute('position');
  const out = P.array;
  if (flags & 1) {
    // int16 about the box centre c with half-extent h: x = c + q h / 32767 (src/live/live.h)
    const q = new Int16Array(buf, HEADER, 3 * nv);
    const c = [0, 1, 2].map((k) => (lo[k] + hi[k]) / 2);
    const s = [0, 1, 2].map((k) => (hi[k] - lo[k]) / 2 / 32767);
    for (let i = 0; i < 3 * nv; i += 3) {
      out[i] = c[0] + q[i] * s[0]; out[i + 1] = c[1] + q[i + 1] * s[1];
      out[i + 2] = c[2] + q[i + 2] * s[2];
    }
  } else {
    out.set(new Float32Array(buf, HEADER, 3 * nv));
  }
  P.needsUpdate = true;
  geom.computeVertexNormals();
  geom.computeBoundingSphere();
  state.box = { lo, hi };
  drawSkeleton(J);
  state.frames++;
  const now = performance.now();
  state.recv.push(now);
  while (state.recv.length && now - state.recv[0] > 1000) state.recv.shift();
}

// Bridges leave joints out (OSCeleton sends no wrists or ankles: they arrive NaN), so the
// overlay draws what it can: the finite joints and every bone with both ends finite, packed at
// the front of the buffers and cut with setDrawRange. The tail is filled with a drawn point,
// never NaN, because three.js bounds the whole attribute, not the draw range.
function drawSkeleton(J) {
  const sp = skelGeom.getAttribute('position').array, jp = jointGeom.getAttribute('position').array;
  const ok = (j) => Number.isFinite(J[3 * j]) && Number.isFinite(J[3 * j + 1]) && Number.isFinite(J[3 * j + 2]);
  let nj = 0, nb = 0;
  for (let j = 0; j < 20; ++j) {
    if (!ok(j)) continue;
    for (let a = 0; a < 3; ++a) jp[3 * nj + a] = J[3 * j + a];
    ++nj;
    const p = PARENT[j];
    if (p < 0 || !ok(p)) continue;
    for (let a = 0; a < 3; ++a) { sp[6 * nb + a] = J[3 * p + a]; sp[6 * nb + 3 + a] = J[3 * j + a]; }
    ++nb;
  }
  for (let k = 3 * nj; k < jp.length; ++k) jp[k] = nj ? jp[k % 3] : 0;
  for (let k = 6 * nb; k < sp.length; ++k) sp[k] = nb ? sp[k % 3] : 0;
  jointGeom.setDrawRange(0, nj);
  skelGeom.setDrawRange(0, 2 * nb);
  skelGeom.getAttribute('position').needsUpdate = true;
  jointGeom.getAttribute('position').needsUpdate = true;
  // The overlay moves with the performer: a bounding sphere from the first frame would cull it.
  skelGeom.computeBoundingSphere();
  jointGeom.computeBoundingSphere();
  state.overlay = { joints: nj, bones: nb,
    finite: jp.every(Number.isFinite) && sp.every(Number.isFinite) };
  const show = $('show-skel').checked;
  joints.visible = show && nj > 0;
  skel.visible = show && nb > 0;
}

function connect() {
  const ws = new WebSocket(`ws://${location.host}/${api('ws')}`, 'kinemesh');
  state.ws = ws; // the camera sends its joint frames on it
  ws.binaryType = 'arraybuffer';
  ws.onopen = () => { state.connected = true; $('conn').textContent = 'connected'; $('conn').className = 'ok'; };
  ws.onclose = () => {
    state.connected = false;
    $('conn').textContent = 'disconnected'; $('conn').className = 'bad';
    setTimeout(connect, 1000);
  };
  ws.onmessage = (e) => onFrame(e.data);
}

async function pollStatus() {
  try {
    const s = await (await fetch(api('status'))).json();
    state.status = s;
    $('s-in').textContent = s.frames_in; $('s-out').textContent = s.frames_out;
    $('s-bad').textContent = s.bad_packets;
    const l = s.times_ms.latency_median;
    $('s-lat').textContent = l == null ? '–' : l.toFixed(2);
  } catch (e) { /* server gone; the socket reconnects */ }
}

// ---------------------------------------------------------------- picking
const ray = new THREE.Raycaster();
let down = null;
canvas.addEventListener('pointerdown', (e) => { down = [e.clientX, e.clientY]; });
// The vertex under a client-space point: the nearest corner of the hit triangle, or -1.
function pickVertex(x, y) {
  const r = canvas.getBoundingClientRect();
  const ndc = new THREE.Vector2(((x - r.left) / r.width) * 2 - 1, -((y - r.top) / r.height) * 2 + 1);
  ray.setFromCamera(ndc, camera);
  const hit = ray.intersectObject(mesh)[0];
  if (!hit || !hit.face) return -1;
  const P = geom.getAttribute('position');
  let best = -1, bd = Infinity;
  for (const v of [hit.face.a, hit.face.b, hit.face.c]) {
    const d = new THREE.Vector3().fromBufferAttribute(P, v).distanceTo(hit.point);
    if (d < bd) { bd = d; best = v; }
  }
  return best;
}
canvas.addEventListener('pointerup', (e) => {
  if (!down || Math.hypot(e.clientX - down[0], e.clientY - down[1]) > 4) return; // a drag
  const v = pickVertex(e.clientX, e.clientY);
  if (v >= 0) setPending(v);
});
// Hover readout: id and rest position of the vertex under the cursor (once per frame).
let hoverAt = null;
canvas.addEventListener('pointermove', (e) => {
  if (!hoverAt) requestAnimationFrame(() => {
    const v = pickVertex(hoverAt[0], hoverAt[1]);
    hoverAt = null;
    state.hover = v;
    const R = state.rest;
    $('hover').textContent = v < 0 || !R ? '–'
      : `${v} (${[0, 1, 2].map((k) => R[3 * v + k].toFixed(3)).join(', ')})`;
  });
  hoverAt = [e.clientX, e.clientY];
});
canvas.addEventListener('pointerleave', () => { state.hover = -1; $('hover').textContent = '–'; });

// The handle region: the geodesic ball the server resolves for {"vertex", "radius"} (shortest
// path along mesh edges <= radius, so it stays on the clicked limb), minus the vertices other
// handles already hold (a vertex belongs to one handle only: the default rig's pelvis and
// chest bands sit inside an 8 cm ball clicked on the torso). When nothing is taken the handle
// is saved as {"vertex", "radius"}; otherwise as the explicit "vertices" left, so the save is
// not refused as overlapping; when nothing is left the panel says which handle has them.
function edgeGraph() {
  if (state.graph) return state.graph;
  const idx = geom.getIndex().array, nv = state.nv, ptr = new Int32Array(nv + 1);
  for (let k = 0; k < idx.length; ++k) ptr[idx[k] + 1] += 2;
  for (let v = 0; v < nv; ++v) ptr[v + 1] += ptr[v];
  const adj = new Int32Array(ptr[nv]), fill = ptr.slice(0, nv);
  for (let f = 0; f + 2 < idx.length; f += 3)
    for (let k = 0; k < 3; ++k) {
      const a = idx[f + k], b = idx[f + (k + 1) % 3];
      adj[fill[a]++] = b; adj[fill[b]++] = a;
    }
  return (state.graph = { ptr, adj });
}
function geodesicBall(seed, radius) {
  const R = state.rest, { ptr, adj } = edgeGraph(), dist = new Map([[seed, 0]]), out = [];
  const heap = [[0, seed]], done = new Set();
  const push = (e) => { heap.push(e); for (let i = heap.length - 1; i > 0;) { const p = (i - 1) >> 1; if (heap[p][0] <= heap[i][0]) break; [heap[p], heap[i]] = [heap[i], heap[p]]; i = p; } };
  const pop = () => {
    const top = heap[0], last = heap.pop();
    if (heap.length) {
      heap[0] = last;
      for (let i = 0; ;) {
        const l = 2 * i + 1, r = l + 1; let m = i;
        if (l < heap.length && heap[l][0] < heap[m][0]) m = l;
        if (r < heap.length && heap[r][0] < heap[m][0]) m = r;
        if (m === i) break;
        [heap[m], heap[i]] = [heap[i], heap[m]]; i = m;
      }
    }
    return top;
  };
  while (heap.length) {
    const [d, v] = pop();
    if (done.has(v)) continue;
    done.add(v); out.push(v);
    for (let k = ptr[v]; k < ptr[v + 1]; ++k) {
      const w = adj[k];
      if (done.has(w)) continue;
      const nd = d + Math.hypot(R[3 * w] - R[3 * v], R[3 * w + 1] - R[3 * v + 1], R[3 * w + 2] - R[3 * v + 2]);
      if (nd <= radius && nd < (dist.get(w) ?? Infinity)) { dist.set(w, nd); push([nd, w]); }
    }
  }
  return out;
}
function setPending(v) {
  const radius = +$('h-radius').value, owner = new Map();
  for (const h of state.handleSets) for (const u of h.vertices) owner.set(u, h.name);
  // The taken check uses a slightly larger ball: the server's double-precision distances must
  // not find a taken vertex on the rim that this float32 copy missed.
  const rim = geodesicBall(v, radius * 1.001 + 1e-9);
  const ball = new Set(geodesicBall(v, radius));
  const taken = rim.filter((u) => owner.has(u));
  const free = rim.filter((u) => ball.has(u) && !owner.has(u));
  state.pending = { vertex: v, preview: free, taken: taken.length,
    explicit: taken.length > 0, owners: [...new Set(taken.map((u) => owner.get(u)))] };
  $('h-vertex').textContent = v;
  $('h-add').disabled = free.length === 0;
  $('rig-resting').disabled = false;
  $('save-status').textContent = !taken.length ? ''
    : free.length ? `${taken.length} vertices within the radius belong to ${state.pending.owners.join(', ')}: the new handle takes the ${free.length} others`
      : `every vertex within the radius belongs to ${state.pending.owners.join(', ')}: click elsewhere, lower the radius or remove that handle`;
  recolor();
}

$('h-radius').addEventListener('input', () => {
  $('h-radius-v').textContent = (+$('h-radius').value).toFixed(3);
  if (state.pending) setPending(state.pending.vertex);
});

// project(i): client-space pixel position of vertex i (used by the end-to-end test)
state.project = (i) => {
  const P = geom.getAttribute('position');
  const p = new THREE.Vector3().fromBufferAttribute(P, i).project(camera);
  const r = canvas.getBoundingClientRect();
  return { x: r.left + (p.x + 1) / 2 * r.width, y: r.top + (1 - p.y) / 2 * r.height, z: p.z };
};
state.vertexPosition = (i) => Array.from(geom.getAttribute('position').array.slice(3 * i, 3 * i + 3));
state.vertexColor = (i) => Array.from(geom.getAttribute('color').array.slice(3 * i, 3 * i + 3));

// ---------------------------------------------------------------- panel
const sel = $('h-joint');
KINECT.forEach((n) => { const o = document.createElement('option'); o.value = o.textContent = n; sel.append(o); });
sel.value = 'HandRight';
sel.addEventListener('change', drawDiagram);

function drawDiagram() {
  const svg = $('diagram');
  const rest = LAYOUT.map((p) => p.slice());
  for (const j of (state.rig && state.rig.joints) || []) {
    const k = KINECT.indexOf(j.name);
    if (k >= 0 && Array.isArray(j.rest)) rest[k] = [j.rest[0], j.rest[1]];
  }
  const xs = rest.map((p) => p[0]), ys = rest.map((p) => p[1]);
  const minx = Math.min(...xs), maxx = Math.max(...xs), miny = Math.min(...ys), maxy = Math.max(...ys);
  const s = Math.min(210 / Math.max(1e-6, maxx - minx), 220 / Math.max(1e-6, maxy - miny));
  const X = (p) => 120 + (p[0] - (minx + maxx) / 2) * s, Y = (p) => 235 - (p[1] - miny) * s;
  const mapped = new Set(((state.rig && state.rig.map) || []).map((m) => m.joint || (m.bone && m.bone[1])));
  let html = '';
  for (let j = 1; j < 20; ++j) {
    const a = rest[PARENT[j]], b = rest[j];
    html += `<line x1="${X(a)}" y1="${Y(a)}" x2="${X(b)}" y2="${Y(b)}" stroke="#777" stroke-width="2"/>`;
  }
  rest.forEach((p, j) => {
    const fill = KINECT[j] === sel.value ? '#3cf' : mapped.has(KINECT[j]) ? '#f90' : '#bbb';
    html += `<circle data-joint="${KINECT[j]}" cx="${X(p)}" cy="${Y(p)}" r="6" fill="${fill}"><title>${KINECT[j]}</title></circle>`;
  });
  svg.innerHTML = html;
  svg.querySelectorAll('circle').forEach((c) => c.addEventListener('click', () => {
    sel.value = c.dataset.joint;
    drawDiagram();
  }));
}

function renderHandles() {
  const ul = $('handles');
  ul.innerHTML = '';
  for (const h of state.rig.handles || []) {
    const maps = (state.rig.map || []).filter((m) => m.handle === h.name);
    const li = document.createElement('li');
    li.innerHTML = `<span>${h.name} → ${maps.map((m) => (m.bone ? `bone ${m.bone[0]}→${m.bone[1]}` : `${m.joint} ${m.axes || 'xyz'}×${m.scale ?? 1}`)).join(', ') || '(anchor)'}</span>`;
    const b = document.createElement('button');
    b.textContent = '✕';
    b.title = 'remove handle';
    b.className = 'remove';
    b.addEventListener('click', () => {
      state.rig.handles = state.rig.handles.filter((x) => x !== h);
      state.rig.map = (state.rig.map || []).filter((m) => m.handle !== h.name);
      state.handleSets = state.handleSets.filter((x) => x.name !== h.name);
      state.edits = (state.edits || 0) + 1;
      renderHandles(); drawDiagram(); recolor();
    });
    li.append(b);
    ul.append(li);
  }
}

$('h-add').addEventListener('click', () => {
  if (!state.pending || !state.rig) return;
  const joint = sel.value;
  const axes = ['x', 'y', 'z'].filter((a) => $('ax-' + a).checked).join('');
  if (!axes) { $('save-status').textContent = 'pick at least one axis'; return; }
  let name = `${joint}_${state.pending.vertex}`;
  const names = new Set((state.rig.handles || []).map((h) => h.name));
  for (let k = 2; names.has(name); ++k) name = `${joint}_${state.pending.vertex}_${k}`;
  const radius = +$('h-radius').value;
  state.rig.handles = state.rig.handles || [];
  state.rig.map = state.rig.map || [];
  state.rig.handles.push(state.pending.explicit
    ? { name, seed: state.pending.vertex, vertices: state.pending.preview.slice().sort((a, b) => a - b) }
    : { name, vertex: state.pending.vertex, radius });
  state.rig.map.push({ handle: name, joint, axes, scale: +$('h-scale').value || 1 });
  state.handleSets.push({ name, vertices: state.pending.preview });
  state.edits = (state.edits || 0) + 1;
  state.pending = null;
  $('h-vertex').textContent = '–';
  $('h-add').disabled = true;
  $('rig-resting').disabled = true;
  renderHandles(); drawDiagram(); recolor();
});

$('save').addEventListener('click', async () => {
  $('save-status').textContent = 'saving…';
  const r = await fetch(api('rig'), { method: 'POST', headers: { 'Content-Type': 'application/json' },
    body: JSON.stringify(state.rig) });
  const j = await r.json().catch(() => ({}));
  if (r.ok) {
    await loadRig();
    $('save-status').textContent = `saved (${j.handles} handles)`;
    state.saved = (state.saved || 0) + 1;
  } else {
    $('save-status').textContent = 'error: ' + (j.error || r.status);
  }
});

// A body lying or curled up: the server rigs the mesh anew from the clicked vertex, the tip of
// its head (`kinemesh rig MESH --skeleton resting --head V`), and replaces the whole rig.
$('rig-resting').addEventListener('click', async () => {
  if (!state.pending) return;
  const head = state.pending.vertex;
  $('rest-status').textContent = 'rigging…';
  const r = await fetch(api('rig'), { method: 'POST', headers: { 'Content-Type': 'application/json' },
    body: JSON.stringify({ autorig: { skeleton: 'resting', head } }) });
  const j = await r.json().catch(() => ({}));
  if (r.ok) {
    state.pending = null;
    $('h-vertex').textContent = '–';
    $('save-status').textContent = '';
    $('h-add').disabled = true;
    $('rig-resting').disabled = true;
    state.edits = (state.edits || 0) + 1; // the panel shows the new rig, not a reload in flight
    await loadRig();
    $('rest-status').textContent = `rigged lying from vertex ${head} (${j.handles} handles)`;
    state.rested = (state.rested || 0) + 1;
  } else {
    $('rest-status').textContent = 'error: ' + (j.error || r.status);
  }
});

$('replay').addEventListener('click', async () => {
  const r = await fetch(api('replay'), { method: 'POST',
    headers: { 'Content-Type': 'application/json' }, body: '{}' });
  if (!r.ok) $('replay').textContent = 'no take to replay';
});

// ---------------------------------------------------------------- loop
function animate() {
  requestAnimationFrame(animate);
  controls.update();
  renderer.render(scene, camera);
  $('fps').textContent = state.recv.length;
  $('seq').textContent = state.seq;
  $('t-rt').textContent = state.times[0].toFixed(3);
  $('t-def').textContent = state.times[1].toFixed(2);
  $('t-pack').textContent = state.times[2].toFixed(2);
}

resize();
await loadMesh();
await loadRig();
initCamera(state, $);
state.ready = true;
connect();
setInterval(pollStatus, 500);
animate();
