// Colour maps of the 3-D view and its colour bar: a sequential one (viridis) for curvature
// and speed, a diverging one (blue, white, red) for signed torsion.

const VIRIDIS = [
  [0.267, 0.005, 0.329], [0.283, 0.141, 0.458], [0.254, 0.265, 0.530], [0.207, 0.372, 0.553],
  [0.164, 0.471, 0.558], [0.128, 0.567, 0.551], [0.135, 0.659, 0.518], [0.267, 0.749, 0.441],
  [0.478, 0.821, 0.318], [0.741, 0.873, 0.150], [0.993, 0.906, 0.144],
];
const DIVERGING = [[0.129, 0.400, 0.675], [0.573, 0.773, 0.871], [0.969, 0.969, 0.969],
  [0.957, 0.647, 0.510], [0.698, 0.094, 0.169]];

function lerpStops(stops, t) {
  const x = Math.min(1, Math.max(0, t)) * (stops.length - 1);
  const i = Math.min(stops.length - 2, Math.floor(x));
  const f = x - i;
  return stops[i].map((c, k) => c + (stops[i + 1][k] - c) * f);
}

// The scale of one quantity: maps a value to [r, g, b] in [0, 1]; NaN (undefined there,
// e.g. torsion where the curvature is 0) is grey.
// The scale ends at the 98th percentile (of |value| when diverging), so that a few sharp
// peaks do not flatten the colours of the rest; values beyond it take the end colour
// (`clipped` tells the colour bar to say so).
export function makeScale(values, diverging) {
  const finite = values.filter(Number.isFinite);
  const sorted = (diverging ? finite.map(Math.abs) : finite).sort((a, b) => a - b);
  const at = (q) => (sorted.length ? sorted[Math.min(sorted.length - 1, Math.floor(q * (sorted.length - 1)))] : 1);
  let lo;
  let hi;
  if (diverging) {
    const m = at(0.98) || sorted[sorted.length - 1] || 1;
    lo = -m;
    hi = m;
  } else {
    lo = Math.min(0, sorted.length ? sorted[0] : 0);
    hi = at(0.98);
    if (!(hi > lo)) hi = sorted.length ? sorted[sorted.length - 1] : lo + 1;
    if (!(hi > lo)) hi = lo + 1;
  }
  const top = sorted.length ? sorted[sorted.length - 1] : hi;
  const clipped = top > hi * (1 + 1e-9);
  const stops = diverging ? DIVERGING : VIRIDIS;
  return {
    lo,
    hi,
    diverging,
    clipped,
    color(value) {
      if (!Number.isFinite(value)) return [0.55, 0.55, 0.55];
      return lerpStops(stops, (value - lo) / (hi - lo));
    },
    css(t) {
      const [r, g, b] = lerpStops(stops, t);
      return `rgb(${Math.round(r * 255)}, ${Math.round(g * 255)}, ${Math.round(b * 255)})`;
    },
  };
}

// A categorical palette for joints and families (Tableau 10).
export const PALETTE = ['#4e79a7', '#f28e2b', '#e15759', '#76b7b2', '#59a14f', '#edc948', '#b07aa1',
  '#ff9da7', '#9c755f', '#bab0ac'];
