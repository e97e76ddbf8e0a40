// frictiond operator console (docs/console.md). Plain JS, no framework;
// everything it loads comes from the daemon (the CSP forbids the rest).
'use strict';

const $ = (id) => document.getElementById(id);
const TOKEN_KEY = 'frictiond.token';
const state = { materials: [], id: null, fingertip: 'default', version: null, jobsTimer: null };

// ---------------------------------------------------------------- HTTP ----

function authHeaders() {
  const t = $('token').value.trim();
  return t ? { Authorization: 'Bearer ' + t } : {};
}

// JSON GET; throws an Error carrying the body text on a non-2xx answer.
async function getJson(path) {
  const res = await fetch(path, { headers: { Accept: 'application/json' } });
  const text = await res.text();
  if (!res.ok) {
    const e = new Error(text);
    e.status = res.status;
    throw e;
  }
  return JSON.parse(text);
}

// A write: Authorization: Bearer <token> on every one (when a token is set).
async function write(method, path, body, type) {
  const headers = Object.assign({ Accept: 'application/json' }, authHeaders());
  if (type) headers['Content-Type'] = type;
  // An explicit empty body: a POST without one has no Content-Length.
  const res = await fetch(path, { method, headers, body: body === undefined ? '' : body });
  return { status: res.status, ok: res.ok, text: await res.text() };
}

// Upload with progress (fetch has no upload progress; XMLHttpRequest does).
function upload(path, file, type, onProgress) {
  return new Promise((resolve) => {
    const xhr = new XMLHttpRequest();
    xhr.open('POST', path);
    xhr.setRequestHeader('Content-Type', type);
    xhr.setRequestHeader('Accept', 'application/json');
    const auth = authHeaders();
    for (const k of Object.keys(auth)) xhr.setRequestHeader(k, auth[k]);
    xhr.upload.onprogress = (e) => { if (e.lengthComputable) onProgress(e.loaded / e.total); };
    xhr.onload = () => resolve({ status: xhr.status, ok: xhr.status >= 200 && xhr.status < 300, text: xhr.responseText });
    xhr.onerror = () => resolve({ status: 0, ok: false, text: 'network error: the daemon did not answer' });
    xhr.send(file);
  });
}

const enc = encodeURIComponent;

// ----------------------------------------------------------------- DOM ----

function el(tag, text, cls) {
  const e = document.createElement(tag);
  if (text !== undefined && text !== null) e.textContent = String(text);
  if (cls) e.className = cls;
  return e;
}

function row(cells) {
  const tr = document.createElement('tr');
  for (const c of cells) tr.appendChild(c instanceof Node ? c : el('td', c));
  return tr;
}

function fmt(x, digits = 3) {
  if (x === null || x === undefined || !isFinite(x)) return '–';
  const a = Math.abs(x);
  if (a !== 0 && (a < 1e-3 || a >= 1e5)) return x.toExponential(2);
  return Number(x.toPrecision(digits)).toString();
}

function showError(pre, text) {
  pre.textContent = text;
  pre.hidden = !text;
}

// --------------------------------------------------------------- plots ----
// plot(canvas, {x, y, series}) draws axes and series onto a canvas.
// Series kinds: points {x[], y[], color}, line {x[], y[], color, dash},
// band {x[], lo[], hi[], color}, polygon {x[], y[], color}, rect {x0,x1,y0,y1},
// bars {x0[], x1[], h[], color}. The canvas gets data-points (scatter points
// drawn) and data-drawn="1" so tests can tell it drew.

const COLORS = { pts: 'rgba(31,111,235,0.35)', model: '#d1242f', band: 'rgba(209,36,47,0.15)', alt: '#137333', grey: '#6b7385' };

function niceTicks(lo, hi, n) {
  const span = hi - lo || Math.abs(hi) || 1;
  const step0 = span / n;
  const mag = Math.pow(10, Math.floor(Math.log10(step0)));
  const step = [1, 2, 2.5, 5, 10].map((m) => m * mag).find((s) => span / s <= n) || 10 * mag;
  const out = [];
  for (let t = Math.ceil(lo / step) * step; t <= hi + step * 1e-9; t += step) out.push(Math.abs(t) < step * 1e-9 ? 0 : t);
  return out;
}

function extent(values, pad) {
  let lo = Infinity, hi = -Infinity;
  for (const v of values) if (isFinite(v)) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
  if (!isFinite(lo)) return [0, 1];
  if (hi === lo) { const d = Math.abs(lo) * 0.1 || 1; return [lo - d, hi + d]; }
  const d = (hi - lo) * (pad === undefined ? 0.05 : pad);
  return [lo - d, hi + d];
}

function plot(canvas, spec) {
  const dpr = window.devicePixelRatio || 1;
  const W = canvas.clientWidth || canvas.width, H = canvas.clientHeight || canvas.height;
  canvas.width = W * dpr;
  canvas.height = H * dpr;
  const g = canvas.getContext('2d');
  g.setTransform(dpr, 0, 0, dpr, 0, 0);
  g.clearRect(0, 0, W, H);
  const m = { l: 56, r: 12, t: 10, b: 40 };
  const xs = [], ys = [];
  for (const s of spec.series) {
    if (s.kind === 'bars') { xs.push(...s.x0, ...s.x1); ys.push(0, ...s.h); continue; }
    if (s.kind === 'rect') { xs.push(s.x0, s.x1); ys.push(s.y0, s.y1); continue; }
    xs.push(...s.x);
    ys.push(...(s.y || []), ...(s.lo || []), ...(s.hi || []));
  }
  const [x0, x1] = spec.xr || extent(xs);
  const [y0, y1] = spec.yr || extent(ys);
  const px = (x) => m.l + ((x - x0) / (x1 - x0)) * (W - m.l - m.r);
  const py = (y) => H - m.b - ((y - y0) / (y1 - y0)) * (H - m.t - m.b);
  // axes and grid
  g.font = '11px system-ui, sans-serif';
  g.strokeStyle = '#e3e6ec';
  g.fillStyle = '#444';
  g.lineWidth = 1;
  g.textAlign = 'center';
  for (const t of niceTicks(x0, x1, 6)) {
    g.beginPath(); g.moveTo(px(t), m.t); g.lineTo(px(t), H - m.b); g.stroke();
    g.fillText(fmt(t), px(t), H - m.b + 14);
  }
  g.textAlign = 'right';
  for (const t of niceTicks(y0, y1, 5)) {
    g.beginPath(); g.moveTo(m.l, py(t)); g.lineTo(W - m.r, py(t)); g.stroke();
    g.fillText(fmt(t), m.l - 4, py(t) + 4);
  }
  g.strokeStyle = '#888';
  g.strokeRect(m.l, m.t, W - m.l - m.r, H - m.t - m.b);
  g.textAlign = 'center';
  g.fillText(spec.x, m.l + (W - m.l - m.r) / 2, H - 6);
  g.save(); g.translate(12, m.t + (H - m.t - m.b) / 2); g.rotate(-Math.PI / 2); g.fillText(spec.y, 0, 0); g.restore();
  // series, clipped to the plot area
  g.save();
  g.beginPath(); g.rect(m.l, m.t, W - m.l - m.r, H - m.t - m.b); g.clip();
  let points = 0;
  for (const s of spec.series) {
    g.setLineDash(s.dash || []);
    if (s.kind === 'points') {
      g.fillStyle = s.color || COLORS.pts;
      for (let i = 0; i < s.x.length; ++i) {
        if (!isFinite(s.x[i]) || !isFinite(s.y[i])) continue;
        g.fillRect(px(s.x[i]) - 1.5, py(s.y[i]) - 1.5, 3, 3);
        ++points;
      }
    } else if (s.kind === 'band') {
      g.fillStyle = s.color || COLORS.band;
      g.beginPath();
      s.x.forEach((x, i) => (i ? g.lineTo(px(x), py(s.hi[i])) : g.moveTo(px(x), py(s.hi[i]))));
      for (let i = s.x.length - 1; i >= 0; --i) g.lineTo(px(s.x[i]), py(s.lo[i]));
      g.closePath(); g.fill();
    } else if (s.kind === 'line' || s.kind === 'polygon') {
      g.strokeStyle = s.color || COLORS.model;
      g.lineWidth = s.width || 2;
      g.beginPath();
      s.x.forEach((x, i) => (i ? g.lineTo(px(x), py(s.y[i])) : g.moveTo(px(x), py(s.y[i]))));
      if (s.kind === 'polygon') { g.closePath(); g.fillStyle = s.fill || 'rgba(19,115,51,0.12)'; g.fill(); }
      g.stroke();
    } else if (s.kind === 'rect') {
      g.strokeStyle = s.color || COLORS.grey;
      g.lineWidth = 1.5;
      g.strokeRect(px(s.x0), py(s.y1), px(s.x1) - px(s.x0), py(s.y0) - py(s.y1));
    } else if (s.kind === 'bars') {
      g.fillStyle = s.color || 'rgba(31,111,235,0.5)';
      g.strokeStyle = '#fff';
      for (let i = 0; i < s.h.length; ++i) {
        const a = px(s.x0[i]), b = px(s.x1[i]);
        g.fillRect(a, py(s.h[i]), Math.max(1, b - a), py(0) - py(s.h[i]));
      }
    }
  }
  g.restore();
  g.setLineDash([]);
  // legend
  let ly = m.t + 14;
  g.textAlign = 'left';
  const labelled = spec.series.filter((s) => s.label).length;
  if (labelled) {
    g.fillStyle = 'rgba(255,255,255,0.85)';
    g.fillRect(spec.legend === 'left' ? m.l + 4 : W - m.r - 154, m.t + 2, 150, 14 * labelled + 4);
  }
  for (const s of spec.series) {
    if (!s.label) continue;
    const lx = spec.legend === 'left' ? m.l + 8 : W - m.r - 150;
    g.fillStyle = s.kind === 'points' ? '#1f6feb' : s.kind === 'band' ? 'rgba(209,36,47,0.3)' : (s.color || COLORS.model);
    g.fillRect(lx, ly - 8, 10, 10);
    g.fillStyle = '#333';
    g.fillText(s.label, lx + 15, ly + 1);
    ly += 14;
  }
  canvas.dataset.points = String(points);
  canvas.dataset.drawn = '1';
}

function clearPlot(canvas) {
  const g = canvas.getContext('2d');
  g.clearRect(0, 0, canvas.width, canvas.height);
  canvas.dataset.points = '0';
  canvas.dataset.drawn = '0';
}

function linspace(a, b, n) {
  const out = [];
  for (let i = 0; i < n; ++i) out.push(a + ((b - a) * i) / (n - 1));
  return out;
}

// ---------------------------------------------------------------- list ----

async function loadList() {
  try {
    const q = $('search').value.trim();
    const data = await getJson('/v1/materials' + (q ? '?q=' + enc(q) : ''));
    state.materials = data.materials;
    const body = $('materials').tBodies[0];
    body.replaceChildren();
    for (const m of data.materials) {
      const tr = row([m.id, m.name, m.latest_version === null ? 'none' : 'v' + m.latest_version, (m.tags || []).join(', ')]);
      tr.className = 'click';
      tr.dataset.id = m.id;
      tr.addEventListener('click', () => { location.hash = '#/m/' + enc(m.id); });
      body.appendChild(tr);
    }
    $('list-count').textContent = data.materials.length + ' material(s)';
  } catch (e) {
    $('list-count').textContent = 'cannot list materials: ' + e.message;
  }
}

async function registerMaterial(ev) {
  ev.preventDefault();
  const id = $('reg-id').value.trim();
  const body = { name: $('reg-name').value.trim() || id, description: $('reg-description').value.trim() };
  const tags = $('reg-tags').value.split(',').map((t) => t.trim()).filter(Boolean);
  if (tags.length) body.tags = tags;
  showError($('reg-error'), '');
  $('reg-submit').disabled = true;
  try {
    const r = await write('PUT', '/v1/materials/' + enc(id), JSON.stringify(body), 'application/json');
    if (!r.ok) { showError($('reg-error'), r.text); return; }
    $('register').reset();
    location.hash = '#/m/' + enc(id);
  } catch (e) {
    showError($('reg-error'), String(e));
  } finally {
    $('reg-submit').disabled = false;
  }
}

// ------------------------------------------------------------ material ----

function fillSelect(sel, values, current) {
  sel.replaceChildren();
  for (const v of values) {
    const o = el('option', v.label);
    o.value = v.value;
    if (String(v.value) === String(current)) o.selected = true;
    sel.appendChild(o);
  }
}

async function loadMaterial(id) {
  state.id = id;
  let m;
  try {
    m = await getJson('/v1/materials/' + enc(id));
  } catch (e) {
    $('m-title').textContent = id;
    $('m-description').textContent = '';
    showError($('upload-error'), e.message);
    return;
  }
  $('m-title').textContent = m.name && m.name !== m.id ? m.name + ' (' + m.id + ')' : m.id;
  $('m-description').textContent = [m.description, (m.tags || []).join(', ')].filter(Boolean).join(' · ');
  const tips = m.models.map((x) => x.fingertip);
  if (!tips.includes(state.fingertip)) state.fingertip = tips[0] || 'default';
  if (!tips.includes(state.fingertip)) tips.push(state.fingertip);
  fillSelect($('m-fingertip'), tips.map((t) => ({ value: t, label: t })), state.fingertip);
  await loadModel();
}

async function loadModel() {
  const id = state.id, tip = state.fingertip;
  const qs = '?fingertip=' + enc(tip);
  let versions = [];
  try {
    versions = (await getJson('/v1/materials/' + enc(id) + '/models' + qs)).versions;
  } catch (e) {
    versions = [];
  }
  const latest = versions.length ? versions[versions.length - 1].version : null;
  if (state.version === null || !versions.some((v) => v.version === state.version)) state.version = latest;
  fillSelect($('m-version'), versions.slice().reverse().map((v) => ({ value: v.version, label: 'v' + v.version + (v.version === latest ? ' (latest)' : '') })), state.version);
  await renderVersions(versions);
  const plots = ['plot-mu-fn', 'plot-mu-v', 'plot-eps', 'plot-slip', 'plot-hull'].map($);
  if (latest === null) {
    $('m-nomodel').hidden = false;
    $('m-summary').textContent = '';
    plots.forEach(clearPlot);
    return;
  }
  $('m-nomodel').hidden = true;
  const vq = qs + '&version=' + state.version;
  const base = '/v1/materials/' + enc(id);
  try {
    const [model, samples] = await Promise.all([getJson(base + '/model' + vq), getJson(base + '/samples' + vq + '&max=1500')]);
    await drawModel(base, vq, model, samples);
  } catch (e) {
    showError($('upload-error'), e.message);
  }
}

async function drawModel(base, vq, model, samples) {
  const st = model.stochastic;
  if (!st) { $('m-summary').textContent = 'version ' + model.version + ' has no stochastic model'; return; }
  const coef = Object.entries(st.coefficients).map(([k, v]) => k + ' ' + fmt(v, 4)).join(', ');
  $('m-summary').textContent = 'v' + model.version + ': ' + coef + '; sigma_eps ' + fmt(st.sigma_eps) + ', R² ' + fmt(st.r2) + ', ' + st.samples + ' slipping samples in ' + st.strokes + ' stroke(s)';
  const inputs = st.inputs || {};
  const fnR = extent(samples.fn_n, 0), vR = extent(samples.v_mm_s, 0);
  const fnMean = (inputs.fn_n && inputs.fn_n.mean) || (fnR[0] + fnR[1]) / 2;
  const vMean = (inputs.v_mm_s && inputs.v_mm_s.mean) || (vR[0] + vR[1]) / 2;
  const predict = (fn, v) => getJson(base + '/predict' + vq + '&fn_n=' + fn + '&v_mm_s=' + v);
  const fnGrid = linspace(Math.max(fnR[0], 1e-9), fnR[1], 21);
  const vGrid = linspace(Math.max(vR[0], 0), vR[1], 21);
  const [pf, pv] = await Promise.all([Promise.all(fnGrid.map((f) => predict(f, vMean))), Promise.all(vGrid.map((v) => predict(fnMean, v)))]);
  const line = (grid, p, label) => [
    { kind: 'band', x: grid, lo: p.map((q) => q.interval95[0]), hi: p.map((q) => q.interval95[1]), label: '95% band' },
    { kind: 'line', x: grid, y: p.map((q) => q.mu), label },
  ];
  plot($('plot-mu-fn'), { x: 'Fn [N]', y: 'mu', series: [{ kind: 'points', x: samples.fn_n, y: samples.mu, label: 'slipping samples' }, ...line(fnGrid, pf, 'model at v = ' + fmt(vMean) + ' mm/s')] });
  plot($('plot-mu-v'), { x: 'v [mm/s]', y: 'mu', series: [{ kind: 'points', x: samples.v_mm_s, y: samples.mu, label: 'slipping samples' }, ...line(vGrid, pv, 'model at Fn = ' + fmt(fnMean) + ' N')] });
  const others = Object.keys(inputs).filter((k) => k !== 'fn_n' && k !== 'v_mm_s');
  const shown = samples.returned + ' of ' + samples.slip_samples + ' samples' + (others.length ? '; model at mean ' + others.join(', ') : '');
  $('cap-mu-fn').textContent = shown;
  $('cap-mu-v').textContent = shown;
  drawEps(st);
  await drawSlip(base, vq, st, fnMean);
  drawHull(samples);
}

// eps density from the model's quantiles: between two quantile levels
// p_a < p_b at q_a, q_b the density is (p_b - p_a) / (q_b - q_a). A subset
// of the levels keeps the bars wide enough to read.
const EPS_LEVELS = [0.005, 0.01, 0.02, 0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.35, 0.4, 0.45, 0.5, 0.55, 0.6, 0.65, 0.7, 0.75, 0.8, 0.85, 0.9, 0.95, 0.98, 0.99, 0.995];

function epsAt(q, p) {
  const i = q.levels.findIndex((l) => Math.abs(l - p) < 1e-9);
  return i >= 0 ? q.values[i] : null;
}

function drawEps(st) {
  const q = st.eps_quantiles || { levels: [], values: [] };
  const pts = EPS_LEVELS.map((p) => [p, epsAt(q, p)]).filter(([, v]) => v !== null);
  const x0 = [], x1 = [], h = [];
  for (let k = 0; k + 1 < pts.length; ++k) {
    const w = pts[k + 1][1] - pts[k][1];
    if (!(w > 0)) continue;
    x0.push(pts[k][1]); x1.push(pts[k + 1][1]); h.push((pts[k + 1][0] - pts[k][0]) / w);
  }
  const series = [{ kind: 'bars', x0, x1, h, color: 'rgba(31,111,235,0.45)', label: 'from eps quantiles' }];
  const s = st.sigma_eps;
  if (s > 0 && x0.length) {
    const xs = linspace(Math.min(x0[0], -3 * s), Math.max(x1[x1.length - 1], 3 * s), 81);
    series.push({ kind: 'line', x: xs, y: xs.map((x) => Math.exp(-0.5 * (x / s) ** 2) / (s * Math.sqrt(2 * Math.PI))), color: COLORS.model, label: 'normal, sigma_eps' });
  }
  plot($('plot-eps'), { x: 'eps (mu - model)', y: 'density', series });
  const parts = [0.01, 0.05, 0.5, 0.95, 0.99].map((p) => (epsAt(q, p) !== null ? Math.round(p * 100) + '% ' + fmt(epsAt(q, p)) : null)).filter(Boolean);
  $('cap-eps').textContent = 'sigma ' + fmt(s) + (parts.length ? '; quantiles ' + parts.join(', ') : '');
}

async function drawSlip(base, vq, st, fnMean) {
  const muC = st.mu_coulomb;
  const hi = Math.max(1.6 * muC, ...(st.eps_quantiles ? [muC + 4 * (st.sigma_eps || 0)] : [0]), 0.1);
  const ratios = linspace(0, hi, 41);
  const L = await Promise.all(ratios.map((r) => getJson(base + '/slip-likelihood' + vq + '&fn_n=' + fnMean + '&ft_n=' + r * fnMean)));
  const stepX = [0, muC, muC, hi], stepY = [0, 0, 1, 1];
  plot($('plot-slip'), {
    x: 'Ft/Fn', y: 'P(slip)', yr: [-0.02, 1.05], legend: 'left',
    series: [
      { kind: 'line', x: stepX, y: stepY, color: COLORS.grey, dash: [5, 4], label: 'Coulomb, mu = ' + fmt(muC) },
      { kind: 'line', x: ratios, y: L.map((l) => l.likelihood), color: COLORS.model, label: 'L(Ft/Fn), ' + (L[0] ? L[0].method : '') },
    ],
  });
  $('cap-slip').textContent = 'at Fn = ' + fmt(fnMean) + ' N';
}

function drawHull(samples) {
  const c = samples.coverage, h = samples.hull;
  const series = [
    { kind: 'rect', x0: c.plan.fn_n[0], x1: c.plan.fn_n[1], y0: c.plan.v_mm_s[0], y1: c.plan.v_mm_s[1], color: COLORS.grey, label: 'requested span' },
    { kind: 'points', x: samples.fn_n, y: samples.v_mm_s, label: 'slipping samples' },
  ];
  if (h.fn_n.length >= 3) series.push({ kind: 'polygon', x: h.fn_n, y: h.v_mm_s, color: COLORS.alt, label: 'hull' });
  plot($('plot-hull'), { x: 'Fn [N]', y: 'v [mm/s]', series });
  $('cap-hull').textContent = fmt(c.span_pct) + ' % of the requested span (enough at ' + fmt(c.min_span_pct) + ' %)';
}

async function renderVersions(versions) {
  const body = $('versions').tBodies[0];
  body.replaceChildren();
  const base = '/v1/materials/' + enc(state.id);
  // Diagnosis findings stored with a version (reason "diagnosis").
  const notes = await Promise.all(versions.map(async (v) => {
    if (v.reason !== 'diagnosis') return '';
    try {
      const m = await getJson(base + '/model?fingertip=' + enc(state.fingertip) + '&version=' + v.version);
      const d = m.diagnosis;
      if (!d) return '';
      return d.extended + ' (causes: ' + (d.causes || []).join(', ') + '; CV MAE ' + fmt(d.baseline_cv_mae) + ' → ' + fmt(d.extended_cv_mae) + ', gain ' + fmt(d.gain_pct) + ' %)';
    } catch (e) {
      return '';
    }
  }));
  versions.slice().reverse().forEach((v) => {
    const i = versions.indexOf(v);
    const tr = row(['v' + v.version, v.created_at, v.reason, v.stroke_id || '', notes[i]]);
    tr.className = 'click';
    tr.addEventListener('click', () => { state.version = v.version; loadModel(); });
    body.appendChild(tr);
  });
}

async function runDiagnosis() {
  const store = $('diagnose-store').checked ? 1 : 0;
  $('run-diagnose').disabled = true;
  $('diagnose-status').textContent = 'diagnosing…';
  showError($('diagnose-error'), '');
  try {
    const r = await write('POST', '/v1/materials/' + enc(state.id) + '/diagnose?fingertip=' + enc(state.fingertip) + '&store=' + store);
    if (!r.ok) { showError($('diagnose-error'), r.text); $('diagnose-status').textContent = ''; return; }
    const out = JSON.parse(r.text);
    const d = out.diagnosis;
    const body = $('findings').tBodies[0];
    body.replaceChildren();
    for (const f of d.findings || []) body.appendChild(row([f.cause, f.kind, fmt(f.p_value), fmt(f.cv_mae_gain_pct), f.effect || '']));
    $('findings').hidden = !(d.findings || []).length;
    $('diagnose-status').textContent = 'v' + out.diagnosed_version + ': baseline ' + d.baseline.model + ' CV MAE ' + fmt(d.baseline.cv_mae) + '; ' +
      ((d.findings || []).length ? d.findings.length + ' finding(s)' : 'no significant finding') +
      (out.stored_version ? '; stored as v' + out.stored_version : '');
    if (out.stored_version) { state.version = out.stored_version; await loadModel(); }
  } catch (e) {
    showError($('diagnose-error'), String(e));
  } finally {
    $('run-diagnose').disabled = false;
  }
}

async function uploadFile(kind) {
  const input = kind === 'csv' ? $('csv-file') : $('image-file');
  const file = input.files[0];
  showError($('upload-error'), '');
  if (!file) { showError($('upload-error'), 'choose a file first'); return; }
  const id = state.id, tip = state.fingertip;
  const path = kind === 'csv' ? '/v1/materials/' + enc(id) + '/strokes?fingertip=' + enc(tip) : '/v1/materials/' + enc(id) + '/images';
  const type = kind === 'csv' ? 'text/csv' : file.type || 'application/octet-stream';
  const bar = $('upload-progress');
  bar.value = 0;
  $('upload-status').textContent = 'uploading ' + file.name + ' (' + file.size + ' bytes)…';
  $('upload-csv').disabled = $('upload-image').disabled = true;
  const r = await upload(path, file, type, (f) => { bar.value = Math.round(100 * f); });
  $('upload-csv').disabled = $('upload-image').disabled = false;
  if (!r.ok) {
    $('upload-status').textContent = file.name + ': rejected (HTTP ' + r.status + ')';
    showError($('upload-error'), r.text); // the server's error JSON, verbatim
    return;
  }
  bar.value = 100;
  let out = {};
  try { out = JSON.parse(r.text); } catch (e) { /* keep {} */ }
  $('upload-status').textContent = file.name + ': ' + (kind === 'csv' ? 'stored as model v' + out.version + ' (' + out.samples + ' samples, fit ' + out.fit_status + ')' : 'reference image stored');
  input.value = '';
  if (kind === 'csv') { state.version = out.version || null; await loadMaterial(id); }
}

// ---------------------------------------------------------- recognition ----

// POST /v1/recognize: the verdict with its reason, and the candidates with
// their calibrated scores (docs/recognition.md). Unsure answers say so.
async function recognizePhoto() {
  const file = $('recognize-file').files[0];
  showError($('recognize-error'), '');
  $('recognize-verdict').hidden = true;
  $('recognize-candidates').hidden = true;
  if (!file) { showError($('recognize-error'), 'choose a photo first'); return; }
  $('recognize-status').textContent = 'recognising ' + file.name + '…';
  $('recognize-run').disabled = true;
  const r = await upload('/v1/recognize', file, file.type || 'application/octet-stream', () => {});
  $('recognize-run').disabled = false;
  if (!r.ok) {
    $('recognize-status').textContent = file.name + ': rejected (HTTP ' + r.status + ')';
    showError($('recognize-error'), r.text);
    return;
  }
  let out = {};
  try { out = JSON.parse(r.text); } catch (e) { showError($('recognize-error'), r.text); return; }
  $('recognize-status').textContent = file.name;
  const v = $('recognize-verdict');
  const best = (out.candidates || [])[0];
  v.textContent = (out.unknown ? 'Unknown material: ' : 'Recognised ' + (best ? best.material : '') + ': ') +
    (out.reason || '') + (out.operating_point !== undefined ? ' (operating point ' + fmt(out.operating_point, 2) + ')' : '');
  v.className = out.unknown ? 'notice' : 'muted';
  v.hidden = false;
  const body = $('recognize-candidates').tBodies[0];
  body.replaceChildren();
  for (const c of out.candidates || []) {
    const a = el('a', c.material);
    a.href = '#/m/' + enc(c.material);
    const td = el('td');
    td.appendChild(a);
    body.appendChild(row([td, fmt(c.score, 2), fmt(c.similarity, 3)]));
  }
  $('recognize-candidates').hidden = !(out.candidates || []).length;
}

// ---------------------------------------------------------------- jobs ----

async function pollJobs() {
  try {
    const open = $('jobs-open').checked ? '?open=1' : '';
    const data = await getJson('/v1/identifications' + open);
    const body = $('jobs').tBodies[0];
    body.replaceChildren();
    for (const j of data.identifications.slice().reverse()) {
      const st = el('td', j.state, 'state-' + j.state);
      body.appendChild(row([j.id, j.material, j.fingertip, st, j.detail, j.requested_by, j.updated_at]));
    }
    $('jobs-updated').textContent = data.identifications.length + ' job(s), updated ' + new Date().toLocaleTimeString();
  } catch (e) {
    $('jobs-updated').textContent = 'cannot poll jobs: ' + e.message;
  }
}

// -------------------------------------------------------------- routing ----

function route() {
  const h = location.hash || '#/';
  const m = h.match(/^#\/m\/(.+)$/);
  $('view-list').hidden = !!m;
  $('view-material').hidden = !m;
  if (m) {
    const id = decodeURIComponent(m[1]);
    if (id !== state.id) {
      state.version = null;
      showError($('upload-error'), '');
      $('upload-status').textContent = '';
      $('upload-progress').value = 0;
    }
    loadMaterial(id);
  } else {
    state.id = null;
    loadList();
  }
}

async function health() {
  try {
    const h = await getJson('/healthz');
    $('health').textContent = h.status + ' · ' + h.backend;
  } catch (e) {
    $('health').textContent = 'daemon unreachable';
  }
}

function init() {
  const tok = $('token');
  tok.value = localStorage.getItem(TOKEN_KEY) || '';
  tok.addEventListener('input', () => localStorage.setItem(TOKEN_KEY, tok.value));
  let searchTimer = null;
  $('search').addEventListener('input', () => { clearTimeout(searchTimer); searchTimer = setTimeout(loadList, 200); });
  $('register').addEventListener('submit', registerMaterial);
  $('upload-csv').addEventListener('click', () => uploadFile('csv'));
  $('upload-image').addEventListener('click', () => uploadFile('image'));
  $('run-diagnose').addEventListener('click', runDiagnosis);
  $('recognize-run').addEventListener('click', recognizePhoto);
  $('m-fingertip').addEventListener('change', (e) => { state.fingertip = e.target.value; state.version = null; loadModel(); });
  $('m-version').addEventListener('change', (e) => { state.version = Number(e.target.value); loadModel(); });
  $('jobs-open').addEventListener('change', pollJobs);
  window.addEventListener('hashchange', route);
  health();
  route();
  pollJobs();
  state.jobsTimer = setInterval(pollJobs, 2000);
}

document.addEventListener('DOMContentLoaded', init);
