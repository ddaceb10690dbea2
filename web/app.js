// The try-on page: pick a garment, enter measurements, watch it drape live, read the fit.
//
// Modules: scene.js (three.js stage), api.js (REST + WebSocket), controls.js (form fields),
// fitmap.js (strain colours). State for tests and debugging is on `window.tryon`.
import { Stage } from './scene.js';
import { ApiError, flatMesh, getJSON, liveTryOn, postJSON, saveBlob } from './api.js';
import { MeasurementForm, normaliseRanges } from './controls.js';
import { smoothStrain, strainScale } from './fitmap.js';
import { DEFAULT_STRAIN_LIMIT, metricRows, packed } from './metrics.js';

const $ = (id) => document.getElementById(id);
const BODY_PREVIEW_DELAY_MS = 350;  // debounce: rebuild the body when the sliders rest this long

const state = {
  framesReceived: 0,
  state: 'loading',     // loading | ready | draping | done | error
  garments: [],
  styles: [],           // GET /api/styles: each style's sizes in order
  garmentId: null,
  companionId: null,    // a garment of the other kind worn with it (an outfit), or null
  advice: null,         // the last POST /api/fit answer shown, or null
  fitting: false,
  showNext: null,       // a garment to show when the drape on the way ends (advice that came during it)
  refit: false,         // the advice asked for again while one was on its way
  init: null,
  done: null,
  lastError: null,
  lastStep: 0,
  bodyRequests: 0,
  live: null,           // the open live session (re-posing) after a try-on, or null
  poseUpdates: 0,       // pose updates sent over it
  poseDones: 0,         // their settles' done messages received
  motionPoses: [],      // the poses the garment settled in since the try-on, for "Motion .glb" (at most 10)
};
window.tryon = state;

const stage = new Stage($('viewport'));
state.stage = stage;
let form = null;
let live = null;
let bodyTimer = null;
let bodySeq = 0;

// ---- notices ----------------------------------------------------------------------------------
function showNotice(message, info) {
  $('notice').classList.toggle('info', info);
  $('notice-text').textContent = message;
  $('notice').hidden = false;
}
function showError(error) {
  const message = error instanceof ApiError || error instanceof Error ? error.message : String(error);
  state.lastError = message;
  showNotice(message, false);
  $('notice').scrollIntoView({ block: 'nearest' });  // the controls may be scrolled past it
}
function showInfo(message) { showNotice(message, true); }
function clearNotice() { $('notice').hidden = true; }
$('notice-close').addEventListener('click', clearNotice);

// ---- catalogue ----------------------------------------------------------------------------------
const CATEGORY_ICONS = {
  top: '<path d="M8 3 3 6l2 5 2-1v11h10V10l2 1 2-5-5-3c-1 1.5-2.3 2-4 2S9 4.5 8 3z"/>',
  bottom: '<path d="M6 3h12l1 18h-5l-2-11-2 11H5z"/>',
  dress: '<path d="M9 2h6l-1 5 5 14H5l5-14z"/>',
};
const CATEGORY_COLORS = { top: '#b5523b', bottom: '#3f5f8a', dress: '#7a4f7f' };

/**
 * One row per style (GET /api/styles: its name, its sizes in the style's order) with size chips; entries
 * without a style that differ only by size ("T-shirt S", "T-shirt M") become one row too.
 */
function groupGarments(list) {
  const groups = new Map();
  const styles = new Map(state.styles.map((s) => [s.style, s]));
  const position = new Map();  // garment id -> place among its style's sizes
  for (const s of state.styles) s.sizes.forEach((z, i) => position.set(z.garment_id, i));
  for (const g of list) {
    const style = g.style && styles.has(g.style) ? styles.get(g.style) : null;
    const base = style ? style.name
      : (g.size && g.name.endsWith(` ${g.size}`) ? g.name.slice(0, -g.size.length - 1) : g.name);
    const key = style ? `style|${style.style}` : `${g.category}|${base}`;
    if (!groups.has(key)) groups.set(key, { name: base, category: g.category, style: style?.style ?? null, entries: [] });
    groups.get(key).entries.push(g);
  }
  const order = ['XXS', 'XS', 'S', 'M', 'L', 'XL', 'XXL', 'XXXL'];
  const rank = (g) => {
    if (position.has(g.id)) return position.get(g.id);
    const i = order.indexOf(String(g.size).toUpperCase());
    return i < 0 ? 99 : i;
  };
  for (const group of groups.values()) group.entries.sort((a, b) => rank(a) - rank(b));
  return [...groups.values()];
}

/** What a garment is made of, in a few words ("jersey, 187 g/m²"): its entry's fabric and the areal density
 * of its masses; '' for an entry that says none. */
function fabricWords(g) {
  if (!g?.fabric) return '';
  const density = Number(g.density ?? g.fabric_figures?.density);
  const name = g.fabric.replace(/-/g, ' ');
  return Number.isFinite(density) ? `${name}, ${Math.round(density * 1000)} g/m²` : name;
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
    // "top · jersey": the fabric beside the category when the garment's sizes share one
    const fabrics = [...new Set(group.entries.map((g) => g.fabric).filter(Boolean))];
    sub.textContent = [group.category, fabrics.length === 1 ? fabrics[0].replace(/-/g, ' ') : null]
      .filter(Boolean).join(' · ');
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
      chip.title = `${g.name}: ${[fabricWords(g), `${Number(g.vertices).toLocaleString()} vertices, ${Number(g.coarse_vertices).toLocaleString()} simulated`].filter(Boolean).join('; ')}`;
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
  if (state.advice && !state.advice.sizes.some((z) => z.garment_id === id)) clearAdvice();  // another garment
  for (const row of $('size-advice').querySelectorAll('.advice-row')) {
    row.setAttribute('aria-current', String(row.dataset.id === id));
  }
  renderCompanions();
  updateTryOnButton();
}

// ---- an outfit: a top with a bottom -----------------------------------------------------------------
const garmentById = (id) => state.garments.find((g) => g.id === id);
const isBottom = (g) => g?.category === 'bottom';

/** The "Wear with" choice: the catalogue's garments of the other kind (bottoms for a top or a dress, tops
 * and dresses for a bottom); the tuck choice only once one is chosen. A file that is already an outfit (its
 * `pieces`: a MakeHuman shirt and trousers) is worn alone: no choice beside it, and it is no one's companion. */
function renderCompanions() {
  const chosen = garmentById(state.garmentId);
  const others = chosen && !chosen.pieces
    ? state.garments.filter((g) => !g.pieces && isBottom(g) !== isBottom(chosen)) : [];
  const select = $('companion');
  if (!others.some((g) => g.id === state.companionId)) state.companionId = null;
  select.replaceChildren(new Option('nothing else', ''));
  for (const g of others) select.append(new Option(g.name, g.id, false, g.id === state.companionId));
  $('outfit').hidden = !others.length;
  $('tuck').hidden = $('tuck-label').hidden = !state.companionId;
}
$('companion').addEventListener('change', (e) => {
  state.companionId = e.target.value || null;
  renderCompanions();
});

/** The try-on request: one garment, or the chosen top and bottom as an outfit (top first, then tuck). */
function tryOnPayload() {
  if (!state.companionId) return form.tryOnRequest(state.garmentId);
  const pair = [state.garmentId, state.companionId];
  const ids = isBottom(garmentById(pair[0])) ? pair.reverse() : pair;
  const { garment_id: _, ...body } = form.tryOnRequest(ids[0]);
  return { ...body, garment_ids: ids, tuck: $('tuck').value };
}

function updateTryOnButton() {
  updateFitButton();
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
// A pose change: with a garment on or going on (a live session open) the body is re-posed with the garment
// on it, over the same connection (during the first drape the server keeps it for after); else the body
// alone is rebuilt.
function poseChanged() {
  if (state.live?.open && (state.state === 'done' || state.state === 'draping') && form.valid()) {
    state.live.sendPose(form.poseValues());
    state.poseUpdates++;
    setProgress(0.05, 'Moving…');
    return;
  }
  scheduleBody();
}

function closeLive() {
  if (state.live?.open) state.live.cancel();
  state.live = null;
}

function scheduleBody() {
  closeLive();  // the garment on the screen was draped for the old measurements
  clearTimeout(bodyTimer);
  if (state.advice) clearAdvice();  // the advice was for the old measurements
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
      // an outfit is draped once (only one garment follows a pose live), and new measurements are a new body
      showInfo('The garment was draped on the body as it was: press “Try on” to see it on this one.');
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
  const raised = ['left', 'right'].filter((side) => {
    const asked = body.pose?.requested?.[`arm_angle_${side}`];
    const built = body.pose?.achieved?.[`arm_angle_${side}`];
    return Number.isFinite(asked) && Number.isFinite(built) && built > asked + 0.05;
  }).map((side) => `${side} arm out ${body.pose.achieved[`arm_angle_${side}`].toFixed(1)}°`);
  if (raised.length) {
    const said = raised.join(', ');
    text += `${text ? '. ' : ''}${said[0].toUpperCase()}${said.slice(1)}: lower, it would pass into the torso`;
  }
  return text;
}

// ---- try-on ------------------------------------------------------------------------------------
// Said under the fit summary of a file of several garments (its catalogue entry's `pieces`: a shirt and
// trousers), which is draped once instead of staying live.
const PIECES_NOTE = 'Several garments in one file: draped once, in this pose (they do not follow a pose live). '
  + 'For another pose, choose it and press “Try on” again.';
function setProgress(fraction, text) {
  $('progress').hidden = false;
  $('progress-bar').style.width = `${Math.round(Math.min(Math.max(fraction, 0), 1) * 100)}%`;
  $('progress-text').textContent = text;
}
// the progress full with a last word, gone 1.5 s later unless something new started meanwhile
function finishProgress(text) {
  setProgress(1, text);
  setTimeout(() => { if (state.state === 'done') $('progress').hidden = true; }, 1500);
}

async function tryOn() {
  if (state.state === 'draping') { state.showNext = null; live?.cancel(); return; }
  clearNotice();
  closeLive();
  // the try-on brings its own body: a body preview still waiting or on its way would land after it and
  // take the garment off (a pose chosen just before "Try on")
  clearTimeout(bodyTimer);
  bodySeq++;
  // uint16 frames: half the bytes of float32, 0.04 mm steps (far below what a screen shows); one garment
  // stays live for re-posing (an outfit, or a file that is one, is draped once: layers do not follow a pose live)
  const payload = { ...tryOnPayload(), fps: 30, encoding: 'uint16' };
  state.motionPoses = [form.poseValues()];
  const pieces = payload.garment_id ? garmentById(payload.garment_id)?.pieces : null;
  if (payload.garment_id && !pieces) payload.live = true;
  $('result-note').hidden = !pieces;
  $('result-note').textContent = pieces ? PIECES_NOTE : '';
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
      const category = init.garment?.category ?? init.garments?.at(-1)?.category;  // an outfit: the outermost
      stage.startGarment(init.vertex_count, flatMesh({ vertices: [], faces: init.faces }).faces, category,
        init.garments);
      setProgress(0.02, 'Dressing…');
    },
    onFrame(frameNo, step, positions) {
      state.framesReceived++;
      state.lastStep = step;
      stage.updateGarment(positions);
      if (state.state !== 'draping') return;  // a re-pose: the progress says "Moving…"
      const maxSteps = state.init?.max_steps || 0;
      const seconds = ((performance.now() - started) / 1000).toFixed(1);
      setProgress(maxSteps ? step / maxSteps : 0.5, `Draping… step ${step}${maxSteps ? ` of at most ${maxSteps}` : ''} · ${seconds} s`);
    },
    onBody(message) { stage.setPosedBody(message.vertices, message.vertex_part); },
    onBodyPose(parts) { stage.poseBody(parts); },
    onPoseDone(done) {
      state.poseDones++;
      if (done.metrics?.pose) rememberPose(done.metrics.pose);
      state.done = done;
      showDone(done);
      finishProgress('Done.');
    },
    onLiveError(message) { showError(message.reason); },
    onClosed() { if (state.live === session) state.live = null; },
  });
  const session = live;
  state.live = payload.live ? session : null;
  try {
    const done = await live.promise;
    state.done = done;
    showDone(done);
    finishProgress(done.cached ? 'Done (from the fitting-room memory).' : 'Done.');
    $('result').hidden = false;
    $('download-motion').hidden = !payload.live;  // a motion is of one garment, moved live
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
  const next = state.showNext;
  state.showNext = null;
  if (next) showSize(next);
}

/** A done message's strain on the fit map and its metrics in the summary. */
function showDone(done) {
  if (done.strain?.length) {
    const strain = smoothStrain(done.strain, stage.garment.geometry.index.array);
    const top = strainScale(strain);
    stage.setStrain(strain, top);
    $('legend-max').textContent = `${(top * 100).toFixed(0)}%+`;
    $('legend-mid').textContent = `${(top * 50).toFixed(0)}%`;
    showLimitOnLegend(state.init?.strain_limit ?? DEFAULT_STRAIN_LIMIT, top);
  }
  showMetrics(done);
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

/** Fill the fit summary from a done message (`strainLimit`: the init message's, else the default). An
 * outfit's: its own figures (cloth through cloth, the tuck), then each garment's under its name. */
function showMetrics(done, strainLimit = state.init?.strain_limit ?? DEFAULT_STRAIN_LIMIT) {
  const m = done.metrics || {};
  const dl = $('metrics');
  dl.replaceChildren();
  const addRow = ({ name, value, tone, wide }, className = wide ? 'wide' : '') => {
    const div = document.createElement('div');
    if (className) div.className = className;
    const dt = document.createElement('dt');
    dt.textContent = name;
    const dd = document.createElement('dd');
    dd.textContent = value;
    if (tone) dd.className = tone;
    div.append(dt, dd);
    dl.append(div);
  };
  if (!Array.isArray(m.garments)) {
    for (const row of packed(metricRows(m, { strainLimit, stoppedBy: done.stopped_by }))) addRow(row);
    const g = done.garment || state.init?.garment || {};
    // "T-shirt L", not "T-shirt L · size L": the size is named only when the name does not end with it
    const sized = g.size && !g.name.endsWith(` ${g.size}`);
    const fabric = fabricWords(garmentById(g.id));  // "T-shirt L · jersey, 187 g/m²"
    $('result-garment').textContent = [g.name, sized ? `size ${g.size}` : null, fabric || null].filter(Boolean).join(' · ');
    return;
  }
  for (const row of packed(outfitRows(m))) addRow(row);
  const names = new Map((state.init?.garments || []).map((g) => [g.id, g.name]));
  for (const g of m.garments) {
    addRow({ name: names.get(g.garment_id) || g.garment_id, value: '' }, 'wide garment-head');
    for (const row of packed(metricRows(g, { strainLimit, stoppedBy: done.stopped_by }))) addRow(row);
  }
  const worn = (state.init?.garments || []).map((g) => g.name).reverse().join(' over ');  // outermost first
  $('result-garment').textContent = `${worn} · ${m.tuck === 'in' ? 'tucked in' : 'hem over the waistband'}`;
}

/** An outfit's own figures: cloth of one garment through another's, and whether the tuck is as asked. */
function outfitRows(m) {
  const n = m.layer_penetrating_vertices;
  const through = !Number.isFinite(n) ? { value: '—', tone: '' }
    : (n === 0 ? { value: 'none', tone: 'good' }
      : { value: `${n} ${n === 1 ? 'point' : 'points'}, up to ${Number(m.max_layer_penetration_mm).toFixed(0)} mm`,
        tone: 'warn' });
  const tuck = m.tuck_as_asked === true ? { value: m.tuck === 'in' ? 'tucked in' : 'over the waistband', tone: 'good' }
    : (m.tuck_as_asked === false ? { value: 'not as asked', tone: 'warn' } : { value: '—', tone: '' });
  return [{ name: 'Cloth through cloth', ...through, wide: false }, { name: "Top's hem", ...tuck, wide: false }];
}

state.showMetrics = showMetrics;  // for tests: render a given done message

// ---- which size fits me -------------------------------------------------------------------------
const VERDICT_WORDS = {
  fits: 'Fits', tight: 'Too tight', loose: 'Loose', falls_off: 'Falls off', not_draped: 'Not draped',
};

/** The style of the chosen garment (null: it comes in no sizes of a style). */
function chosenStyle() {
  const g = state.garments.find((x) => x.id === state.garmentId);
  return state.styles.find((s) => s.style === g?.style) || null;
}

function updateFitButton() {
  const style = chosenStyle();
  $('fit-button').disabled = !style || !form || !form.valid() || state.fitting || state.state === 'draping';
  if (!state.fitting) {
    $('fit-note').textContent = style
      ? `Drapes the ${style.name}'s sizes (${style.sizes.map((z) => z.size).join(', ')}) on your body and says which fits.`
      : 'Choose a garment that comes in several sizes to compare them on your body.';
  }
}

function clearAdvice() {
  state.advice = null;
  $('size-advice').replaceChildren();
  $('fit-summary').textContent = '';
  $('fit-notes').textContent = '';
  for (const chip of $('garments').querySelectorAll('.size.recommended')) chip.classList.remove('recommended');
}

/** "ease +8 cm chest" / "ease +3 cm waist · +4 cm hips" (cm, rounded), '' when nothing was measured. */
function easeText(ease) {
  const parts = Object.entries(ease || {}).filter(([, v]) => Number.isFinite(v))
    .map(([name, v]) => `${v >= 0 ? '+' : '−'}${Math.abs(Math.round(v))} cm ${name}`);
  return parts.length ? `ease ${parts.join(' · ')}` : '';
}

function renderAdvice(advice) {
  // "M: the chart's size for you is M; ..." / "M is the smallest size ..." -> "Take M: ..."
  const lead = new RegExp(`^${advice.recommended}(: | is )`);
  $('fit-summary').textContent = advice.recommended
    ? `Take ${advice.recommended}: ${advice.reason.replace(lead, '')}.`
    : `No size to recommend: ${advice.reason}.`;
  $('fit-notes').textContent = (advice.notes || []).map((note) => `Note: ${note}.`).join(' ');
  const list = $('size-advice');
  list.replaceChildren();
  for (const z of advice.sizes) {
    const li = document.createElement('li');
    li.className = `verdict-${z.verdict}${z.size === advice.recommended ? ' recommended' : ''}`;
    const row = document.createElement('button');
    row.type = 'button';
    row.className = 'advice-row';
    row.dataset.id = z.garment_id;
    row.setAttribute('aria-current', String(z.garment_id === state.garmentId));
    row.title = `Show size ${z.size} on your body`;
    const size = document.createElement('span');
    size.className = 'advice-size';
    size.textContent = z.size;
    const head = document.createElement('span');
    head.className = 'advice-head';
    const verdict = document.createElement('span');
    verdict.className = 'advice-verdict';
    verdict.textContent = VERDICT_WORDS[z.verdict] || z.verdict;
    head.append(verdict);
    if (z.size === advice.recommended) {
      const tag = document.createElement('span');
      tag.className = 'recommended-tag';
      tag.textContent = 'Your size';
      head.append(tag);
    }
    const ease = easeText(z.ease_cm);
    if (ease) {
      const e = document.createElement('span');
      e.className = 'advice-ease';
      e.textContent = ease;
      head.append(e);
    }
    const reason = document.createElement('span');
    reason.className = 'advice-reason';
    reason.textContent = z.verdict === 'not_draped' ? z.reason.replace(/^not draped: /, '') : z.reason;
    row.append(size, head, reason);
    row.addEventListener('click', () => showSize(z.garment_id));
    li.append(row);
    list.append(li);
  }
  const recommended = advice.sizes.find((z) => z.size === advice.recommended);
  for (const chip of $('garments').querySelectorAll('.size')) {
    chip.classList.toggle('recommended', chip.dataset.id === recommended?.garment_id);
  }
}

/** One size's drape: the same try-on the advice ran, so the server answers it from its result cache. */
function showSize(garmentId) {
  if (state.state === 'draping') return;
  selectGarment(garmentId);
  tryOn();
}

async function findSize() {
  const style = chosenStyle();
  if (!style) return;
  if (state.fitting) { state.refit = true; return; }  // asked again meanwhile (another fit): once this one ends
  clearNotice();
  clearAdvice();
  state.fitting = true;
  updateTryOnButton();
  $('fit-button').textContent = 'Draping the sizes…';
  $('fit-summary').textContent = `Draping the ${style.name}'s sizes on your body…`;
  try {
    const response = await postJSON('/api/fit', {
      style: style.style, preference: $('fit-preference').value, ...form.bodyRequest(),
    });
    state.advice = await response.json();
    renderAdvice(state.advice);
    const recommended = state.advice.sizes.find((z) => z.size === state.advice.recommended);
    // a drape on its way (the last advice's size, still streaming): the new one's size follows it
    if (recommended && state.state === 'draping') state.showNext = recommended.garment_id;
    else if (recommended) showSize(recommended.garment_id);
  } catch (error) {
    $('fit-summary').textContent = '';
    showError(error);
  } finally {
    state.fitting = false;
    $('fit-button').textContent = 'Find my size';
    updateTryOnButton();
  }
  if (state.refit) {
    state.refit = false;
    findSize();
  }
}
$('fit-button').addEventListener('click', findSize);
// another fit asked for: the advice again (its drapes come from the server's result cache)
$('fit-preference').addEventListener('change', () => { if (state.advice || state.fitting) findSize(); });

// ---- layout -------------------------------------------------------------------------------------
// On a narrow screen (the breakpoint of style.css) the fit summary is the first card of the controls,
// under the 3D view, rather than a card over the figure it describes.
const NARROW = matchMedia('(max-width: 820px)');
// the fit summary lies over the stage's right side on a wide screen: the view centres the body beside it
function syncStageInset() {
  const card = $('result');
  stage.setRightInset(!card.hidden && !NARROW.matches ? card.offsetWidth + 18 : 0);
}
new MutationObserver(syncStageInset).observe($('result'), { attributes: true, attributeFilter: ['hidden'] });
NARROW.addEventListener('change', syncStageInset);
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
  const worn = [state.garmentId, state.companionId].filter(Boolean).map((id) => garmentById(id)?.name || 'garment');
  const name = worn.join(' with ').replace(/\W+/g, '-').toLowerCase();
  saveBlob(glb, `${name}-fitted.glb`);
}));
// The poses a garment settled in, in order, each once in a row; the last MAX_MOTION_POSES kept.
const MAX_MOTION_POSES = 10;
function rememberPose(pose) {
  const last = state.motionPoses.at(-1);
  if (last !== undefined && JSON.stringify(last) === JSON.stringify(pose)) return;
  state.motionPoses = [...state.motionPoses, pose].slice(-MAX_MOTION_POSES);
}
// What "Motion .glb" animates: the poses tried since the try-on, or, if none was tried yet, a short tour from
// the pose the garment was tried on in.
function motionPoses() {
  const tried = state.motionPoses;
  return tried.length >= 2 ? tried : [tried[0] ?? form.poseValues(), 'arms_raised', 'hands_on_hips', tried[0] ?? 'a_pose'];
}
$('download-motion').addEventListener('click', (e) => withBusy(e.currentTarget, async () => {
  const poses = motionPoses();
  const { pose: _, ...request } = form.tryOnRequest(state.garmentId);
  setProgress(0.1, `Draping the motion: ${poses.length} poses…`);
  const response = await postJSON('/api/tryon?format=glb', { ...request, poses });
  const name = (garmentById(state.garmentId)?.name || 'garment').replace(/\W+/g, '-').toLowerCase();
  saveBlob(await response.blob(), `${name}-motion.glb`);
  finishProgress(`Motion saved: ${poses.length} poses.`);
}));
$('download-body').addEventListener('click', (e) => withBusy(e.currentTarget, async () => {
  const response = await postJSON('/api/bodies?format=glb', form.bodyRequest());
  saveBlob(await response.blob(), 'body.glb');
}));

// ---- start --------------------------------------------------------------------------------------
async function start() {
  try {
    const [ranges, garments, styles] = await Promise.all([
      getJSON('/api/bodies/ranges'), getJSON('/api/garments'),
      getJSON('/api/styles').catch(() => []),  // an older server without styles: no size advice
    ]);
    state.styles = Array.isArray(styles) ? styles : [];
    form = new MeasurementForm(normaliseRanges(ranges), {
      required: $('measurements'), optional: $('more-measurements'), pose: $('pose'),
    }, scheduleBody, ranges, poseChanged);
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
