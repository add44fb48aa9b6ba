// Issue 18: no web page can touch the live server. Raw HTTP over loopback (node's net, so Host,
// Origin and Content-Length are exactly what an attacker would send) against a running
// `kinemesh live`: DNS rebinding (forged Host), cross-site POST (foreign Origin, text/plain, no
// token), the per-run token, JSON content type, the 4 MB body limit, Content-Length: 0 answered
// once, cross-origin and token-less WebSocket upgrades, the client cap, POST /rig merging into
// the sidecar (skeleton, skin, landmarks and the file's mode kept), binding off loopback.
import { spawnSync } from 'node:child_process';
import fs from 'node:fs';
import net from 'node:net';
import path from 'node:path';
import { check, finish, TOKEN } from '../live/lib.mjs';

const [http, , , work] = process.argv.slice(2);
const PORT = +http;
const rigPath = path.join(work, 'c.rig.json');

// One request on a fresh connection; resolves with everything received within `ms` after the
// first bytes (so a second, unwanted response on the keep-alive connection is seen too).
function raw(req, ms = 400) {
  return new Promise((resolve) => {
    const s = net.connect(PORT, '127.0.0.1');
    let data = Buffer.alloc(0), timer = null;
    const done = () => { s.destroy(); resolve(data.toString('latin1')); };
    s.on('data', (d) => {
      data = Buffer.concat([data, d]);
      clearTimeout(timer);
      timer = setTimeout(done, ms);
    });
    s.on('error', done);
    s.on('close', () => { clearTimeout(timer); resolve(data.toString('latin1')); });
    s.write(req);
    setTimeout(done, 10000);
  });
}
const statusOf = (resp) => +(/^HTTP\/1\.1 (\d+)/.exec(resp) || [0, 0])[1];
const host = `127.0.0.1:${PORT}`;
function request(method, target, { headers = {}, body = '' } = {}) {
  const h = { Host: host, ...headers };
  if (method === 'POST' && !('Content-Length' in h)) h['Content-Length'] = Buffer.byteLength(body);
  let s = `${method} ${target} HTTP/1.1\r\n`;
  for (const [k, v] of Object.entries(h)) if (v !== null) s += `${k}: ${v}\r\n`;
  return raw(s + '\r\n' + body);
}
const tok = `token=${TOKEN}`;
const JSONCT = { 'Content-Type': 'application/json' };
const evilBody = '{"handles":[{"name":"x","vertex":0}]}';

const rig0 = fs.readFileSync(rigPath);
const mode0 = fs.statSync(rigPath).mode & 0o777;
check(mode0 === 0o600, `rig file starts at mode ${mode0.toString(8)}`);
const unchanged = () => fs.readFileSync(rigPath).equals(rig0);

// ---- cross-site POST, exactly as in the issue: foreign Origin, text/plain, no token
let r = await request('POST', '/rig', { headers: { Origin: 'http://evil.example', 'Content-Type': 'text/plain' }, body: evilBody });
check(statusOf(r) === 403, `cross-site POST /rig refused (${statusOf(r)})`);
r = await request('POST', `/rig?${tok}`, { headers: { Origin: 'http://evil.example', ...JSONCT }, body: evilBody });
check(statusOf(r) === 403, `POST /rig with the token but a foreign Origin refused (${statusOf(r)})`);
r = await request('POST', `/rig?${tok}`, { headers: { Origin: 'null', ...JSONCT }, body: evilBody });
check(statusOf(r) === 403, `POST /rig with Origin: null refused (${statusOf(r)})`);
r = await request('POST', '/rig', { headers: JSONCT, body: evilBody });
check(statusOf(r) === 401, `POST /rig without the token -> 401 (${statusOf(r)})`);
r = await request('POST', '/rig?token=0123456789abcdef0123456789abcdef', { headers: JSONCT, body: evilBody });
check(statusOf(r) === 401, `POST /rig with a wrong token -> 401 (${statusOf(r)})`);
r = await request('POST', `/rig?${tok}`, { headers: { 'Content-Type': 'text/plain' }, body: evilBody });
check(statusOf(r) === 415, `POST /rig as text/plain -> 415 (${statusOf(r)})`);
r = await request('POST', `/rig?${tok}`, { headers: { 'Content-Type': 'application/x-www-form-urlencoded' }, body: evilBody });
check(statusOf(r) === 415, `POST /rig as a form -> 415 (${statusOf(r)})`);
r = await request('POST', '/replay', { headers: { Origin: 'http://evil.example', 'Content-Type': 'text/plain' }, body: '{}' });
check(statusOf(r) === 403, `cross-site POST /replay refused (${statusOf(r)})`);
r = await request('POST', `/rig?${tok}`, { headers: { Host: 'rebind.attacker.example', ...JSONCT }, body: evilBody });
check(statusOf(r) === 403, `POST /rig through a rebound name refused (${statusOf(r)})`);
check(unchanged(), 'rig file untouched by the refused POSTs');

// ---- body size
const big = ' '.repeat(5 << 20);
r = await request('POST', `/rig?${tok}`, { headers: JSONCT, body: big });
check(statusOf(r) === 413, `5 MB POST /rig -> 413 (${statusOf(r)})`);
check(unchanged(), 'rig file untouched by the oversized POSTs');

// ---- Content-Length: 0 is answered once (keep-alive: a second header block would follow)
r = await request('POST', `/replay?${tok}`, { headers: { ...JSONCT, 'Content-Length': '0' } });
const blocks = (r.match(/HTTP\/1\.1 \d+/g) || []).length;
check(statusOf(r) === 200 && blocks === 1, `POST /replay with Content-Length: 0 answered ${blocks} time(s)`);
r = await request('POST', `/rig?${tok}`, { headers: { ...JSONCT, 'Content-Length': '0' } });
const blocks2 = (r.match(/HTTP\/1\.1 \d+/g) || []).length;
check(statusOf(r) === 400 && blocks2 === 1, `POST /rig with Content-Length: 0 -> one 400 (${statusOf(r)}, ${blocks2} answer(s))`);

// ---- DNS rebinding: the data GETs need an allowed Host
for (const p of ['/rig', '/status', '/mesh', '/handles', '/']) {
  r = await request('GET', p, { headers: { Host: 'rebind.attacker.example' } });
  check(statusOf(r) === 403, `GET ${p} with Host: rebind.attacker.example refused (${statusOf(r)})`);
}
r = await request('GET', '/rig', { headers: { Host: `rebind.attacker.example:${PORT}` } });
check(statusOf(r) === 403, `GET /rig with a rebound name and port refused (${statusOf(r)})`);
r = await request('GET', '/status', { headers: { Host: null } });
check(statusOf(r) >= 400, `GET /status without Host refused (${statusOf(r)})`);
for (const h of [host, `localhost:${PORT}`, 'localhost', `[::1]:${PORT}`]) {
  r = await request('GET', '/status', { headers: { Host: h } });
  check(statusOf(r) === 200, `GET /status with Host: ${h} -> 200 (${statusOf(r)})`);
}

// ---- WebSocket upgrades
const upgrade = (target, extra = {}) => request('GET', target, {
  headers: { Upgrade: 'websocket', Connection: 'Upgrade', 'Sec-WebSocket-Key': 'dGhlIHNhbXBsZSBub25jZQ==',
    'Sec-WebSocket-Version': '13', 'Sec-WebSocket-Protocol': 'kinemesh', ...extra } });
r = await upgrade(`/ws?${tok}`, { Origin: 'http://evil.example' });
check(statusOf(r) !== 101, `cross-origin WebSocket refused (${statusOf(r) || 'closed'})`);
r = await upgrade('/ws', { Origin: `http://${host}` });
check(statusOf(r) !== 101, `WebSocket without the token refused (${statusOf(r) || 'closed'})`);
r = await upgrade(`/ws?${tok}`, { Host: 'rebind.attacker.example', Origin: 'http://rebind.attacker.example' });
check(statusOf(r) !== 101, `WebSocket through a rebound name refused (${statusOf(r) || 'closed'})`);
r = await upgrade(`/ws?${tok}`, { Origin: `http://${host}` });
check(statusOf(r) === 101, `same-origin WebSocket with the token accepted (${statusOf(r)})`);

// ---- WebSocket clients are capped (32): the 33rd upgrade is refused, the others stay open
const socks = [];
const openWs = () => new Promise((resolve) => {
  const s = net.connect(PORT, '127.0.0.1');
  let data = '';
  s.on('data', (d) => { data += d.toString('latin1'); if (data.includes('\r\n\r\n')) resolve({ s, ok: / 101 /.test(data) }); });
  s.on('error', () => resolve({ s, ok: false }));
  s.on('close', () => resolve({ s, ok: false }));
  s.write(`GET /ws?${tok} HTTP/1.1\r\nHost: ${host}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n` +
    'Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\nSec-WebSocket-Protocol: kinemesh\r\n\r\n');
});
let accepted = 0;
for (let i = 0; i < 33; ++i) {
  const c = await openWs();
  socks.push(c.s);
  accepted += c.ok;
}
check(accepted === 32, `WebSocket clients capped: ${accepted} of 33 accepted`);
for (const s of socks) s.destroy();

// ---- a good POST /rig merges the puppetry part; skeleton, skin, landmarks and mode stay
const before = JSON.parse(rig0.toString('utf8'));
const h0 = before.handles[0];
const posted = { handles: [{ name: 'only', vertex: h0.vertex ?? 0 }], map: [{ handle: 'only', joint: 'HandLeft' }] };
r = await request('POST', `/rig?${tok}`, { headers: { ...JSONCT, Origin: `http://${host}` }, body: JSON.stringify(posted) });
check(statusOf(r) === 200, `same-origin POST /rig with the token -> 200 (${statusOf(r)})`);
const after = JSON.parse(fs.readFileSync(rigPath, 'utf8'));
check(after.handles.length === 1 && after.handles[0].name === 'only', 'posted handles saved');
for (const k of ['skeleton', 'joints', 'skin', 'landmarks', 'filter'])
  check(JSON.stringify(after[k]) === JSON.stringify(before[k]), `"${k}" kept in the sidecar`);
const mode1 = fs.statSync(rigPath).mode & 0o777;
check(mode1 === 0o600, `rig file mode kept: ${mode1.toString(8)}`);
check(!fs.readdirSync(work).some((f) => f.includes('.tmp.')), 'no temporary left beside the rig');

// ---- off loopback only with a token
const bin = process.env.KM_BIN;
const off = spawnSync(bin, ['live', '--mesh', path.join(work, 'c.obj'), '--bind', '0.0.0.0', '--no-token',
  '--http', String(PORT + 7)], { timeout: 60000, encoding: 'utf8' });
check(off.status !== 0 && off.status !== null && /token/.test(off.stderr),
  `--bind 0.0.0.0 --no-token refused (exit ${off.status}: ${off.stderr.trim().split('\n').pop()})`);
const weak = spawnSync(bin, ['live', '--mesh', path.join(work, 'c.obj'), '--token', 'abc',
  '--http', String(PORT + 7)], { timeout: 60000, encoding: 'utf8' });
check(weak.status !== 0 && weak.status !== null && /token/.test(weak.stderr),
  `a 3-character --token refused (exit ${weak.status})`);
finish('security');
