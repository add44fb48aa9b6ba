// End-to-end without a rig: `kinemesh live --mesh c.obj` with no c.rig.json rigs the mesh itself
// (km_autorig, printed) and writes nothing; the page paints the mesh's own vertex colours; the page's hover readout shows the id and position
// of the vertex under the cursor; the first handle placed by a click is saved, which creates
// c.rig.json. Keeps a screenshot.
import fs from 'node:fs';
import path from 'node:path';
import { check, status, runLivePage, waitFor, TOKEN } from './lib.mjs';

const [http, , , work] = process.argv.slice(2);
const rigPath = path.join(work, 'c.rig.json');
const out = fs.readFileSync(path.join(work, 'server.out'), 'utf8');
check(/no rig at .*rigged .* as a humanoid/.test(out), `server rigged the mesh itself: ${out.split('\n')[0]}`);
check(!fs.existsSync(rigPath), 'no rig file written before the page saves');

await runLivePage(http, 'live_e2e_norig', path.join(work, 'live_norig.png'), async (page) => {
  const s0 = await status(http);
  const auto = Object.keys(s0.handles);
  check(['head', 'hand_left', 'hand_right', 'foot_left', 'foot_right'].every((h) => auto.includes(h)),
    `automatic rig: ${auto.join(', ')}`);

  // A belly vertex facing the camera (front-most near the mid-line at 67% of the height:
  // between the automatic rig's pelvis and chest bands, which a new handle may not overlap).
  const pos = await page.evaluate(() => { const o = []; for (let i = 0; i < window.kmLive.nv; ++i) o.push(window.kmLive.vertexPosition(i)); return o; });
  let ymin = Infinity, ymax = -Infinity;
  for (const p of pos) { ymin = Math.min(ymin, p[1]); ymax = Math.max(ymax, p[1]); }
  const yt = ymin + 0.67 * (ymax - ymin);
  let target = -1, bz = -Infinity;
  pos.forEach((p, i) => { if (Math.abs(p[0]) < 0.04 && Math.abs(p[1] - yt) < 0.02 && p[2] > bz) { bz = p[2]; target = i; } });
  check(target >= 0, `belly vertex ${target}`);
  // the mesh's own colour (0.9 0.4 0.1 in the file, sRGB) where no handle is, linear in the page
  const lin = (x) => (x <= 0.04045 ? x / 12.92 : ((x + 0.055) / 1.055) ** 2.4);
  const want = [0.9, 0.4, 0.1].map((x) => lin(Math.round(x * 255) / 255));
  const got = await page.evaluate((i) => window.kmLive.vertexColor(i), target);
  check(got.every((x, k) => Math.abs(x - want[k]) < 1e-5),
    `the page paints the mesh's own colour: ${got.map((x) => x.toFixed(4))} (want ${want.map((x) => x.toFixed(4))})`);
  const px = await page.evaluate((i) => window.kmLive.project(i), target);

  // Hover: the readout names the vertex under the cursor and its position.
  check((await page.textContent('#hover')).trim() === '–', 'hover readout empty before the cursor is on the mesh');
  await page.mouse.move(px.x - 30, px.y);
  await page.mouse.move(px.x, px.y, { steps: 3 });
  await page.waitForFunction(() => /^\d+ \(/.test(document.getElementById('hover').textContent), null, { timeout: 20000 });
  const hoverText = (await page.textContent('#hover')).trim();
  const hv = await page.evaluate(() => window.kmLive.hover);
  const hd = Math.hypot(...[0, 1, 2].map((k) => pos[hv][k] - pos[target][k]));
  check(hd < 0.05 && hoverText.startsWith(`${hv} (`) && hoverText.includes(pos[hv][1].toFixed(3)),
    `hover shows "${hoverText}" (${hd.toFixed(3)} m from ${target})`);

  // The first handle placed by hand: click, joint, add, save -> c.rig.json appears with it
  // (a 3 cm ball: the default 8 cm would reach into the pelvis and chest bands).
  await page.$eval('#h-radius', (e) => { e.value = '0.03'; e.dispatchEvent(new Event('input')); });
  await page.mouse.click(px.x, px.y);
  const pending = await page.evaluate(() => window.kmLive.pending && window.kmLive.pending.vertex);
  check(pending === hv, `click placed the handle at the hovered vertex ${pending}`);
  await page.click('#diagram circle[data-joint="ShoulderCenter"]');
  await page.click('#h-add');
  await page.click('#save');
  await page.waitForFunction(() => window.kmLive.saved >= 1, null, { timeout: 40000 });
  const rig = fs.existsSync(rigPath) ? JSON.parse(fs.readFileSync(rigPath, 'utf8')) : null;
  const h = rig && rig.handles.find((x) => x.vertex === pending);
  const m = h && rig.map.find((x) => x.handle === h.name);
  check(rig && rig.handles.length === auto.length + 1 && m && m.joint === 'ShoulderCenter',
    `saved ${rigPath}: ${rig ? rig.handles.length : 0} handles, the new one on ${m && m.joint}`);
  check(rig && rig.joints && rig.skin, 'the saved rig keeps the automatic skeleton and skin');

  // "Lying or curled up": a click on the head's tip (the top vertex), then "rig lying" rigs
  // the mesh anew as `kinemesh rig --skeleton resting --head V` does and replaces the whole rig
  // (skeleton, skin, two handles: the head turning with the neck, the body held), written to
  // c.rig.json and applied by the server.
  // the head's tip as the camera sees it: the front-most vertex of the top 6 cm, near the
  // mid-line (the crown itself faces up, away from the camera)
  let top = -1, tz = -Infinity;
  pos.forEach((p, i) => { if (p[1] > ymax - 0.06 && Math.abs(p[0]) < 0.03 && p[2] > tz) { tz = p[2]; top = i; } });
  check(await page.isDisabled('#rig-resting'), '"rig lying" waits for a clicked vertex');
  // a head that is no vertex, or another skeleton, is refused, naming what is expected
  const post = async (b) => {
    const r = await fetch(`http://127.0.0.1:${http}/rig${TOKEN ? `?token=${encodeURIComponent(TOKEN)}` : ''}`,
      { method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify(b) });
    return [r.status, (await r.json()).error || ''];
  };
  const bad = [await post({ autorig: { skeleton: 'resting', head: 1e9 } }),
    await post({ autorig: { skeleton: 'bust', head: 0 } })];
  check(bad[0][0] === 400 && /head must be a vertex id \(0\.\.\d+\), got 1000000000/.test(bad[0][1]) &&
    bad[1][0] === 400 && bad[1][1].includes('"skeleton": "resting"'), `bad autorig refused: ${bad.map((b) => b.join(' ')).join(' | ')}`);
  const tp = await page.evaluate((i) => window.kmLive.project(i), top);
  await page.mouse.click(tp.x, tp.y);
  const tip = await page.evaluate(() => window.kmLive.pending && window.kmLive.pending.vertex);
  const td = tip == null ? Infinity : Math.hypot(...[0, 1, 2].map((k) => pos[tip][k] - pos[top][k]));
  check(td < 0.03 && !(await page.isDisabled('#rig-resting')), `clicked the head's tip: vertex ${tip}, ${td.toFixed(3)} m from ${top}`);
  await page.click('#rig-resting');
  await page.waitForFunction(() => window.kmLive.rested >= 1, null, { timeout: 40000 });
  const rr = fs.existsSync(rigPath) ? JSON.parse(fs.readFileSync(rigPath, 'utf8')) : null;
  const names = rr ? rr.handles.map((x) => x.name).sort().join(',') : '';
  check(rr && names === 'base,head' && rr.local_turn === true && rr.map.length === 1 &&
    rr.map[0].bone && rr.map[0].bone.join() === 'ShoulderCenter,Head' && rr.joints && rr.skin,
    `rigged lying from vertex ${tip}: handles ${names}, local_turn ${rr && rr.local_turn}`);
  const ok = await waitFor(async () => {
    const s = await status(http);
    return Object.keys(s.handles).sort().join(',') === 'base,head';
  }, 10000);
  check(ok, 'the server drives the lying rig (status: handles base, head)');
  check((await page.textContent('#rest-status')).includes(`vertex ${tip}`),
    `page says: ${await page.textContent('#rest-status')}`);
});
