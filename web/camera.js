// The Camera button: MediaPipe Pose (npm @mediapipe/pose, served by kinemesh from mediapipe/,
// no CDN) runs on the webcam in this page; its 33 world landmarks go to the server over the
// page's WebSocket as {"skeleton": "mediapipe", "joints": [99 numbers or nulls]} (the JSON of
// the UDP input, apps/live/live_input.c), converted to kinemesh space here.
//
// MediaPipe world landmarks: metres, origin between the hips, camera axes (x to the image's
// right, y down, z away from the camera; right-handed), left/right the performer's own sides
// on the unmirrored image. The performer faces the camera, so in kinemesh space (y up, the
// performer facing +z, the performer's left at +x):
//     kinemesh (x, y, z) = (x_mp, -y_mp, -z_mp)      (a half turn about x: no mirroring)
// The performer's left hand is on the image's right (+x_mp) and lands at kinemesh +x, the
// side of the mesh's left hand. A landmark below the visibility threshold is sent as null: a
// lost joint, held by the filter as for any tracker.
//
// MediaPipe at times reads a performer facing the camera as one seen from behind (on the
// test's rendered figure, mostly in symmetric poses: 14 of 31 frames in one run): left and
// right swapped and the depth reversed, the nose behind the shoulders and the left shoulder on
// the image's left. With facing (the page's "faces the camera", on by default) such a frame is
// turned back: left and right landmarks exchanged and z negated about the hips ("turned": true
// in the message). Off, a performer may turn round. A frame whose body MediaPipe lifted with
// shoulders of the wrong width is held, not sent (spanGuard below).

const MP_DIR = 'mediapipe/';
const VISIBLE = 0.5;
const HIP_HEIGHT = 0.9; // metres: where the pelvis is put (the retarget uses displacements)
// Lines of the thumbnail's skeleton (BlazePose landmark indices).
const LINES = [[11, 12], [11, 13], [13, 15], [12, 14], [14, 16], [11, 23], [12, 24], [23, 24],
  [23, 25], [25, 27], [24, 26], [26, 28], [27, 31], [28, 32], [15, 19], [16, 20], [0, 11],
  [0, 12]];

// The other side's landmark of each BlazePose landmark (0, the nose, has none).
const PAIR = [0, 4, 5, 6, 1, 2, 3, 8, 7, 10, 9, 12, 11, 14, 13, 16, 15, 18, 17, 20, 19, 22, 21, 24,
  23, 26, 25, 28, 27, 30, 29, 32, 31];

function loadScript(src) {
  return new Promise((resolve, reject) => {
    const s = document.createElement('script');
    s.src = src;
    s.onload = resolve;
    s.onerror = () => reject(new Error(`${src} not found: MediaPipe is not installed ` +
      '(run scripts/deps.sh and build again)'));
    document.head.append(s);
  });
}

// MediaPipe's world landmarks now and then lift a body facing the camera into one turned sideways:
// on the test's rendered figure 10-35 % of the frames, the shoulders 0.03-0.16 m apart in 3D
// against 0.25-0.32, an arm across the chest. A body's shoulder width does not change, in 3D, as
// it turns; sent, such a frame twisted the mesh's chest 55 degrees for a frame and back (the
// library's glitch test allows a bone 4 cm on top of 40 %, which the 13 cm half-width from the
// neck mostly stays inside). The guard holds a frame whose 3D shoulder width departs by more than
// 40 % from the upper quartile of the widths of the last 31 frames (this one, and the held ones,
// included): it is not sent, so the server keeps the last good pose. The first two frames are held
// too, unjudged: the first frame the server takes is the reference every later one is measured
// from (the heading, the root), and a misread one turned the mesh sideways for a whole recording
// (shoulders 0.11 m apart facing away, hips 0.03 m apart, in one run). The upper quartile, because
// misreads are narrow: it stays on the body's width while fewer than three frames in four are
// misread (a median of the accepted frames alone, tried first, held 32 of 41 frames in one loaded
// run). Another performer is taken from their 8th frame when wider, from their 24th when narrower
// (a quarter and four fifths of a second at 30 fps). The hips are not judged: on the same figure
// their 3D width reads 0.01-0.21 m, half the frames under 0.1, so a test on it would hold most of
// them (the library's heading filter takes a hip line that turns too fast for a body).
export const SPAN_WINDOW = 31, SPAN_MIN = 3, SPAN_TOL = 0.4;
export function spanGuard() {
  const win = [];
  // world: 33 MediaPipe world landmarks. Returns true when the frame may be sent.
  const guard = (world) => {
    const a = world[11], b = world[12];
    if ((a.visibility ?? 1) < VISIBLE || (b.visibility ?? 1) < VISIBLE) return true;
    const w = Math.hypot(a.x - b.x, a.y - b.y, a.z - b.z);
    if (!Number.isFinite(w)) return true;
    win.push(w);
    if (win.length > SPAN_WINDOW) win.shift();
    guard.widths.push(Math.round(w * 1000) / 1000);
    if (guard.widths.length > 100) guard.widths.shift();
    if (win.length < SPAN_MIN) return false;
    const ref = win.slice().sort((x, y) => x - y)[Math.floor(0.75 * win.length)];
    return Math.abs(w - ref) <= SPAN_TOL * ref;
  };
  guard.widths = []; // the last 100 widths judged (metres), for a look in the console
  return guard;
}

// The joint frame for the server, from one result; null when no body was detected.
// root: 'fixed' keeps the pelvis in place; 'image' moves it with the hips' image position
// (x, y; metres from the landmarks' own scale; depth is not estimated). aspect: the image's
// height / width (image landmarks are fractions of each). facing: see above.
export function landmarkFrame(world, image, root, aspect = 0.75, facing = true) {
  if (!world || world.length !== 33) return null;
  const off = [0, HIP_HEIGHT, 0];
  if (root === 'image' && image && image.length === 33) {
    // metres per image unit: the shoulder span in the world over its span in the image
    const ws = Math.hypot(world[11].x - world[12].x, world[11].y - world[12].y);
    const is = Math.hypot(image[11].x - image[12].x, (image[11].y - image[12].y) * aspect);
    if (is > 1e-3 && ws > 1e-3) {
      const s = ws / is, hx = (image[23].x + image[24].x) / 2, hy = (image[23].y + image[24].y) / 2;
      off[0] += (hx - 0.5) * s;
      off[1] -= (hy - 0.6) * aspect * s;
    }
  }
  const nose = world[0], ls = world[11], rs = world[12];
  const seen = (p) => (p.visibility ?? 1) >= VISIBLE;
  const turned = facing && seen(nose) && seen(ls) && seen(rs) && ls.x < rs.x - 0.02 &&
    nose.z > (ls.z + rs.z) / 2;
  if (turned) world = world.map((_, i) => ({ ...world[PAIR[i]], z: -world[PAIR[i]].z }));
  const joints = new Array(99), visibility = new Array(33);
  for (let i = 0; i < 33; ++i) {
    const p = world[i], v = p.visibility ?? 1;
    visibility[i] = Math.round(v * 1000) / 1000;
    const ok = v >= VISIBLE && Number.isFinite(p.x) && Number.isFinite(p.y) && Number.isFinite(p.z);
    joints[3 * i] = ok ? off[0] + p.x : null;
    joints[3 * i + 1] = ok ? off[1] - p.y : null;
    joints[3 * i + 2] = ok ? off[2] - p.z : null;
  }
  return turned ? { skeleton: 'mediapipe', joints, visibility, turned }
    : { skeleton: 'mediapipe', joints, visibility };
}

export function initCamera(state, $) {
  const cam = { status: 'off', frames: 0, detected: 0, sent: 0, turned: 0, held: 0, error: null,
    last: null };
  let guard = spanGuard();
  state.camera = cam;
  const button = $('cam'), thumb = $('cam-thumb'), ctx = thumb.getContext('2d');
  let video = null, pose = null, running = false;
  const say = (s, bad) => {
    cam.status = s;
    $('cam-status').textContent = s;
    $('cam-status').className = bad ? 'bad' : '';
  };

  function draw(results) {
    const w = thumb.width, h = thumb.height;
    ctx.save();
    // a mirror, as people expect of a webcam; the landmarks are flipped with the image
    ctx.translate(w, 0);
    ctx.scale(-1, 1);
    if (results.image) ctx.drawImage(results.image, 0, 0, w, h);
    const L = results.poseLandmarks;
    if (L) {
      ctx.lineWidth = 2;
      ctx.strokeStyle = '#33ff99';
      for (const [a, b] of LINES) {
        if ((L[a].visibility ?? 1) < VISIBLE || (L[b].visibility ?? 1) < VISIBLE) continue;
        ctx.beginPath();
        ctx.moveTo(L[a].x * w, L[a].y * h);
        ctx.lineTo(L[b].x * w, L[b].y * h);
        ctx.stroke();
      }
      for (let i = 0; i < 33; ++i) {
        const v = L[i].visibility ?? 1;
        ctx.fillStyle = v < VISIBLE ? '#888' : i % 2 ? '#ff9933' : '#ffee55'; // odd: left side
        ctx.fillRect(L[i].x * w - 2, L[i].y * h - 2, 4, 4);
      }
    }
    ctx.restore();
  }

  function onResults(results) {
    cam.frames++;
    draw(results);
    const im = results.image, aspect = im && im.width ? im.height / im.width : 0.75;
    const f = landmarkFrame(results.poseWorldLandmarks, results.poseLandmarks, $('cam-root').value,
      aspect, $('cam-facing').checked);
    if (!f) { say('no body in view'); return; }
    cam.detected++;
    const sent = guard(results.poseWorldLandmarks);
    cam.widths = guard.widths;
    if (!sent) {
      cam.held++;
      say(`tracking (${cam.detected} frames, ${cam.held} held)`);
      return;
    }
    if (f.turned) cam.turned++;
    cam.last = f;
    const ws = state.ws;
    if (ws && ws.readyState === WebSocket.OPEN && ws.bufferedAmount < 65536) {
      ws.send(JSON.stringify(f));
      cam.sent++;
    }
    say(`tracking (${cam.detected} frames${cam.held ? `, ${cam.held} held` : ''})`);
  }

  // One detection per new camera frame, the next one asked for when it is done: the page
  // keeps drawing and answering between them (a slow machine detects less often, never
  // queues frames).
  async function loop() {
    if (!running) return;
    try {
      if (video.readyState >= 2) await pose.send({ image: video });
    } catch (e) {
      cam.error = String(e);
      say('error: ' + e.message, true);
    }
    if (!running) return;
    if (video.requestVideoFrameCallback) video.requestVideoFrameCallback(() => loop());
    else requestAnimationFrame(() => loop());
  }

  async function start() {
    say('starting…');
    button.disabled = true;
    try {
      if (!window.Pose) await loadScript(MP_DIR + 'pose.js');
      if (!pose) {
        pose = new window.Pose({ locateFile: (f) => MP_DIR + f });
        // ?pose=lite in the page's address: the lite landmark model (faster, less precise)
        const lite = new URLSearchParams(location.search).get('pose') === 'lite';
        pose.setOptions({ modelComplexity: lite ? 0 : 1, smoothLandmarks: true, enableSegmentation: false,
          minDetectionConfidence: 0.5, minTrackingConfidence: 0.5, selfieMode: false });
        pose.onResults(onResults);
        await pose.initialize();
      }
      const stream = await navigator.mediaDevices.getUserMedia({ video: { width: 640, height: 480 },
        audio: false });
      video = document.createElement('video');
      video.muted = true;
      video.playsInline = true;
      video.srcObject = stream;
      await video.play();
      guard = spanGuard();
      running = true;
      button.textContent = '■ Stop camera';
      say('looking for a body…');
      loop();
    } catch (e) {
      cam.error = String(e);
      say('error: ' + (e.message || e), true);
    }
    button.disabled = false;
  }

  function stop() {
    running = false;
    if (video && video.srcObject) for (const t of video.srcObject.getTracks()) t.stop();
    video = null;
    button.textContent = '📷 Camera';
    say('off');
  }

  button.addEventListener('click', () => (running ? stop() : start()));
}
