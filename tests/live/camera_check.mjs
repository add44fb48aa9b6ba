// After live_camera: the server's recording (--record) of the landmark frames it received from
// the page's camera, against the clip (tests/live/clip.mjs: the character's LEFT arm rises from
// LOW to HIGH degrees and back, the right arm hangs at LOW). Checks the wrist moves as the
// clip's does, on the side it does: the left wrist sweeps up past the shoulder at kinemesh +x
// (the performer's left, the mesh's left hand), the right one stays down at -x.
//   node camera_check.mjs WORK
import fs from 'node:fs';
import path from 'node:path';
import { check, finish } from './lib.mjs';
import { LOW, HIGH, readPc2 } from './clip.mjs';

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
const med = (a) => a.slice().sort((x, y) => x - y)[Math.floor(a.length / 2)];
const down = R.filter((e) => e < 0).length / R.length, rmed = med(R);
check(R.length >= 16 && down >= 0.85 && rmed < -40,
  `the right wrist stays down: ${(100 * down).toFixed(0)}% of frames below the shoulder, median ${rmed.toFixed(0)} deg`);
// The raised hand's height follows the sweep: in the frames where the left arm is up (elevation
// over HIGH / 2, in the clip the top third of the sweep) the left wrist is by the head and well
// above the right one, judged on the median of those frames. MediaPipe now and then swaps or
// merges the arms for a frame, and a loaded machine detects few frames near the top (one
// sanitizer run had two among five frames with the highest "left" wrist; one loaded run five
// raised frames, the left wrist 0.38-0.63 m above the right). The frames are those where
// MediaPipe read the shoulders at no less than 3/4 of their median width: the figure faces the
// camera throughout, and on 10-35 % of the frames MediaPipe's world landmarks put it turned
// sideways, the shoulders 0.02-0.15 m apart against 0.25, the arms merged.
const span = (f) => Math.hypot(at(f, 'ShoulderLeft')[0] - at(f, 'ShoulderRight')[0],
  at(f, 'ShoulderLeft')[1] - at(f, 'ShoulderRight')[1]);
const smed = med(frames.map(span));
const wide = frames.filter((f) => span(f) >= 0.75 * smed);
check(wide.length >= frames.length / 2,
  `${wide.length} of ${frames.length} frames read with the shoulders at least 3/4 of their median width (${smed.toFixed(2)} m) apart`);
const raised = wide.filter((f) => elev(f, 'ShoulderLeft', 'WristLeft') > HIGH / 2);
const overR = med(raised.map((f) => at(f, 'WristLeft')[1] - at(f, 'WristRight')[1]));
const overHead = med(raised.map((f) => at(f, 'WristLeft')[1] - at(f, 'Head')[1]));
const sideOk = (f) => at(f, 'WristLeft')[0] > at(f, 'HipCenter')[0] && at(f, 'WristRight')[0] < at(f, 'HipCenter')[0];
check(raised.length >= 1 && raised.filter(sideOk).length >= raised.length / 2,
  `performer's left at kinemesh +x in ${raised.filter(sideOk).length} of the ${raised.length} frames with the left arm up`);
check(raised.length >= 1 && overR > 0.3 && overHead > -0.1,
  `with the left arm up the left wrist is by the head (median ${raised.length ? overHead.toFixed(2) : '-'} m above it, at least -0.1) and well above the right one (${raised.length ? overR.toFixed(2) : '-'} m, more than 0.3), ${raised.length} frames`);
const sided = frames.filter((f) => at(f, 'ShoulderLeft')[0] > at(f, 'ShoulderRight')[0]).length / frames.length;
check(sided >= 0.8, `the left shoulder at +x of the right one in ${(100 * sided).toFixed(0)}% of the frames`);
// The recording animated (run.sh: kinemesh animate on rec.json, the character's own rig), as a
// person would look at it: the mesh faces the camera as the figure did, its hip and shoulder
// lines (the rig's landmarks) within 60 degrees of kinemesh +x on nearly every frame, and its
// chest does not swing round between frames, the shoulder line turning at most 30 degrees from
// one frame to the next. Before the page held its first frames, a misread first frame (the
// reference every turn is measured from) turned the mesh away from the camera for a whole
// recording (160-179 degrees on 35 of 37 frames, twice); before it held frames read with the
// shoulders of the wrong width, the shoulder line stepped up to 52 and 60 degrees in two of six
// recordings (12-15 in the others). The raw recording's own shoulder line is not judged:
// MediaPipe swaps left and right now and then (a 158 degree step), which the library's heading
// filter holds.
const pc2 = path.join(work, 'rec.pc2');
if (fs.existsSync(pc2)) {
  const rig = JSON.parse(fs.readFileSync(path.join(work, 'c.rig.json'), 'utf8'));
  const lm = (n) => rig.landmarks.find((l) => l.name === n).vertex;
  // the turn about y (degrees) of the line from landmark b to landmark a, 0 along +x
  const line = (X, a, b) => {
    const dx = X[3 * lm(a)] - X[3 * lm(b)], dz = X[3 * lm(a) + 2] - X[3 * lm(b) + 2];
    return Math.atan2(-dz, dx) * 180 / Math.PI;
  };
  const mesh = readPc2(pc2);
  const turn = mesh.map((X) => Math.max(Math.abs(line(X, 'hip_left', 'hip_right')),
    Math.abs(line(X, 'shoulder_left', 'shoulder_right'))));
  const off = turn.filter((t) => t > 60).length;
  check(mesh.length >= 16 && off <= 0.1 * mesh.length,
    `the animated recording faces the camera: hips and shoulders within 60 deg of +x on ${mesh.length - off} of ${mesh.length} frames (at worst ${Math.max(...turn).toFixed(0)} deg)`);
  const yaw = mesh.map((X) => line(X, 'shoulder_left', 'shoulder_right'));
  const ysteps = yaw.slice(1).map((v, i) => Math.abs(((v - yaw[i] + 540) % 360) - 180));
  const ymax = Math.max(...ysteps);
  check(ymax <= 30, `the mesh's shoulder line turns at most ${ymax.toFixed(0)} deg between frames (at most 30)`);
} else {
  check(false, `${pc2}: the recording was not animated`);
}
finish('live_camera (recording)');
