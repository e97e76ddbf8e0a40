// Browser test of the operator console (docs/console.md): starts a daemon on
// loopback, drives Debian's chromium headless through puppeteer-core, and
// checks what a person would: register a material through the form, upload
// a stroke CSV through the file input, see the plots drawn, upload a bad
// CSV and see the server's error verbatim, watch an identification job
// appear by polling. Screenshots go to <artifacts>/console-*.png.
//
//   node console_test.mjs --bin build/bin --artifacts build/test-artifacts
//
// Env: CHROMIUM (default /usr/bin/chromium), FRICTIOND_TEST_TOKEN (typed
// into the token field before writes; every write must then carry
// "Authorization: Bearer <token>").
import { spawn } from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import puppeteer from 'puppeteer-core';

const args = Object.fromEntries(
  process.argv.slice(2).reduce((acc, a, i, all) => (a.startsWith('--') ? [...acc, [a.slice(2), all[i + 1]]] : acc), []),
);
const binDir = args.bin || process.env.FRICTIOND_BIN_DIR || 'build/bin';
const artifacts = args.artifacts || 'build/test-artifacts';
const chromium = process.env.CHROMIUM || '/usr/bin/chromium';
// The daemon's operator token (writes need one, docs/auth.md).
const token = process.env.FRICTIOND_TEST_TOKEN || 'console-test-operator-0123456789abcdef';
const started = Date.now();
let daemonChild = null; // killed by the watchdog too

let passed = 0;
let failed = 0;
function check(ok, what, detail = '') {
  if (ok) {
    ++passed;
    console.log(`ok   ${what}`);
  } else {
    ++failed;
    console.log(`FAIL ${what}${detail ? ': ' + detail : ''}`);
  }
  return ok;
}

// --- a stroke CSV in the contract's columns: eq. (1) with a seeded PRNG ---
function mulberry32(seed) {
  return () => {
    seed = (seed + 0x6d2b79f5) | 0;
    let t = Math.imul(seed ^ (seed >>> 15), 1 | seed);
    t = (t + Math.imul(t ^ (t >>> 7), 61 | t)) ^ t;
    return ((t ^ (t >>> 14)) >>> 0) / 4294967296;
  };
}
function strokeCsv({ strokes = 12, rate = 200, b0 = 0.9, b1 = 0.004, b2 = -0.06, sigma = 0.03, seed = 7 }) {
  const rnd = mulberry32(seed);
  const normal = () => Math.sqrt(-2 * Math.log(rnd() + 1e-12)) * Math.cos(2 * Math.PI * rnd());
  const lines = ['# simulated test stroke: mu = b0 + b1 v + b2 Fn + eps', 't_s,fn_n,ft_n,v_mm_s'];
  let t = 0;
  for (let s = 0; s < strokes; ++s) {
    const fnMean = 0.5 + 4 * rnd();
    const vPeak = 15 + 65 * rnd();
    const nRest = Math.round(0.4 * rate), nSlip = Math.round(0.6 * rate);
    for (let i = 0; i < nRest + nSlip; ++i) {
      const fn = fnMean + 0.2 * Math.sin((2 * Math.PI * i) / (nRest + nSlip));
      let v = 0, ft;
      if (i >= nRest) {
        v = vPeak * Math.sin((Math.PI * (i - nRest + 0.5)) / nSlip);
        ft = (b0 + b1 * v + b2 * fn + sigma * normal()) * fn;
      } else {
        ft = (0.1 + (0.8 * i) / nRest) * (b0 + b2 * fn) * fn;
      }
      lines.push(`${t.toFixed(4)},${fn.toFixed(5)},${Math.max(0, ft).toFixed(5)},${v.toFixed(3)}`);
      t += 1 / rate;
    }
  }
  return lines.join('\n') + '\n';
}

// --- daemon --------------------------------------------------------------
function startDaemon(tmp) {
  const bin = path.join(binDir, 'frictiond');
  const child = spawn(bin, ['--db', path.join(tmp, 'console.db'), '--data', 'none', '--port', '0', '--lcm', 'none', '--bind', '127.0.0.1', '--bootstrap-token', token], {
    stdio: ['ignore', 'ignore', 'pipe'],
  });
  return new Promise((resolve, reject) => {
    let log = '';
    const timer = setTimeout(() => reject(new Error('frictiond did not report its port in 10 s:\n' + log)), 10000);
    child.stderr.on('data', (d) => {
      log += d;
      const m = log.match(/serving http:\/\/([0-9.]+):(\d+)/);
      if (m) {
        clearTimeout(timer);
        resolve({ child, url: `http://${m[1]}:${m[2]}` });
      }
    });
    child.on('exit', (code) => reject(new Error(`frictiond exited (${code}) during start-up:\n${log}`)));
  });
}

async function main() {
  fs.mkdirSync(artifacts, { recursive: true });
  const tmp = fs.mkdtempSync(path.join(os.tmpdir(), 'frictiond-console-'));
  const goodCsv = path.join(tmp, 'stroke-oak.csv');
  const badCsv = path.join(tmp, 'stroke-bad.csv');
  fs.writeFileSync(goodCsv, strokeCsv({}));
  fs.writeFileSync(badCsv, 't_s,fn_n,ft_n,v_mm_s\n0.000,1.0,0.5,0\n0.005,-2.0,0.5,0\n');
  const { child: daemon, url } = await startDaemon(tmp);
  daemonChild = daemon;
  let browser;
  try {
    // Served by the daemon, with a CSP that forbids other origins.
    const root = await fetch(url + '/');
    const csp = root.headers.get('content-security-policy') || '';
    check(root.status === 200 && root.headers.get('content-type').startsWith('text/html'), 'GET / serves the console as text/html');
    check(/default-src 'none'/.test(csp) && /script-src 'self'/.test(csp) && /connect-src 'self'/.test(csp), 'console has a CSP allowing only self', csp);
    const js = await fetch(url + '/console/app.js');
    check(js.status === 200 && js.headers.get('content-type').startsWith('text/javascript'), 'app.js served as text/javascript');

    browser = await puppeteer.launch({
      executablePath: chromium,
      headless: true,
      userDataDir: path.join(tmp, 'chromium-profile'),
      args: ['--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run', '--disable-background-networking',
        '--disable-component-update', '--disable-sync', '--disable-dev-shm-usage'],
      protocolTimeout: 30000,
    });
    const page = await browser.newPage();
    await page.setViewport({ width: 1400, height: 1200 });
    page.setDefaultTimeout(15000);
    const pageErrors = [];
    const foreign = [];
    const writes = [];
    page.on('pageerror', (e) => pageErrors.push(String(e)));
    page.on('console', (m) => {
      // 4xx answers the test provokes are logged by chromium as resource errors.
      if (m.type() === 'error' && !/status of 4\d\d/.test(m.text())) pageErrors.push(m.text());
    });
    page.on('request', (r) => {
      if (!r.url().startsWith(url)) foreign.push(r.url());
      if (['PUT', 'POST', 'DELETE', 'PATCH'].includes(r.method())) writes.push({ method: r.method(), url: r.url(), auth: r.headers().authorization });
    });

    await page.goto(url + '/', { waitUntil: 'load' });
    await page.waitForSelector('#materials');
    // The token field: typed before any write, kept in localStorage.
    await page.click('#token', { clickCount: 3 });
    await page.keyboard.press('Backspace');
    if (token) await page.type('#token', token);

    // Register a material through the form.
    const id = 'browser-oak';
    await page.type('#reg-id', id);
    await page.type('#reg-name', 'Sanded oak');
    await page.type('#reg-description', 'registered by the browser test');
    await page.type('#reg-tags', 'test, wood');
    await Promise.all([page.waitForResponse((r) => r.url().endsWith('/v1/materials/' + id) && r.request().method() === 'PUT'), page.click('#reg-submit')]);
    await page.waitForFunction((i) => !document.getElementById('view-material').hidden && document.getElementById('m-title').textContent.includes(i), {}, id);
    const stored = await (await fetch(`${url}/v1/materials/${id}`)).json();
    check(stored.name === 'Sanded oak' && stored.tags.join(',') === 'test,wood', 'material registered through the form', JSON.stringify(stored));
    check(await page.$eval('#m-nomodel', (e) => !e.hidden), 'new material page says there is no model yet');

    // Upload the stroke CSV through the file input, wait for the plots.
    const input = await page.$('#csv-file');
    await input.uploadFile(goodCsv);
    const [upRes] = await Promise.all([page.waitForResponse((r) => r.url().includes(`/v1/materials/${id}/strokes`)), page.click('#upload-csv')]);
    check(upRes.status() === 201, 'stroke CSV upload answered 201', String(upRes.status()));
    await page.waitForFunction(() => ['plot-mu-fn', 'plot-mu-v', 'plot-eps', 'plot-slip', 'plot-hull'].every((p) => document.getElementById(p).dataset.drawn === '1'), { timeout: 20000 });
    const samples = await (await fetch(`${url}/v1/materials/${id}/samples?max=1500`)).json();
    const pts = await page.$eval('#plot-mu-fn', (c) => Number(c.dataset.points));
    check(samples.returned > 100 && pts === samples.returned, 'mu-Fn scatter drew every returned slipping sample', `${pts} drawn, ${samples.returned} returned`);
    check((await page.$eval('#plot-hull', (c) => Number(c.dataset.points))) === samples.returned, 'hull plot drew the samples');
    // Pixels, not just attributes: the model line's red must be on the canvas.
    const red = await page.$eval('#plot-mu-fn', (c) => {
      const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
      let n = 0;
      for (let i = 0; i < d.length; i += 4) if (d[i] > 180 && d[i + 1] < 90 && d[i + 2] < 90 && d[i + 3] > 200) ++n;
      return n;
    });
    check(red > 200, 'fitted model line drawn on the mu-Fn canvas', `${red} red pixels`);
    const summary = await page.$eval('#m-summary', (e) => e.textContent);
    check(/^v1: .*intercept [0-9.]+/.test(summary), 'model summary shows version 1 and its coefficients', summary);
    const caption = await page.$eval('#cap-hull', (e) => e.textContent);
    check(/% of the requested span/.test(caption), 'span coverage caption shown', caption);
    check((await page.$$eval('#versions tbody tr', (r) => r.length)) === 1, 'one model version listed');
    check((await page.$eval('#upload-progress', (e) => e.value)) === 100, 'progress bar at 100 % after the upload');
    await page.screenshot({ path: path.join(artifacts, 'console-material.png'), fullPage: true });

    // A bad CSV: the server's error JSON is shown verbatim.
    await input.uploadFile(badCsv);
    const [badRes] = await Promise.all([page.waitForResponse((r) => r.url().includes(`/v1/materials/${id}/strokes`)), page.click('#upload-csv')]);
    // The same file sent by the test itself: the page must show this body.
    const direct = await fetch(`${url}/v1/materials/${id}/strokes`, { method: 'POST', headers: { 'Content-Type': 'text/csv', Authorization: 'Bearer ' + token }, body: fs.readFileSync(badCsv) });
    const badBody = await direct.text();
    await page.waitForFunction(() => !document.getElementById('upload-error').hidden);
    const shown = await page.$eval('#upload-error', (e) => e.textContent);
    check(badRes.status() === 400, 'bad CSV answered 400', String(badRes.status()));
    check(shown === badBody && /fn_n/.test(shown) && /line 3/.test(shown), 'server error shown verbatim', `shown ${JSON.stringify(shown)} vs body ${JSON.stringify(badBody)}`);
    const after = await (await fetch(`${url}/v1/materials/${id}/models`)).json();
    check(after.versions.length === 1, 'nothing stored from the rejected upload');
    await page.screenshot({ path: path.join(artifacts, 'console-bad-csv.png'), fullPage: true });

    // Identification jobs update live: a robot asks for an unknown material.
    const ask = await fetch(`${url}/v1/materials/unknown-felt/model`, { headers: { 'X-Robot-Id': 'arm-7' } });
    check(ask.status === 404, 'unknown material answers 404 (identification requested)');
    await page.waitForFunction(() => [...document.querySelectorAll('#jobs tbody td')].some((td) => td.textContent === 'unknown-felt'), { timeout: 10000 });
    check(true, 'identification job appeared in the console by polling');

    // Material list with search.
    await page.goto(url + '/#/', { waitUntil: 'load' });
    await page.waitForFunction((i) => [...document.querySelectorAll('#materials tbody tr')].some((r) => r.dataset.id === i), {}, id);
    await page.type('#search', 'oak');
    await page.waitForFunction(() => document.querySelectorAll('#materials tbody tr').length === 1 && document.getElementById('list-count').textContent.startsWith('1 '));
    check(true, 'search narrows the material list');
    await page.screenshot({ path: path.join(artifacts, 'console-list.png'), fullPage: true });
    check((await page.evaluate(() => localStorage.getItem('frictiond.token') || '')) === token, 'token kept in localStorage');

    // Every write carried the token (or none when no token is set).
    check(writes.length >= 3, 'writes were made from the page', String(writes.length));
    const wrongAuth = writes.filter((w) => (token ? w.auth !== 'Bearer ' + token : w.auth !== undefined));
    check(wrongAuth.length === 0, token ? 'every write sent Authorization: Bearer <token>' : 'no Authorization header without a token', JSON.stringify(wrongAuth));
    check(foreign.length === 0, 'the page loaded nothing from other origins', foreign.join(' '));
    check(pageErrors.length === 0, 'no script errors or CSP violations in the page', pageErrors.join(' | '));
  } finally {
    if (browser) await browser.close().catch(() => {});
    daemon.kill('SIGTERM');
    await new Promise((r) => (daemon.exitCode !== null ? r() : daemon.on('exit', r)));
    fs.rmSync(tmp, { recursive: true, force: true });
  }
}

const watchdog = setTimeout(() => {
  console.log('FAIL console test did not finish within 55 s');
  if (daemonChild) daemonChild.kill('SIGKILL');
  process.exit(1);
}, 55000);
main()
  .catch((e) => check(false, 'console test ran to the end', e.stack || String(e)))
  .finally(() => {
    clearTimeout(watchdog);
    console.log(`console browser test: ${((Date.now() - started) / 1000).toFixed(1)} s, screenshots in ${artifacts}`);
    console.log(`${passed} passed, ${failed} failed`);
    process.exit(failed === 0 && passed > 0 ? 0 : 1);
  });
