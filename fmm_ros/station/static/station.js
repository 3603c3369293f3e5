// The station page: one EventSource (/events) keeps it in step with the station node; every
// figure is a uPlot chart (vendored, no CDN). All text from the rig goes in as textContent,
// never as markup. State is what the last snapshot and the events since said; a reconnect
// (the station or a source restarted) starts again from a fresh snapshot.
'use strict';

const MU_POINTS = 1000;  // running-mu history kept on the page
const PLOT_HEIGHT = 200;

const page = {
  config: null,
  hits: new Map(),       // id -> row
  figures: new Map(),    // id -> figure data
  levels: new Map(),     // level name -> average
  diagnostics: new Map(),
  muHistory: [[], [], [], []],  // estimate number, mu, mu - 2 se, mu + 2 se
  muCount: 0,
  selected: null,        // id of the hit shown
  hitSeen: {},           // id -> when the page first had the hit (ms since the epoch)
  recorderSeen: 0,
};
window.stationPage = page;  // tests read which hits the page holds

const $ = (id) => document.getElementById(id);

function width(el) { return Math.max(300, el.clientWidth || 520); }

function chart(id, title, series, scales, extra) {
  const el = $(id);
  const opts = Object.assign({
    title: title, width: width(el), height: PLOT_HEIGHT,
    scales: scales || { x: { time: false } },
    series: [{}].concat(series),
    axes: [{}, {}],
  }, extra || {});
  return new uPlot(opts, Array.from({ length: series.length + 1 }, () => []), el);
}

const charts = {
  streams: chart('streams', 'force [N] and velocity [mm/s] against time [s]', [
    { label: 'force [N]', stroke: '#c62828', scale: 'force' },
    { label: 'velocity [mm/s]', stroke: '#1565c0', scale: 'velocity' },
  ], { x: { time: false }, force: {}, velocity: {} }, {
    axes: [{}, { scale: 'force', label: 'N' }, { scale: 'velocity', side: 1, label: 'mm/s' }],
  }),
  pulse: chart('pulse', 'pulse: force [N] against time from trigger [ms]', [
    { label: 'force [N]', stroke: '#c62828' },
  ]),
  decay: chart('decay', 'decay: velocity [mm/s] against time from trigger [s]', [
    { label: 'measured', stroke: '#1565c0' },
    { label: 'model', stroke: '#ef6c00', dash: [6, 4] },
  ]),
  magnitude: chart('frf-magnitude', '|mobility| [mm/(N·s)] against frequency [Hz]', [
    { label: '|mobility|', stroke: '#1565c0' },
  ], { x: { time: false }, y: { distr: 3 } }),
  phase: chart('frf-phase', 'phase of mobility [°] against frequency [Hz]', [
    { label: 'phase [°]', stroke: '#6a1b9a' },
  ]),
  coherence: chart('coherence', 'coherence γ² against frequency [Hz], per level', [],
    { x: { time: false }, y: { range: [0, 1.05] } }),
  mu: chart('mu-history', 'running μ with its ±2σ band, per estimate', [
    { label: 'μ', stroke: '#2e7d32' },
    { label: 'μ − 2σ', stroke: '#a5d6a7' },
    { label: 'μ + 2σ', stroke: '#a5d6a7' },
  ], null, { axes: [{}, { values: (u, splits) => spanTicks(u, splits), size: 80 }] }),
};

function show(message, isError) {
  const banner = $('banner');
  banner.textContent = message;
  banner.className = isError ? 'error' : 'info';
  banner.hidden = !message;
}

function fmt(value, digits) {
  return value === null || value === undefined ? '–' : Number(value).toFixed(digits);
}

// A value with its uncertainty, as fmm_ros.core.results_schema.format_with_uncertainty: the
// value to the second significant digit of the uncertainty, both with those decimals.
function withUncertainty(value, std) {
  if (value === null || value === undefined) return '–';
  if (!(Number.isFinite(value) && Number.isFinite(std) && std > 0)) return String(Number(Number(value).toPrecision(5)));
  const decimals = Math.min(12, Math.max(0, 1 - Math.floor(Math.log10(std))));
  return `${value.toFixed(decimals)} ± ${std.toFixed(decimals)}`;
}

// Axis ticks with as many decimals as their step needs, so a span of 1e-6 around 0.113 does
// not read 0.113 at every tick.
function spanTicks(u, splits) {
  if (splits.length < 2) return splits.map((v) => String(v));
  const step = Math.abs(splits[1] - splits[0]) || Math.abs(splits[0]) || 1;
  let decimals = Math.max(0, Math.ceil(-Math.log10(step) - 1e-9));
  const exact = (d) => splits.every((v) => Math.abs(Number(v.toFixed(d)) - v) <= step * 1e-6);
  while (decimals < 12 && !exact(decimals)) decimals += 1;
  return splits.map((v) => v.toFixed(decimals));
}

function cell(tr, text, cls) {
  const td = document.createElement('td');
  td.textContent = text;
  if (cls) td.className = cls;
  tr.appendChild(td);
  return td;
}

// -- hits ----------------------------------------------------------------------------------

function renderHit(row) {
  if (!(row.id in page.hitSeen)) {
    page.hitSeen[row.id] = Date.now();
    const seen = Object.keys(page.hitSeen);
    if (seen.length > 1000) delete page.hitSeen[seen[0]];
  }
  page.hits.set(row.id, row);
  const body = $('hits').tBodies[0];
  let tr = body.querySelector(`tr[data-id="${row.id}"]`);
  if (!tr) {
    tr = document.createElement('tr');
    tr.dataset.id = row.id;
    tr.addEventListener('click', () => select(row.id));
    body.insertBefore(tr, body.firstChild);
    while (body.rows.length > 500) body.deleteRow(body.rows.length - 1);
  }
  tr.replaceChildren();
  tr.className = (row.taken ? 'taken' : 'rejected') + (page.selected === row.id ? ' selected' : '');
  tr.dataset.taken = row.taken ? 'yes' : 'no';
  cell(tr, String(row.id));
  cell(tr, row.level || 'no level', 'text');
  cell(tr, fmt(row.peak_force_n, 0));
  cell(tr, fmt(row.impulse_n_s, 3));
  cell(tr, row.flags.join(', ') || 'none', 'text');
  const d = row.decision;
  cell(tr, d ? `${d.verdict} by ${d.decided_by}${d.reason ? ': ' + d.reason : ''}` : 'flags', 'text decision');
  cell(tr, row.taken ? 'yes' : 'no', 'text taken');
  const buttons = cell(tr, '', 'text');
  for (const verdict of ['accept', 'reject']) {
    const button = document.createElement('button');
    button.textContent = verdict;
    button.className = verdict;
    button.addEventListener('click', (event) => { event.stopPropagation(); judge(row.id, verdict); });
    buttons.appendChild(button);
  }
}

async function post(path, body) {
  const response = await fetch(path, {
    method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify(body),
  });
  const answer = await response.json();
  if (!response.ok || !answer.ok) throw new Error(answer.message || response.statusText);
  return answer.message;
}

async function judge(id, verdict) {
  try {
    show(await post('api/judge', {
      impact_id: id, verdict: verdict,
      decided_by: $('operator').value.trim(), reason: $('reason').value.trim(),
    }), false);
  } catch (error) {
    show(`not saved: ${error.message}`, true);
  }
}

function select(id) {
  page.selected = id;
  for (const tr of $('hits').tBodies[0].rows) {
    tr.classList.toggle('selected', Number(tr.dataset.id) === id);
  }
  drawFigure(page.figures.get(id));
}

function drawFigure(figure) {
  if (!figure) return;
  const row = page.hits.get(figure.id);
  $('hit-title').textContent = `${figure.id}` + (row ? ` (${row.level || 'no level'}, peak ${fmt(row.peak_force_n, 0)} N)` : '');
  charts.magnitude.setData([figure.frf.f, figure.frf.magnitude]);
  charts.phase.setData([figure.frf.f, figure.frf.phase_deg]);
  if (figure.pulse) charts.pulse.setData([figure.pulse.t, figure.pulse.force]);
  if (figure.decay) {
    const model = figure.decay.model || figure.decay.t.map(() => null);
    charts.decay.setData([figure.decay.t, figure.decay.velocity, model]);
  }
}

function onFigure(figure) {
  page.figures.set(figure.id, figure);
  while (page.figures.size > 12) page.figures.delete(page.figures.keys().next().value);
  const newest = Math.max(...page.figures.keys());
  if (page.selected === null || page.selected < newest && figure.id === newest) select(figure.id);
  else if (figure.id === page.selected) drawFigure(figure);
}

// -- levels, progress, friction ------------------------------------------------------------

const LEVEL_COLOURS = ['#1565c0', '#2e7d32', '#c62828', '#6a1b9a', '#ef6c00'];

function onLevel(level) {
  page.levels.set(level.name, level);
  const names = [...page.levels.keys()];
  const wanted = names.length;
  if (charts.coherence.series.length - 1 !== wanted) {
    while (charts.coherence.series.length > 1) charts.coherence.delSeries(1);
    names.forEach((name, k) => charts.coherence.addSeries(
      { label: name, stroke: LEVEL_COLOURS[k % LEVEL_COLOURS.length] }, k + 1));
  }
  const first = page.levels.get(names[0]);
  charts.coherence.setData([first.f, ...names.map((n) => {
    const lv = page.levels.get(n);
    return lv.f.length === first.f.length ? lv.coherence : first.f.map(() => null);
  })]);
  const single = names.filter((n) => page.levels.get(n).count < 2);
  $('coherence-note').textContent = single.length
    ? `coherence needs two hits of a level: ${single.join(', ')} has one (drawn as a flat 1)` : '';
}

function onProgress(progress) {
  const body = $('progress').tBodies[0];
  body.replaceChildren();
  for (const lv of progress.levels) {
    const tr = document.createElement('tr');
    tr.dataset.level = lv.name;
    cell(tr, lv.name + (progress.aim === lv.name ? ' ◀ now' : ''), 'text');
    cell(tr, `${lv.taken} / ${lv.target}`);
    cell(tr, `${lv.peak_force_n} ± ${lv.tolerance_n} N`);
    body.appendChild(tr);
  }
  const advice = $('advice');
  if (progress.last_id === null) { advice.textContent = ''; return; }
  advice.textContent = `last hit ${progress.last_id}: peak ${fmt(progress.last_peak_force_n, 0)} N` +
    (progress.aim ? ` for ${progress.aim}: ${progress.advice}` : ': every level complete');
  advice.className = 'advice-' + (progress.advice || 'on').split(' ')[0];
}

function onFriction(friction) {
  if (!friction || friction.mu === null) {
    $('mu').textContent = friction ? `μ: no impact left in the estimate (impact ${friction.impact_id} taken out)` : 'μ: no estimate yet';
    return;
  }
  $('mu').textContent = `μ = ${withUncertainty(friction.mu, 2 * friction.mu_stderr)} (2σ) over ` +
    `${friction.count} hits; one μ for all: p = ${fmt(friction.p_value, 3)}; ids ${friction.impact_ids.join(', ')}`;
  $('mu').dataset.ids = friction.impact_ids.join(',');
  page.muCount += 1;
  const h = page.muHistory;
  h[0].push(page.muCount); h[1].push(friction.mu);
  h[2].push(friction.mu - 2 * friction.mu_stderr); h[3].push(friction.mu + 2 * friction.mu_stderr);
  if (h[0].length > MU_POINTS) h.forEach((a) => a.shift());
  charts.mu.setData(h);
  const body = $('mu-levels').tBodies[0];
  body.replaceChildren();
  for (const lv of friction.levels) {
    const tr = document.createElement('tr');
    cell(tr, lv.name, 'text');
    cell(tr, String(lv.count));
    cell(tr, withUncertainty(lv.mu, lv.mu_stderr));
    body.appendChild(tr);
  }
}

// -- health, streams, session --------------------------------------------------------------

function onDiagnostics(rows) {
  for (const row of rows) page.diagnostics.set(row.name, row);
  const body = $('diagnostics').tBodies[0];
  body.replaceChildren();
  for (const row of [...page.diagnostics.values()].sort((a, b) => a.name.localeCompare(b.name))) {
    const tr = document.createElement('tr');
    tr.className = 'level-' + row.level;
    cell(tr, row.name, 'text');
    cell(tr, row.level, 'text');
    cell(tr, row.message, 'text');
    body.appendChild(tr);
    if (row.name.endsWith(': recorder')) {
      page.recorderSeen = Date.now();
      $('recording').textContent = 'recording: ' + row.message;
      $('recording').className = 'state on';
    }
  }
}

function checkRecording() {
  if (page.recorderSeen && Date.now() - page.recorderSeen > 3000) {
    $('recording').textContent = 'recording: no recorder heard for 3 s';
    $('recording').className = 'state off';
  } else if (!page.recorderSeen) {
    $('recording').textContent = 'recording: no recorder';
    $('recording').className = 'state off';
  }
}

function onStream(stream) {
  if (stream) charts.streams.setData([stream.t, stream.force, stream.velocity]);
}

function buildSessionForm(fields, values) {
  const form = $('session-form');
  form.replaceChildren();
  for (const field of fields) {
    const label = document.createElement('label');
    label.textContent = field.label + (field.unit ? ` [${field.unit}] ` : ' ');
    const input = document.createElement(field.name === 'notes' ? 'textarea' : 'input');
    input.name = field.name;
    if (field.numeric) input.inputMode = 'decimal';
    const value = values ? values[field.name] : null;
    input.value = value === null || value === undefined ? '' : String(value);
    label.appendChild(input);
    form.appendChild(label);
  }
  const save = document.createElement('button');
  save.type = 'submit';
  save.textContent = 'save session metadata';
  form.appendChild(save);
}

$('session-form').addEventListener('submit', async (event) => {
  event.preventDefault();
  const body = {};
  for (const input of $('session-form').querySelectorAll('input, textarea')) body[input.name] = input.value;
  try {
    $('session-saved').textContent = await post('api/session', body);
    show('', false);
  } catch (error) {
    show(`session metadata not saved: ${error.message}`, true);
  }
});

// -- the event stream ----------------------------------------------------------------------

function onSnapshot(snapshot) {
  page.config = snapshot.config;
  for (const th of document.querySelectorAll('th[data-key]')) {  // the schema's labels
    const label = (snapshot.config.columns || {})[th.dataset.key];
    if (label) th.textContent = label;
  }
  $('mode').textContent = `judging: ${snapshot.config.mode}`;
  page.hits.clear();
  $('hits').tBodies[0].replaceChildren();
  snapshot.hits.forEach(renderHit);
  page.figures.clear();
  page.selected = null;
  snapshot.figures.forEach(onFigure);
  snapshot.levels.forEach(onLevel);
  onProgress(snapshot.progress);
  onFriction(snapshot.friction);
  page.diagnostics.clear();
  onDiagnostics(snapshot.diagnostics);
  onStream(snapshot.stream);
  buildSessionForm(snapshot.config.session_fields, snapshot.session);
}

function connect() {
  const source = new EventSource('events');
  const handlers = {
    snapshot: onSnapshot, hit: renderHit, figure: onFigure, level: onLevel,
    progress: onProgress, friction: onFriction, stream: onStream, session: () => {},
    diagnostics: (data) => onDiagnostics(data.rows),
  };
  for (const [name, handler] of Object.entries(handlers)) {
    source.addEventListener(name, (event) => handler(JSON.parse(event.data)));
  }
  source.onopen = () => { $('connection').textContent = 'live'; $('connection').className = 'state live'; };
  source.onerror = () => { $('connection').textContent = 'reconnecting'; $('connection').className = 'state lost'; };
}

$('operator').value = localStorage.getItem('fmm-operator') || '';
$('operator').addEventListener('change', () => localStorage.setItem('fmm-operator', $('operator').value));
setInterval(checkRecording, 1000);
connect();
