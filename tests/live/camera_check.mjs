// After live_camera: the server's recording (--record) of the landmark frames it received from
// the page's camera, against the clip (tests/live/clip.mjs: the character's LEFT arm rises from
// LOW to HIGH degrees and back, the right arm hangs at LOW). Checks the wrist moves as the
// clip's does, on the side it does: the left wrist sweeps up past the shoulder at kinemesh +x
// (the performer's left, the mesh's left hand), the right one stays down at -x.
//   node camera_check.mjs WORK
import fs from 'node:fs';
import path from 'node:path';
import { check, finish } from './lib.mjs';
import { LOW, HIGH } from './clip.mjs';

const work = process.argv[2];
const rec = JSON.parse(fs.readFileSync(path.join(work, 'rec.json'), 'utf8'));
const J = (n) => rec.joints.indexOf(n);
const at = (f, n) => f.slice(3 * J(n), 3 * J(n) + 3);
const ok = (p) => p.every(Number.isFinite);
// Elevation (degrees above horizontal) of shoulder -> wrist in the frontal plane.
const elev = (f, s, w) => {
  const a = at(f, s), b = at(f, w);
  return ok(a) && ok(b) ? Math.atan2(b[1] - a[1], Math.abs(b[0] - a[0])) * 180 / Math.PI : NaN;
};
// The camera's frames (camera.mjs also sends one hand-made frame with a wrist and the hips only).
const frames = rec.frames.filter((f) => ['HipCenter', 'Head', 'ShoulderLeft', 'ShoulderRight',
  'WristLeft', 'WristRight'].every((n) => ok(at(f, n))));
check(frames.length >= 16, `${frames.length} recorded frames with the pelvis, head, shoulders and wrists (${rec.frames.length} in all)`);
const L = frames.map((f) => elev(f, 'ShoulderLeft', 'WristLeft')).filter(Number.isFinite);
const R = frames.map((f) => elev(f, 'ShoulderRight', 'WristRight')).filter(Number.isFinite);
const lo = Math.min(...L), hi = Math.max(...L), rlo = Math.min(...R), rhi = Math.max(...R);
console.log(`left arm elevation ${lo.toFixed(0)}..${hi.toFixed(0)} deg, right ${rlo.toFixed(0)}..${rhi.toFixed(0)} deg (clip: left ${LOW}..${HIGH}, right ${LOW})`);
check(L.length >= 16 && lo < LOW / 2 && hi > HIGH / 2,
  `the left wrist sweeps from below to above the shoulder as in the clip (${lo.toFixed(0)}..${hi.toFixed(0)} deg)`);
check(hi - lo > 0.6 * (HIGH - LOW), `the sweep is most of the clip's (${(hi - lo).toFixed(0)} of ${HIGH - LOW} deg)`);
// MediaPipe (the lite model especially) now and then swaps the arms for a frame: the right arm
// is judged on most frames, not all.
const Rs = R.slice().sort((a, b) => a - b), down = R.filter((e) => e < 0).length / R.length;
const rmed = Rs[Math.floor(Rs.length / 2)];
check(R.length >= 16 && down >= 0.85 && rmed < -40,
  `the right wrist stays down: ${(100 * down).toFixed(0)}% of frames below the shoulder, median ${rmed.toFixed(0)} deg`);
// The raised hand's height follows the sweep: at the top of it (the five frames with the
// highest left wrist) the left wrist is up by the head, on the performer's left (kinemesh +x),
// the right one down on the right. Judged on most of the five: MediaPipe now and then swaps or
// merges the arms for a frame, and such a frame can be the one with the highest "left" wrist
// (a sanitizer run once picked one with both wrists at +x).
const tops = frames.slice().sort((a, b) => at(b, 'WristLeft')[1] - at(a, 'WristLeft')[1]).slice(0, 5);
const sideOk = (f) => at(f, 'WristLeft')[0] > at(f, 'HipCenter')[0] && at(f, 'WristRight')[0] < at(f, 'HipCenter')[0];
const upOk = (f) => at(f, 'WristLeft')[1] > at(f, 'Head')[1] - 0.1 && at(f, 'WristLeft')[1] > at(f, 'WristRight')[1] + 0.5;
const top = tops[0];
const hip = at(top, 'HipCenter');
check(tops.length === 5 && tops.filter(sideOk).length >= 3,
  `performer's left at kinemesh +x in ${tops.filter(sideOk).length} of the 5 top frames (highest: left wrist x ${(at(top, 'WristLeft')[0] - hip[0]).toFixed(2)}, right ${(at(top, 'WristRight')[0] - hip[0]).toFixed(2)} m from the pelvis)`);
const sided = frames.filter((f) => at(f, 'ShoulderLeft')[0] > at(f, 'ShoulderRight')[0]).length / frames.length;
check(sided >= 0.8, `the left shoulder at +x of the right one in ${(100 * sided).toFixed(0)}% of the frames`);
check(tops.length === 5 && tops.filter(upOk).length >= 3,
  `at the top of the sweep the left wrist is up by the head, well above the right one (${tops.filter(upOk).length} of the 5 top frames)`);
finish('live_camera (recording)');
