// Helpers shared by the live-mode test scripts.
export const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
let failures = 0, passes = 0;
export function check(cond, what) {
  if (cond) { passes++; console.log('ok   ' + what); } else { failures++; console.log('FAIL ' + what); }
}
export function finish(name) {
  console.log(`${name}: ${passes} passed, ${failures} failed`);
  process.exit(failures ? 1 : 0);
}
// The server's per-run secret (tests/live/run.sh reads it from the printed URL).
export const TOKEN = process.env.KM_LIVE_TOKEN || '';
export async function status(http) {
  return (await fetch(`http://127.0.0.1:${http}/status`)).json();
}
// Waits are deadlines for something to happen, not speed checks: they are stretched
// generously (x4) so a loaded CI machine or the sanitizer build does not fail them.
export const SLACK = 4;
export async function waitFor(fn, ms, step = 50) {
  ms *= SLACK;
  const t0 = Date.now();
  for (;;) {
    const v = await fn();
    if (v) return v;
    if (Date.now() - t0 > ms) return v;
    await sleep(step);
  }
}
// Waits for a replay started after status `s0` to finish: input has stopped and every frame
// that came in is accounted for (deformed, superseded by a newer one, or a solve error). The
// counts depend on how busy the machine is (latest wins), so callers check the accounting,
// not a frame rate. Returns the final status, or null when the replay never settled.
export async function replayDone(http, s0, ms = 8000) {
  return waitFor(async () => {
    const a = await status(http);
    await sleep(300);
    const b = await status(http);
    // The server says when the take's last frame is pushed; counters that stand still for
    // 300 ms are not enough on a busy machine (the replay thread can be starved that long).
    const settled = b.frames_in > s0.frames_in && !a.replaying && !b.replaying &&
      b.frames_in === a.frames_in && b.frames_out === a.frames_out;
    return settled && accounted(s0, b) ? b : null;
  }, ms);
}
export function accounted(s0, s1) {
  return (s1.frames_out - s0.frames_out) + (s1.frames_dropped - s0.frames_dropped) +
    (s1.solve_errors - s0.solve_errors) >= s1.frames_in - s0.frames_in;
}
// An OpenNI-style skeleton as OSCeleton sends it: centimetres, y pointing down, ~2 m from the
// sensor. Like the real bridges it has no wrists, ankles or waist.
export const OSCELETON_SKEL = {
  head: [0, -75, 200], neck: [0, -55, 200], torso: [0, -25, 200],
  l_shoulder: [-18, -52, 200], l_elbow: [-45, -52, 200], l_hand: [-70, -52, 200],
  r_shoulder: [18, -52, 200], r_elbow: [45, -52, 200], r_hand: [70, -52, 200],
  l_hip: [-10, 5, 200], l_knee: [-11, 45, 200], l_foot: [-12, 85, 200],
  r_hip: [10, 5, 200], r_knee: [11, 45, 200], r_foot: [12, 85, 200],
};
// OSC encoding (big-endian, strings NUL-terminated and padded to 4 bytes).
export const oscString = (s) => { const b = Buffer.from(s + '\0'); return Buffer.concat([b, Buffer.alloc((4 - b.length % 4) % 4)]); };
export const oscFloat = (x) => { const b = Buffer.alloc(4); b.writeFloatBE(x); return b; };
export const oscInt = (x) => { const b = Buffer.alloc(4); b.writeInt32BE(x); return b; };
export const oscMessage = (addr, types, ...args) => Buffer.concat([oscString(addr), oscString(',' + types), ...args]);
// One datagram holding many messages, so a frame cannot be split by a scheduling delay.
export const oscBundle = (msgs) => Buffer.concat([oscString('#bundle'), Buffer.alloc(8),
  ...msgs.flatMap((m) => [oscInt(m.length), m])]);
// An OSCeleton frame (/joint siiffff per joint) as one bundle.
export const osceletonFrame = (skel, user = 1) => oscBundle(Object.entries(skel).map(([name, p]) =>
  oscMessage('/joint', 'siiffff', oscString(name), oscInt(0), oscInt(user), ...p.map(oscFloat), oscFloat(1))));

// Headless Debian chromium (driven by playwright-core, no browser download) with the live
// page open at ?token= and loaded (mesh, rig, WebSocket). Page errors and console errors are
// collected in `errors`. Returns { browser, page, errors }; the caller closes the browser.
export async function openLivePage(http, { viewport = { width: 1100, height: 700 }, args = [] } = {}) {
  const { createRequire } = await import('node:module');
  const require = createRequire(new URL('../../web/package.json', import.meta.url));
  const { chromium } = require('playwright-core');
  const browser = await chromium.launch({
    executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
    headless: true,
    args: ['--no-sandbox', '--enable-unsafe-swiftshader', '--use-angle=swiftshader',
      '--ignore-gpu-blocklist', '--disable-dev-shm-usage', ...args],
  });
  const errors = [];
  try {
    const page = await browser.newPage({ viewport });
    page.on('pageerror', (e) => errors.push(String(e)));
    page.on('console', (m) => { if (m.type() === 'error') errors.push(m.text()); });
    await page.goto(`http://127.0.0.1:${http}/?token=${TOKEN}`);
    await page.waitForFunction(() => window.kmLive && window.kmLive.ready && window.kmLive.connected,
      null, { timeout: 80000 });
    return { browser, page, errors };
  } catch (e) {
    await browser.close();
    throw e;
  }
}

// A live-page test: opens the page (openLivePage), runs body(page), keeps a screenshot, checks
// the page logged no error, closes the browser whatever happened and prints the summary.
export async function runLivePage(http, name, screenshot, body, opts) {
  let browser = null, errors = [];
  try {
    const o = await openLivePage(http, opts);
    browser = o.browser;
    errors = o.errors;
    await body(o.page);
    if (screenshot) await o.page.screenshot({ path: screenshot });
    check(errors.length === 0, `no page errors ${errors.join(' | ')}`);
  } catch (e) {
    check(false, 'exception: ' + (e && e.stack || e));
  } finally {
    if (browser) await browser.close();
  }
  finish(name);
}
