// The readout of a plan: the geometry achieved at every key frame next to what was asked
// (PlanResponse.frames), or for a joint path where the motion passes each waypoint; the
// plan's summary (arc length, closed loop, motion, robot, optimisers) and its warnings.
// Every value has a stable data-testid and its full precision in data-value.

import { fmt } from './plots.js';
import { KIND_NAMES, requestKind } from './request.js';

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

// The motion a plan makes, in words: {kind, text}. kind: 'frames' or 'pieces' (a path),
// 'jointPath', 'jointMove', 'linearMove' or 'sequence'; a path after an approach move says
// so (its steps are in PlanResponse.steps).
export function motionKind(request, response) {
  let kind = requestKind(request);
  if (kind === 'path') kind = request.path?.frames?.length || !(request.path?.start || request.path?.pieces?.length) ? 'frames' : 'pieces';
  const steps = response?.steps || [];
  let text = KIND_NAMES[kind];
  if (kind === 'sequence') {
    text = `sequence of ${(request.sequence || []).length} steps`;
  } else if (steps.length > 1) {
    text = `${text}, after a ${KIND_NAMES[steps[0].kind] || steps[0].kind} to its start (robot.approach)`;
  }
  return { kind, text };
}

// A step of PlanResponse.steps in words: "step 2: joint move", "steps 1-3: blended chain".
export function stepName(step) {
  const index = step.index ?? 0;
  const last = step.lastIndex ?? index;
  const kind = KIND_NAMES[step.kind] || step.kind || '';
  return last !== index ? `steps ${index}-${last}: ${kind}` : `step ${index}: ${kind}`;
}

// The plan's summary: the motion's kind, its steps (a sequence, a path after its approach
// move: each step's kind and duration), the path's arc length and segments (report: the
// path's own report, a step's for a path after an approach), the motion's duration and
// peaks, the robot's report and the optimisers'.
export function renderSummary(root, response, request, report = response) {
  root.replaceChildren();
  if (!response) return;
  const dl = el('dl', { class: 'summary' });
  const item = (label, testid, value, unit) => {
    dl.append(el('dt', {}, label));
    const dd = el('dd');
    dd.append(valueSpan(testid, value));
    if (unit) dd.append(document.createTextNode(` ${unit}`));
    dl.append(dd);
    return dd;
  };
  const kind = motionKind(request, response);
  dl.append(el('dt', {}, 'motion'));
  dl.append(el('dd', { 'data-testid': 'plan-kind', 'data-kind': kind.kind,
    'data-steps': String((response.steps || []).length) }, kind.text));
  for (const step of response.steps || []) {
    const dd = item(stepName(step), `plan-step-${step.index ?? 0}`, step.durationS ?? 0,
      `s from t = ${fmt(step.startTimeS ?? 0)} s${step.arcLength ? `, ${fmt(step.arcLength)} m` : ''}`);
    dd.querySelector('.value').dataset.kind = step.kind || '';
  }
  const jointPath = request?.jointPath;
  const planKind = requestKind(request);
  if (jointPath) {
    // No Cartesian path: no arc length, no segments.
    item('waypoints', 'plan-waypoints', (jointPath.waypoints || []).length);
    item('blend tolerance', 'plan-blend-tolerance', jointPath.blendTolerance ?? 0, 'rad (joint space)');
  } else if (planKind === 'path') {
    item('arc length', 'plan-arc-length', report?.arcLength ?? 0, 'm');
    item('segments', 'plan-segments', (report?.segments || []).length);
  }
  if (report?.closedLoop) {
    item('closed-loop max error', 'plan-closed-loop', report.closedLoop.maxError ?? 0,
      report.closedLoop.worstField ? `at ${report.closedLoop.worstField}` : '');
  }
  const m = response.motion;
  if (m) {
    item('duration', 'plan-duration', m.durationS ?? 0, 's');
    item('peak speed', 'plan-peak-speed', m.peakSpeed ?? 0, 'm/s');
    item('peak acceleration', 'plan-peak-acceleration', m.peakAcceleration ?? 0, 'm/s²');
    item('samples', 'plan-samples', Number(m.sampleCount ?? 0));
  } else {
    dl.append(el('dt', {}, 'duration'));
    dl.append(el('dd', { 'data-testid': 'plan-no-motion' }, 'none: the geometry only (give the motion a duration, or 0 for the fastest, to time it)'));
  }
  const r = response.robot;
  if (r) {
    dl.append(el('dt', {}, 'robot'));
    dl.append(el('dd', { 'data-testid': 'plan-robot-feasible' },
      `${r.name || ''}: ${r.feasible ? 'within every limit' : `${(r.violations || []).length} limit(s) broken`}`));
    item('min manipulability', 'plan-min-manipulability', r.minManipulability ?? 0, `at t = ${fmt(r.minManipulabilityT ?? 0)} s`);
    item('max IK error', 'plan-ik-error', r.maxIkPositionError ?? 0, 'm');
  }
  const optimization = response.optimization || report?.optimization;
  const timing = optimization?.timing;
  if (timing) {
    item('time-optimal duration', 'plan-time-optimal', timing.objectiveAfter ?? 0,
      `s (before ${fmt(timing.objectiveBefore ?? 0)} s, ${(timing.status || '').replace('OPTIMIZER_STATUS_', '').toLowerCase()})`);
  }
  const scales = optimization?.tangentScales;
  if (scales) {
    item('tangent-scale objective', 'plan-tangent-objective', scales.objectiveAfter ?? 0,
      `(before ${fmt(scales.objectiveBefore ?? 0)}); scales ${(scales.tangentScales || []).map(fmt).join(', ')}`);
  }
  root.append(dl);
}

// The length [m] of the tool's path over samples[from, to).
function toolPathLength(samples, from, to) {
  let sum = 0;
  for (let i = Math.max(1, from + 1); i < Math.min(to, samples.length); ++i) {
    const p = samples[i - 1].position || {};
    const q = samples[i].position || {};
    sum += Math.hypot((q.x ?? 0) - (p.x ?? 0), (q.y ?? 0) - (p.y ?? 0), (q.z ?? 0) - (p.z ?? 0));
  }
  return sum;
}

// The steps of a move or a sequence (the readout beside the plan): a row per step of
// PlanResponse.steps (a single move: one row, the whole motion), its kind, when it starts,
// how long it moves, the length of the tool's path, and how its goal was chosen or how its
// corners were blended. samples (once streamed): the tool's path length of a step the plan
// gives none for (a joint move, a single move) is measured on them.
export function renderSteps(root, request, response, samples = null) {
  const steps = response?.steps?.length ? response.steps
    : [{ index: 0, kind: requestKind(request), startTimeS: 0, durationS: response?.motion?.durationS ?? 0 }];
  const table = el('table', { class: 'readout', 'data-testid': 'step-readout' });
  const head = el('tr');
  for (const text of ['step', 'kind', 'from t [s]', 'duration [s]', 'tool path [m]']) head.append(el('th', {}, text));
  const thead = el('thead');
  thead.append(head);
  table.append(thead);
  const body = el('tbody');
  const notes = [];
  steps.forEach((step) => {
    const i = step.index ?? 0;
    const row = el('tr', { 'data-testid': `step-${i}-row` });
    const last = step.lastIndex ?? i;
    row.append(el('td', {}, last !== i ? `${i}-${last}` : `${i}`));
    row.append(el('td', { 'data-testid': `step-${i}-kind`, 'data-kind': step.kind || '' }, KIND_NAMES[step.kind] || step.kind || ''));
    let length = step.arcLength || undefined;
    if (length === undefined && samples?.length) {
      const first = response?.steps?.length ? Number(step.firstSample ?? 0) : 0;
      const count = response?.steps?.length ? Number(step.sampleCount ?? 0) : samples.length;
      length = toolPathLength(samples, first, first + count);
    }
    for (const [key, value] of [['start', step.startTimeS ?? 0], ['duration', step.durationS ?? 0], ['arc-length', length]]) {
      const td = el('td');
      td.append(valueSpan(`step-${i}-${key}`, value));
      row.append(td);
    }
    body.append(row);
    if (step.goalChoice) notes.push(`Step ${i}'s goal, of the inverse kinematics' solutions: ${step.goalChoice}.`);
    for (const c of step.corners || []) {
      notes.push(`The corner after step ${c.afterStep ?? 0}: blended within ${fmt(c.tolerance ?? 0)} m ` +
        `(${fmt(c.deviation ?? 0)} m off the corner's route), turning ${fmt(((c.corner ?? 0) * 180) / Math.PI)}°.`);
    }
  });
  table.append(body);
  root.replaceChildren(table);
  const note = el('div', { class: 'plot-note' });
  note.textContent = [
    'Each step from rest to rest (a blended chain without resting at its corners); the tool\'s path is drawn from the samples, each step\'s end marked;',
    'its length is the plan\'s, or measured on the samples for a joint move.',
    ...notes].join(' ');
  root.append(note);
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
