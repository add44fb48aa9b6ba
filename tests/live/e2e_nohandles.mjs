// End-to-end from zero handles (issue 11): `kinemesh live --mesh c.obj --no-handles` keeps the
// rig's skeleton and skin but starts with no handle. The page loads and shows the rest mesh,
// input is counted but nothing is deformed; the first handle is placed by a click on the hand,
// mapped to HandLeft and saved; the saved rig keeps the skeleton and skin, and the replayed take
// then moves the hand. Keeps a screenshot.
import fs from 'node:fs';
import path from 'node:path';
import dgram from 'node:dgram';
import { check, status, waitFor, replayDone, osceletonFrame, OSCELETON_SKEL, runLivePage } from './lib.mjs';

const [http, osc, , work] = process.argv.slice(2);
const url = `http://127.0.0.1:${http}/`;
const rigPath = path.join(work, 'c.rig.json');
const rig0 = JSON.parse(fs.readFileSync(rigPath, 'utf8'));

await runLivePage(http, 'live_e2e_nohandles', path.join(work, 'live_nohandles.png'), async (page) => {
  const s0 = await status(http);
  check(Object.keys(s0.handles).length === 0, `no handles at start (${Object.keys(s0.handles).join(', ')})`);
  const hs0 = await (await fetch(`${url}handles`)).json();
  check(Array.isArray(hs0.handles) && hs0.handles.length === 0, 'GET /handles is empty');

  // Input with no handle: counted, nothing deformed, no solve error.
  const sock = dgram.createSocket('udp4');
  await new Promise((r) => sock.send(osceletonFrame(OSCELETON_SKEL), +osc, '127.0.0.1', () => r()));
  sock.close();
  const s1 = await waitFor(async () => { const x = await status(http); return x.frames_in >= 1 && x; }, 5000);
  check(s1 && s1.frames_in === 1 && s1.frames_out === 0 && s1.solve_errors === 0,
    `a frame with no handles is counted, not deformed (${s1 && s1.frames_in} in, ${s1 && s1.frames_out} out)`);

  // The left hand's tip: the vertex farthest along +x (the character faces +z, its left is +x).
  const pos = await page.evaluate(() => { const o = []; for (let i = 0; i < window.kmLive.nv; ++i) o.push(window.kmLive.vertexPosition(i)); return o; });
  let target = 0;
  pos.forEach((p, i) => { if (p[0] > pos[target][0]) target = i; });
  // Front-facing vertices near the tip, so the click lands on the hand and not behind it.
  let best = -1, bz = -Infinity;
  pos.forEach((p, i) => { if (pos[target][0] - p[0] < 0.05 && Math.abs(p[1] - pos[target][1]) < 0.05 && p[2] > bz) { bz = p[2]; best = i; } });
  const px = await page.evaluate((i) => window.kmLive.project(i), best);
  await page.mouse.move(px.x - 20, px.y);
  await page.mouse.move(px.x, px.y, { steps: 3 });
  await page.mouse.click(px.x, px.y);
  const pending = await page.evaluate(() => window.kmLive.pending && window.kmLive.pending.vertex);
  check(pending != null && pos[pending][0] > pos[target][0] - 0.08, `click placed a handle on the left hand (vertex ${pending})`);
  await page.click('#diagram circle[data-joint="HandLeft"]');
  await page.click('#h-add');
  await page.click('#save');
  await page.waitForFunction(() => window.kmLive.saved >= 1, null, { timeout: 40000 });
  const rig = JSON.parse(fs.readFileSync(rigPath, 'utf8'));
  check(rig.handles.length === 1 && rig.map.length === 1 && rig.map[0].joint === 'HandLeft',
    `saved rig: ${rig.handles.length} handle(s), mapped to ${rig.map.map((m) => m.joint || m.bone).join(', ')}`);
  check(JSON.stringify(rig.joints) === JSON.stringify(rig0.joints) && rig.skin && rig.landmarks !== undefined === (rig0.landmarks !== undefined),
    'the saved rig keeps the skeleton, skin and landmarks');
  const st = await waitFor(async () => { const x = await status(http); return Object.keys(x.handles).length === 1 && x; }, 5000);
  check(st, `/status lists the new handle (${st && Object.keys(st.handles).join(', ')})`);

  // The take now moves the hand.
  const snap = () => page.evaluate((i) => window.kmLive.vertexPosition(i), pending);
  const a = await snap();
  const s2 = await status(http);
  await page.click('#replay');
  const s3 = await replayDone(http, s2);
  await page.waitForFunction(() => window.kmLive.frames >= 2, null, { timeout: 40000 }).catch(() => {});
  const b = await snap();
  const moved = Math.hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]);
  check(s3 && s3.frames_out > s2.frames_out && s3.solve_errors === 0,
    `frames deformed once the handle is saved (${s3 && s3.frames_out - s2.frames_out})`);
  check(moved > 0.02, `the hand follows the take (moved ${moved.toFixed(3)} m: ${a.map((x) => x.toFixed(3))} -> ${b.map((x) => x.toFixed(3))})`);
});
