// Validates a .glb with the Khronos glTF validator; exits 1 on any error, 2 on usage/IO.
// Usage: node validate.mjs [--allow CODE]... FILE.glb   (after `npm install` in this directory)
// --allow CODE: an issue of that code is listed as allowed and not counted in the summary line's
// errors and warnings. The one use: MESH_PRIMITIVE_GENERATED_TANGENT_SPACE on a material with a
// normal map. kinemesh writes no TANGENT: glTF says a client then generates MikkTSpace tangents,
// which is the space Blender and other bakers write normal maps in, while tangents of another
// method written into the file would turn the map's normals (no maintained MikkTSpace library is
// packaged in Debian; see the README's materials paragraph).
import { readFile } from 'node:fs/promises';
import validator from 'gltf-validator';

const args = process.argv.slice(2);
const allow = new Set();
while (args[0] === '--allow' && args.length > 2) {
  allow.add(args[1]);
  args.splice(0, 2);
}
const path = args[0];
if (!path || args.length !== 1) {
  console.error('usage: node validate.mjs [--allow CODE]... FILE.glb');
  process.exit(2);
}
let data;
try {
  data = new Uint8Array(await readFile(path));
} catch (e) {
  console.error(`${path}: ${e.message}`);
  process.exit(2);
}
const report = await validator.validateBytes(data, { uri: path, maxIssues: 100 });
let { numErrors, numWarnings } = report.issues;
const { numInfos, messages } = report.issues;
for (const m of messages) {
  if (m.severity > 1) continue;
  const kind = ['error', 'warning'][m.severity];
  if (allow.has(m.code)) {
    console.log(`allowed ${kind} ${m.code} ${m.pointer ?? ''}`);
    if (m.severity === 0) numErrors -= 1;
    else numWarnings -= 1;
    continue;
  }
  console.log(`${kind} ${m.code} ${m.pointer ?? ''}: ${m.message}`);
}
console.log(`${path}: ${numErrors} errors, ${numWarnings} warnings, ${numInfos} infos`);
process.exit(numErrors > 0 ? 1 : 0);
