// The family view (thesis Ch. 4), in two modes:
// - whole path: one constraint of one key frame (or, on a path of pieces, one parameter of
//   one piece: its length, an arc's radius, a helix's radius or pitch, a clothoid's end
//   curvature, or the path's transition tolerance) swept over a range, N curves planned
//   (POST /v1/analyze, one call each) and overlaid in the 3-D view, with a legend of each
//   value, its arc length and its peak curvature;
// - local shape at the frame (Figs. 4.10-4.27): one of the frame's κ, τ, κ', τ' swept, and
//   for each value the curve the frame's natural equations give near it, κ(s) = κ + κ' s,
//   τ(s) = τ + τ' s for -h <= s <= h, integrated by the server (POST /v1/analyze of a path of
//   one profile piece, forward from the frame and backward from it), drawn with the frame's
//   T, N, B.

import * as api from './api.js';
import { analysisRequest, getField, pieceParameters, withConstraint, withPieceParameter } from './request.js';
import { fmt } from './plots.js';

export const FAMILY_CONSTRAINTS = [
  ['curvature', 'curvature κ [1/m]'],
  ['torsion', 'torsion τ [1/m]'],
  ['curvatureDerivative', "curvature derivative κ'"],
  ['torsionDerivative', "torsion derivative τ'"],
  ['tangentScale', 'tangent scale [m]'],
];

// What the local mode sweeps and holds: key, symbol, unit (derivatives per metre of arc).
export const LOCAL_QUANTITIES = [
  ['curvature', 'κ', '1/m'],
  ['torsion', 'τ', '1/m'],
  ['curvatureDerivative', "κ'", '1/m²'],
  ['torsionDerivative', "τ'", '1/m²'],
];

// Points of each branch of a local curve (POST /v1/analyze's analysisPoints).
export const LOCAL_POINTS = 101;
export const DEFAULT_HALF_LENGTH = 0.1;

// A piece's kind: the shape it holds (line, arc, helix, clothoid, profile, to).
const PIECE_KINDS = ['line', 'arc', 'helix', 'clothoid', 'profile', 'to'];
export const pieceKind = (piece) => PIECE_KINDS.find((k) => piece?.[k] !== undefined) || 'piece';

// Blue to red over the family.
function familyColor(k, n) {
  const t = n <= 1 ? 0 : k / (n - 1);
  const hue = 230 - 230 * t;
  return `hsl(${hue}, 75%, 45%)`;
}

// --- vectors {x, y, z} ---------------------------------------------------------------------

const vec = (p) => ({ x: p?.x ?? 0, y: p?.y ?? 0, z: p?.z ?? 0 });
const dot = (a, b) => a.x * b.x + a.y * b.y + a.z * b.z;
const cross = (a, b) => ({ x: a.y * b.z - a.z * b.y, y: a.z * b.x - a.x * b.z, z: a.x * b.y - a.y * b.x });
const scaled = (a, k) => ({ x: a.x * k, y: a.y * k, z: a.z * k });
const minus = (a, b) => ({ x: a.x - b.x, y: a.y - b.y, z: a.z - b.z });
const neg = (a) => scaled(a, -1);
function unit(a) {
  const n = Math.hypot(a.x, a.y, a.z);
  return n > 1e-12 ? scaled(a, 1 / n) : null;
}

// The Frenet frame of a key frame as the local mode uses it: p, unit T, N made
// perpendicular to T (from the normal, or from a binormal B as B x T; null when the frame
// has neither), B = T x N, the cusp and inflection flags; `fallbackNormal` is a unit vector
// perpendicular to T for a frame without a normal (the world axis least along T, made
// perpendicular to it). Null when the frame has no tangent.
export function localFrame(frame) {
  const T = unit(vec(frame?.tangent));
  if (!T) return null;
  let N = null;
  if (frame.normal) N = unit(minus(vec(frame.normal), scaled(T, dot(vec(frame.normal), T))));
  else if (frame.binormal) N = unit(cross(vec(frame.binormal), T));
  const axes = [{ x: 1, y: 0, z: 0 }, { x: 0, y: 1, z: 0 }, { x: 0, y: 0, z: 1 }];
  const least = axes.reduce((a, b) => (Math.abs(dot(b, T)) < Math.abs(dot(a, T)) ? b : a));
  const fallbackNormal = unit(minus(least, scaled(T, dot(least, T))));
  return {
    p: vec(frame.position), T, N, B: N ? cross(T, N) : null, fallbackNormal,
    cusp: Boolean(frame.cusp), inflection: Boolean(frame.inflection),
  };
}

// The frame's own κ, τ, κ', τ' (absent: 0), the derivatives per metre of arc: under the
// per-parameter convention d/ds = d/du / |dp/du|, |dp/du| the frame's tangent scale or, not
// given, the one the last plan achieved there (`achieved`: PlanResponse.frames[i]).
// `unconverted` says a derivative per u was kept as given for want of a scale.
export function ownValues(frame, perParameter, achieved) {
  const values = {};
  let unconverted = false;
  const scale = frame?.tangentScale ?? achieved?.leave?.speed ?? achieved?.approach?.speed;
  for (const [key] of LOCAL_QUANTITIES) {
    let v = typeof frame?.[key] === 'number' ? frame[key] : 0;
    if (perParameter && key.endsWith('Derivative') && v !== 0) {
      if (scale > 0) v /= scale;
      else unconverted = true;
    }
    values[key] = v;
  }
  return { values, unconverted };
}

// The two AnalyzePath requests of one member of the local family: paths of one profile
// piece of length h from the frame, forward (the leaving side: T, or -T at a cusp; N, or -N
// at an inflection; κ(s) = κ + κ' s, τ(s) = τ + τ' s) and backward (the curve for s < 0
// traced away from the frame: -T, N, κ(σ) = κ - κ' σ, τ(σ) = τ - τ' σ; at a cusp too, so
// both branches of a cusp leave towards -T). The normal goes where the frame has one, or,
// where it has none, the fallback where the piece bends.
export function localRequests(frame, values, halfLength) {
  const { curvature: k, torsion: t, curvatureDerivative: dk, torsionDerivative: dt } = values;
  const bends = k !== 0 || dk !== 0;
  const N = frame.N || (bends ? frame.fallbackNormal : null);
  const branch = (tangent, normal, curvature, torsion) => {
    const start = { position: frame.p, tangent };
    if (normal) start.normal = normal;
    return {
      path: { start, pieces: [{ lengthM: halfLength, profile: { curvature, torsion } }] },
      analysisPoints: LOCAL_POINTS,
    };
  };
  return {
    normalChosen: !frame.N && bends,
    forward: branch(frame.cusp ? neg(frame.T) : frame.T, N && (frame.inflection ? neg(N) : N), [k, dk], [t, dt]),
    backward: branch(neg(frame.T), N, [k, -dk], [t, -dt]),
  };
}

const refusal = (error) =>
  error.fieldViolations?.map((v) => `${v.field}: ${v.description}`).join('; ') || error.summary || error.message;

export class Family {
  // getRequest(): the request edited; getReport(): the last plan's report (its frames'
  // achieved |dp/du| convert per-u derivatives), or null.
  constructor(root, view, getRequest, getReport = () => null) {
    this.root = root;
    this.view = view;
    this.getRequest = getRequest;
    this.getReport = getReport;
    this.form = root.querySelector('form');
    this.mode = root.querySelector('[name=mode]');
    this.frame = root.querySelector('[name=frame]');
    this.constraint = root.querySelector('[name=constraint]');
    this.from = root.querySelector('[name=from]');
    this.to = root.querySelector('[name=to]');
    this.count = root.querySelector('[name=count]');
    this.local = root.querySelector('.family-local');
    this.halfLength = root.querySelector('[name=halfLength]');
    this.held = Object.fromEntries(LOCAL_QUANTITIES.map(([key]) => [key, root.querySelector(`[name=local-${key}]`)]));
    this.note = root.querySelector('.family-note');
    this.legend = root.querySelector('.family-legend');
    this.status = root.querySelector('.family-status');
    this.target = root.querySelector('.family-target');
    this.fillConstraints(FAMILY_CONSTRAINTS);
    this.halfLength.value ||= String(DEFAULT_HALF_LENGTH);
    this.form.addEventListener('submit', (e) => {
      e.preventDefault();
      this.run();
    });
    root.querySelector('[data-action=clear]').addEventListener('click', () => this.clear());
    this.mode.addEventListener('change', () => {
      this.clear();
      this.updateMode();
      this.suggestRange();
    });
    this.frame.addEventListener('change', () => {
      if (this.isPieces()) this.fillConstraints(pieceParameters(this.pickedPiece()));
      this.updateHeld();
      this.suggestRange();
    });
    this.constraint.addEventListener('change', () => {
      this.updateHeld();
      this.suggestRange();
    });
    this.generation = 0;
    this.updateMode();
  }

  isLocal() {
    return this.mode.value === 'local';
  }

  // A path of pieces: the path mode sweeps a piece's parameters; the local mode, which needs
  // a key frame's constraints, is off.
  isPieces() {
    return Boolean(this.getRequest()?.path?.pieces?.length);
  }

  pickedPiece() {
    return this.getRequest()?.path?.pieces?.[Number(this.frame.value)];
  }

  // The constraint choices: [value, label] pairs, the current one kept where it remains.
  fillConstraints(list) {
    const current = this.constraint.value;
    this.constraint.replaceChildren();
    for (const [value, text] of list) {
      const option = document.createElement('option');
      option.value = value;
      option.textContent = text;
      option.dataset.pathLabel = text;
      this.constraint.append(option);
    }
    if (list.some(([value]) => value === current)) this.constraint.value = current;
  }

  // The local mode sweeps κ, τ, κ', τ' only (per metre), and shows what it holds.
  updateMode() {
    const local = this.isLocal();
    this.root.dataset.mode = local ? 'local' : 'path';
    this.local.hidden = !local;
    for (const option of this.constraint.options) {
      const quantity = LOCAL_QUANTITIES.find(([key]) => key === option.value);
      option.hidden = local && !quantity;
      option.disabled = local && !quantity;
      option.textContent = local && quantity
        ? `${option.dataset.pathLabel.replace(/ \[.*\]$/, '')} [${quantity[2]}]` : option.dataset.pathLabel;
    }
    if (local && this.constraint.selectedOptions[0]?.disabled) this.constraint.value = 'curvature';
    this.updateHeld();
  }

  // The key frame picked, its local frame and its own values per metre.
  pickedFrame() {
    const request = this.getRequest();
    const index = Number(this.frame.value);
    const frame = request?.path?.frames?.[index];
    if (!frame || this.frame.value === '') return null;
    const perParameter = request.path.derivativeConvention === 'DERIVATIVE_CONVENTION_PER_PARAMETER';
    const own = ownValues(frame, perParameter, this.getReport()?.frames?.[index]);
    return { index, frame, local: localFrame(frame), ...own };
  }

  // The held values' inputs: empty is the frame's own value (their placeholder); the swept
  // one is disabled.
  updateHeld() {
    const picked = this.pickedFrame();
    for (const [key, , unitText] of LOCAL_QUANTITIES) {
      const input = this.held[key];
      input.disabled = key === this.constraint.value;
      input.placeholder = key === this.constraint.value ? 'swept'
        : picked ? `frame's: ${fmt(picked.values[key])}` : unitText;
    }
  }

  // A change of the request that keeps its frames: the frame's own values may have changed;
  // on a path of pieces a piece's kind, and with it its parameters, may have.
  requestChanged() {
    if (this.isPieces() || this.root.dataset.targets === 'pieces') this.updateTargets(this.getRequest()?.path);
    else if (this.isLocal()) this.updateHeld();
  }

  // The frame choices follow the request's frames, or its pieces on a path of pieces.
  updateTargets(path) {
    const current = this.frame.value;
    const pieces = Boolean(path?.pieces?.length);
    const targets = (pieces ? path.pieces : path?.frames) || [];
    const wasPieces = this.target.textContent === 'piece';
    this.target.textContent = pieces ? 'piece' : 'frame';
    this.root.dataset.targets = pieces ? 'pieces' : 'frames';
    const localOption = this.mode.querySelector('option[value=local]');
    localOption.disabled = pieces;
    if (pieces && this.isLocal()) {
      this.mode.value = 'path';
      this.updateMode();
    }
    this.frame.replaceChildren();
    targets.forEach((target, i) => {
      const option = document.createElement('option');
      option.value = String(i);
      option.textContent = pieces ? `piece ${i} (${pieceKind(target)})` : `frame ${i}`;
      this.frame.append(option);
    });
    if (current && Number(current) < targets.length && wasPieces === pieces) this.frame.value = current;
    else if (targets.length > 1) this.frame.value = String(Math.min(1, targets.length - 1));
    if (pieces) this.fillConstraints(pieceParameters(this.pickedPiece()));
    else if (wasPieces) this.fillConstraints(FAMILY_CONSTRAINTS);
    if (wasPieces !== pieces) {
      this.from.value = '';
      this.to.value = '';
    }
    this.updateHeld();
    if (!this.from.value && !this.to.value) this.suggestRange();
  }

  // A range around the frame's current value: half to one and a half times it (the local
  // mode: its value per metre).
  suggestRange() {
    const key = this.constraint.value;
    let v;
    if (this.isLocal()) {
      const picked = this.pickedFrame();
      if (!picked) return;
      v = picked.values[key];
    } else if (this.isPieces()) {
      v = key === 'transitionTolerance' ? this.getRequest().path.transitionTolerance : getField(this.pickedPiece(), key);
      if (typeof v !== 'number' || v === 0) {
        const fallback = { transitionTolerance: [0.00005, 0.0005], 'clothoid.endCurvature': [0, 20] }[key] || [0.01, 0.1];
        [this.from.value, this.to.value] = fallback.map(String);
        return;
      }
    } else {
      const frames = this.getRequest()?.path?.frames || [];
      const f = frames[Number(this.frame.value)];
      if (!f) return;
      v = f[key];
    }
    if (typeof v === 'number' && v !== 0) {
      this.from.value = String(Number((v * 0.5).toPrecision(4)));
      this.to.value = String(Number((v * 1.5).toPrecision(4)));
    } else if (this.isLocal() && key.endsWith('Derivative')) {
      this.from.value = '-100';
      this.to.value = '100';
    } else {
      this.from.value = key === 'tangentScale' ? '0.1' : '0';
      this.to.value = key === 'tangentScale' ? '0.5' : '20';
    }
  }

  clear() {
    ++this.generation;
    this.view.setFamily([]);
    this.legend.replaceChildren();
    this.status.textContent = '';
    this.note.textContent = '';
    this.root.dataset.curves = '0';
    this.root.dataset.branches = '0';
    delete this.root.dataset.local;
    delete this.root.dataset.drawn;
  }

  // The N values of the range, or null (with the status saying why).
  sweepValues() {
    const a = Number(this.from.value);
    const b = Number(this.to.value);
    const n = Math.max(2, Math.min(50, Math.round(Number(this.count.value) || 5)));
    if (this.from.value.trim() === '' || this.to.value.trim() === '' || !Number.isFinite(a) || !Number.isFinite(b)) {
      return null;
    }
    return { a, b, n, values: Array.from({ length: n }, (_, k) => a + ((b - a) * k) / (n - 1)) };
  }

  run() {
    return this.isLocal() ? this.runLocal() : this.runPath();
  }

  async runPath() {
    const request = this.getRequest();
    const frame = Number(this.frame.value);
    const key = this.constraint.value;
    const sweep = this.sweepValues();
    const pieces = this.isPieces();
    const target = pieces ? 'piece' : 'frame';
    if (!(pieces ? request.path.pieces[frame] : request?.path?.frames?.[frame]) || !sweep) {
      this.status.textContent = `pick a ${target} and a numeric range`;
      return;
    }
    const member = (value) => (pieces ? withPieceParameter(request, frame, key, value) : withConstraint(request, frame, key, value));
    const label = pieces ? this.constraint.selectedOptions[0]?.textContent.replace(/ \[.*$/, '') ?? key : key;
    const { a, b, n, values } = sweep;
    const generation = ++this.generation;
    this.status.textContent = `planning ${n} curves…`;
    this.root.dataset.curves = '0';
    const results = await api.mapLimited(values, 2, async (value) => {
      try {
        const profile = await api.analyze(analysisRequest(member(value), 201));
        return { value, profile };
      } catch (error) {
        return { value, error };
      }
    });
    if (generation !== this.generation) return;
    const ok = results.filter((r) => r.profile);
    const curves = ok.map((r, k) => ({ points: r.profile.points || [], color: familyColor(k, ok.length), r }));
    this.view.setFamily(curves);
    this.legend.replaceChildren();
    const drawn = [];
    for (const c of curves) {
      const peak = Math.max(0, ...c.points.map((p) => p.curvature ?? 0));
      drawn.push({ value: c.r.value, arcLength: c.r.profile.arcLength ?? 0, peakCurvature: peak });
      this.legendItem(c.color, `${label} = ${fmt(c.r.value)}: length ${fmt(c.r.profile.arcLength ?? 0)} m, peak κ ${fmt(peak)} 1/m`);
    }
    for (const r of results.filter((x) => x.error)) this.refusedItem(`${label} = ${fmt(r.value)}: refused (${refusal(r.error)})`);
    this.root.dataset.drawn = JSON.stringify(drawn);
    this.root.dataset.curves = String(curves.length);
    this.root.dataset.branches = String(curves.length);
    this.status.textContent = `${curves.length} of ${n} curves drawn (${target} ${frame}, ${label} from ${fmt(a)} to ${fmt(b)})`;
    this.status.setAttribute('data-value', String(curves.length));
    this.finished();
  }

  // The local family: for each value, the two branches of the frame's local curve (2 N calls
  // of POST /v1/analyze, two at a time), drawn forward solid and backward dashed in the
  // member's colour, with the frame's T, N, B. What was asked and drawn is in data-local
  // (JSON: the frame, and per member its values, each branch's request and points).
  async runLocal() {
    const key = this.constraint.value;
    const picked = this.pickedFrame();
    const sweep = this.sweepValues();
    const h = Number(this.halfLength.value);
    if (!picked || !sweep) {
      this.status.textContent = 'pick a key frame and a numeric range';
      return;
    }
    if (!picked.local) {
      this.status.textContent = `frame ${picked.index} has no tangent`;
      return;
    }
    if (!(h > 0) || !Number.isFinite(h)) {
      this.status.textContent = 'the half-length must be a length > 0 [m]';
      return;
    }
    const held = { ...picked.values };
    for (const [k] of LOCAL_QUANTITIES) {
      const text = this.held[k].value.trim();
      if (k === key || text === '') continue;
      const v = Number(text);
      if (!Number.isFinite(v)) {
        this.status.textContent = `${k}: "${text}" is not a number`;
        return;
      }
      held[k] = v;
    }
    const { a, b, n, values } = sweep;
    const frame = picked.local;
    const generation = ++this.generation;
    this.status.textContent = `integrating ${n} local curves (${2 * n} branches)…`;
    this.root.dataset.curves = '0';
    this.root.dataset.branches = '0';
    const members = values.map((value) => {
      const memberValues = { ...held, [key]: value };
      return { value, values: memberValues, requests: localRequests(frame, memberValues, h) };
    });
    const jobs = members.flatMap((m) => [[m, 'forward'], [m, 'backward']]);
    await api.mapLimited(jobs, 2, async ([m, branch]) => {
      try {
        m[branch] = await api.analyze(m.requests[branch]);
      } catch (error) {
        m.errors = [...(m.errors || []), `${branch}: ${refusal(error)}`];
      }
    });
    if (generation !== this.generation) return;

    const ok = members.filter((m) => !m.errors);
    const curves = [];
    ok.forEach((m, k) => {
      m.color = familyColor(k, ok.length);
      curves.push({ points: m.forward.points || [], color: m.color, width: 3 });
      curves.push({ points: m.backward.points || [], color: m.color, width: 2, dashed: true });
    });
    const axes = [['T', frame.T]];
    const N = frame.N || (members.some((m) => m.requests.normalChosen) ? frame.fallbackNormal : null);
    if (N) axes.push(['N', N], ['B', cross(frame.T, N)]);
    this.view.setFamily(curves, { position: frame.p, axes, length: Math.min(0.15, Math.max(0.02, 0.5 * h)) });
    // The view on the frame and its local curves ("fit view" frames the whole curve again).
    let radius = 0.5 * h;
    for (const c of curves) {
      for (const q of c.points) {
        const d = minus(vec(q.position), frame.p);
        radius = Math.max(radius, Math.hypot(d.x, d.y, d.z));
      }
    }
    if (curves.length) this.view.focus(frame.p, radius);

    const [, symbol, unitText] = LOCAL_QUANTITIES.find(([k]) => k === key);
    this.legend.replaceChildren();
    for (const m of ok) {
      const points = [...(m.backward.points || []), ...(m.forward.points || [])];
      const peak = Math.max(0, ...points.map((p) => Math.abs(p.curvature ?? 0)));
      const ends = [m.backward.points?.at(-1), m.forward.points?.at(-1)].map((p) => vec(p?.position));
      const chord = Math.hypot(ends[0].x - ends[1].x, ends[0].y - ends[1].y, ends[0].z - ends[1].z);
      this.legendItem(m.color, `${symbol} = ${fmt(m.value)} ${unitText}: peak κ ${fmt(peak)} 1/m, chord of the ±${fmt(h)} m curve ${fmt(chord)} m`);
    }
    for (const m of members.filter((x) => x.errors)) {
      this.refusedItem(`${symbol} = ${fmt(m.value)} ${unitText}: refused (${m.errors.join('; ')})`);
    }

    const notes = [];
    const heldText = LOCAL_QUANTITIES.filter(([k]) => k !== key).map(([k, s]) => `${s} ${fmt(held[k])}`).join(', ');
    notes.push(`held: ${heldText}; forward solid, backward dashed`);
    if (frame.cusp) notes.push('cusp: both branches leave towards -T');
    if (frame.inflection) notes.push('inflection: the forward branch bends towards -N');
    if (members.some((m) => m.requests.normalChosen)) {
      const f = frame.fallbackNormal;
      notes.push(`frame ${picked.index} has no normal: N taken as (${fmt(f.x)}, ${fmt(f.y)}, ${fmt(f.z)}), perpendicular to T`);
    }
    if (picked.unconverted) notes.push("κ', τ' per unit u kept as given: no tangent scale to convert them per metre");
    this.note.textContent = notes.join('. ');

    const xyzs = (points) => (points || []).map((p) => [p.position?.x ?? 0, p.position?.y ?? 0, p.position?.z ?? 0, p.s ?? 0]);
    this.root.dataset.local = JSON.stringify({
      frame: picked.index, swept: key, halfLength: h,
      p: frame.p, T: frame.T, N: frame.N, B: frame.B, cusp: frame.cusp, inflection: frame.inflection,
      members: members.map((m) => ({
        value: m.value, values: m.values, drawn: !m.errors, errors: m.errors || [],
        forward: { start: m.requests.forward.path.start, profile: m.requests.forward.path.pieces[0].profile,
          points: xyzs(m.forward?.points) },
        backward: { start: m.requests.backward.path.start, profile: m.requests.backward.path.pieces[0].profile,
          points: xyzs(m.backward?.points) },
      })),
    });
    this.root.dataset.curves = String(ok.length);
    this.root.dataset.branches = String(curves.length);
    this.status.textContent = `${ok.length} of ${n} local curves drawn, ${curves.length} branches (frame ${picked.index}, ` +
      `${symbol} from ${fmt(a)} to ${fmt(b)} ${unitText}, ±${fmt(h)} m)`;
    this.status.setAttribute('data-value', String(ok.length));
    this.finished();
  }

  // data-runs: the families drawn so far (a run's end can be told from outside).
  finished() {
    this.root.dataset.runs = String(Number(this.root.dataset.runs || 0) + 1);
  }

  legendItem(color, text) {
    const li = document.createElement('li');
    const swatch = document.createElement('span');
    swatch.className = 'swatch';
    swatch.style.background = color;
    li.append(swatch, document.createTextNode(text));
    this.legend.append(li);
  }

  refusedItem(text) {
    const li = document.createElement('li');
    li.className = 'violation';
    li.textContent = text;
    this.legend.append(li);
  }
}
