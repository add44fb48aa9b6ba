// Validates a .glb with the Khronos glTF validator; exits 1 on any error, 2 on usage/IO.
// Usage: node validate.mjs FILE.glb   (after `npm install` in this directory)
import { readFile } from 'node:fs/promises';
import validator from 'gltf-validator';

const path = process.argv[2];
if (!path) {
  console.error('usage: node validate.mjs FILE.glb');
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
const { numErrors, numWarnings, numInfos, messages } = report.issues;
for (const m of messages) {
  if (m.severity <= 1) console.log(`${['error', 'warning'][m.severity]} ${m.code} ${m.pointer ?? ''}: ${m.message}`);
}
console.log(`${path}: ${numErrors} errors, ${numWarnings} warnings, ${numInfos} infos`);
process.exit(numErrors > 0 ? 1 : 0);
