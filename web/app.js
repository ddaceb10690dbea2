// The try-on page: pick a garment, enter measurements, watch it drape live, read the fit.
//
// Modules: scene.js (three.js stage), api.js (REST + WebSocket), controls.js (form fields),
// fitmap.js (strain colours). State for tests and debugging is on `window.tryon`.
import { Stage } from './scene.js';
import { ApiError, flatMesh, getJSON, liveTryOn, postJSON, saveBlob } from './api.js';
import { MeasurementForm, normaliseRanges } from './controls.js';
import { smoothStrain, strainScale } from './fitmap.js';
import { DEFAULT_STRAIN_LIMIT, metricRows } from './metrics.js';

const $ = (id) => document.getElementById(id);
const BODY_PREVIEW_DELAY_MS = 350;  // debounce: rebuild the body when the sliders rest this long

const state = {
  framesReceived: 0,
  state: 'loading',     // loading | ready | draping | done | error
  garments: [],
  garmentId: null,
  init: null,
  done: null,
  lastError: null,
  lastStep: 0,
  bodyRequests: 0,
};
window.tryon = state;

const stage = new Stage($('viewport'));
state.stage = stage;
let form = null;
let live = null;
let bodyTimer = null;
let bodySeq = 0;

// ---- notices ----------------------------------------------------------------------------------
function showError(error) {
  const message = error instanceof ApiError || error instanceof Error ? error.message : String(error);
  state.lastError = message;
  $('notice').classList.remove('info');
  $('notice-text').textContent = message;
  $('notice').hidden = false;
  $('notice').scrollIntoView({ block: 'nearest' });  // the controls may be scrolled past it
}
function clearNotice() { $('notice').hidden = true; }
$('notice-close').addEventListener('click', clearNotice);

// ---- catalogue ----------------------------------------------------------------------------------
const CATEGORY_ICONS = {
  top: '<path d="M8 3 3 6l2 5 2-1v11h10V10l2 1 2-5-5-3c-1 1.5-2.3 2-4 2S9 4.5 8 3z"/>',
  bottom: '<path d="M6 3h12l1 18h-5l-2-11-2 11H5z"/>',
  dress: '<path d="M9 2h6l-1 5 5 14H5l5-14z"/>',
};
const CATEGORY_COLORS = { top: '#b5523b', bottom: '#3f5f8a', dress: '#7a4f7f' };

/** Entries that differ only by size ("T-shirt S", "T-shirt M") become one row with size chips. */
function groupGarments(list) {
  const groups = new Map();
  for (const g of list) {
    const base = g.size && g.name.endsWith(` ${g.size}`) ? g.name.slice(0, -g.size.length - 1) : g.name;
    const key = `${g.category}|${base}`;
    if (!groups.has(key)) groups.set(key, { name: base, category: g.category, entries: [] });
    groups.get(key).entries.push(g);
  }
  const order = ['XXS', 'XS', 'S', 'M', 'L', 'XL', 'XXL', 'XXXL'];
  const rank = (size) => { const i = order.indexOf(String(size).toUpperCase()); return i < 0 ? 99 : i; };
  for (const group of groups.values()) group.entries.sort((a, b) => rank(a.size) - rank(b.size));
  return [...groups.values()];
}

function renderGarments(list) {
  const box = $('garments');
  box.replaceChildren();
  if (!list.length) {
    const p = document.createElement('p');
    p.className = 'muted';
    p.textContent = 'The catalogue is empty: add garments with `tryon ingest` first.';
    box.append(p);
    return;
  }
  for (const group of groupGarments(list)) {
    const row = document.createElement('div');
    row.className = 'garment';
    row.dataset.ids = group.entries.map((g) => g.id).join(' ');
    const color = CATEGORY_COLORS[group.category] || '#8a6f5a';
    const swatch = document.createElement('span');
    swatch.className = 'swatch';
    swatch.style.background = `${color}22`;
    swatch.innerHTML = `<svg viewBox="0 0 24 24" fill="${color}" aria-hidden="true">${CATEGORY_ICONS[group.category] || CATEGORY_ICONS.top}</svg>`;
    const text = document.createElement('span');
    text.className = 'text';
    const name = document.createElement('span');
    name.className = 'name';
    // non-breaking hyphens: "T-shirt" wraps as a whole, never as "T-" / "shirt"
    name.textContent = group.name.replace(/-/g, '\u2011');
    const sub = document.createElement('span');
    sub.className = 'sub';
    sub.textContent = group.category;
    text.append(name, ' ', sub);
    const sizes = document.createElement('span');
    sizes.className = 'sizes';
    for (const g of group.entries) {
      const chip = document.createElement('button');
      chip.type = 'button';
      chip.className = 'size';
      chip.setAttribute('role', 'radio');
      chip.setAttribute('aria-checked', 'false');
      chip.dataset.id = g.id;
      chip.textContent = g.size || 'one size';
      chip.title = `${g.name}: ${Number(g.vertices).toLocaleString()} vertices, ${Number(g.coarse_vertices).toLocaleString()} simulated`;
      chip.setAttribute('aria-label', `${group.name}, size ${g.size || 'one size'}`);
      chip.addEventListener('click', (e) => { e.stopPropagation(); selectGarment(g.id); });
      sizes.append(chip);
    }
    row.append(swatch, text, sizes);
    // Clicking the row keeps the chosen size of this garment, else takes the middle one.
    row.addEventListener('click', () => {
      if (group.entries.some((g) => g.id === state.garmentId)) return;
      selectGarment(group.entries[Math.floor((group.entries.length - 1) / 2)].id);
    });
    box.append(row);
  }
}

function selectGarment(id) {
  state.garmentId = id;
  for (const row of $('garments').querySelectorAll('.garment')) {
    row.classList.toggle('selected', row.dataset.ids.split(' ').includes(id));
  }
  for (const chip of $('garments').querySelectorAll('.size')) chip.setAttribute('aria-checked', String(chip.dataset.id === id));
  updateTryOnButton();
}

function updateTryOnButton() {
  const button = $('tryon-button');
  if (state.state === 'draping') {
    button.textContent = 'Stop';
    button.disabled = false;
    return;
  }
  button.textContent = 'Try on';
  button.disabled = !state.garmentId || !form || !form.valid();
}

// ---- body preview ---------------------------------------------------------------------------------
function scheduleBody() {
  clearTimeout(bodyTimer);
  if (state.state === 'draping') live?.cancel();  // that drape is for the old measurements
  updateTryOnButton();
  if (!form.valid()) return;
  bodyTimer = setTimeout(refreshBody, BODY_PREVIEW_DELAY_MS);
}

async function refreshBody() {
  const seq = ++bodySeq;
  $('body-status').textContent = 'Updating the body…';
  try {
    const response = await postJSON('/api/bodies?format=json', form.bodyRequest());
    const body = await response.json();
    if (seq !== bodySeq) return;  // a newer request is on its way
    state.bodyRequests++;
    const mesh = flatMesh(body.mesh ?? body);
    stage.setBody(mesh.vertices, mesh.faces);
    form.showAchieved(body.measurements?.estimated || body.achieved || {});
    $('body-status').textContent = describeBody(body);
    if (state.state === 'done') {  // the fitted garment belongs to the previous body
      stage.clearGarment();
      $('result').hidden = true;
      $('legend').hidden = true;
      $('progress').hidden = true;
      state.state = 'ready';
    }
  } catch (error) {
    if (seq !== bodySeq) return;
    $('body-status').textContent = '';
    showError(error);
  }
}

function describeBody(body) {
  const a = body.measurements?.achieved || body.achieved || {};
  const parts = ['chest', 'waist', 'hips'].filter((k) => Number.isFinite(a[k])).map((k) => `${k} ${a[k].toFixed(1)}`);
  let text = parts.length ? `Your body as built: ${parts.join(' · ')} cm` : '';
  // an arm angle too low for the arm to clear the torso is raised to where the arm rests against it
  const asked = body.pose?.requested?.arm_angle;
  const built = body.pose?.achieved?.arm_angle;
  if (Number.isFinite(asked) && Number.isFinite(built) && built > asked + 0.05) {
    text += `${text ? '. ' : ''}Arms at ${built.toFixed(1)}°: lower, they would pass into the torso`;
  }
  return text;
}

// ---- try-on ------------------------------------------------------------------------------------
function setProgress(fraction, text) {
  $('progress').hidden = false;
  $('progress-bar').style.width = `${Math.round(Math.min(Math.max(fraction, 0), 1) * 100)}%`;
  $('progress-text').textContent = text;
}

async function tryOn() {
  if (state.state === 'draping') { live?.cancel(); return; }
  clearNotice();
  // uint16 frames: half the bytes of float32, 0.04 mm steps (far below what a screen shows)
  const payload = { ...form.tryOnRequest(state.garmentId), fps: 30, encoding: 'uint16' };
  state.state = 'draping';
  state.framesReceived = 0;
  state.done = null;
  state.init = null;
  state.lastStep = 0;
  $('result').hidden = true;
  $('legend').hidden = true;
  updateTryOnButton();
  setProgress(0, 'Waiting for the fitting room…');
  const started = performance.now();
  live = liveTryOn(payload, {
    onInit(init) {
      state.init = init;
      if (init.body) {
        const body = flatMesh(init.body);
        stage.setBody(body.vertices, body.faces);
      }
      stage.startGarment(init.vertex_count, flatMesh({ vertices: [], faces: init.faces }).faces, init.garment?.category);
      setProgress(0.02, 'Dressing…');
    },
    onFrame(frameNo, step, positions) {
      state.framesReceived++;
      state.lastStep = step;
      stage.updateGarment(positions);
      const maxSteps = state.init?.max_steps || 0;
      const seconds = ((performance.now() - started) / 1000).toFixed(1);
      setProgress(maxSteps ? step / maxSteps : 0.5, `Draping… step ${step}${maxSteps ? ` of at most ${maxSteps}` : ''} · ${seconds} s`);
    },
  });
  try {
    const done = await live.promise;
    state.done = done;
    if (done.strain?.length) {
      const strain = smoothStrain(done.strain, stage.garment.geometry.index.array);
      const top = strainScale(strain);
      stage.setStrain(strain, top);
      $('legend-max').textContent = `${(top * 100).toFixed(0)}%+`;
      $('legend-mid').textContent = `${(top * 50).toFixed(0)}%`;
      showLimitOnLegend(state.init?.strain_limit ?? DEFAULT_STRAIN_LIMIT, top);
    }
    showMetrics(done);
    setProgress(1, done.cached ? 'Done (from the fitting-room memory).' : 'Done.');
    setTimeout(() => { if (state.state === 'done') $('progress').hidden = true; }, 1500);
    $('result').hidden = false;
    if (NARROW.matches) $('result').scrollIntoView({ block: 'start' });
    $('legend').hidden = !$('fitmap-toggle').checked;
    state.state = 'done';
  } catch (error) {
    if (error.stopped) {
      state.state = 'ready';
      stage.clearGarment();
      setProgress(0, 'Stopped. Press "Try on" to start again.');
    } else {
      state.state = 'error';
      showError(error);
      $('progress').hidden = true;
    }
    if (!state.framesReceived) stage.clearGarment();
  } finally {
    live = null;
    updateTryOnButton();
  }
}

/** The fit map's scale is this garment's own (fitmap.strainScale): mark the cloth's limit on it. */
function showLimitOnLegend(limit, top) {
  const mark = $('legend-limit');
  const limitText = `${Number((limit * 100).toFixed(1))} %`;
  mark.hidden = !(limit < top);
  if (limit < top) {
    mark.style.left = `${(100 * limit) / top}%`;
    $('legend-note').textContent = `▏ the cloth's stretch limit, ${limitText}`;
  } else {
    $('legend-note').textContent = `All within the cloth's ${limitText} stretch limit`;
  }
}

/** Fill the fit summary from a done message (`strainLimit`: the init message's, else the default). */
function showMetrics(done, strainLimit = state.init?.strain_limit ?? DEFAULT_STRAIN_LIMIT) {
  const rows = metricRows(done.metrics || {}, { strainLimit, stoppedBy: done.stopped_by });
  const dl = $('metrics');
  dl.replaceChildren();
  for (const { name, value, tone, wide } of rows) {
    const div = document.createElement('div');
    if (wide) div.className = 'wide';
    const dt = document.createElement('dt');
    dt.textContent = name;
    const dd = document.createElement('dd');
    dd.textContent = value;
    if (tone) dd.className = tone;
    div.append(dt, dd);
    dl.append(div);
  }
  const g = done.garment || state.init?.garment || {};
  $('result-garment').textContent = [g.name, g.size ? `size ${g.size}` : null].filter(Boolean).join(' · ');
}

state.showMetrics = showMetrics;  // for tests: render a given done message

// ---- layout -------------------------------------------------------------------------------------
// On a narrow screen (the breakpoint of style.css) the fit summary is the first card of the controls,
// under the 3D view, rather than a card over the figure it describes.
const NARROW = matchMedia('(max-width: 820px)');
function placeResult() {
  const result = $('result');
  if (NARROW.matches) $('notice').after(result);
  else $('legend').before(result);
}
NARROW.addEventListener('change', placeResult);
placeResult();

$('tryon-button').addEventListener('click', tryOn);
$('fitmap-toggle').addEventListener('change', (e) => {
  stage.setFitMap(e.target.checked);
  $('legend').hidden = !e.target.checked;
});
$('more-toggle').addEventListener('click', (e) => {
  const open = e.currentTarget.getAttribute('aria-expanded') !== 'true';
  e.currentTarget.setAttribute('aria-expanded', String(open));
  e.currentTarget.textContent = open ? 'Fewer measurements' : 'More measurements';
  $('more-measurements').hidden = !open;
});

// ---- downloads ----------------------------------------------------------------------------------
async function withBusy(button, work) {
  button.disabled = true;
  try { await work(); } catch (error) { showError(error); } finally { button.disabled = false; }
}
$('download-garment').addEventListener('click', (e) => withBusy(e.currentTarget, async () => {
  const glb = await stage.garmentGLB();
  const name = (state.garments.find((g) => g.id === state.garmentId)?.name || 'garment').replace(/\W+/g, '-').toLowerCase();
  saveBlob(glb, `${name}-fitted.glb`);
}));
$('download-body').addEventListener('click', (e) => withBusy(e.currentTarget, async () => {
  const response = await postJSON('/api/bodies?format=glb', form.bodyRequest());
  saveBlob(await response.blob(), 'body.glb');
}));

// ---- start --------------------------------------------------------------------------------------
async function start() {
  try {
    const [ranges, garments] = await Promise.all([getJSON('/api/bodies/ranges'), getJSON('/api/garments')]);
    form = new MeasurementForm(normaliseRanges(ranges), {
      required: $('measurements'), optional: $('more-measurements'), pose: $('pose'),
    }, scheduleBody);
    state.garments = Array.isArray(garments) ? garments : (garments.garments || garments.items || []);
    renderGarments(state.garments);
    if (state.garments.length) {
      const first = groupGarments(state.garments)[0].entries;
      selectGarment(first[Math.floor((first.length - 1) / 2)].id);
    }
    state.state = 'ready';
    updateTryOnButton();
    await refreshBody();
  } catch (error) {
    state.state = 'error';
    $('garments-empty')?.remove();
    showError(error);
  }
}
start();
