// three.js as a real client of kinemesh's .glb exports (issue 16): headless Debian chromium
// (playwright-core, no browser download) loads FILE.glb with GLTFLoader (+ MeshoptDecoder),
// plays its animation with an AnimationMixer to frames 0, the middle and the last, reads back
// the vertex positions three.js computes (skinned: SkinnedMesh.applyBoneTransform; morphs:
// base + influences x targets) and compares them with the exact frames of EXACT.pc2.
// Usage: node three_check.mjs FILE.glb EXACT.pc2 TOL_MM|auto
// auto: the file's own reported max error (asset.extras.kinemesh.max_error_m) plus a margin for
// float32 (0.05 mm).
// Exits 1 when a frame is off by more than the tolerance, 2 on usage / load errors.
import { createRequire } from 'node:module';
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

const here = path.dirname(fileURLToPath(import.meta.url));
const web = path.join(here, '../../web');
const require = createRequire(path.join(web, 'package.json'));
const { chromium } = require('playwright-core');
const [glbPath, pc2Path, tolArg] = process.argv.slice(2);
if (!glbPath || !pc2Path || !tolArg) {
  console.error('usage: node three_check.mjs FILE.glb EXACT.pc2 TOL_MM');
  process.exit(2);
}
const glbBytes = fs.readFileSync(glbPath);
const glbJson = JSON.parse(glbBytes.subarray(20, 20 + glbBytes.readUInt32LE(12)).toString('utf8'));
const reported = glbJson.asset?.extras?.kinemesh?.max_error_m ?? 0;
const tol = tolArg === 'auto' ? reported + 5e-5 : Number(tolArg) / 1000;
const pc2 = fs.readFileSync(pc2Path);
const nv = pc2.readInt32LE(16), nf = pc2.readInt32LE(28);
const exact = (k, i, c) => pc2.readFloatLE(32 + (k * nv + i) * 12 + 4 * c);

const page_html = `<!doctype html><script type="importmap">{"imports":{
  "three": "/three/build/three.module.js", "three/addons/": "/three/examples/jsm/"}}</script>
<script type="module">
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { MeshoptDecoder } from 'three/addons/libs/meshopt_decoder.module.js';
window.kmFrames = async (frames) => {
  const loader = new GLTFLoader();
  loader.setMeshoptDecoder(MeshoptDecoder);
  const gltf = await loader.loadAsync('/file.glb');
  const fps = gltf.asset.extras?.kinemesh?.fps ?? 30;
  let mesh = null;
  gltf.scene.traverse((o) => { if (o.isMesh && !mesh) mesh = o; });
  const mixer = new THREE.AnimationMixer(gltf.scene);
  for (const clip of gltf.animations) {
    const a = mixer.clipAction(clip);
    a.setLoop(THREE.LoopOnce); /* the last frame is the clip's end, not its start again */
    a.clampWhenFinished = true;
    a.play();
  }
  const out = [];
  const pos = mesh.geometry.attributes.position, v = new THREE.Vector3();
  for (const k of frames) {
    mixer.setTime(k / fps);
    gltf.scene.updateMatrixWorld(true);
    const P = new Array(pos.count * 3);
    if (mesh.isSkinnedMesh) {
      mesh.skeleton.update();
      for (let i = 0; i < pos.count; ++i) {
        v.fromBufferAttribute(pos, i);
        mesh.applyBoneTransform(i, v);
        v.applyMatrix4(mesh.matrixWorld);
        P[3 * i] = v.x; P[3 * i + 1] = v.y; P[3 * i + 2] = v.z;
      }
    } else {
      const targets = mesh.geometry.morphAttributes.position || [], inf = mesh.morphTargetInfluences || [];
      for (let i = 0; i < pos.count; ++i) {
        v.fromBufferAttribute(pos, i);
        for (let t = 0; t < targets.length; ++t)
          if (inf[t]) { v.x += inf[t] * targets[t].getX(i); v.y += inf[t] * targets[t].getY(i); v.z += inf[t] * targets[t].getZ(i); }
        v.applyMatrix4(mesh.matrixWorld);
        P[3 * i] = v.x; P[3 * i + 1] = v.y; P[3 * i + 2] = v.z;
      }
    }
    out.push(P);
  }
  return { skinned: !!mesh.isSkinnedMesh, count: pos.count, out };
};
window.kmReady = true;
</script>`;

const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
  headless: true,
  args: ['--no-sandbox', '--disable-dev-shm-usage'],
});
let rc = 0;
try {
  const page = await browser.newPage();
  const errors = [];
  page.on('pageerror', (e) => errors.push(String(e)));
  await page.route('http://km.test/**', (route) => {
    const u = new URL(route.request().url()).pathname;
    if (u === '/') return route.fulfill({ contentType: 'text/html', body: page_html });
    if (u === '/file.glb') return route.fulfill({ contentType: 'model/gltf-binary', body: glbBytes });
    if (u.startsWith('/three/')) {
      const f = path.join(web, 'node_modules', u);
      if (fs.existsSync(f)) return route.fulfill({ contentType: 'text/javascript', body: fs.readFileSync(f) });
    }
    return route.fulfill({ status: 404, body: '' });
  });
  await page.goto('http://km.test/');
  await page.waitForFunction(() => window.kmReady, null, { timeout: 60000 });
  const frames = [0, Math.floor((nf - 1) / 2), nf - 1];
  const r = await page.evaluate((f) => window.kmFrames(f), frames);
  if (errors.length) throw new Error(errors.join('; '));
  if (r.count !== nv) throw new Error(`${glbPath}: three.js sees ${r.count} vertices, the pc2 ${nv}`);
  frames.forEach((k, n) => {
    let worst = 0;
    for (let i = 0; i < nv; ++i) {
      const d = Math.hypot(r.out[n][3 * i] - exact(k, i, 0), r.out[n][3 * i + 1] - exact(k, i, 1),
        r.out[n][3 * i + 2] - exact(k, i, 2));
      if (d > worst) worst = d;
    }
    const ok = worst <= tol;
    if (!ok) rc = 1;
    console.log(`${ok ? 'ok' : 'FAIL'}: ${path.basename(glbPath)} (${r.skinned ? 'skinned' : 'morphs'}) frame ${k}: max ${(worst * 1e3).toFixed(3)} mm (tolerance ${(tol * 1e3).toFixed(3)} mm)`);
  });
} catch (e) {
  console.log(`FAIL: ${e.message}`);
  rc = 2;
} finally {
  await browser.close();
}
process.exit(rc);
