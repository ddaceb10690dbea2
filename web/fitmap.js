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

/** The legend's top value for a strain array: at least 5 %, else the 98th percentile, rounded up. */
export function strainScale(strain) {
  if (!strain || strain.length === 0) return 0.05;
  const sorted = Float32Array.from(strain).sort();
  const p98 = sorted[Math.min(sorted.length - 1, Math.floor(sorted.length * 0.98))];
  const top = Math.max(p98, 0.05);
  return Math.ceil(top * 100) / 100;
}
