// Helpers shared by the live-mode test scripts.
export const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
let failures = 0, passes = 0;
export function check(cond, what) {
  if (cond) { passes++; console.log('ok   ' + what); } else { failures++; console.log('FAIL ' + what); }
}
export function finish(name) {
  console.log(`${name}: ${passes} passed, ${failures} failed`);
  process.exit(failures ? 1 : 0);
}
export async function status(http) {
  return (await fetch(`http://127.0.0.1:${http}/status`)).json();
}
// Waits are deadlines for something to happen, not speed checks: they are stretched
// generously (x4) so a loaded CI machine or the sanitizer build does not fail them.
export const SLACK = 4;
export async function waitFor(fn, ms, step = 50) {
  ms *= SLACK;
  const t0 = Date.now();
  for (;;) {
    const v = await fn();
    if (v) return v;
    if (Date.now() - t0 > ms) return v;
    await sleep(step);
  }
}
