// The fit summary in words: each figure of a try-on's `metrics` (REST answer or WebSocket `done`) as a
// row {name, value, tone, wide}. Tones: 'good' (green), 'warn' (amber), 'bad' (red), '' (neutral).
//
// Rules: every figure is judged on the mesh the shopper sees (the fitted, displayed garment), a row is
// green only when its figure says nothing is wrong, and a figure the server did not send is '—' and
// never green (an older server, or a field this page does not know yet).

// The structural springs' stretch limit when the init message does not carry `strain_limit`
// (SimSettings.strain_limit[0], a ratio: 0.10 = the cloth stretches at most 10 %).
export const DEFAULT_STRAIN_LIMIT = 0.10;

// Strain tiers, as multiples of that limit L:
// RELAXED: green only below 0.6 L (6 % for a 10 % cloth). The solver lets a pulled spring go right up to
//   its limit and stops it there, so "within the limit" alone includes cloth pulled taut; below 60 % of
//   it no edge is near its limit, which is what "comfortably within" means to a shopper.
export const RELAXED_RATIO = 0.6;
// AT_LIMIT: up to 1.6 L is still "at the limit", not beyond it: the shown mesh's edges run across the simulated
//   lattice, which the simulation holds to the shear limit, 1.5 x the structural one (0.15 vs 0.10), and its
//   stretch passes leave them within a per cent of that. Beyond it, on the body, the server reports the place as
//   too tight (metrics.too_tight: the shear limit plus 1 %).
export const AT_LIMIT_RATIO = 1.6;
// FAR_BEYOND: beyond 3 L (30 %) no spring of the cloth may stretch at all (the bending limit, 3 x the
//   structural one, is the loosest): an edge stretched further is not cloth pulled tight but the shown
//   drape coming apart (a gap opening at a sleeve), so the page says the drape is wrong, not the size.
export const FAR_BEYOND_RATIO = 3.0;

/** A strain ratio as a percentage: one decimal below 10 %, whole per cents above ("6.2 %", "15 %"). */
export function percent(ratio) {
  const p = ratio * 100;
  return `${Math.abs(p) < 10 ? p.toFixed(1) : Math.round(p)} %`;
}

/**
 * The shown mesh's largest strain (`display_max_strain`) in words, relative to the cloth's limit.
 * `springsOver`: the simulated springs past their own type's limit (`strain_by_kind`), or null if unknown. With
 * none, a shown strain between 1.5 L and 3 L is the shown mesh following the simulated one between its points
 * (a T-shirt L hanging loose: every spring within its limit, the shown mesh 17.5 %), not cloth stretched past
 * its limit: it is told as at the limit, not beyond it.
 */
export function describeStrain(strain, limit = DEFAULT_STRAIN_LIMIT, springsOver = null) {
  if (!Number.isFinite(strain)) return { value: '—', tone: '' };
  const L = Number.isFinite(limit) && limit > 0 ? limit : DEFAULT_STRAIN_LIMIT;
  const figure = percent(strain);
  const limitText = `${Number((L * 100).toFixed(1))} %`;  // "10 %", "12.5 %"
  if (strain < RELAXED_RATIO * L) return { value: `${figure}: relaxed`, tone: 'good' };
  if (strain <= L) return { value: `${figure}: stretched, within the cloth's ${limitText} limit`, tone: '' };
  if (strain <= AT_LIMIT_RATIO * L || (springsOver === 0 && strain <= FAR_BEYOND_RATIO * L)) {
    return { value: `${figure}: at the cloth's ${limitText} stretch limit`, tone: 'warn' };
  }
  // not "too small here": the page cannot say where (the fit map shows the simulated mesh's strain), and
  // the too-tight row says whether the body is what stretches it
  if (strain <= FAR_BEYOND_RATIO * L) {
    return { value: `${figure}: beyond the cloth's ${limitText} stretch limit`, tone: 'bad' };
  }
  return {
    value: `${figure}: far beyond the cloth's ${limitText} stretch limit: this drape is not reliable`, tone: 'bad',
  };
}

/** Points of one surface through the other: a count and the deepest, mm. Green only for none. */
function depthRow(count, deepestMm) {
  if (!Number.isFinite(count)) return { value: '—', tone: '' };
  if (count === 0) return { value: 'none', tone: 'good' };
  const depth = Number.isFinite(deepestMm) ? `, ${deepestMm.toFixed(1)} mm deep` : '';
  return { value: `${count} ${count === 1 ? 'point' : 'points'}${depth}`, tone: 'warn' };
}

/** 'upper_arm_l' -> 'left upper arm', 'torso chest' -> 'chest' (the places of metrics.too_tight). */
export function placeName(place) {
  const side = place.endsWith('_l') ? 'left ' : (place.endsWith('_r') ? 'right ' : '');
  return side + place.replace(/^torso /, '').replace(/_[lr]$/, '').replace(/_/g, ' ');
}

/**
 * One section's rows (a garment's, or an outfit's own) in the order a two-column grid shows them with no hole:
 * a half-width row left alone on its line before a full-width one gets the next half-width row of the section
 * beside it. The grid's own dense flow did this across sections, so the first figure of an outfit's second
 * garment could fill the last hole of the first, under the wrong name (a polo of guessed units, whose "Size"
 * row is full-width, showed the trousers' "Too tight at" among its own figures).
 */
export function packed(rows) {
  const rest = rows.slice();
  const out = [];
  let alone = false; // a half-width row waits for a partner on its line
  while (rest.length) {
    let i = 0;
    if (alone && rest[0].wide) i = Math.max(0, rest.findIndex((r) => !r.wide));
    const [row] = rest.splice(i, 1);
    out.push(row);
    alone = row.wide ? false : !alone;
  }
  return out;
}

// The server's one verdict (metrics.verdict, judged on the shown mesh as the size advice judges a size): its
// word and tone. A garment that falls off is never a fit: red.
const VERDICTS = {
  fits: { word: 'Fits', tone: 'good' },
  tight: { word: 'Too tight', tone: 'bad' },
  loose: { word: 'Loose', tone: 'warn' },
  falls_off: { word: 'Falls off', tone: 'bad' },
};

/**
 * The verdict row: 'Fits: 8 cm of ease at the chest; stays on the shoulders', 'Too tight at the waist: ...' (a
 * reason that starts with the verdict's own words is only capitalised); null without a verdict.
 */
export function verdictRow(m) {
  const v = VERDICTS[m.verdict];
  if (!v) return null;
  const reason = typeof m.verdict_reason === 'string' ? m.verdict_reason : '';
  if (!reason) return { value: v.word, tone: v.tone };
  if (reason.toLowerCase().startsWith(v.word.toLowerCase())) {
    return { value: reason[0].toUpperCase() + reason.slice(1), tone: v.tone };
  }
  return { value: `${v.word}: ${reason}`, tone: v.tone };
}

const seconds = (s) => (Number.isFinite(s) ? `${s.toFixed(2)} s` : '—');

/**
 * The rows of the fit summary, most telling first. `m`: the metrics object; `strainLimit`: the init
 * message's `strain_limit`; `stoppedBy`: the done message's `stopped_by`.
 */
export function metricRows(m, { strainLimit = DEFAULT_STRAIN_LIMIT, stoppedBy = null } = {}) {
  const rows = [];
  const add = (name, { value, tone = '' }, wide = false) => rows.push({ name, value, tone, wide });

  const kinds = m.strain_by_kind ? Object.values(m.strain_by_kind) : [];
  const springsOver = kinds.length ? kinds.reduce((n, k) => n + (Number(k.over) || 0), 0) : null;
  const strain = describeStrain(m.display_max_strain, strainLimit, springsOver);
  const withinLimit = strain.tone === 'good' || (strain.tone === '' && strain.value !== '—');
  // where the (simulated) cloth is over its limit on the body; "nowhere" is green only if the shown mesh
  // agrees (its strain within the limit), else it would call a drape good that the strain row calls bad
  const tight = m.too_tight ? Object.keys(m.too_tight) : null;  // largest count first
  // one verdict: cloth at its limit where the body holds nothing too tight is taut cloth, not a size too
  // small (a loose T-shirt's shoulders): told, not coloured as a warning beside "Fits"
  if (strain.tone === 'warn' && tight !== null && !tight.length) strain.tone = '';
  // the verdict decides the colours: beside a size that is not too tight, a strain short of "not reliable" is told,
  // not coloured (the server counts every shown edge past the limit on the body as too tight)
  const verdict = verdictRow(m);
  if (verdict && m.verdict !== 'tight' && strain.tone && !strain.value.includes('not reliable')) strain.tone = '';
  if (verdict) add('Verdict', verdict, true);
  add('Max strain', strain, true);
  add('Too tight at', tight === null ? { value: '—' }
    : (tight.length ? { value: tight.slice(0, 3).map(placeName).join(', '), tone: 'warn' }
      : { value: 'nowhere', tone: withinLimit ? 'good' : '' }));

  add('Cloth in body', depthRow(m.penetrating_vertices, m.max_penetration_mm));
  add('Body through cloth', depthRow(m.body_through_vertices, m.max_body_through_mm));
  const crossings = m.self_crossings;
  add('Cloth through itself', !Number.isFinite(crossings) ? { value: '—' }
    : (crossings === 0 ? { value: 'none', tone: 'good' }
      : { value: `${crossings} ${crossings === 1 ? 'edge' : 'edges'} in its folds`, tone: 'warn' }));

  let openings;
  if (m.openings_on_limbs === undefined) openings = { value: '—' };
  else if (m.openings_on_limbs === null) openings = { value: 'none' };  // nothing to judge: neutral
  else if (m.openings_on_limbs) openings = { value: 'around the limbs', tone: 'good' };
  else {
    const off = (m.limb_openings || []).filter((o) => !o.ok).map((o) => o.opening).join(', ');
    openings = { value: `off at ${off || 'a limb'}`, tone: 'warn' };
  }
  add('Sleeves, legs', openings, openings.value.length > 24);

  // the server's words on where the ends lie (metrics.length: "too long: the sleeves end 7 cm past the wrists")
  if (Array.isArray(m.length) && m.ends_cm && Object.keys(m.ends_cm).length) {
    add('Length', m.length.length ? { value: m.length.join('; '), tone: 'warn' } : { value: 'right', tone: 'good' },
      m.length.length > 0);
  }

  let stays;
  if (typeof m.stays_up !== 'boolean') stays = { value: '—' };
  else if (m.stays_up) {
    stays = { value: m.slid_cm >= 1 ? `yes, slid ${Math.round(m.slid_cm)} cm` : 'yes', tone: 'good' };
  }
  else stays = { value: `no, slid ${Math.round(m.slid_cm)} cm down`, tone: 'warn' };
  add('Stays up', stays);

  add('Rest reached', typeof m.rest_reached !== 'boolean' ? { value: '—' }
    : { value: m.rest_reached ? 'yes' : 'no', tone: m.rest_reached ? 'good' : 'warn' });
  const sized = m.sized_to_body === undefined ? { value: '—' }
    : { value: m.sized_to_body ? 'sized to this body (units unknown)' : 'as made' };
  add('Size', sized, sized.value.length > 24);
  if (stoppedBy === 'wall_limit' || m.timed_out) add('Stopped', { value: 'time limit', tone: 'warn' });
  add('Time', { value: seconds(m.wall_seconds) });
  add('Steps', { value: Number.isFinite(m.steps) ? `${m.steps}` : '—' });
  add('Simulated', { value: seconds(m.sim_seconds) });
  return rows;
}
