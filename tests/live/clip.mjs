// A fake-camera clip for the Camera button's test: the procedural character (kinemesh gen
// character) performs a generated take, its LEFT arm raising from hanging at its side to above
// the shoulder and back while the right arm hangs still, deformed by `kinemesh animate`
// (.pc2), rendered by the small rasteriser below (skin-coloured with a painted face, hair and
// clothes, Gouraud-lit, z-buffered) from
// a camera in front of it, written as YUV4MPEG2 4:2:0 for chromium's
// --use-file-for-fake-video-capture.
//   node clip.mjs KINEMESH WORK  ->  WORK/clip.y4m, WORK/clip_take.json, WORK/clip_{0,30}.png
// The take's left-arm elevation (degrees above horizontal) per frame is in the take's "elev".
import { execFileSync } from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import zlib from 'node:zlib';

export const W = 640, H = 480, FRAMES = 60, LOW = -70, HIGH = 60;
// Elevation of the left arm in frame f: LOW -> HIGH -> LOW over the clip (it loops).
export const elevation = (f) => LOW + (HIGH - LOW) * Math.sin(Math.PI * f / FRAMES) ** 2;

function rotZ(p, c, deg) {
  const a = deg * Math.PI / 180, x = p[0] - c[0], y = p[1] - c[1];
  return [c[0] + x * Math.cos(a) - y * Math.sin(a), c[1] + x * Math.sin(a) + y * Math.cos(a), p[2]];
}

export function makeTake(rig) {
  const names = rig.joints.map((j) => j.name), rest = rig.joints.map((j) => j.rest);
  const J = (n) => names.indexOf(n);
  const frames = [];
  for (let f = 0; f < FRAMES; ++f) {
    const p = rest.map((r) => r.slice());
    // T-pose rest: the left arm points +x (elevation 0), the right arm -x.
    const sl = p[J('ShoulderLeft')], sr = p[J('ShoulderRight')];
    for (const n of ['ElbowLeft', 'WristLeft', 'HandLeft']) p[J(n)] = rotZ(p[J(n)], sl, elevation(f));
    for (const n of ['ElbowRight', 'WristRight', 'HandRight']) p[J(n)] = rotZ(p[J(n)], sr, -LOW);
    frames.push(p.flat());
  }
  const parents = rig.joints.map((j) => j.parent);
  return { format: 'kinemesh-take', version: 1, fps: 30, units: 'm', joints: names, parents,
    frames, elev: Array.from({ length: FRAMES }, (_, f) => elevation(f)) };
}

export function readObj(file) {
  const V = [], F = [];
  for (const line of fs.readFileSync(file, 'utf8').split('\n')) {
    const t = line.trim().split(/\s+/);
    if (t[0] === 'v') V.push(+t[1], +t[2], +t[3]);
    else if (t[0] === 'f') {
      const ix = t.slice(1).map((s) => parseInt(s, 10) - 1);
      for (let k = 1; k + 1 < ix.length; ++k) F.push(ix[0], ix[k], ix[k + 1]);
    }
  }
  return { V: Float32Array.from(V), F: Uint32Array.from(F) };
}

export function readPc2(file) {
  const b = fs.readFileSync(file);
  if (b.toString('latin1', 0, 11) !== 'POINTCACHE2') throw new Error(`${file}: not a .pc2`);
  const n = b.readInt32LE(16), frames = b.readInt32LE(28);
  const out = [];
  for (let f = 0; f < frames; ++f) {
    const a = new Float32Array(3 * n);
    for (let k = 0; k < 3 * n; ++k) a[k] = b.readFloatLE(32 + 4 * (3 * n * f + k));
    out.push(a);
  }
  return out;
}

// The surface colour at rest position q: a face on the front of the head and hair on its top
// and back (a faceless head looks the same from behind: the detector could not tell the
// performer's left from right), a shirt on the trunk, trousers on the legs, skin elsewhere.
const SKIN = [232, 180, 150], HAIR = [70, 45, 30], SHIRT = [60, 90, 160], TROUSERS = [55, 55, 65];
function paint(q, body) {
  const d = [q[0] - body.head[0], q[1] - body.head[1], q[2] - body.head[2]];
  if (q[1] > body.neck && Math.hypot(...d) < 0.2) {
    if (d[1] > 0.05 || d[2] < -0.01 || (d[1] > 0.03 && Math.abs(d[0]) > 0.06)) return HAIR;
    if (d[2] > 0) {
      const ex = Math.abs(d[0]) - 0.038, ey = d[1] - 0.012;
      if (ex * ex + ey * ey < 0.007 ** 2) return [40, 30, 25];
      if (ex * ex + ey * ey < 0.014 ** 2) return [245, 245, 240];
      if (Math.abs(d[0]) > 0.02 && Math.abs(d[0]) < 0.058 && d[1] > 0.03 && d[1] < 0.038) return HAIR;
      if (Math.abs(d[0]) < 0.028 && d[1] > -0.052 && d[1] < -0.04) return [150, 60, 60];
      if (Math.abs(d[0]) < 0.01 && d[1] > -0.03 && d[1] < 0.0) return [200, 150, 125];
    }
    return SKIN;
  }
  if (q[1] < body.hip - 0.02) return q[1] < body.ankle ? [40, 40, 40] : TROUSERS;
  if (Math.abs(q[0]) < body.shoulderX + 0.04 && q[1] < body.neck) return SHIRT;
  return SKIN;
}

// Renders positions P (faces F, rest positions R) to RGB (W*H*3 bytes): a pinhole camera on +z
// looking at -z, y up, so the character's left (+x) is on the image's right as for a real
// camera.
export function render(P, F, R, body, cam) {
  const rgb = new Uint8Array(W * H * 3), zb = new Float32Array(W * H).fill(Infinity);
  for (let i = 0; i < W * H; ++i) { // a wall with a soft vertical gradient
    const g = 150 + 40 * Math.floor(i / W) / H;
    rgb[3 * i] = g * 0.85; rgb[3 * i + 1] = g * 0.9; rgb[3 * i + 2] = g;
  }
  const n = P.length / 3, N = new Float32Array(3 * n);
  for (let t = 0; t < F.length; t += 3) {
    const a = 3 * F[t], b = 3 * F[t + 1], c = 3 * F[t + 2];
    const u = [P[b] - P[a], P[b + 1] - P[a + 1], P[b + 2] - P[a + 2]];
    const v = [P[c] - P[a], P[c + 1] - P[a + 1], P[c + 2] - P[a + 2]];
    const nx = u[1] * v[2] - u[2] * v[1], ny = u[2] * v[0] - u[0] * v[2], nz = u[0] * v[1] - u[1] * v[0];
    for (const i of [a, b, c]) { N[i] += nx; N[i + 1] += ny; N[i + 2] += nz; }
  }
  const L = [-0.35, 0.5, 0.8], ll = Math.hypot(...L);
  const sx = new Float32Array(n), sy = new Float32Array(n), sz = new Float32Array(n), sh = new Float32Array(n);
  for (let i = 0; i < n; ++i) {
    const x = P[3 * i] - cam.x, y = P[3 * i + 1] - cam.y, d = cam.z - P[3 * i + 2];
    sx[i] = W / 2 + cam.f * x / d; sy[i] = H / 2 - cam.f * y / d; sz[i] = d;
    const nl = Math.hypot(N[3 * i], N[3 * i + 1], N[3 * i + 2]) || 1;
    const dot = (N[3 * i] * L[0] + N[3 * i + 1] * L[1] + N[3 * i + 2] * L[2]) / nl / ll;
    sh[i] = 0.35 + 0.65 * Math.max(0, dot); // double-sided meshes: no back-face light
  }
  for (let t = 0; t < F.length; t += 3) {
    const a = F[t], b = F[t + 1], c = F[t + 2];
    const x0 = Math.max(0, Math.floor(Math.min(sx[a], sx[b], sx[c])));
    const x1 = Math.min(W - 1, Math.ceil(Math.max(sx[a], sx[b], sx[c])));
    const y0 = Math.max(0, Math.floor(Math.min(sy[a], sy[b], sy[c])));
    const y1 = Math.min(H - 1, Math.ceil(Math.max(sy[a], sy[b], sy[c])));
    const area = (sx[b] - sx[a]) * (sy[c] - sy[a]) - (sx[c] - sx[a]) * (sy[b] - sy[a]);
    if (Math.abs(area) < 1e-9) continue;
    for (let y = y0; y <= y1; ++y) {
      for (let x = x0; x <= x1; ++x) {
        const px = x + 0.5, py = y + 0.5;
        const w0 = ((sx[b] - px) * (sy[c] - py) - (sx[c] - px) * (sy[b] - py)) / area;
        const w1 = ((sx[c] - px) * (sy[a] - py) - (sx[a] - px) * (sy[c] - py)) / area;
        const w2 = 1 - w0 - w1;
        if (w0 < 0 || w1 < 0 || w2 < 0) continue;
        const z = w0 * sz[a] + w1 * sz[b] + w2 * sz[c], k = y * W + x;
        if (z >= zb[k]) continue;
        zb[k] = z;
        const s = w0 * sh[a] + w1 * sh[b] + w2 * sh[c];
        const q = [0, 1, 2].map((e) => w0 * R[3 * a + e] + w1 * R[3 * b + e] + w2 * R[3 * c + e]);
        const col = paint(q, body);
        rgb[3 * k] = Math.min(255, col[0] * s); rgb[3 * k + 1] = Math.min(255, col[1] * s);
        rgb[3 * k + 2] = Math.min(255, col[2] * s);
      }
    }
  }
  return rgb;
}

// RGB (W*H*3) as a PNG file, to look at.
function crc32(buf) {
  let c = ~0;
  for (const b of buf) { c ^= b; for (let k = 0; k < 8; ++k) c = (c >>> 1) ^ (0xedb88320 & -(c & 1)); }
  return ~c >>> 0;
}
export function writePng(file, rgb) {
  const chunk = (type, data) => {
    const len = Buffer.alloc(4), crc = Buffer.alloc(4), td = Buffer.concat([Buffer.from(type), data]);
    len.writeUInt32BE(data.length); crc.writeUInt32BE(crc32(td));
    return Buffer.concat([len, td, crc]);
  };
  const ihdr = Buffer.alloc(13);
  ihdr.writeUInt32BE(W, 0); ihdr.writeUInt32BE(H, 4); ihdr[8] = 8; ihdr[9] = 2;
  const raw = Buffer.alloc((3 * W + 1) * H);
  for (let y = 0; y < H; ++y) Buffer.from(rgb.buffer, 3 * W * y, 3 * W).copy(raw, (3 * W + 1) * y + 1);
  fs.writeFileSync(file, Buffer.concat([Buffer.from([137, 80, 78, 71, 13, 10, 26, 10]),
    chunk('IHDR', ihdr), chunk('IDAT', zlib.deflateSync(raw)), chunk('IEND', Buffer.alloc(0))]));
}

// RGB -> YUV 4:2:0, full range BT.601 (C420jpeg).
function yuv420(rgb) {
  const Y = new Uint8Array(W * H), U = new Uint8Array(W * H / 4), V = new Uint8Array(W * H / 4);
  const cl = (v) => Math.max(0, Math.min(255, Math.round(v)));
  for (let i = 0; i < W * H; ++i) {
    Y[i] = cl(0.299 * rgb[3 * i] + 0.587 * rgb[3 * i + 1] + 0.114 * rgb[3 * i + 2]);
  }
  for (let y = 0; y < H / 2; ++y) {
    for (let x = 0; x < W / 2; ++x) {
      let r = 0, g = 0, b = 0;
      for (const [dx, dy] of [[0, 0], [1, 0], [0, 1], [1, 1]]) {
        const k = 3 * ((2 * y + dy) * W + 2 * x + dx);
        r += rgb[k] / 4; g += rgb[k + 1] / 4; b += rgb[k + 2] / 4;
      }
      U[y * W / 2 + x] = cl(128 - 0.168736 * r - 0.331264 * g + 0.5 * b);
      V[y * W / 2 + x] = cl(128 + 0.5 * r - 0.418688 * g - 0.081312 * b);
    }
  }
  return [Y, U, V];
}

export function makeClip(bin, work) {
  const rig = JSON.parse(fs.readFileSync(path.join(work, 'c.rig.json'), 'utf8'));
  const take = makeTake(rig);
  fs.writeFileSync(path.join(work, 'clip_take.json'), JSON.stringify(take));
  execFileSync(bin, ['animate', '--mesh', path.join(work, 'c.obj'), '--motion',
    path.join(work, 'clip_take.json'), '-o', path.join(work, 'clip.pc2')], { stdio: 'pipe' });
  const { V, F } = readObj(path.join(work, 'c.obj'));
  const frames = readPc2(path.join(work, 'clip.pc2'));
  if (!frames.length || frames[0].length !== V.length) throw new Error('clip.pc2 does not match c.obj');
  let lo = Infinity, hi = -Infinity;
  for (let i = 1; i < V.length; i += 3) { lo = Math.min(lo, V[i]); hi = Math.max(hi, V[i]); }
  // The whole body, raised hand included, in about 85% of the frame height.
  const rest = (n) => rig.joints.find((j) => j.name === n).rest;
  const body = { head: rest('Head'), neck: (rest('Head')[1] + rest('ShoulderCenter')[1]) / 2 + 0.02,
    hip: rest('HipCenter')[1], ankle: rest('AnkleLeft')[1] + 0.02,
    shoulderX: Math.abs(rest('ShoulderLeft')[0]) };
  const cam = { x: 0, y: (lo + hi) / 2 + 0.1, z: 4, f: 0 };
  cam.f = 0.8 * H * cam.z / (hi - lo + 0.5);
  const out = fs.openSync(path.join(work, 'clip.y4m'), 'w');
  fs.writeSync(out, `YUV4MPEG2 W${W} H${H} F30:1 Ip A1:1 C420jpeg\n`);
  frames.forEach((P, f) => {
    const rgb = render(P, F, V, body, cam);
    if (f === 0 || f === FRAMES / 2) writePng(path.join(work, `clip_${f}.png`), rgb);
    fs.writeSync(out, 'FRAME\n');
    for (const plane of yuv420(rgb)) fs.writeSync(out, plane);
  });
  fs.closeSync(out);
  return take;
}

if (process.argv[1] && process.argv[1].endsWith('clip.mjs')) {
  const [bin, work] = process.argv.slice(2);
  makeClip(bin, work);
  console.log(`${work}/clip.y4m: ${FRAMES} frames ${W}x${H}`);
}
