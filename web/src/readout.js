// The readout of a plan: the geometry achieved at every key frame next to what was asked
// (PlanResponse.frames), or for a joint path where the motion passes each waypoint; the
// plan's summary (arc length, closed loop, motion, robot, optimisers) and its warnings.
// Every value has a stable data-testid and its full precision in data-value.

import { fmt } from './plots.js';

const QUANTITIES = [
  ['curvature', 'κ', '1/m'],
  ['torsion', 'τ', '1/m'],
  ['curvatureDerivative', "κ'", 'deriv'],
  ['torsionDerivative', "τ'", 'deriv'],
  ['speed', '|dp/du|', 'm'],
];

const el = (tag, attrs = {}, text) => {
  const node = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) if (v !== undefined) node.setAttribute(k, v);
  if (text !== undefined) node.textContent = text;
  return node;
};

function valueSpan(testid, value, extraClass) {
  const span = el('span', { 'data-testid': testid, class: `value ${extraClass || ''}` });
  if (typeof value === 'number') {
    span.dataset.value = String(value);
    span.textContent = fmt(value);
  } else {
    span.dataset.value = '';
    span.textContent = '—';
  }
  return span;
}

export function renderFrames(root, request, response) {
  const frames = request.path?.frames || [];
  // A path of pieces: the rows are the joins of its segments, asked nothing.
  const joins = !frames.length && Boolean(request.path?.pieces?.length);
  const achieved = response?.frames || [];
  const perParameter = request.path?.derivativeConvention === 'DERIVATIVE_CONVENTION_PER_PARAMETER';
  const dUnit = perParameter ? '1/m per u' : '1/m²';
  const table = el('table', { class: 'readout', 'data-testid': 'frame-readout' });
  const head = el('tr');
  head.append(el('th', {}, 'frame'));
  for (const [, name, unit] of QUANTITIES) head.append(el('th', {}, `${name} [${unit === 'deriv' ? dUnit : unit}]`));
  head.append(el('th', {}, 'position error [m]'));
  const thead = el('thead');
  thead.append(head);
  table.append(thead);
  const body = el('tbody');
  achieved.forEach((a, i) => {
    const asked = frames[i] || {};
    const row = el('tr', { 'data-testid': `frame-${i}-row` });
    row.append(el('td', {}, `${joins ? 'join ' : ''}${i}${asked.cusp ? ' cusp' : ''}${asked.inflection ? ' infl.' : ''}`));
    for (const [key] of QUANTITIES) {
      const cell = el('td');
      const approach = a.approach?.[key];
      const leave = a.leave?.[key];
      // Absent in proto JSON is 0 for the plain double |dp/du|; optional ones stay undefined.
      const side = (g) => (g ? (key === 'speed' ? g.speed ?? 0 : g[key]) : undefined);
      const primary = a.leave ? side(a.leave) : side(a.approach);
      cell.append(valueSpan(`frame-${i}-${key}`, primary));
      if (a.approach && a.leave && side(a.approach) !== side(a.leave)) {
        cell.append(el('br'));
        const small = el('small', {}, 'in: ');
        small.append(valueSpan(`frame-${i}-${key}-approach`, side(a.approach), 'approach'));
        cell.append(small);
      } else if (a.approach) {
        const hidden = valueSpan(`frame-${i}-${key}-approach`, side(a.approach), 'hidden');
        cell.append(hidden);
      }
      if (a.leave) cell.append(valueSpan(`frame-${i}-${key}-leave`, side(a.leave), 'hidden'));
      const askedValue = key === 'speed' ? asked.tangentScale : asked[key];
      if (askedValue !== undefined) {
        cell.title = `asked ${askedValue}`;
        const match = [approach, leave].filter((v) => v !== undefined)
          .every((v) => Math.abs(v - askedValue) <= 1e-6 * Math.max(1, Math.abs(askedValue)));
        cell.classList.add(match ? 'met' : 'missed');
      }
      row.append(cell);
    }
    const p = a.position || {};
    const q = asked.position || {};
    const err = Math.hypot((p.x ?? 0) - (q.x ?? 0), (p.y ?? 0) - (q.y ?? 0), (p.z ?? 0) - (q.z ?? 0));
    const cell = el('td');
    cell.append(valueSpan(`frame-${i}-position-error`, joins ? undefined : err));
    row.append(cell);
    body.append(row);
  });
  table.append(body);
  root.replaceChildren(table);
  if (!achieved.length) root.append(el('div', { class: 'plot-empty' }, 'no plan yet'));
  else if (joins) root.append(el('div', { class: 'plot-note' },
    'A path of pieces: the joins of its segments (its start, the ends of pieces and transitions), leaving side (in: the approach side where it differs).'));
  else root.append(el('div', { class: 'plot-note' },
    'Achieved on the curve, leaving side (in: the approach side where it differs). Green: as asked; red: not as asked.'));
}

export function renderSummary(root, response, request) {
  root.replaceChildren();
  if (!response) return;
  const dl = el('dl', { class: 'summary' });
  const item = (label, testid, value, unit) => {
    dl.append(el('dt', {}, label));
    const dd = el('dd');
    dd.append(valueSpan(testid, value));
    if (unit) dd.append(document.createTextNode(` ${unit}`));
    dl.append(dd);
  };
  for (const step of response.steps || []) {
    item(`step ${step.index ?? 0}: ${step.kind || ''}`, `plan-step-${step.index ?? 0}`, step.durationS ?? 0,
      `s from t = ${fmt(step.startTimeS ?? 0)} s, ${fmt(step.arcLength ?? 0)} m`);
  }
  const jointPath = request?.jointPath;
  if (jointPath) {
    // No Cartesian path: no arc length, no segments.
    item('waypoints', 'plan-waypoints', (jointPath.waypoints || []).length);
    item('blend tolerance', 'plan-blend-tolerance', jointPath.blendTolerance ?? 0, 'rad (joint space)');
  } else {
    item('arc length', 'plan-arc-length', response.arcLength ?? 0, 'm');
    item('segments', 'plan-segments', (response.segments || []).length);
  }
  if (response.closedLoop) {
    item('closed-loop max error', 'plan-closed-loop', response.closedLoop.maxError ?? 0,
      response.closedLoop.worstField ? `at ${response.closedLoop.worstField}` : '');
  }
  const m = response.motion;
  if (m) {
    item('duration', 'plan-duration', m.durationS ?? 0, 's');
    item('peak speed', 'plan-peak-speed', m.peakSpeed ?? 0, 'm/s');
    item('peak acceleration', 'plan-peak-acceleration', m.peakAcceleration ?? 0, 'm/s²');
    item('samples', 'plan-samples', Number(m.sampleCount ?? 0));
  }
  const r = response.robot;
  if (r) {
    dl.append(el('dt', {}, 'robot'));
    dl.append(el('dd', { 'data-testid': 'plan-robot-feasible' },
      `${r.name || ''}: ${r.feasible ? 'within every limit' : `${(r.violations || []).length} limit(s) broken`}`));
    item('min manipulability', 'plan-min-manipulability', r.minManipulability ?? 0, `at t = ${fmt(r.minManipulabilityT ?? 0)} s`);
    item('max IK error', 'plan-ik-error', r.maxIkPositionError ?? 0, 'm');
  }
  const timing = response.optimization?.timing;
  if (timing) {
    item('time-optimal duration', 'plan-time-optimal', timing.objectiveAfter ?? 0,
      `s (before ${fmt(timing.objectiveBefore ?? 0)} s, ${(timing.status || '').replace('OPTIMIZER_STATUS_', '').toLowerCase()})`);
  }
  const scales = response.optimization?.tangentScales;
  if (scales) {
    item('tangent-scale objective', 'plan-tangent-objective', scales.objectiveAfter ?? 0,
      `(before ${fmt(scales.objectiveBefore ?? 0)}); scales ${(scales.tangentScales || []).map(fmt).join(', ')}`);
  }
  root.append(dl);
  if (request && (request.sequence || []).length) {
    root.append(el('div', { class: 'plot-note' }, 'a sequence: the editor shows its path requests only'));
  }
}

export function renderWarnings(root, warnings, violations) {
  root.replaceChildren();
  const list = el('ul', { class: 'warnings', 'data-testid': 'plan-warnings' });
  (warnings || []).forEach((w, k) => {
    const li = el('li', { 'data-testid': `warning-${k}` });
    li.textContent = `⚠ ${k + 1} ${(w.code || '').replace('PLAN_WARNING_CODE_', '').toLowerCase().replace('_', ' ')} ` +
      `(segment ${w.segment ?? 0}, s = ${fmt(w.s ?? 0)} m): ${w.message || ''}`;
    list.append(li);
  });
  for (const v of violations || []) {
    const li = el('li', { class: 'violation' });
    li.textContent = `✖ ${v.subject || v.type || ''}: ${v.description}`;
    list.append(li);
  }
  if (list.children.length) root.append(list);
  root.dataset.count = String((warnings || []).length);
}

// Where a motion passes the waypoints of a joint path: for each waypoint, the sample nearest
// it in joint space (Euclidean over the joints, as the blend tolerance is), the samples taken
// in the waypoints' order (a waypoint visited again later is matched to its own pass: the
// indices are the non-decreasing sequence with the least sum of distances). Returns
// [{index, t, distance}] (null without samples or waypoints).
export function waypointPasses(waypoints, samples) {
  const n = waypoints?.length || 0;
  const m = samples?.length || 0;
  if (!n || !m || !samples[0].joints?.length) return null;
  const distance = (w, k) => {
    const q = samples[k].joints || [];
    const p = w.positions || [];
    let sum = 0;
    for (let j = 0; j < Math.max(p.length, q.length); ++j) sum += ((p[j] ?? 0) - (q[j] ?? 0)) ** 2;
    return Math.sqrt(sum);
  };
  // cost[k]: the least sum for the waypoints so far with the last one at sample k;
  // from[i][k]: the sample of waypoint i - 1 on that best sequence.
  let cost = new Float64Array(m);
  const from = [];
  for (let k = 0; k < m; ++k) cost[k] = distance(waypoints[0], k);
  for (let i = 1; i < n; ++i) {
    const next = new Float64Array(m);
    const back = new Int32Array(m);
    let best = Infinity;
    let arg = 0;
    for (let k = 0; k < m; ++k) {
      if (cost[k] < best) {
        best = cost[k];
        arg = k;
      }
      next[k] = best + distance(waypoints[i], k);
      back[k] = arg;
    }
    from.push(back);
    cost = next;
  }
  let k = 0;
  for (let j = 1; j < m; ++j) if (cost[j] < cost[k]) k = j;
  const indices = new Array(n);
  for (let i = n - 1; i >= 0; --i) {
    indices[i] = k;
    if (i > 0) k = from[i - 1][k];
  }
  return indices.map((index, i) => ({ index, t: samples[index].t ?? 0, distance: distance(waypoints[i], index) }));
}

// How near the motion may pass waypoint i of a joint path [rad]: the blend tolerance at an
// interior waypoint, 0 at the ends, at a stop and with no tolerance (met exactly).
export function allowedDistance(jointPath, i) {
  const count = jointPath.waypoints?.length || 0;
  if (i === 0 || i === count - 1 || jointPath.waypoints[i]?.stop) return 0;
  return jointPath.blendTolerance ?? 0;
}

// The waypoints of a joint path and where the motion passes them (passes: waypointPasses,
// with `tool`: the tool's distance [m] there from where the waypoint puts it, when known;
// null: not streamed yet).
export function renderWaypoints(root, request, passes) {
  const jointPath = request.jointPath || {};
  const waypoints = jointPath.waypoints || [];
  const table = el('table', { class: 'readout', 'data-testid': 'waypoint-readout' });
  const head = el('tr');
  for (const text of ['waypoint', 't [s]', 'joint distance [rad]', 'tool distance [m]']) head.append(el('th', {}, text));
  const thead = el('thead');
  thead.append(head);
  table.append(thead);
  const body = el('tbody');
  waypoints.forEach((w, i) => {
    const pass = passes?.[i];
    const row = el('tr', { 'data-testid': `pass-${i}-row` });
    row.append(el('td', {}, `${i}${w.stop ? ' stop' : ''}`));
    const cell = (testid, value) => {
      const td = el('td');
      td.append(valueSpan(testid, value));
      row.append(td);
      return td;
    };
    cell(`pass-${i}-t`, pass?.t);
    const d = cell(`pass-${i}-joint-distance`, pass?.distance);
    if (pass) {
      const allowed = allowedDistance(jointPath, i);
      d.title = `within ${allowed} rad asked`;
      // The nearest sample, not the nearest point between samples: 1e-4 rad to spare.
      d.classList.add(pass.distance <= allowed + 1e-4 ? 'met' : 'missed');
    }
    cell(`pass-${i}-tool-distance`, pass?.tool);
    body.append(row);
  });
  table.append(body);
  root.replaceChildren(table);
  root.append(el('div', { class: 'plot-note' }, passes
    ? 'Where the motion passes each waypoint: the nearest sample in joint space (its time, its distance; green: within '
      + 'the blend tolerance, or met at the ends and stops) and how far the tool is there from where the waypoint puts it.'
    : 'waiting for the samples'));
}
