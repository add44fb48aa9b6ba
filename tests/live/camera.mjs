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

const here = path.dirname(fileURLToPath(import.meta.url));
const require = createRequire(path.join(here, '../../web/package.json'));
const { chromium } = require('playwright-core');
const [http, , , work] = process.argv.slice(2);

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
  await page.goto(`http://127.0.0.1:${http}/?token=${TOKEN}`);
  await page.waitForFunction(() => window.kmLive && window.kmLive.ready && window.kmLive.connected,
    null, { timeout: 80000 });
  const s0 = await status(http);
  await page.click('#cam');
  // MediaPipe's first inference compiles its graph in software WebGL: minutes on a loaded
  // machine, so the deadline is generous (and a deadline, not a speed check).
  const cam = await waitFor(() => page.evaluate(() => {
    const c = window.kmLive.camera;
    return c && (c.error || c.sent >= 30) ? c : null;
  }), 65000, 500);
  const c = await page.evaluate(() => window.kmLive.camera);
  console.log(`camera: ${JSON.stringify({ status: c.status, frames: c.frames, detected: c.detected, sent: c.sent, error: c.error })}`);
  check(cam && !cam.error, `MediaPipe Pose ran on the fake camera (${c.error || c.status})`);
  check(c.detected >= 30, `a body was detected in ${c.detected} of ${c.frames} frames`);
  const s1 = await status(http);
  const got = s1.ws_messages - s0.ws_messages;
  check(got >= 30 && s1.bad_packets === s0.bad_packets,
    `the server took ${got} landmark frames over the WebSocket, ${s1.bad_packets - s0.bad_packets} bad`);
  check(s1.frames_in - s0.frames_in >= 30, `they became joint frames (${s1.frames_in - s0.frames_in})`);
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
  await page.click('#cam'); // stop
  check(await page.evaluate(() => window.kmLive.camera.status === 'off'), 'the button stops the camera');
  check(offsite.length === 0, `nothing fetched from outside the server${offsite.length ? ': ' + offsite.slice(0, 3).join(' ') : ''}`);
  check(errors.length === 0, `no page errors${errors.length ? ': ' + errors.slice(0, 3).join(' | ') : ''}`);
} finally {
  await browser.close();
}
finish('live_camera');
