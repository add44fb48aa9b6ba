// End-to-end: headless Debian chromium (driven by playwright-core, no browser download) opens
// the live page, draws the partial skeleton of an OSCeleton frame, plays the take with the
// replay button, checks frames arrive, the mesh moves and its decoded positions fill the
// frame's box (float32, or int16 with --quantize), adds a handle through the mapping panel (click on a projected vertex, pick the joint
// on the diagram, add, save) and checks the rig file on disk; a torso handle with the default
// 8 cm ball, which overlaps the default rig's chest and pelvis bands, takes the vertices left
// and saves. Keeps a screenshot.
import dgram from 'node:dgram';
import fs from 'node:fs';
import path from 'node:path';
import { check, status, waitFor, sleep, replayDone, OSCELETON_SKEL,
  osceletonFrame, runLivePage } from './lib.mjs';

const [http, osc, , work] = process.argv.slice(2);
const url = `http://127.0.0.1:${http}/`;
const rigPath = path.join(work, 'c.rig.json');
const rigBefore = JSON.parse(fs.readFileSync(rigPath, 'utf8'));

await runLivePage(http, 'live_e2e', path.join(work, 'live_page.png'), async (page) => {
  check(true, 'page loaded the mesh and the rig and opened the WebSocket');
  const s0 = await status(http);
  check(s0.clients >= 1, `/status counts the page as a client (${s0.clients})`);
  check(s0.frames_in === 0, 'no frames before replay (--no-autoplay)');

  // An OSCeleton frame has no wrists or ankles (the mid-hip stands in for HipCenter): the
  // overlay draws the 16 joints it has and the 11 bones between them, with no NaN in its
  // buffers. One bundle, so it is one frame.
  const sock = dgram.createSocket('udp4');
  await new Promise((r) => sock.send(osceletonFrame(OSCELETON_SKEL), +osc, '127.0.0.1', () => r()));
  sock.close();
  await page.waitForFunction(() => window.kmLive.inSeq >= 1, null, { timeout: 40000 }).catch(() => {});
  const ov = await page.evaluate(() => window.kmLive.overlay);
  check(ov && ov.joints === 16 && ov.bones === 11 && ov.finite,
    `partial skeleton: ${ov ? `${ov.joints} joints, ${ov.bones} bones drawn${ov.finite ? '' : ', NaN in the buffers'}` : 'no frame'} (want 16, 11)`);
  check(await page.evaluate(() => window.kmLive.frames >= 1 && document.getElementById('show-skel').checked),
    'overlay shown for a partial skeleton');
  const s0b = await replayDone(http, s0);
  check(s0b && s0b.frames_in === 1, `the OSC bundle was one frame (frames_in ${s0b && s0b.frames_in})`);

  // Replay button -> frames arrive and vertices move. Frame counts depend on how busy the
  // machine is (latest wins), so the checks are on motion and accounting, not on a rate.
  await page.click('#replay');
  await page.waitForFunction(() => window.kmLive.frames >= 3, null, { timeout: 40000 });
  const snap = () => page.evaluate(() => {
    const out = [];
    for (let i = 0; i < window.kmLive.nv; i += 7) out.push(...window.kmLive.vertexPosition(i));
    return out;
  });
  const a = await snap();
  const fa = await page.evaluate(() => window.kmLive.frames);
  await sleep(700);
  // Wait for the take (2 s) to end so the mesh holds still for picking.
  const s1 = await replayDone(http, s0b || s0);
  const b = await snap();
  let moved = 0;
  for (let i = 0; i < a.length; ++i) moved = Math.max(moved, Math.abs(a[i] - b[i]));
  const frames = await page.evaluate(() => window.kmLive.frames);
  check(a.length > 0 && moved > 0.01, `vertex positions change between frames ${fa} and ${frames} (max ${moved.toFixed(3)} m)`);
  check(s1 && s1.solve_errors === 0 && s1.frames_out >= 3 && s1.frames_sent >= 3 && s1.times_ms.latency_median != null,
    s1 ? `/status: ${s1.frames_in} in, ${s1.frames_out} out, ${s1.frames_dropped} superseded, ${s1.frames_sent} sent, latency ${s1.times_ms.latency_median} ms`
      : '/status: the replay did not settle');
  await page.waitForFunction((n) => window.kmLive.inSeq === n, s1 ? s1.frames_in : -1, { timeout: 20000 }).catch(() => {});
  const inSeq = await page.evaluate(() => window.kmLive.inSeq);
  check(s1 && inSeq === s1.frames_in, `page shows the take's last frame (input ${inSeq} of ${s1 && s1.frames_in})`);
  const ov2 = await page.evaluate(() => window.kmLive.overlay);
  check(ov2 && ov2.joints === 20 && ov2.bones === 19 && ov2.finite, `full skeleton: ${ov2 && ov2.joints} joints, ${ov2 && ov2.bones} bones drawn`);
  // The decoded positions span the frame's box: its extremes are vertices, exact in float32
  // and within one int16 step (half-extent / 32767) when quantised. A wrong decode (uint16
  // offsets from the minimum, say) lands outside it.
  const fit = await page.evaluate(() => {
    const { lo, hi } = window.kmLive.box, nv = window.kmLive.nv, out = [];
    for (let a = 0; a < 3; ++a) {
      let mn = Infinity, mx = -Infinity;
      for (let i = 0; i < nv; ++i) { const x = window.kmLive.vertexPosition(i)[a]; mn = Math.min(mn, x); mx = Math.max(mx, x); }
      out.push({ lo: lo[a], hi: hi[a], mn, mx });
    }
    return out;
  });
  const fitOk = fit.every((f) => {
    const tol = (f.hi - f.lo) / 2 / 32767 + 1e-6;
    return Math.abs(f.mn - f.lo) <= tol && Math.abs(f.mx - f.hi) <= tol;
  });
  check(fitOk, `decoded positions span the frame's box: ${fit.map((f) => `[${f.mn.toFixed(5)}, ${f.mx.toFixed(5)}] vs [${f.lo.toFixed(5)}, ${f.hi.toFixed(5)}]`).join(' ')}`);

  // Pick a vertex on the chest facing the camera: the front-most vertex near the mid-line at
  // 70% of the height (current positions, read from the page).
  const pos = await page.evaluate(() => { const o = []; for (let i = 0; i < window.kmLive.nv; ++i) o.push(window.kmLive.vertexPosition(i)); return o; });
  let ymin = Infinity, ymax = -Infinity;
  for (const p of pos) { ymin = Math.min(ymin, p[1]); ymax = Math.max(ymax, p[1]); }
  const yt = ymin + 0.7 * (ymax - ymin);
  let target = -1, bz = -Infinity;
  pos.forEach((p, i) => { if (Math.abs(p[0]) < 0.04 && Math.abs(p[1] - yt) < 0.04 && p[2] > bz) { bz = p[2]; target = i; } });
  check(target >= 0, `chest vertex ${target}`);
  const px = await page.evaluate((i) => window.kmLive.project(i), target);
  await page.mouse.click(px.x, px.y);
  const pending = await page.evaluate(() => window.kmLive.pending && window.kmLive.pending.vertex);
  const dist = pending == null ? Infinity : Math.hypot(...[0, 1, 2].map((k) => pos[pending][k] - pos[target][k]));
  check(pending != null && dist < 0.05, `click on the canvas picked vertex ${pending} (${dist.toFixed(3)} m from ${target})`);
  await page.fill('#h-radius', '0.06');
  await page.dispatchEvent('#h-radius', 'input');
  await page.click('#diagram circle[data-joint="ElbowLeft"]');
  check(await page.inputValue('#h-joint') === 'ElbowLeft', 'diagram click selects ElbowLeft');
  await page.uncheck('#ax-z');
  await page.fill('#h-scale', '0.5');
  await page.click('#h-add');
  await page.click('#save');
  await page.waitForFunction(() => window.kmLive.saved >= 1, null, { timeout: 40000 });
  const rigAfter = JSON.parse(fs.readFileSync(rigPath, 'utf8'));
  check(rigAfter.handles.length === rigBefore.handles.length + 1, `rig on disk has ${rigAfter.handles.length} handles (was ${rigBefore.handles.length})`);
  const h = rigAfter.handles.find((x) => x.vertex === pending);
  const m = h && rigAfter.map.find((x) => x.handle === h.name);
  check(h && Math.abs(h.radius - 0.06) < 1e-9, 'new handle: picked vertex and radius');
  check(m && m.joint === 'ElbowLeft' && m.axes === 'xy' && m.scale === 0.5, 'new map entry: ElbowLeft, axes xy, scale 0.5');
  check(rigAfter.joints && rigAfter.skin, 'other rig keys (joints, skin) preserved');
  const hs = await (await fetch(`${url}handles`)).json();
  const hh = h && hs.handles.find((x) => x.name === h.name);
  check(hh && hh.vertices.includes(pending), `server resolved the new handle (${hh ? hh.vertices.length : 0} vertices)`);
  const st = await waitFor(async () => { const x = await status(http); return h && x.handles[h.name] !== undefined && x; }, 3000);
  check(st, '/status reports the new handle (the deformation switched to the new rig)');

  // Remove a handle in the panel and save again.
  const nBefore = rigAfter.handles.length;
  await page.click('#handles li:has-text("foot_left") button.remove');
  await page.click('#save');
  await page.waitForFunction(() => window.kmLive.saved >= 2, null, { timeout: 40000 });
  const rig2 = JSON.parse(fs.readFileSync(rigPath, 'utf8'));
  check(rig2.handles.length === nBefore - 1 && !rig2.handles.some((x) => x.name === 'foot_left') &&
    !rig2.map.some((x) => x.handle === 'foot_left'), 'removed foot_left: handle and map entry gone from the rig on disk');

  // A handle on the torso with the default 8 cm ball: the default rig's chest and pelvis bands
  // lie inside it, and a vertex may belong to one handle only. The page gives the new handle
  // the vertices no other handle has (saved as an explicit list) and the save succeeds; a ball
  // with nothing left says so and cannot be added. The vertices are picked on the rest mesh
  // (front-most: facing the camera) and clicked where they are now.
  const hsNow = (await (await fetch(`${url}handles`)).json()).handles;
  const chest = hsNow.find((x) => x.name === 'chest'), pelvis = hsNow.find((x) => x.name === 'pelvis');
  check(chest && pelvis, `the default rig has chest and pelvis band handles (${hsNow.map((x) => x.name).join(', ')})`);
  const cur = await page.evaluate(() => Array.from(window.kmLive.rest));
  const taken = new Set(hsNow.flatMap((x) => x.vertices));
  const front = (cands) => cands.reduce((b, i) => (b < 0 || cur[3 * i + 2] > cur[3 * b + 2] ? i : b), -1);
  const clickVertex = async (i) => {
    const q = await page.evaluate((k) => window.kmLive.project(k), i);
    await page.mouse.click(q.x, q.y);
    return page.evaluate(() => window.kmLive.pending);
  };
  const mean = (h, a) => h.vertices.reduce((t, i) => t + cur[3 * i + a], 0) / h.vertices.length;
  const xc = mean(pelvis, 0);
  // (1) radius 0 on a pelvis-band vertex facing the camera: nothing left
  const frontBand = pelvis.vertices.filter((i) => Math.abs(cur[3 * i] - xc) < 0.05);
  const bandV = front(frontBand);
  await page.fill('#h-radius', '0');
  await page.dispatchEvent('#h-radius', 'input');
  const p0 = await clickVertex(bandV);
  const msg0 = await page.textContent('#save-status');
  check(p0 && p0.preview.length === 0 && await page.isDisabled('#h-add') && /every vertex .*belongs to pelvis/.test(msg0),
    `a ball inside the pelvis band cannot be added, and says why (vertex ${p0 && p0.vertex}: "${msg0}")`);
  // (2) the default 8 cm ball on the belly, just above the pelvis band's front
  const yb = Math.max(...frontBand.map((i) => cur[3 * i + 1])) + 0.03;
  const belly = front([...Array(cur.length / 3).keys()].filter((i) => !taken.has(i) &&
    Math.abs(cur[3 * i] - xc) < 0.03 && Math.abs(cur[3 * i + 1] - yb) < 0.02));
  await page.fill('#h-radius', '0.08');
  await page.dispatchEvent('#h-radius', 'input');
  const p1 = await clickVertex(belly);
  const msg1 = await page.textContent('#save-status');
  check(p1 && p1.owners.includes('pelvis') && p1.preview.length > 0 && p1.preview.every((i) => !taken.has(i)) && /pelvis/.test(msg1),
    `torso click (vertex ${p1 && p1.vertex}): the 8 cm ball overlaps ${p1 && p1.owners.join(', ')} (${p1 && p1.taken} vertices), the handle takes the ${p1 && p1.preview.length} free ones ("${msg1}")`);
  await page.click('#diagram circle[data-joint="Spine"]');
  await page.click('#h-add');
  await page.click('#save');
  await page.waitForFunction(() => window.kmLive.saved >= 3 || /error/.test(document.getElementById('save-status').textContent), null, { timeout: 40000 });
  const msg2 = await page.textContent('#save-status');
  check(/^saved/.test(msg2), `the torso handle saves (${msg2})`);
  const rig3 = JSON.parse(fs.readFileSync(rigPath, 'utf8'));
  const ht = p1 && rig3.handles.find((x) => x.seed === p1.vertex);
  check(ht && Array.isArray(ht.vertices) && ht.vertices.length === p1.preview.length && rig3.map.some((x) => x.handle === ht.name && x.joint === 'Spine'),
    `rig on disk: the torso handle as ${ht ? ht.vertices.length : 0} explicit vertices, mapped to Spine`);
  const hs3 = (await (await fetch(`${url}handles`)).json()).handles;
  const ht3 = ht && hs3.find((x) => x.name === ht.name);
  const others = new Set(hs3.filter((x) => x !== ht3).flatMap((x) => x.vertices));
  check(ht3 && ht3.vertices.length === ht.vertices.length && ht3.vertices.every((i) => !others.has(i)) &&
    hs3.find((x) => x.name === 'chest').vertices.length === chest.vertices.length,
    'the server resolved it with no vertex of another handle; chest keeps its own');

  // The deformation keeps running with the new rig: the whole replay is deformed (or
  // superseded by newer input) with no solve error, and the page gets its last frame.
  const s2 = await status(http);
  await page.click('#replay');
  const s3 = await replayDone(http, s2);
  check(s3 && s3.frames_out > s2.frames_out && s3.solve_errors === s2.solve_errors,
    s3 ? `replay after the rig change: ${s3.frames_in - s2.frames_in} in, ${s3.frames_out - s2.frames_out} out, no solve errors`
      : 'replay after the rig change did not settle');
  await page.waitForFunction((n) => window.kmLive.inSeq === n, s3 ? s3.frames_in : -1, { timeout: 20000 }).catch(() => {});
  check(s3 && (await page.evaluate(() => window.kmLive.inSeq)) === s3.frames_in, 'page shows the last frame after the rig change');
  await sleep(600);
});
