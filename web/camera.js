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

const MP_DIR = 'mediapipe/';
const VISIBLE = 0.5;
const HIP_HEIGHT = 0.9; // metres: where the pelvis is put (the retarget uses displacements)
// Lines of the thumbnail's skeleton (BlazePose landmark indices).
const LINES = [[11, 12], [11, 13], [13, 15], [12, 14], [14, 16], [11, 23], [12, 24], [23, 24],
  [23, 25], [25, 27], [24, 26], [26, 28], [27, 31], [28, 32], [15, 19], [16, 20], [0, 11],
  [0, 12]];

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

// The joint frame for the server, from one result; null when no body was detected.
// root: 'fixed' keeps the pelvis in place; 'image' moves it with the hips' image position
// (x, y; metres from the landmarks' own scale; depth is not estimated). aspect: the image's
// height / width (image landmarks are fractions of each).
export function landmarkFrame(world, image, root, aspect = 0.75) {
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
  const joints = new Array(99), visibility = new Array(33);
  for (let i = 0; i < 33; ++i) {
    const p = world[i], v = p.visibility ?? 1;
    visibility[i] = Math.round(v * 1000) / 1000;
    const ok = v >= VISIBLE && Number.isFinite(p.x) && Number.isFinite(p.y) && Number.isFinite(p.z);
    joints[3 * i] = ok ? off[0] + p.x : null;
    joints[3 * i + 1] = ok ? off[1] - p.y : null;
    joints[3 * i + 2] = ok ? off[2] - p.z : null;
  }
  return { skeleton: 'mediapipe', joints, visibility };
}

export function initCamera(state, $) {
  const cam = { status: 'off', frames: 0, detected: 0, sent: 0, error: null, last: null };
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
      aspect);
    if (!f) { say('no body in view'); return; }
    cam.detected++;
    cam.last = f;
    const ws = state.ws;
    if (ws && ws.readyState === WebSocket.OPEN && ws.bufferedAmount < 65536) {
      ws.send(JSON.stringify(f));
      cam.sent++;
    }
    say(`tracking (${cam.detected} frames)`);
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
