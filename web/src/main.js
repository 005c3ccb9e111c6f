// The operator's page: wires the editor, the 3-D view, the readout, the plots, the family
// view and the replay to geotrajd's JSON API. It opens any PlanRequest (a path, a move, a
// sequence, a joint path) as it is, from a file, a paste or a drop, with undo and redo.
// Every edit replans (debounced): plan and analysis at once for the view, then the stream
// of samples for the replay, the speed and the joints. What has no Cartesian path to
// analyse (a joint path, a move, a sequence) is drawn from its samples: the tool's path,
// for a joint path the tool at each waypoint (forward kinematics) and where the motion
// passes them, for a sequence where each step ends.

import 'uplot/dist/uPlot.min.css';
import '../style.css';
import * as api from './api.js';
import { Editor, pathForm } from './editor.js';
import { View3D } from './view3d.js';
import { Plots } from './plots.js';
import { Family } from './family.js';
import { Replay, fkRobot } from './replay.js';
import { renderFrames, renderSteps, renderSummary, renderWarnings, renderWaypoints, waypointPasses } from './readout.js';
import { presets, analysisRequest, cloneRequest, commandLines, openDocument, requestKind, setField } from './request.js';

const $ = (selector) => document.querySelector(selector);
const byTestId = (id) => document.querySelector(`[data-testid="${id}"]`);

const REQUEST_KEY = 'geotraj.request';
const DEBOUNCE_MS = 30;
const STREAM_DEBOUNCE_MS = 200;
const ANALYSIS_POINTS = 401;
// The most points of a joint path's tool path drawn (from its samples).
const TOOL_PATH_POINTS = 2000;

const state = {
  request: null,
  robots: [],
  generation: 0,
  plans: 0,
  controller: null,
  streamController: null,
  editTime: 0,
  timer: null,
  streamTimer: null,
  profile: null,
  samples: null,
  // A joint path: where the motion passes its waypoints (readout.waypointPasses), and the
  // tool's position at each waypoint by joint values and robot (POST /v1/fk, kept).
  passes: null,
  waypointTools: new Map(),
};

const body = document.body;
const statusEl = byTestId('status');
const generalErrors = byTestId('general-errors');
const view = new View3D(byTestId('view3d'), byTestId('colorbar'));
view.attachSegmentLegend(byTestId('legend-segments'));
const plots = new Plots(byTestId('plots'));
const editor = new Editor(byTestId('editor'), (kind) => onEdit(kind));
// The kinds of request drawn from their samples (no Cartesian path to analyse): the tool's
// path where the motion takes it.
const TOOL_PATH_KINDS = new Set(['jointPath', 'jointMove', 'linearMove', 'sequence']);
const replay = new Replay({
  slider: byTestId('replay-slider'), play: byTestId('replay-play'), time: byTestId('replay-time'),
  tool: byTestId('replay-tool'), status: byTestId('replay-status'),
}, view);
const family = new Family(byTestId('family'), view, () => state.request, () => state.response || null);

function setStatus(text, kind) {
  statusEl.textContent = text;
  statusEl.dataset.state = kind;
}

function showErrors(error) {
  generalErrors.replaceChildren();
  if (!error) {
    editor.showViolations([]);
    return;
  }
  const unplaced = editor.showViolations(error.fieldViolations || []);
  const head = document.createElement('div');
  head.className = 'error-summary';
  head.textContent = error.summary || error.message;
  generalErrors.append(head);
  const list = document.createElement('ul');
  for (const v of unplaced) {
    const li = document.createElement('li');
    li.textContent = `${v.field}: ${v.description}`;
    list.append(li);
  }
  for (const v of error.preconditionViolations || []) {
    const li = document.createElement('li');
    li.textContent = `${v.subject || v.type}: ${v.description}`;
    list.append(li);
  }
  if (list.children.length) generalErrors.append(list);
}

// The page for the kind of request being edited (requestKind: a path, a joint path, a joint
// or linear move, a sequence): the readout's title, the waypoints' legend, the colour modes
// (a tool path drawn from the samples is coloured by speed: it has no curvature to show),
// the family (of key frames) hidden but for a path. On a change of kind what the other one
// drew goes.
const colorSelect = byTestId('color-mode');
function applyMode(kind) {
  const jointPath = kind === 'jointPath';
  const toolPathOnly = TOOL_PATH_KINDS.has(kind);
  const wasKind = body.dataset.requestKind || 'path';
  const was = TOOL_PATH_KINDS.has(wasKind);
  body.dataset.requestKind = kind;
  body.dataset.toolPath = String(toolPathOnly);
  byTestId('readout-title').textContent = jointPath ? 'Waypoints passed'
    : toolPathOnly ? 'Steps of the motion' : 'Achieved at the key frames';
  byTestId('legend-waypoints').hidden = !jointPath;
  byTestId('family').hidden = toolPathOnly;
  byTestId('family-title').hidden = toolPathOnly;
  for (const option of colorSelect.options) option.disabled = toolPathOnly && option.value !== 'speed';
  if (kind === wasKind) return;
  view.setTrace(null);
  view.setStepMarks(null);
  if (toolPathOnly === was) {
    view.setCurve([], null);
    view.setWaypoints(null);
    byTestId('readout').replaceChildren();
    return;
  }
  if (toolPathOnly) {
    state.colorModeBefore = colorSelect.value;
    colorSelect.value = 'speed';
  } else {
    colorSelect.value = state.colorModeBefore || 'curvature';
    view.colorMode = colorSelect.value;
  }
  state.profile = null;
  state.segmentKinds = null;
  state.samples = null;
  state.speedAtS = null;
  state.passes = null;
  view.fitExtra = [];
  view.setCurve([], null);
  view.setWaypoints(null);
  plots.setTimeMarks([]);
  byTestId('readout').replaceChildren();
}

function saveLocally() {
  try {
    sessionStorage.setItem(REQUEST_KEY, JSON.stringify(state.request));
  } catch {
    // Too large or refused: the page works without it.
  }
}

function onEdit(kind) {
  state.editTime = performance.now();
  remember(kind);
  saveLocally();
  if (requestKind(state.request) !== 'path') family.updateTargets(null);
  else if (kind === 'structure') family.updateTargets(state.request.path);
  else family.requestChanged();
  schedule();
}

function schedule() {
  clearTimeout(state.timer);
  state.scheduled = true;
  body.dataset.planState = 'scheduled';
  body.dataset.streamState = 'pending';
  state.timer = setTimeout(replan, DEBOUNCE_MS);
}

// The joint names and limits of the request's robot (for the plots), from its inline model
// or the built-in model of that name, with the request's overrides.
function robotInfo(spec) {
  if (!spec) return null;
  const model = spec.model || state.robots.find((r) => r.name === spec.name);
  if (!model) return { names: [], limits: [] };
  const names = (model.links?.length ? model.links : model.joints || []).map((j) => j.name || '');
  const limits = (model.limits || []).map((l) => ({ ...l }));
  for (const o of spec.jointLimits || []) {
    const j = names.indexOf(o.joint);
    if (j < 0 || !limits[j]) continue;
    if (o.maxVelocity !== undefined) limits[j].maxVelocity = o.maxVelocity;
    if (o.maxAcceleration !== undefined) limits[j].maxAcceleration = o.maxAcceleration;
  }
  return { names, limits, velocityScale: spec.velocityScale, accelerationScale: spec.accelerationScale };
}

// Arc length [m] at every key frame, from the segments' lengths.
function frameArcLengths(response, frameCount) {
  const s = [0];
  for (const seg of response.segments || []) {
    if ((seg.toFrame ?? 0) === 0 && s.length >= frameCount) break;
    s.push(s[s.length - 1] + (seg.arcLength ?? 0));
  }
  return s.slice(0, frameCount);
}

// The frames the view marks: the key frames, or for a path of pieces its start and the key
// frames of its `to` pieces (tagged "start" and "to i").
function viewFrames(request) {
  const path = request?.path;
  if (requestKind(request) !== 'path') return { frames: [], labels: null, fields: [] };
  if (pathForm(path) === 'frames') {
    const frames = path?.frames || [];
    return { frames, labels: null, fields: frames.map((_, i) => `path.frames[${i}]`) };
  }
  const frames = [];
  const labels = [];
  const fields = [];
  if (path.start) {
    frames.push(path.start);
    labels.push('start');
    fields.push('path.start');
  }
  (path.pieces || []).forEach((piece, i) => {
    if (!piece.to) return;
    frames.push(piece.to);
    labels.push(`to ${i}`);
    fields.push(`path.pieces[${i}].to`);
  });
  return { frames, labels, fields };
}

// The kind of each segment of a path of pieces (PlanResponse.segments[].kind), or null for
// a path of key frames (blends only): the view draws the segments of the former apart.
function segmentKinds(report) {
  const kinds = (report?.segments || []).map((seg) => seg.kind || 'SEGMENT_KIND_BLEND');
  return kinds.some((k) => k !== 'SEGMENT_KIND_BLEND') ? kinds : null;
}

// Where each piece of a path of pieces ends ({position, tangent}, from the joins the plan
// reports): the end of the last segment that draws it.
function pieceEnds(report, count) {
  const ends = new Array(count).fill(null);
  for (const seg of report?.segments || []) {
    if (seg.kind === 'SEGMENT_KIND_TRANSITION') continue;
    const piece = seg.piece ?? 0;
    const frame = report.frames?.[seg.toFrame ?? 0];
    if (piece < count && frame) {
      ends[piece] = { position: frame.position || {}, tangent: frame.approach?.tangent || frame.leave?.tangent || { x: 1 } };
    }
  }
  return ends;
}

function extent(points) {
  if (!points?.length) return 0.5;
  const lo = [Infinity, Infinity, Infinity];
  const hi = [-Infinity, -Infinity, -Infinity];
  for (const p of points) {
    ['x', 'y', 'z'].forEach((k, i) => {
      const v = p.position?.[k] ?? 0;
      lo[i] = Math.min(lo[i], v);
      hi[i] = Math.max(hi[i], v);
    });
  }
  return Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]);
}

async function replan() {
  state.scheduled = false;
  if (!state.request) return;
  if (editor.hasLocalErrors()) {
    setStatus('a value is not a number: fix it to replan', 'error');
    body.dataset.planState = 'local-error';
    return;
  }
  state.controller?.abort();
  const controller = new AbortController();
  state.controller = controller;
  const generation = ++state.generation;
  const request = cloneRequest(state.request);
  const started = performance.now();
  const editTime = state.editTime || started;
  setStatus('planning…', 'planning');
  body.dataset.planState = 'planning';
  const [planned, analyzed] = await Promise.allSettled([
    api.plan(request, controller.signal),
    request.path ? api.analyze(analysisRequest(request, ANALYSIS_POINTS), controller.signal) : Promise.resolve(null),
  ]);
  if (generation !== state.generation) return;
  const aborted = (r) => r.status === 'rejected' && r.reason?.name === 'AbortError';
  if (aborted(planned) || aborted(analyzed)) return;
  const callsMs = performance.now() - started;

  const response = planned.status === 'fulfilled' ? planned.value : null;
  const profile = analyzed.status === 'fulfilled' ? analyzed.value : null;
  const error = planned.status === 'rejected' ? planned.reason : analyzed.status === 'rejected' ? analyzed.reason : null;
  if (error && !(error instanceof api.ApiError)) {
    console.warn(error);
  }
  showErrors(error);

  const frames = request.path?.frames || [];
  const kind = requestKind(request);
  const jointPath = kind === 'jointPath';
  const pieces = kind === 'path' && pathForm(request.path) === 'pieces';
  // A path with an approach move is planned as a sequence: its path's report is a step's.
  const report = kind === 'path' && response?.steps?.length
    ? response.steps.find((step) => step.kind === 'path' || step.kind === 'blended') || {}
    : response;
  if (profile) {
    state.profile = profile;
    state.segmentKinds = segmentKinds(report);
    view.setCurve(profile.points || [], state.speedAtS || null, state.segmentKinds);
  }
  const marked = viewFrames(request);
  view.setFrames(marked.frames, report?.warnings || [], profile?.points || state.profile?.points, extent(profile?.points),
    marked.labels, marked.fields);
  renderWarnings(byTestId('warnings'), report?.warnings, error?.preconditionViolations);
  // What the readout shows belongs to the last plan that succeeded.
  for (const id of ['readout', 'summary']) byTestId(id).classList.toggle('stale', !response);
  if (response) {
    state.response = report;
    if (jointPath) {
      // Where the motion passes the waypoints comes with the samples: until then, the last
      // one's (if it has as many waypoints).
      const count = request.jointPath.waypoints?.length || 0;
      renderWaypoints(byTestId('readout'), request, state.passes?.length === count ? state.passes : null);
    } else if (kind === 'path') {
      renderFrames(byTestId('readout'), request, report);
    } else {
      renderSteps(byTestId('readout'), request, response);
    }
    renderSummary(byTestId('summary'), response, request, report);
    // A path of pieces: the joins of its segments (start, piece and transition ends).
    plots.setFrameMarks(frameArcLengths(report, pieces ? (report.frames || []).length : frames.length));
    if (pieces) editor.setPieceEnds(pieceEnds(report, (request.path.pieces || []).length));
    const names = robotInfo(request.robot)?.names || [];
    const timing = response.optimization?.timing;
    if (timing?.binding?.length) plots.setBinding(timing.binding, response.motion?.durationS, names, 'timing report');
    else if (response.robot?.binding?.length) plots.setBinding(response.robot.binding, response.motion?.durationS, names, 'robot report');
    else if (response.motion?.binding?.length) plots.setBinding(response.motion.binding, response.motion.durationS, names, 'tool limits, measured on the samples');
    else plots.setBinding(null, 0);
  }
  if (profile) plots.setProfile(profile.points || []);
  else if (kind !== 'path') plots.setProfile(null, `a ${kind === 'jointPath' ? 'joint path' : 'move or sequence'} has no path of key frames to profile: see the speed and the joints below`);
  const elapsed = performance.now() - editTime;
  state.plans += 1;
  body.dataset.plans = String(state.plans);
  // An edit made while this plan was on its way has its own plan coming.
  if (!state.scheduled) body.dataset.planState = error ? 'error' : 'ready';
  if (error) {
    setStatus(`${error.summary || error.message}`, 'error');
  } else {
    setStatus(`planned: view updated ${Math.round(elapsed)} ms after the edit (plan and analysis calls ${Math.round(callsMs)} ms)`, 'ready');
  }
  statusEl.dataset.ms = String(Math.round(elapsed));
  state.editTime = 0;

  clearTimeout(state.streamTimer);
  if (response && request.motion) {
    body.dataset.streamState = 'pending';
    state.streamTimer = setTimeout(() => streamSamples(request, response, generation), STREAM_DEBOUNCE_MS);
  } else {
    state.streamController?.abort();
    body.dataset.streamState = 'none';
    state.samples = null;
    state.speedAtS = null;
    replay.clear(response ? 'no motion in the request: give it a duration to replay' : 'no plan');
    plots.setSamples(null, null);
    plots.setTimeMarks([]);
    view.setTrace(null);
    view.setStepMarks(null);
  }
}

// The samples of the plan (POST /v1/stream): the replay, the speed plot, the joint plots
// and the curve's speed colouring.
async function streamSamples(request, response, generation) {
  state.streamController?.abort();
  const controller = new AbortController();
  state.streamController = controller;
  body.dataset.streamState = 'streaming';
  const samples = [];
  try {
    await api.stream({ ...request, samplesPerBatch: 1024, pacing: undefined },
      (batch) => { for (const s of batch.samples || []) samples.push(s); }, controller.signal);
  } catch (e) {
    if (e.name === 'AbortError' || generation !== state.generation) return;
    body.dataset.streamState = 'error';
    replay.clear(`stream failed: ${e.summary || e.message}`);
    plots.setSamples(null, null);
    return;
  }
  if (generation !== state.generation) return;
  state.samples = samples;
  const kind = requestKind(request);
  const jointPath = kind === 'jointPath';
  const steps = response?.steps || [];
  let passes = null;
  // The steps of a sequence (or of a path after its approach move): where each ends, marked
  // in the view, and when each starts, marked on the plots over time.
  const ends = stepEnds(steps, samples);
  view.setStepMarks(ends.length > 1 ? ends : null);
  if (jointPath) {
    // No Cartesian path: the tool's path is where the samples take it.
    state.speedAtS = null;
    passes = waypointPasses(request.jointPath.waypoints, samples);
    state.passes = passes;
    plots.setTimeMarks((passes || []).map((p) => p.t));
    view.setCurve(toolPath(samples), null, null, true);
    renderWaypoints(byTestId('readout'), request, passes);
  } else if (TOOL_PATH_KINDS.has(kind)) {
    state.speedAtS = null;
    renderSteps(byTestId('readout'), request, response, samples);
    plots.setTimeMarks(steps.slice(1).map((step) => step.startTimeS ?? 0), steps.slice(1).map((step) => `s${step.index ?? 0}`));
    view.setCurve(toolPath(samples), null, null, true);
  } else {
    plots.setTimeMarks(steps.slice(1).map((step) => step.startTimeS ?? 0), steps.slice(1).map((step) => `s${step.index ?? 0}`));
    state.speedAtS = speedLookup(samples);
    if (view.colorMode === 'speed' && state.profile) view.setCurve(state.profile.points || [], state.speedAtS, state.segmentKinds);
  }
  // A path after an approach move: the whole motion's tool path too, thin, with the path.
  const trace = kind === 'path' && steps.length ? toolPath(samples) : null;
  view.setTrace(trace);
  plots.setSamples(samples, robotInfo(request.robot));
  replay.steps = steps;
  await Promise.all([replay.load(samples, request.robot || null),
    jointPath ? markWaypoints(request, samples, passes, generation) : null]);
  if (generation !== state.generation) return;
  // The arm in view with the motion (the path is small beside it), and the approach's tool
  // path: once per request, and on `fit view`.
  view.fitExtra = [...[...replay.fk.values()].flat(), ...(trace || []).map((p) => p.position)];
  if (state.fitArm) view.refit();
  state.fitArm = false;
  body.dataset.streamState = 'ready';
}

// Where each step of a plan ends (StepReport.firstSample, sampleCount): [{position, label}]
// from the samples, labelled with the step's index and kind.
function stepEnds(steps, samples) {
  const ends = [];
  for (const step of steps) {
    const last = Number(step.firstSample ?? 0) + Number(step.sampleCount ?? 0) - 1;
    const sample = samples[Math.min(samples.length - 1, Math.max(0, last))];
    if (!sample) continue;
    const index = step.index ?? 0;
    const span = step.lastIndex !== undefined && step.lastIndex !== index ? `${index}-${step.lastIndex}` : `${index}`;
    ends.push({ position: sample.position || {}, label: `end of step ${span}` });
  }
  return ends;
}

// The samples of a joint path as the view's tool path: {position, speed}, at most
// TOOL_PATH_POINTS of them (the last one always).
function toolPath(samples) {
  const step = Math.max(1, Math.ceil(samples.length / TOOL_PATH_POINTS));
  const points = [];
  for (let i = 0; i < samples.length; i += step) points.push(samples[i]);
  if (points[points.length - 1] !== samples[samples.length - 1]) points.push(samples[samples.length - 1]);
  return points.map((x) => ({ position: x.position || {}, speed: x.speed ?? 0 }));
}

// The tool's position {x, y, z} [m] at joint values `joints` of the robot `spec` (its FK
// part), by POST /v1/fk, kept for the next plans.
function waypointTool(spec, joints) {
  const key = JSON.stringify([spec, joints]);
  let known = state.waypointTools.get(key);
  if (!known) {
    if (state.waypointTools.size > 2000) state.waypointTools.clear();
    known = api.forwardKinematics({ robot: spec, joints }).then((answer) => answer.pose?.position || {});
    known.catch(() => state.waypointTools.delete(key));
    state.waypointTools.set(key, known);
  }
  return known;
}

// The waypoints of a joint path in the view: the tool at each (forward kinematics), and the
// tool where the motion passes it (passes); the readout then says how far apart they are.
async function markWaypoints(request, samples, passes, generation) {
  const waypoints = request.jointPath.waypoints || [];
  const spec = fkRobot(request.robot || {});
  let tools;
  try {
    tools = await api.mapLimited(waypoints, 4, (w) => waypointTool(spec, w.positions || []));
  } catch (e) {
    if (generation !== state.generation) return;
    view.setWaypoints(null);
    byTestId('readout').append(Object.assign(document.createElement('div'), { className: 'plot-note',
      textContent: `the waypoints' tool positions: forward kinematics failed: ${e.summary || e.message}` }));
    return;
  }
  if (generation !== state.generation) return;
  const at = (i) => (passes ? samples[passes[i].index].position || {} : null);
  view.setWaypoints(waypoints.map((w, i) => ({ position: tools[i], passed: at(i), label: `w${i}`, stop: Boolean(w.stop) })));
  if (!passes) return;
  passes.forEach((p, i) => {
    const q = at(i);
    p.tool = Math.hypot((tools[i].x ?? 0) - (q.x ?? 0), (tools[i].y ?? 0) - (q.y ?? 0), (tools[i].z ?? 0) - (q.z ?? 0));
  });
  renderWaypoints(byTestId('readout'), request, passes);
}

// Tool speed [m/s] at arc length s [m], from the samples (nearest sample in s).
function speedLookup(samples) {
  if (!samples.length || samples.some((s) => (s.step ?? 0) !== 0)) return null;
  const s = samples.map((x) => x.s ?? 0);
  return (value) => {
    let lo = 0;
    let hi = s.length - 1;
    while (lo < hi) {
      const mid = (lo + hi) >> 1;
      if (s[mid] < value) lo = mid + 1;
      else hi = mid;
    }
    return samples[lo].speed ?? 0;
  };
}

// Opens `request` (a start page's choice, a file, a pasted text, or the tab's saved one):
// the editor shows it as it is, the view is framed on it when planned. note: what the
// page says about it above the editor ('' for nothing). An opened request is an edit: undo
// gives the one before back. keepView (undo, redo): the view stays where it is.
function setRequest(request, { note = '', keepView = false, remembered = false } = {}) {
  state.request = request;
  const kind = requestKind(request);
  applyMode(kind);
  if (!keepView) {
    view.fitted = false;
    view.fitExtra = [];
    state.fitArm = Boolean(request.robot);
    // Nothing of the request before stays on show (if this one is refused, nothing is).
    state.profile = null;
    state.samples = null;
    view.setCurve([], null);
    view.setTrace(null);
    view.setStepMarks(null);
    view.setWaypoints(null);
    replay.clear('planning…');
    for (const id of ['readout', 'summary']) byTestId(id).replaceChildren();
  }
  state.speedAtS = null;
  family.clear();
  editor.render(request);
  family.updateTargets(request.path);
  if (kind === 'path') family.suggestRange();
  showNote(note);
  if (!remembered) remember('open');
  saveLocally();
  state.editTime = performance.now();
  schedule();
}

const openNote = byTestId('open-note');
function showNote(text) {
  openNote.textContent = text || '';
  openNote.hidden = !text;
}

// --- undo and redo -------------------------------------------------------------------------
// The request after every edit, as JSON: undo goes back one, redo forward again. Typing in
// one box (edits of kind 'value' less than UNDO_MERGE_MS apart) is one step.

const UNDO_MERGE_MS = 800;
const UNDO_DEPTH = 200;
const history = { undo: [], redo: [], current: null, kind: '', at: 0 };
const undoButton = byTestId('undo');
const redoButton = byTestId('redo');

function updateHistoryButtons() {
  undoButton.disabled = !history.undo.length;
  redoButton.disabled = !history.redo.length;
  body.dataset.undo = String(history.undo.length);
  body.dataset.redo = String(history.redo.length);
}

function remember(kind) {
  const json = JSON.stringify(state.request);
  if (json === history.current) return;
  const now = performance.now();
  const merge = kind === 'value' && history.kind === 'value' && now - history.at < UNDO_MERGE_MS && history.undo.length;
  if (!merge && history.current !== null) {
    history.undo.push(history.current);
    if (history.undo.length > UNDO_DEPTH) history.undo.shift();
  }
  history.redo = [];
  history.current = json;
  history.kind = kind;
  history.at = now;
  updateHistoryButtons();
}

function travel(from, to) {
  if (!from.length) return;
  to.push(history.current);
  history.current = from.pop();
  history.kind = '';
  const request = JSON.parse(history.current);
  // The same kind of motion: the view stays; another (an opened request undone): framed anew.
  setRequest(request, { keepView: requestKind(request) === requestKind(state.request), remembered: true });
  updateHistoryButtons();
}
const undo = () => travel(history.undo, history.redo);
const redo = () => travel(history.redo, history.undo);
undoButton.addEventListener('click', undo);
redoButton.addEventListener('click', redo);
document.addEventListener('keydown', (e) => {
  if (!(e.ctrlKey || e.metaKey) || e.altKey) return;
  const key = e.key.toLowerCase();
  if (key !== 'z' && key !== 'y') return;
  // The token and the family's boxes keep their own (the browser's) undo.
  const target = e.target;
  if (target instanceof Element && target.closest('form.token, [data-testid="family"], .commands')) return;
  e.preventDefault();
  if (key === 'y' || e.shiftKey) redo();
  else undo();
});

// A key frame dragged in the 3-D view: its position set (rounded to 0.1 mm).
view.onFrameDrag = (field, position) => {
  if (!state.request) return;
  const round = (v) => Number(v.toFixed(4));
  setField(state.request, `${field}.position`, { x: round(position.x), y: round(position.y), z: round(position.z) });
  editor.render(state.request);
  onEdit('structure');
};

// --- start page, files, commands, token --------------------------------------------------

const startDialog = byTestId('start-page');
function openStart() {
  if (!startDialog.open) startDialog.showModal();
}
for (const button of document.querySelectorAll('[data-start]')) {
  button.addEventListener('click', () => {
    startDialog.close();
    setRequest(presets[button.dataset.start]());
  });
}
$('[data-action=start]').addEventListener('click', openStart);

// A request file or pasted text: a PlanRequest opens as it is (what the server is sent is
// the file's request); an ExecuteRequest opens its plan; anything else is refused, saying
// why, and the request being edited stays.
function openText(text, name) {
  const opened = openDocument(text, name);
  if (opened.error) {
    showErrors({ message: opened.error });
    setStatus(opened.error, 'error');
    body.dataset.openState = 'refused';
    return;
  }
  body.dataset.openState = 'opened';
  if (startDialog.open) startDialog.close();
  setRequest(opened.request, { note: opened.note });
}

function loadFile(input) {
  const file = input.files?.[0];
  if (!file) return;
  file.text().then((text) => openText(text, file.name));
  input.value = '';
}
for (const id of ['load-file', 'start-file']) {
  byTestId(id).addEventListener('change', (e) => loadFile(e.target));
}

// Pasted anywhere but in a box, or dropped on the page: opened as a file is.
document.addEventListener('paste', (e) => {
  const target = e.target;
  if (target instanceof Element && target.closest('input, textarea, select')) return;
  const text = e.clipboardData?.getData('text/plain') || '';
  if (!text.trim()) return;
  e.preventDefault();
  openText(text, 'the pasted text');
});
document.addEventListener('dragover', (e) => {
  if (e.dataTransfer?.types?.includes('Files')) e.preventDefault();
});
document.addEventListener('drop', (e) => {
  const file = e.dataTransfer?.files?.[0];
  if (!file) return;
  e.preventDefault();
  file.text().then((text) => openText(text, file.name));
});

byTestId('save').addEventListener('click', () => {
  if (!state.request) return;
  const blob = new Blob([`${JSON.stringify(state.request, null, 2)}\n`], { type: 'application/json' });
  const url = URL.createObjectURL(blob);
  const a = document.createElement('a');
  a.href = url;
  a.download = 'request.json';
  document.body.append(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 1000);
});

const commandsPanel = byTestId('commands');
const addressInput = byTestId('grpc-address');
try {
  addressInput.value = localStorage.getItem('geotraj.grpcAddress') || addressInput.value;
} catch {
  // localStorage refused: keep the default address.
}
function updateCommands() {
  byTestId('command-lines').textContent = commandLines(addressInput.value.trim() || '127.0.0.1:50051',
    Boolean(api.token())).join('\n');
}
addressInput.addEventListener('input', () => {
  try { localStorage.setItem('geotraj.grpcAddress', addressInput.value.trim()); } catch { /* see above */ }
  updateCommands();
});
byTestId('copy-command').addEventListener('click', () => {
  updateCommands();
  commandsPanel.hidden = false;
});
$('[data-action=close-commands]').addEventListener('click', () => { commandsPanel.hidden = true; });
$('[data-action=copy]').addEventListener('click', async () => {
  const text = byTestId('command-lines').textContent;
  try {
    await navigator.clipboard.writeText(text);
    setStatus('commands copied (save the request as request.json beside them)', 'ready');
  } catch {
    const range = document.createRange();
    range.selectNodeContents(byTestId('command-lines'));
    getSelection().removeAllRanges();
    getSelection().addRange(range);
    setStatus('select and copy the lines by hand (the clipboard is not available here)', 'ready');
  }
});

const tokenInput = byTestId('token');
tokenInput.value = api.token();
tokenInput.addEventListener('change', () => {
  api.setToken(tokenInput.value.trim());
  loadRobots();
  schedule();
});

byTestId('color-mode').addEventListener('change', (e) => view.setColorMode(e.target.value, state.speedAtS));
byTestId('show-frames').addEventListener('change', (e) => {
  view.showFrames = e.target.checked;
  if (!state.request) return;
  const marked = viewFrames(state.request);
  view.setFrames(marked.frames, state.response?.warnings || [], state.profile?.points, extent(state.profile?.points),
    marked.labels, marked.fields);
  if (view.lastWaypoints) view.setWaypoints(view.lastWaypoints);
});
byTestId('show-grid').addEventListener('change', (e) => view.setGridVisible(e.target.checked));
$('[data-action=fit]').addEventListener('click', () => view.refit());

async function loadRobots() {
  try {
    const answer = await api.robots();
    state.robots = answer.robots || [];
    editor.setRobots(state.robots);
  } catch (e) {
    showErrors(e);
    setStatus(`robots: ${e.summary || e.message}`, 'error');
  }
}

// Forms here are groups of inputs: Enter never submits them (the family's form has its own
// handler). The page's policy (Content-Security-Policy default-src 'self') allows no inline
// handlers, hence here.
for (const form of document.querySelectorAll('form.editor, form.token')) {
  form.addEventListener('submit', (e) => e.preventDefault());
}

window.addEventListener('unhandledrejection', (e) => {
  if (e.reason?.name === 'AbortError') e.preventDefault();
});

// --- start -----------------------------------------------------------------------------------

loadRobots();
const preset = location.hash.replace(/^#/, '');
let saved = null;
try {
  saved = JSON.parse(sessionStorage.getItem(REQUEST_KEY) || 'null');
} catch {
  saved = null;
}
window.addEventListener('hashchange', () => {
  const name = location.hash.replace(/^#/, '');
  if (!presets[name]) return;
  if (startDialog.open) startDialog.close();
  setRequest(presets[name]());
});
if (presets[preset]) setRequest(presets[preset]());
else if (saved) setRequest(saved);
else openStart();
updateHistoryButtons();
body.dataset.ready = 'true';
