// The Camera button with a fake webcam: chromium plays WORK/clip.y4m (tests/live/clip.mjs: the
// procedural character raising its left arm) as its camera; the page loads MediaPipe Pose from
// the live server (no network), detects the body, draws the thumbnail and sends landmark
// frames over the WebSocket. The server's recording of what it received (--record) is checked
// after it stops (camera_check.mjs, run by run.sh).
import { createRequire } from 'node:module';
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { check, finish, status, waitFor, TOKEN } from './lib.mjs';
import { makeClip } from './clip.mjs';
import { landmarkFrame, spanGuard } from '../../web/camera.js';

const here = path.dirname(fileURLToPath(import.meta.url));
const require = createRequire(path.join(here, '../../web/package.json'));
const { chromium } = require('playwright-core');
const [http, , , work] = process.argv.slice(2);

// The page's conversion, in node: MediaPipe world landmarks (x image right, y down, z away from
// the camera, origin between the hips) -> kinemesh (x, -y, -z), the pelvis 0.9 m up; the
// performer's left wrist, on the image's right, at +x.
{
  const world = Array.from({ length: 33 }, () => ({ x: 0, y: 0, z: 0, visibility: 0.9 }));
  world[15] = { x: 0.5, y: -0.3, z: -0.1, visibility: 0.95 }; // left wrist up, toward the camera
  world[16] = { x: -0.4, y: 0.1, z: 0.2, visibility: 0.2 };   // right wrist: not visible
  world[11] = { x: 0.2, y: -0.5, z: 0, visibility: 1 };
  world[12] = { x: -0.2, y: -0.5, z: 0, visibility: 1 };
  const f = landmarkFrame(world, null, 'fixed');
  check(f.skeleton === 'mediapipe' && f.joints.length === 99 && f.visibility.length === 33, 'a 99-number mediapipe frame');
  const lw = f.joints.slice(45, 48).map((v) => Math.round(v * 1000) / 1000);
  check(lw[0] === 0.5 && lw[1] === 1.2 && lw[2] === 0.1, `left wrist -> (${lw}) (want 0.5, 1.2, 0.1)`);
  check(f.joints.slice(48, 51).every((v) => v === null), 'a landmark under visibility 0.5 goes as null');
  // root from the image: the hips right of the image centre move the root to +x
  const image = Array.from({ length: 33 }, () => ({ x: 0.7, y: 0.6 }));
  image[11] = { x: 0.75, y: 0.3 }; image[12] = { x: 0.65, y: 0.3 };
  const g = landmarkFrame(world, image, 'image');
  check(Math.abs(g.joints[45] - (0.5 + 0.2 * 0.4 / 0.1)) < 1e-9 && Math.abs(g.joints[46] - 1.2) < 1e-9,
    `root from the image: the hips at 0.7 of the width move it +${(g.joints[45] - 0.5).toFixed(2)} m in x`);
  // read as seen from behind (nose behind the shoulders, the left shoulder at -x): turned back
  const sw = world.map((p) => ({ ...p }));
  sw[0] = { x: 0, y: -0.6, z: 0.1, visibility: 1 };
  [sw[11], sw[12]] = [world[12], world[11]];
  sw[16] = { ...world[15], z: 0.1 };
  sw[15] = { ...world[16], z: -0.2 };
  const h = landmarkFrame(sw, null, 'fixed');
  check(h.turned && h.joints[45] === 0.5 && Math.abs(h.joints[47] - 0.1) < 1e-12 && h.joints[33] === 0.2 && h.joints[48] === null,
    'a frame read from behind is turned back to face the camera (left wrist at +x, in front)');
  check(!landmarkFrame(sw, null, 'fixed', 0.75, false).turned, 'not with "faces the camera" off');
  sw[0].z = -0.1; // the nose in front: not a back view, kept as is
  check(!landmarkFrame(sw, null, 'fixed').turned, 'a frame with the nose in front is kept');
  check(landmarkFrame(null, null, 'fixed') === null && landmarkFrame(world.slice(1), null, 'fixed') === null,
    'no body, no frame');
}
// The span guard: a body whose 3D shoulder width departs from the recent ones by more than
// 40 % is held; one turned sideways with its width kept goes through.
{
  const body = (sh, yaw = 0) => {
    const w = Array.from({ length: 33 }, () => ({ x: 0, y: 0, z: 0, visibility: 0.9 }));
    const c = Math.cos(yaw), s = Math.sin(yaw);
    w[11] = { x: c * sh / 2, y: -0.5, z: -s * sh / 2, visibility: 1 };
    w[12] = { x: -c * sh / 2, y: -0.5, z: s * sh / 2, visibility: 1 };
    return w;
  };
  const g = spanGuard();
  const first = Array.from({ length: 8 }, (_, i) => g(body(0.26 + 0.01 * (i % 3))));
  check(!first[0] && !first[1] && first.slice(2).every(Boolean),
    'the span guard holds the first two frames (the reference is judged), then sends a steady body');
  check(!g(body(0.06)) && !g(body(0.5)), 'it holds a frame with the shoulders misread (0.06 or 0.5 m against 0.26)');
  check(g(body(0.27, Math.PI / 2)) && g(body(0.26, Math.PI / 4)), 'a body turned sideways, its width kept, goes through');
  const hidden = body(0.06);
  hidden[12].visibility = 0.1;
  check(g(hidden), 'a frame with a shoulder not seen is not judged');
  // misread first frames do not set the width: the good ones that follow go through
  const g3 = spanGuard();
  const early = [0.05, 0.27, 0.06, 0.28, 0.26, 0.27].map((w) => g3(body(w)));
  check(early.join() === 'false,false,false,true,true,true',
    `a misread first frame is never sent; the good ones after it go, a misread one is held (${early.join(' ')})`);
  // two frames in three misread: the good ones still go
  const g4 = spanGuard();
  const mixed = Array.from({ length: 60 }, (_, i) => [i % 3 === 0, g4(body(i % 3 === 0 ? 0.27 : 0.08))]);
  check(mixed.slice(3).every(([good, sent]) => good === sent),
    'two frames in three misread: the good ones go through, the misread ones are held');
  // another performer: a wider one taken within a quarter of a second, a narrower one within a
  // second, and from then on
  const taken = (w) => {
    const g = spanGuard();
    for (let i = 0; i < 40; ++i) g(body(0.26));
    const r = Array.from({ length: 40 }, () => g(body(w)));
    const k = r.indexOf(true);
    return k >= 0 && r.slice(k).every(Boolean) ? k + 1 : Infinity;
  };
  const kw = taken(0.4), kn = taken(0.15);
  check(kw > 1 && kw <= 8 && kn > 1 && kn <= 30,
    `another performer: a wider one (0.40 m after 0.26) taken from its frame ${kw}, a narrower one (0.15) from its frame ${kn}`);
}

makeClip(process.env.KM_BIN, work);
check(fs.statSync(path.join(work, 'clip.y4m')).size > 1e6, 'clip.y4m written');

const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
  headless: true,
  args: ['--no-sandbox', '--enable-unsafe-swiftshader', '--use-angle=swiftshader',
    '--ignore-gpu-blocklist', '--disable-dev-shm-usage', '--use-fake-ui-for-media-stream',
    '--use-fake-device-for-media-stream',
    `--use-file-for-fake-video-capture=${path.join(work, 'clip.y4m')}`],
});
const errors = [], offsite = [];
try {
  const page = await browser.newPage({ viewport: { width: 1100, height: 700 } });
  page.on('pageerror', (e) => errors.push(String(e)));
  page.on('console', (m) => { if (m.type() === 'error') errors.push(m.text()); });
  // Everything the page loads comes from the live server: no CDN.
  page.on('request', (r) => { if (!r.url().startsWith(`http://127.0.0.1:${http}/`) && !r.url().startsWith('data:') && !r.url().startsWith('blob:')) offsite.push(r.url()); });
  // The lite landmark model: the test runs MediaPipe on software WebGL and WASM on a shared
  // machine (the full model, the page's default, detected the clip as well when tried).
  await page.goto(`http://127.0.0.1:${http}/?token=${TOKEN}&pose=lite`);
  await page.waitForFunction(() => window.kmLive && window.kmLive.ready && window.kmLive.connected,
    null, { timeout: 80000 });
  const s0 = await status(http);
  await page.evaluate(() => document.getElementById('cam').click());
  // MediaPipe's first inference compiles its graph in software WebGL: minutes on a loaded
  // machine, so the deadline is generous (and a deadline, not a speed check).
  await waitFor(() => page.evaluate(() => {
    const c = window.kmLive.camera;
    return c && (c.error || c.sent + c.held >= 40) ? c : null;
  }), 50000, 500);
  const c = await page.evaluate(() => window.kmLive.camera);
  console.log(`camera: ${JSON.stringify({ status: c.status, frames: c.frames, detected: c.detected, sent: c.sent, turned: c.turned, held: c.held, error: c.error })}`);
  console.log(`3D shoulder widths MediaPipe read (m): ${(c.widths || []).join(' ')}`);
  check(!c.error && c.frames > 0, `MediaPipe Pose ran on the fake camera (${c.error || c.status})`);
  check(c.detected >= 16, `a body was detected in ${c.detected} of ${c.frames} frames`);
  const s1 = await status(http);
  const got = s1.ws_messages - s0.ws_messages;
  check(got >= 16 && s1.bad_packets === s0.bad_packets,
    `the server took ${got} landmark frames over the WebSocket, ${s1.bad_packets - s0.bad_packets} bad`);
  check(s1.frames_in - s0.frames_in >= 16, `they became joint frames (${s1.frames_in - s0.frames_in})`);
  // The thumbnail shows the camera image: not the blank canvas.
  const lit = await page.evaluate(() => {
    const t = document.getElementById('cam-thumb'), d = t.getContext('2d').getImageData(0, 0, t.width, t.height).data;
    let n = 0;
    for (let i = 0; i < d.length; i += 4) if (d[i] > 60) ++n;
    return n / (d.length / 4);
  });
  check(lit > 0.5, `the thumbnail shows the camera (${(100 * lit).toFixed(0)}% lit pixels)`);
  // A picture to look at, not a check (a busy machine can time it out).
  await page.screenshot({ path: path.join(work, 'camera.png'), timeout: 60000 }).catch(() => {});
  // stop (a click through the DOM: the page is busy detecting, playwright's pointer click
  // waits for it to be idle)
  await page.evaluate(() => document.getElementById('cam').click());
  check(await page.evaluate(() => window.kmLive.camera.status === 'off'), 'the button stops the camera');
  // Bad messages on the page's WebSocket are counted, never fatal: bad JSON, an unknown
  // skeleton, a binary message, one over the 16 KB limit; then good ones still go through, one
  // of them longer than the server's 4 KB receive buffer (it arrives in pieces).
  const s2 = await status(http);
  await page.evaluate(() => {
    const ws = window.kmLive.ws;
    ws.send('{"skeleton": "mediapipe", "joints": [1, 2');
    ws.send('{"skeleton": "martian", "joints": {"left_wrist": [0, 1, 0]}}');
    ws.send(new Uint8Array([1, 2, 3, 4]));
    ws.send(JSON.stringify({ skeleton: 'mediapipe', joints: {}, pad: 'x'.repeat(20000) }));
    const good = { skeleton: 'mediapipe', joints: { left_wrist: [0.6, 1.5, 0.1], left_hip: [0.1, 0.9, 0], right_hip: [-0.1, 0.9, 0] } };
    ws.send(JSON.stringify(good));
    ws.send(JSON.stringify({ ...good, pad: 'x'.repeat(9000) }));
  });
  const s3 = await waitFor(async () => { const s = await status(http); return s.ws_messages - s2.ws_messages >= 6 ? s : null; }, 10000);
  check(s3 && s3.bad_packets - s2.bad_packets === 4 && s3.frames_in - s2.frames_in === 2,
    `bad WebSocket messages counted (${s3 && s3.bad_packets - s2.bad_packets} of 4), the good ones frames (${s3 && s3.frames_in - s2.frames_in} of 2)`);
  check(offsite.length === 0, `nothing fetched from outside the server${offsite.length ? ': ' + offsite.slice(0, 3).join(' ') : ''}`);
  check(errors.length === 0, `no page errors${errors.length ? ': ' + errors.slice(0, 3).join(' | ') : ''}`);
} finally {
  await browser.close();
}
finish('live_camera');
