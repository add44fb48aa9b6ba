// Garbage on every input: random bytes over UDP and OSC, malformed OSC (wrong arity, wrong
// types, NaN, unknown joints, broken bundles), malformed JSON frames and bad HTTP requests.
// Every bad packet is counted, the server keeps running and still takes a good frame.
import dgram from 'node:dgram';
import crypto from 'node:crypto';
import fs from 'node:fs';
import path from 'node:path';
import { check, finish, status, waitFor, sleep, replayDone, TOKEN } from './lib.mjs';

const [http, osc, udp, work] = process.argv.slice(2);
const sock = dgram.createSocket('udp4');
const send = (port, buf) => new Promise((r) => sock.send(buf, +port, '127.0.0.1', () => r()));

// OSC encoding (big-endian, 4-byte padded strings) for hand-made malformed messages.
const ostr = (s) => { const b = Buffer.from(s + '\0'); return Buffer.concat([b, Buffer.alloc((4 - b.length % 4) % 4)]); };
const f32 = (x) => { const b = Buffer.alloc(4); b.writeFloatBE(x); return b; };
const i32 = (x) => { const b = Buffer.alloc(4); b.writeInt32BE(x); return b; };
const msg = (addr, types, ...args) => Buffer.concat([ostr(addr), ostr(',' + types), ...args]);
const good = msg('/joint', 'siiffff', ostr('r_hand'), i32(0), i32(1), f32(1), f32(2), f32(3), f32(1));

const badOsc = [
  msg('/joint', 'sii', ostr('r_hand'), i32(0), i32(1)),                                   // arity
  msg('/joint', 'siifffffff', ostr('r_hand'), i32(0), i32(1), ...Array(7).fill(f32(1))), // arity
  msg('/joint', 'siiffff', ostr('r_hand'), i32(0), i32(1), f32(NaN), f32(2), f32(3), f32(1)), // NaN
  msg('/joint', 'siiffff', ostr('r_hand'), i32(0), i32(1), f32(Infinity), f32(2), f32(3), f32(1)),
  msg('/joint', 'siiffff', ostr('tail_tip'), i32(0), i32(1), f32(1), f32(2), f32(3), f32(1)), // unknown joint
  msg('/joint', 'fiiffff', f32(1), i32(0), i32(1), f32(1), f32(2), f32(3), f32(1)),        // types
  msg('/bodies/1/joints/HandLeft', 'ff', f32(1), f32(2)),                                  // arity
  msg('/bodies/1/joints/Wing', 'fffs', f32(1), f32(2), f32(3), ostr('Tracked')),           // unknown
  msg('/bodies/1/joints/HandLeft', 'fffs', f32(NaN), f32(2), f32(3), ostr('Tracked')),     // NaN
  good.subarray(0, good.length - 6),                                                       // truncated
  Buffer.concat([ostr('/joint'), ostr(',siiffff')]),                                      // args missing
  Buffer.concat([ostr('#bundle'), Buffer.alloc(8), i32(1000), good]),                     // bad size
  Buffer.concat([ostr('#bundle'), Buffer.alloc(8), i32(good.length), good.subarray(0, 8)]),
  Buffer.from('/joint'),                                                                   // no NUL
  Buffer.alloc(0),
];
const badJson = [
  '{"joints":{"HandLeft":[1,2]}}', '{"joints":{"HandLeft":[1,2,"x"]}}', '[1,2,3]',
  '{"joints":{"HandLeft":[1e999,0,0]}}', '{"joints":{"Tail":[1,2,3]}}', '{"joints":{}}',
  '{"joints":[' + Array(59).fill(0).join(',') + ']}', 'NaN', '{"joints":{"HandLeft":[NaN,0,0]}}',
  '{"joints":', '', '{"hello":1}', '\u0000\u0001\u0002',
].map((s) => Buffer.from(s));

const s0 = await status(http);
let n = 0;
for (const b of badOsc) { await send(osc, b); n++; }
for (const b of badJson) { await send(udp, b); n++; }
const RANDOM = 300;
for (let i = 0; i < RANDOM; ++i) {
  const len = crypto.randomInt(0, 1400);
  const b = crypto.randomBytes(len);
  // a random datagram starting like an OSC address or bundle stresses liblo's validation
  if (i % 3 === 0 && len > 8) b.write(i % 2 ? '/joint\0\0,siiffff' : '#bundle\0', 0);
  await send(i % 2 ? osc : udp, b);
  n++;
}
await waitFor(async () => (await status(http)).bad_packets - s0.bad_packets >= n, 5000);
const s1 = await status(http);
const bad = s1.bad_packets - s0.bad_packets;
// UDP on loopback does not drop at this rate; allow a few random packets that happen to be
// valid OSC carrying no joint.
check(bad >= n - 3 && bad <= n + 3, `bad_packets counted: ${bad} of ${n} garbage datagrams`);
check(s1.frames_in === s0.frames_in, `no frame came out of garbage (frames_in ${s1.frames_in})`);
check(s1.udp_datagrams - s0.udp_datagrams === badJson.length + RANDOM / 2, `udp_datagrams ${s1.udp_datagrams}`);

// A good frame still goes through, on both inputs.
await send(udp, Buffer.from(JSON.stringify({ joints: { HandLeft: [0.7, 1.4, 0.1], Head: [0, 1.65, 0] } })));
await send(udp, Buffer.from(JSON.stringify(Array(60).fill(0.5))));
await send(osc, good);
await waitFor(async () => (await status(http)).frames_in >= s1.frames_in + 3, 3000);
const s2 = await status(http);
check(s2.frames_in >= s1.frames_in + 3, `good frames after the garbage: frames_in ${s2.frames_in}`);
await waitFor(async () => (await status(http)).frames_out >= 1, 3000);
check((await status(http)).solve_errors === 0, 'no solver errors');

// HTTP: bad rig, unknown endpoints, path traversal; the rig file stays as it was.
const url = `http://127.0.0.1:${http}`;
const rigPath = path.join(work, 'c.rig.json');
const rig0 = fs.readFileSync(rigPath, 'utf8');
const post = (p, body) => fetch(`${url}${p}?token=${TOKEN}`, { method: 'POST', body,
  headers: { 'Content-Type': 'application/json' } });
check((await post('/rig', '{"handles": [{"name":"x","vertex": 99999999}]')).status === 400, 'POST /rig with garbage -> 400');
check((await post('/rig', '{"handles": [{"name":"x","vertex": 99999999}]}')).status === 400, 'POST /rig with an out-of-range vertex -> 400');
check((await post('/rig', '{"handles": []}')).status === 400, 'POST /rig without handles -> 400');
check((await post('/nothing', 'x')).status === 404, 'POST to an unknown endpoint -> 404');
check((await fetch(url + '/../../etc/passwd')).status === 404, 'path traversal -> 404');
check((await fetch(url + '/no_such_file.js')).status === 404, 'missing file -> 404');
check(fs.readFileSync(rigPath, 'utf8') === rig0, 'rig file unchanged by bad POSTs');
const sr = await status(http);
const r = await post('/replay', '');
check(r.status === 200, 'POST /replay with an empty body -> 200');
const s3 = await replayDone(http, sr);
check(s3 && s3.frames_out > sr.frames_out && s3.solve_errors === sr.solve_errors,
  'the replay runs after all that: input deformed, no solve error');
sock.close();
finish('live_garbage');
