// Fit-map colours: strain 0 (loose, blue) through pale to red (tight). The stops match the CSS
// gradient of the legend (.legend-bar in style.css).
const STOPS = [
  [0.0, [0x2b, 0x6c, 0xb0]],
  [0.25, [0x7f, 0xb3, 0xd5]],
  [0.5, [0xf2, 0xf0, 0xe6]],
  [0.75, [0xf4, 0xa2, 0x59]],
  [1.0, [0xc0, 0x39, 0x2b]],
];

/** Write the colour of `t` in [0, 1] (clamped) into `color` (a THREE.Color, linear RGB). */
export function strainColor(t, color) {
  const x = Math.min(Math.max(Number.isFinite(t) ? t : 0, 0), 1);
  let i = 1;
  while (i < STOPS.length - 1 && x > STOPS[i][0]) i++;
  const [t0, c0] = STOPS[i - 1];
  const [t1, c1] = STOPS[i];
  const f = (x - t0) / (t1 - t0);
  const r = (c0[0] + f * (c1[0] - c0[0])) / 255;
  const g = (c0[1] + f * (c1[1] - c0[1])) / 255;
  const b = (c0[2] + f * (c1[2] - c0[2])) / 255;
  color.setRGB(r, g, b, 'srgb');
  return color;
}

/**
 * Per-vertex strain averaged with its neighbours `passes` times (faces: flat index array), so the map
 * shows regions rather than single stretched springs. Returns a new Float32Array.
 */
export function smoothStrain(strain, faces, passes = 2) {
  const n = strain.length;
  let value = Float32Array.from(strain);
  const sum = new Float32Array(n);
  const count = new Float32Array(n);
  for (let p = 0; p < passes; p++) {
    sum.set(value);
    count.fill(1);
    for (let f = 0; f < faces.length; f += 3) {
      const a = faces[f], b = faces[f + 1], c = faces[f + 2];
      sum[a] += value[b] + value[c]; count[a] += 2;
      sum[b] += value[a] + value[c]; count[b] += 2;
      sum[c] += value[a] + value[b]; count[c] += 2;
    }
    const next = new Float32Array(n);
    for (let i = 0; i < n; i++) next[i] = sum[i] / count[i];
    value = next;
  }
  return value;
}

/**
 * The legend's top: the 98th percentile of the (smoothed) strain, at least 2 %, rounded up to a whole
 * per cent. Cloth held by strain limits hangs stretched toward its limit almost everywhere, so a fixed
 * scale paints it all one colour; this scale shows where this garment is tighter than elsewhere, and the
 * legend gives the numbers.
 */
export function strainScale(strain) {
  if (!strain || strain.length === 0) return 0.1;
  const sorted = Float32Array.from(strain).sort();
  const p98 = sorted[Math.min(sorted.length - 1, Math.floor(sorted.length * 0.98))];
  return Math.ceil(Math.max(p98, 0.02) * 100) / 100;
}
