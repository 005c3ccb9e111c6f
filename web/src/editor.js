// The path editor: a path of key frames (every field of a KeyFrame) or of pieces (a start
// frame and pieces: line, arc, helix, clothoid, profile, or a blend to a key frame), the
// path's settings (reading of unspecified constraints, blend, derivative convention,
// transition tolerance), or a joint path (a table of joint waypoints and the blend
// tolerance), the motion, the robot and the optimisers, written straight into
// the PlanRequest (proto JSON). Each input carries the request's field path (data-field),
// and an element beside it (data-error-for) shows the field violation the server returns
// for that path; where the server names a field otherwise than the JSON does (a piece's
// `path.pieces[1].radius` is the JSON's `path.pieces[1].arc.radius`), the input carries the
// server's name too (data-error-field).

import { getField, setField, isJointPath, requestKind, stepKind, KIND_NAMES } from './request.js';

const el = (tag, attrs = {}, ...children) => {
  const node = document.createElement(tag);
  for (const [key, value] of Object.entries(attrs)) {
    if (value === undefined || value === null) continue;
    if (key === 'class') node.className = value;
    else if (key === 'text') node.textContent = value;
    else if (key.startsWith('on')) node.addEventListener(key.slice(2), value);
    else node.setAttribute(key, value);
  }
  for (const child of children) if (child) node.append(child);
  return node;
};

// Enum options: value '' is the proto default (the field absent).
export const ENUMS = {
  unspecified: [
    ['', 'default (smoothest)'],
    ['UNSPECIFIED_CONSTRAINTS_SMOOTHEST', 'smoothest: free derivatives minimise jerk energy'],
    ['UNSPECIFIED_CONSTRAINTS_THESIS_ZEROS', "thesis's zeros: orders 1-4 fixed, 0 where not given"],
    ['UNSPECIFIED_CONSTRAINTS_LOWEST_DEGREE', 'lowest degree: only the given orders'],
  ],
  blend: [
    ['', 'default (polynomial)'],
    ['BLEND_METHOD_POLYNOMIAL', 'polynomial (App. B.2)'],
    ['BLEND_METHOD_TRAPEZOIDAL', 'generalized trapezoid (App. B)'],
  ],
  derivativeConvention: [
    ['', 'default (per metre of arc)'],
    ['DERIVATIVE_CONVENTION_PER_ARC_LENGTH', 'd/ds per metre of arc [1/m²]'],
    ['DERIVATIVE_CONVENTION_PER_PARAMETER', "d/du per unit u, the thesis's [1/m]"],
  ],
  orientationMode: [
    ['', 'default (fixed)'],
    ['ORIENTATION_MODE_FIXED', 'fixed'],
    ['ORIENTATION_MODE_FRAME_BASED', 'frame based (T, N, B to the next)'],
    ['ORIENTATION_MODE_CUSTOM', 'custom (orientation below)'],
    ['ORIENTATION_MODE_FRENET', 'Frenet frame'],
    ['ORIENTATION_MODE_PARALLEL_TRANSPORT', 'parallel transport'],
  ],
  profile: [
    ['', 'default (trapezoidal)'],
    ['MOTION_PROFILE_TRAPEZOIDAL', 'trapezoidal (Eq. 6.13)'],
    ['MOTION_PROFILE_S_CURVE', 'S-curve (jerk-limited)'],
  ],
  timeParameterization: [
    ['', 'default (exact arc length)'],
    ['TIME_PARAMETERIZATION_ARC_LENGTH', 'exact arc length'],
    ['TIME_PARAMETERIZATION_TAYLOR_SECOND_ORDER', "thesis's 2nd-order Taylor (Eq. 6.15)"],
    ['TIME_PARAMETERIZATION_TAYLOR_FIRST_ORDER', '1st-order Taylor (Eq. 6.9)'],
    ['TIME_PARAMETERIZATION_LINEAR', 'u linear in t (Eq. 6.3)'],
    ['TIME_PARAMETERIZATION_SMOOTH', 'u smooth in t (Eq. 6.5)'],
  ],
  approach: [
    ['', 'none: the path must start at the robot'],
    ['APPROACH_MOVE_JOINT', 'a joint move there first'],
    ['APPROACH_MOVE_LINEAR', 'a straight line there first'],
  ],
  tangentScaleObjective: [
    ['', 'off'],
    ['TANGENT_SCALE_OBJECTIVE_BENDING_ENERGY', 'bending energy ∫κ² ds'],
    ['TANGENT_SCALE_OBJECTIVE_PEAK_CURVATURE', 'peak curvature'],
    ['TANGENT_SCALE_OBJECTIVE_PEAK_TORSION', 'peak torsion'],
    ['TANGENT_SCALE_OBJECTIVE_ARC_LENGTH', 'arc length'],
  ],
};

// The scalar constraints of a key frame: key, label, unit (the derivatives' unit follows
// the path's derivative convention).
const FRAME_SCALARS = [
  ['curvature', 'curvature κ', '1/m'],
  ['torsion', 'torsion τ', '1/m'],
  ['curvatureDerivative', "κ'", 'deriv'],
  ['torsionDerivative', "τ'", 'deriv'],
  ['tangentScale', 'tangent scale |dp/du|', 'm'],
  ['leaveTangentScale', 'leaving tangent scale', 'm'],
];

function derivativeUnit(request) {
  return request.path?.derivativeConvention === 'DERIVATIVE_CONVENTION_PER_PARAMETER' ? '1/m per u' : '1/m²';
}

const formatNumber = (value) => (value === undefined || value === null ? '' : String(value));

// A box at least as wide as its text (CSS --chars: its length in digits, and one to spare),
// so that a value shows whole: 0.106 as 0.106, 0.06283185307179587 to its last digit.
function fitChars(input) {
  const set = () => input.style.setProperty('--chars', String(Math.max(3, input.value.length + 1)));
  set();
  input.addEventListener('input', set);
  return input;
}

export class Editor {
  // root: the element to fill; onChange(kind): called after every edit ('value' or
  // 'structure').
  constructor(root, onChange) {
    this.root = root;
    this.onChange = onChange;
    this.request = null;
    this.robots = [];
    this.localErrors = new Map();
    // What the other form of the path left when the editor switched (setPathForm).
    this.stash = {};
    this.pieceEnds = null;
  }

  setRobots(robots) {
    this.robots = robots;
    if (this.request) this.render(this.request);
  }

  errorSlot(field) {
    return el('div', { class: 'field-error', 'data-error-for': field, role: 'alert' });
  }

  // A number input bound to `field`. optional: an empty input removes the field;
  // errorField: the server's name of the field, where it is not `field`.
  numberInput(field, { optional = true, testid, placeholder, title, errorField } = {}) {
    const slot = errorField ?? field;
    const input = el('input', {
      type: 'text', inputmode: 'decimal', spellcheck: 'false', 'data-field': field,
      'data-error-field': errorField, 'data-testid': testid,
      placeholder: placeholder ?? (optional ? 'absent' : '0'), title,
      value: formatNumber(getField(this.request, field)),
    });
    fitChars(input);
    input.addEventListener('input', () => {
      const text = input.value.trim();
      if (text === '') {
        this.setLocalError(slot, null);
        setField(this.request, field, optional ? undefined : 0);
        this.onChange('value');
        return;
      }
      const value = Number(text);
      if (!Number.isFinite(value)) {
        this.setLocalError(slot, `"${text}" is not a number`);
        return;
      }
      this.setLocalError(slot, null);
      setField(this.request, field, value);
      this.onChange('value');
    });
    return input;
  }

  // Numbers separated by commas or spaces, bound to the repeated double `field` (kept, as
  // [], when empty: a message such as a profile piece must stay when its lists are empty).
  listInput(field, { testid, placeholder, errorField } = {}) {
    const slot = errorField ?? field;
    const input = el('input', {
      type: 'text', inputmode: 'decimal', spellcheck: 'false', 'data-field': field,
      'data-error-field': errorField, 'data-testid': testid, placeholder,
      value: (getField(this.request, field) || []).join(', '),
    });
    input.addEventListener('input', () => {
      const text = input.value.trim();
      const values = text.split(/[\s,]+/).filter(Boolean).map(Number);
      if (!values.every(Number.isFinite)) {
        this.setLocalError(slot, 'coefficients must be numbers, separated by commas');
        return;
      }
      this.setLocalError(slot, null);
      setField(this.request, field, values);
      this.onChange('value');
    });
    return input;
  }

  // A Vec3 (x, y, z) bound to `field`; optional: three empty inputs remove it.
  vecInput(field, label, { optional = false, testid, unit } = {}) {
    const inputs = [];
    const current = getField(this.request, field);
    const commit = () => {
      const texts = inputs.map((i) => i.value.trim());
      if (optional && texts.every((t) => t === '')) {
        this.setLocalError(field, null);
        setField(this.request, field, undefined);
        this.onChange('value');
        return;
      }
      const values = texts.map((t) => (t === '' ? 0 : Number(t)));
      if (!values.every(Number.isFinite)) {
        this.setLocalError(field, 'each component must be a number');
        return;
      }
      this.setLocalError(field, null);
      setField(this.request, field, { x: values[0], y: values[1], z: values[2] });
      this.onChange('value');
    };
    for (const axis of ['x', 'y', 'z']) {
      const value = current === undefined ? '' : formatNumber(current[axis] ?? 0);
      const input = el('input', {
        type: 'text', inputmode: 'decimal', spellcheck: 'false', 'data-field': `${field}.${axis}`,
        'data-testid': testid ? `${testid}-${axis}` : undefined, placeholder: optional ? axis : '0',
        'aria-label': `${label} ${axis}`, value,
      });
      input.addEventListener('input', commit);
      inputs.push(fitChars(input));
    }
    return el('div', { class: 'row vec-row', 'data-field': field },
      el('label', { text: label }), el('div', { class: 'vec' }, ...inputs),
      unit ? el('span', { class: 'unit', text: unit }) : null, this.errorSlot(field));
  }

  scalarRow(field, label, unit, options = {}) {
    return el('div', { class: 'row' }, el('label', { text: label }), this.numberInput(field, options),
      el('span', { class: 'unit', text: unit }), this.errorSlot(options.errorField ?? field));
  }

  listRow(field, label, unit, options = {}) {
    return el('div', { class: 'row wide-row' }, el('label', { text: label }), this.listInput(field, options),
      el('span', { class: 'unit', text: unit }), this.errorSlot(options.errorField ?? field));
  }

  checkRow(field, label, testid) {
    const input = el('input', { type: 'checkbox', 'data-field': field, 'data-testid': testid });
    input.checked = Boolean(getField(this.request, field));
    input.addEventListener('change', () => {
      setField(this.request, field, input.checked ? true : undefined);
      this.onChange('value');
    });
    return el('label', { class: 'check' }, input, document.createTextNode(` ${label}`), this.errorSlot(field));
  }

  selectRow(field, label, options, testid, structural = false) {
    const select = el('select', { 'data-field': field, 'data-testid': testid });
    const current = getField(this.request, field) ?? '';
    for (const [value, text] of options) {
      const option = el('option', { value, text });
      if (value === current) option.selected = true;
      select.append(option);
    }
    if (current && !options.some(([value]) => value === current)) {
      select.append(el('option', { value: current, text: current, selected: 'selected' }));
    }
    select.addEventListener('change', () => {
      setField(this.request, field, select.value || undefined);
      // No model: the whole robot goes (its other settings mean nothing without one).
      if (field === 'robot.name' && !select.value) delete this.request.robot;
      // κ' and τ' are read in the new convention: their unit labels say so at once.
      if (field === 'path.derivativeConvention') this.updateDerivativeUnits();
      if (structural) this.render(this.request);
      this.onChange(structural ? 'structure' : 'value');
    });
    return el('div', { class: 'row select-row' }, el('label', { text: label }), select, this.errorSlot(field));
  }

  frameCard(i) {
    const base = `path.frames[${i}]`;
    const frames = this.request.path.frames;
    const card = el('fieldset', { class: 'frame', 'data-testid': `frame-${i}`, 'data-field': base });
    const remove = el('button', { type: 'button', class: 'small', title: 'remove this key frame',
      'data-testid': `frame-${i}-remove`, text: '✕ remove' });
    remove.disabled = frames.length <= 2;
    remove.addEventListener('click', () => {
      frames.splice(i, 1);
      this.render(this.request);
      this.onChange('structure');
    });
    const insert = el('button', { type: 'button', class: 'small', title: 'insert a key frame after this one',
      'data-testid': `frame-${i}-insert`, text: '+ after' });
    insert.addEventListener('click', () => {
      frames.splice(i + 1, 0, interpolatedFrame(frames[i], frames[i + 1]));
      this.render(this.request);
      this.onChange('structure');
    });
    card.append(el('legend', {}, el('span', { text: `frame ${i}` }), insert, remove));
    card.append(this.errorSlot(base));
    this.keyFrameFields(card, base, `frame-${i}`);
    return card;
  }

  // The fields of the KeyFrame at `base` (a key frame, or the frame a piece blends to),
  // appended to `card`; their test ids start with `prefix`.
  keyFrameFields(card, base, prefix) {
    const dUnit = derivativeUnit(this.request);
    card.append(this.vecInput(`${base}.position`, 'position', { testid: `${prefix}-input-position`, unit: 'm' }));
    card.append(this.vecInput(`${base}.tangent`, 'tangent T', { testid: `${prefix}-input-tangent` }));
    card.append(this.vecInput(`${base}.normal`, 'normal N', { optional: true, testid: `${prefix}-input-normal` }));
    for (const [key, label, unit] of FRAME_SCALARS.slice(0, 5)) {
      const row = this.scalarRow(`${base}.${key}`, label, unit === 'deriv' ? dUnit : unit,
        { testid: `${prefix}-input-${key}` });
      // Marked so that a change of the path's derivative convention relabels it.
      if (unit === 'deriv') row.querySelector('.unit').dataset.derivativeUnit = '';
      card.append(row);
    }
    card.append(el('div', { class: 'checks' },
      this.checkRow(`${base}.cusp`, 'cusp', `${prefix}-input-cusp`),
      this.checkRow(`${base}.inflection`, 'inflection', `${prefix}-input-inflection`),
      this.checkRow(`${base}.stop`, 'stop', `${prefix}-input-stop`)));
    const more = el('details', { class: 'more' }, el('summary', { text: 'binormal, leaving scale, tool orientation' }));
    more.append(this.vecInput(`${base}.binormal`, 'binormal B', { optional: true, testid: `${prefix}-input-binormal` }));
    more.append(this.scalarRow(`${base}.leaveTangentScale`, 'leaving tangent scale', 'm',
      { testid: `${prefix}-input-leaveTangentScale` }));
    more.append(this.selectRow(`${base}.orientationMode`, 'orientation mode', ENUMS.orientationMode,
      `${prefix}-input-orientationMode`));
    more.append(this.quaternionRow(`${base}.orientation`));
    more.append(this.checkRow(`${base}.easeOrientation`, 'ease the orientation (quintic)', `${prefix}-input-easeOrientation`));
    if (getField(this.request, `${base}.binormal`) || getField(this.request, `${base}.leaveTangentScale`) !== undefined ||
        getField(this.request, `${base}.orientationMode`)) {
      more.open = true;
    }
    card.append(more);
  }

  quaternionRow(field, label = 'orientation w x y z', testid = undefined) {
    const q = el('div', { class: 'row vec-row', 'data-field': field }, el('label', { text: label }));
    const quat = el('div', { class: 'vec quat' });
    for (const c of ['w', 'x', 'y', 'z']) {
      quat.append(this.numberInput(`${field}.${c}`, { placeholder: c, testid: testid ? `${testid}-${c}` : undefined }));
    }
    q.append(quat, this.errorSlot(field));
    return q;
  }

  // The frame a path of pieces starts from: position, tangent, normal (where the first piece
  // bends), the orientation mode and the orientation held; its curvature, torsion and
  // tangent scales only count when piece 0 blends to a key frame.
  startCard() {
    const base = 'path.start';
    const card = el('fieldset', { class: 'frame start', 'data-testid': 'start', 'data-field': base },
      el('legend', {}, el('span', { text: 'start' })));
    card.append(this.errorSlot(base));
    card.append(this.vecInput(`${base}.position`, 'position', { testid: 'start-input-position', unit: 'm' }));
    card.append(this.vecInput(`${base}.tangent`, 'tangent T', { testid: 'start-input-tangent' }));
    card.append(this.vecInput(`${base}.normal`, 'normal N', { optional: true, testid: 'start-input-normal' }));
    card.append(this.selectRow(`${base}.orientationMode`, 'orientation mode', ENUMS.orientationMode,
      'start-input-orientationMode'));
    const more = el('details', { class: 'more' },
      el('summary', { text: 'orientation held; κ, τ, scales (when piece 0 is "to")' }));
    more.append(this.quaternionRow(`${base}.orientation`));
    let given = getField(this.request, `${base}.orientation`) !== undefined;
    for (const [key, label, unit] of FRAME_SCALARS) {
      more.append(this.scalarRow(`${base}.${key}`, label, unit === 'deriv' ? '1/m²' : unit,
        { testid: `start-input-${key}` }));
      given ||= getField(this.request, `${base}.${key}`) !== undefined;
    }
    more.open = given;
    card.append(more);
    return card;
  }

  // Piece i of a path of pieces: its kind, its length and its kind's fields (for `to`, a
  // whole key frame); moved up or down, removed (one at least).
  pieceCard(i) {
    const base = `path.pieces[${i}]`;
    const pieces = this.request.path.pieces;
    const piece = pieces[i];
    const kind = pieceKind(piece);
    const card = el('fieldset', { class: 'frame piece', 'data-testid': `piece-${i}`, 'data-field': base,
      'data-kind': kind || '' });
    const button = (text, title, testid, disabled, action) => {
      const b = el('button', { type: 'button', class: 'small', title, 'data-testid': testid, text });
      b.disabled = disabled;
      b.addEventListener('click', () => {
        action();
        this.render(this.request);
        this.onChange('structure');
      });
      return b;
    };
    const swap = (j) => { [pieces[i], pieces[j]] = [pieces[j], pieces[i]]; };
    card.append(el('legend', {}, el('span', { text: `piece ${i}` }),
      button('↑', 'move this piece up', `piece-${i}-up`, i === 0, () => swap(i - 1)),
      button('↓', 'move this piece down', `piece-${i}-down`, i === pieces.length - 1, () => swap(i + 1)),
      button('✕ remove', 'remove this piece', `piece-${i}-remove`, pieces.length <= 1, () => pieces.splice(i, 1))));
    card.append(this.errorSlot(base));

    const select = el('select', { 'data-field': `${base}.kind`, 'data-testid': `piece-${i}-kind` });
    for (const [value, text] of PIECE_KINDS) {
      const option = el('option', { value, text });
      if (value === kind) option.selected = true;
      select.append(option);
    }
    if (!kind) select.prepend(el('option', { value: '', text: 'no shape given', selected: 'selected' }));
    select.addEventListener('change', () => {
      pieces[i] = newPiece(select.value, piece, this.pieceStartGuess(i));
      this.render(this.request);
      this.onChange('structure');
    });
    card.append(el('div', { class: 'row' }, el('label', { text: 'kind' }), select));

    if (kind === 'to') {
      card.append(el('div', { class: 'note', text: 'a blend from where the previous piece ends to this key frame' }));
      this.keyFrameFields(card, `${base}.to`, `piece-${i}`);
      return card;
    }
    card.append(this.scalarRow(`${base}.lengthM`, 'length', 'm', { optional: false, testid: `piece-${i}-input-lengthM` }));
    // The kind's fields, named by the server without the kind (path.pieces[i].radius).
    for (const [key, label, unit, list] of PIECE_FIELDS[kind] || []) {
      const options = { optional: false, testid: `piece-${i}-input-${key}`, errorField: `${base}.${key}` };
      card.append(list ? this.listRow(`${base}.${kind}.${key}`, label, unit, { ...options, placeholder: 'c0, c1, c2, …' })
        : this.scalarRow(`${base}.${kind}.${key}`, label, unit, options));
    }
    return card;
  }

  // Where piece i starts, as far as the page knows (the plan's joins, else the start
  // frame): a new `to` piece's key frame is put 0.1 m on from there.
  pieceStartGuess(i) {
    const known = i > 0 ? this.pieceEnds?.[i - 1] : null;
    if (known) return known;
    const start = this.request.path.start || {};
    return { position: start.position || {}, tangent: start.tangent || { x: 1 } };
  }

  // The ends of the pieces ({position, tangent} of each, from the last plan), for new `to`
  // pieces.
  setPieceEnds(ends) {
    this.pieceEnds = ends;
  }

  // Key frames <-> pieces. What one form leaves is kept aside while the other is edited, so
  // that switching back gives it again; a form switched to for the first time is converted:
  // key frames become the start and a `to` piece per further frame; pieces become the start
  // and the frames of their `to` pieces (two frames at least).
  setPathForm(form) {
    const path = this.request.path;
    if (form === pathForm(path)) return;
    const take = (keys) => {
      const out = {};
      for (const key of keys) {
        if (path[key] !== undefined) out[key] = path[key];
        delete path[key];
      }
      return out;
    };
    if (form === 'pieces') {
      const frames = path.frames || [];
      this.stash.frames = take(FRAMES_ONLY);
      if (this.stash.pieces) Object.assign(path, this.stash.pieces);
      else if (!path.start && !path.pieces?.length) {
        const first = cloneJson(frames[0]) || { position: { x: 0, y: 0, z: 0.5 }, tangent: { x: 1 } };
        path.start = first;
        path.pieces = frames.slice(1).map((f) => ({ to: cloneJson(f) }));
        if (!path.pieces.length) path.pieces.push({ lengthM: 0.1, line: {} });
      }
    } else {
      const start = path.start;
      const pieces = path.pieces || [];
      this.stash.pieces = take(PIECES_ONLY);
      if (this.stash.frames) Object.assign(path, this.stash.frames);
      else if (!path.frames?.length) {
        const frames = [cloneJson(start) || { position: { x: 0, y: 0, z: 0.5 }, tangent: { x: 1 } }];
        for (const p of pieces) if (p.to) frames.push(cloneJson(p.to));
        while (frames.length < 2) frames.push(extrapolatedFrame(frames[frames.length - 1]));
        path.frames = frames;
      }
    }
    this.render(this.request);
    this.onChange('structure');
  }

  render(request) {
    // Another request (loaded, a start page's choice): what a path form left is not its.
    if (request !== this.request) {
      this.stash = {};
      this.pieceEnds = null;
    }
    // What a render of the same request must not lose (the robots' list arriving, a
    // structural edit): the folds left open, and the text being typed, which may not be a
    // number yet, with its caret.
    const kept = request === this.request ? this.editingState() : null;
    this.request = request;
    this.localErrors.clear();
    this.root.replaceChildren();
    if (isJointPath(request)) {
      delete this.root.dataset.pathForm;
      this.root.dataset.kind = 'jointPath';
      this.root.append(this.jointPathCard());
      this.appendSettings(request, true);
      this.restoreEditing(kept);
      return;
    }
    const kind = requestKind(request);
    if (kind !== 'path') {
      delete this.root.dataset.pathForm;
      this.root.dataset.kind = kind;
      if (kind === 'sequence') this.root.append(this.sequenceCard());
      else this.root.append(this.moveCard(kind, kind, kind));
      this.appendSettings(request, false);
      this.restoreEditing(kept);
      return;
    }
    this.root.dataset.kind = 'path';
    request.path ??= { frames: [] };
    const form = pathForm(request.path);
    if (form === 'frames') request.path.frames ??= [];
    else request.path.pieces ??= [];
    this.root.dataset.pathForm = form;

    const path = el('fieldset', { class: 'settings', 'data-field': 'path' }, el('legend', { text: 'path' }));
    path.append(this.errorSlot('path'));
    const formSelect = el('select', { 'data-testid': 'path-form', 'aria-label': 'the form of the path' });
    for (const [value, text] of [['frames', 'key frames'], ['pieces', 'pieces (start and pieces)']]) {
      const option = el('option', { value, text });
      if (value === form) option.selected = true;
      formSelect.append(option);
    }
    formSelect.addEventListener('change', () => this.setPathForm(formSelect.value));
    path.append(el('div', { class: 'row select-row' }, el('label', { text: 'path of' }), formSelect));
    path.append(this.selectRow('path.unspecified', 'unspecified constraints', ENUMS.unspecified, 'path-unspecified'));
    if (form === 'frames') {
      path.append(this.selectRow('path.blend', 'blend', ENUMS.blend, 'path-blend'));
      path.append(this.selectRow('path.derivativeConvention', "κ', τ' convention", ENUMS.derivativeConvention,
        'path-derivativeConvention'));
    } else {
      path.append(this.scalarRow('path.transitionTolerance', 'transition tolerance', 'm',
        { testid: 'path-transitionTolerance', placeholder: 'absent: rest at joins',
          title: 'where curvature or torsion jumps between pieces, a transition within this distance of them' }));
    }
    path.append(this.scalarRow('path.maxCurvature', 'max curvature (warning)', '1/m', { testid: 'path-maxCurvature' }));
    if (form === 'frames') {
      path.append(el('div', { class: 'checks' }, this.checkRow('path.closed', 'closed path', 'path-closed')));
      path.append(this.errorSlot('path.frames'));
    } else {
      path.append(this.errorSlot('path.pieces'));
    }
    this.root.append(path);

    if (form === 'frames') {
      request.path.frames.forEach((_, i) => this.root.append(this.frameCard(i)));
      const add = el('button', { type: 'button', 'data-testid': 'frame-add', text: '+ add a key frame at the end' });
      add.addEventListener('click', () => {
        const frames = request.path.frames;
        const last = frames[frames.length - 1];
        frames.push(last ? extrapolatedFrame(last) : { position: { x: 0, y: 0, z: 0.5 }, tangent: { x: 1 } });
        this.render(request);
        this.onChange('structure');
      });
      this.root.append(add);
    } else {
      request.path.start ??= { position: { x: 0, y: 0, z: 0.5 }, tangent: { x: 1 } };
      this.root.append(this.startCard());
      request.path.pieces.forEach((_, i) => this.root.append(this.pieceCard(i)));
      const add = el('button', { type: 'button', 'data-testid': 'piece-add', text: '+ add a piece at the end' });
      add.addEventListener('click', () => {
        request.path.pieces.push({ lengthM: 0.1, line: {} });
        this.render(request);
        this.onChange('structure');
      });
      this.root.append(add);
    }

    this.appendSettings(request, false);
    this.restoreEditing(kept);
  }

  // The motion, the robot and the optimisers. jointPath: a joint path is timed by its
  // joints' limits (the Cartesian limits, the speed profile and u(t) do not apply) and
  // starts at its first waypoint (no approach move, no tangent scales): those fields are
  // shown only when the request gives them (the server refuses some of them: they can be
  // emptied here).
  appendSettings(request, jointPath) {
    const shown = (field) => !jointPath || getField(request, field) !== undefined;
    const motion = el('fieldset', { class: 'settings', 'data-field': 'motion' }, el('legend', { text: 'motion' }));
    motion.append(this.errorSlot('motion'));
    motion.append(this.scalarRow('motion.durationS', 'duration (0: fastest)', 's', { testid: 'motion-durationS' }));
    if (shown('motion.profile')) motion.append(this.selectRow('motion.profile', 'speed profile', ENUMS.profile, 'motion-profile'));
    if (shown('motion.rampFraction')) motion.append(this.scalarRow('motion.rampFraction', 'ramp fraction', '', { testid: 'motion-rampFraction' }));
    if (shown('motion.rampTimeS')) motion.append(this.scalarRow('motion.rampTimeS', 'ramp time', 's', { testid: 'motion-rampTimeS' }));
    motion.append(this.scalarRow('motion.cycleRateHz', 'cycle rate', 'Hz', { testid: 'motion-cycleRateHz' }));
    if (shown('motion.timeParameterization')) {
      motion.append(this.selectRow('motion.timeParameterization', 'u(t)', ENUMS.timeParameterization, 'motion-timeParameterization'));
    }
    if (shown('motion.speedScale')) motion.append(this.scalarRow('motion.speedScale', 'speed scale', '', { testid: 'motion-speedScale' }));
    if (shown('motion.maxSpeed')) motion.append(this.scalarRow('motion.maxSpeed', 'max speed', 'm/s', { testid: 'motion-maxSpeed' }));
    if (shown('motion.maxAcceleration')) {
      motion.append(this.scalarRow('motion.maxAcceleration', 'max acceleration', 'm/s²', { testid: 'motion-maxAcceleration' }));
    }
    this.root.append(motion);

    const robot = el('fieldset', { class: 'settings', 'data-field': 'robot' }, el('legend', { text: 'robot' }));
    robot.append(this.errorSlot('robot'));
    const names = [['', jointPath ? 'none (a joint path needs one)' : 'none (Cartesian plan)'],
      ...this.robots.map((r) => [r.name, r.name])];
    if (!request.robot?.model && !request.robot?.urdf) {
      robot.append(this.selectRow('robot.name', 'model', names, 'robot-name', true));
    } else {
      robot.append(el('div', { class: 'note', text: 'an inline robot model (kept as loaded)' }));
    }
    if (request.robot) {
      robot.append(this.checkRow('robot.reportOnly', 'report limit violations instead of refusing', 'robot-reportOnly'));
      robot.append(this.jointsRow('robot.initialJoints', 'initial joints', 'robot-initialJoints'));
      if (shown('robot.approach') && (request.path || getField(request, 'robot.approach') !== undefined)) robot.append(this.selectRow('robot.approach', 'path away from the robot', ENUMS.approach, 'robot-approach'));
      robot.append(this.scalarRow('robot.velocityScale', 'velocity scale', '', { testid: 'robot-velocityScale' }));
      robot.append(this.scalarRow('robot.accelerationScale', 'acceleration scale', '', { testid: 'robot-accelerationScale' }));
    }
    this.root.append(robot);

    const optimize = el('fieldset', { class: 'settings', 'data-field': 'optimize' }, el('legend', { text: 'optimise' }));
    optimize.append(this.errorSlot('optimize'));
    optimize.append(this.checkRow('optimize.timing.timeOptimal',
      jointPath ? 'the time-optimal sweep alone (not jerk-limited)' : 'time-optimal timing within the limits',
      'optimize-timeOptimal'));
    if (shown('optimize.tangentScales.objective')) {
      optimize.append(this.selectRow('optimize.tangentScales.objective', 'tangent scales', ENUMS.tangentScaleObjective,
        'optimize-tangentScales'));
    }
    this.root.append(optimize);
  }

  // The open folds (by their card's field and their summary) and the focused input's field,
  // text and selection.
  editingState() {
    const fold = (d) => `${d.parentElement?.closest('[data-field]')?.getAttribute('data-field') ?? ''}|` +
      `${d.querySelector('summary')?.textContent ?? ''}`;
    const active = document.activeElement;
    const inside = active && this.root.contains(active);
    const typing = inside && active.tagName === 'INPUT' && active.type === 'text';
    return {
      fold,
      open: new Set([...this.root.querySelectorAll('details[open]')].map(fold)),
      field: inside ? active.getAttribute('data-field') : null,
      text: typing ? { value: active.value, start: active.selectionStart, end: active.selectionEnd } : null,
    };
  }

  restoreEditing(kept) {
    if (!kept) return;
    for (const d of this.root.querySelectorAll('details')) if (kept.open.has(kept.fold(d))) d.open = true;
    if (!kept.field) return;
    const again = this.root.querySelector(`[data-field="${CSS.escape(kept.field)}"]`);
    if (!again || !again.focus) return;
    if (kept.text && again.tagName === 'INPUT' && again.type === 'text') {
      again.value = kept.text.value;
      again.focus();
      again.setSelectionRange(kept.text.start, kept.text.end);
    } else {
      again.focus();
    }
  }

  // A tool pose (position [m] and orientation, a unit quaternion w x y z) at `base`.
  poseRows(card, base, label, prefix, optional = false) {
    card.append(this.vecInput(`${base}.position`, `${label} position`, { optional, testid: `${prefix}-position`, unit: 'm' }));
    card.append(this.quaternionRow(`${base}.orientation`, `${label} orientation w x y z`, `${prefix}-orientation`));
  }

  // A joint move or a linear move at `base` (the request's jointMove or linearMove, or a
  // sequence step's): its start and its goal, as joint values or as a tool pose, whichever
  // the request gives (an absent start is where the robot is: its initial joints, or where
  // the step before ends).
  moveFields(card, kind, base, prefix) {
    const move = getField(this.request, base) || {};
    if (kind === 'jointMove') {
      card.append(this.jointsRow(`${base}.start`, 'start joints', `${prefix}-start`,
        'absent: where the robot is'));
      if (move.goalPose) this.poseRows(card, `${base}.goalPose`, 'goal', `${prefix}-goalPose`);
      else card.append(this.jointsRow(`${base}.goal`, 'goal joints', `${prefix}-goal`, 'one value per joint'));
    } else {
      if (move.start) this.poseRows(card, `${base}.start`, 'start', `${prefix}-start`, true);
      else card.append(el('div', { class: 'note', text: 'start: where the robot is (its initial joints, or where the step before ends)' }));
      if (move.goalJoints) card.append(this.jointsRow(`${base}.goalJoints`, 'goal joints', `${prefix}-goalJoints`, 'one value per joint'));
      else this.poseRows(card, `${base}.goal`, 'goal', `${prefix}-goal`);
    }
  }

  // A request of one move (jointMove, linearMove).
  moveCard(kind, base, prefix) {
    const card = el('fieldset', { class: 'settings move', 'data-field': base, 'data-testid': prefix },
      el('legend', { text: KIND_NAMES[kind] }));
    card.append(this.errorSlot(base));
    card.append(el('div', { class: 'note', text: kind === 'jointMove'
      ? 'every joint from its start to its goal on one synchronised profile (thesis 6.2.2.1)'
      : 'the tool on a straight line to its goal, turning by SLERP (thesis 6.2.2.2)' }));
    this.moveFields(card, kind, base, prefix);
    return card;
  }

  // A sequence: a card per step, its kind, its move's start and goal (a path or a joint path
  // in it is shown, not edited here), its own duration and the blend to the next step.
  sequenceCard() {
    const steps = this.request.sequence;
    const card = el('fieldset', { class: 'settings sequence', 'data-field': 'sequence', 'data-testid': 'sequence' },
      el('legend', { text: `sequence of ${steps.length} steps` }));
    card.append(this.errorSlot('sequence'));
    card.append(el('div', { class: 'note', text: 'steps in order, each from where the one before ends; the robot rests '
      + 'between them unless a blend tolerance joins a line to the next' }));
    steps.forEach((step, i) => {
      const base = `sequence[${i}]`;
      const kind = stepKind(step);
      const box = el('fieldset', { class: 'frame step', 'data-testid': `step-${i}`, 'data-field': base, 'data-kind': kind },
        el('legend', {}, el('span', { text: `step ${i}: ${KIND_NAMES[kind] || 'no motion given'}` })));
      box.append(this.errorSlot(base));
      if (kind === 'jointMove' || kind === 'linearMove') {
        this.moveFields(box, kind, `${base}.${kind}`, `step-${i}-${kind}`);
      } else if (kind === 'path') {
        const path = step.path;
        const what = path.frames?.length ? `${path.frames.length} key frames` : `${(path.pieces || []).length} pieces`;
        box.append(el('div', { class: 'note', text: `a path of ${what}: drawn with the motion; open it as a request of its own to edit it` }));
        box.append(this.errorSlot(`${base}.path`));
      } else if (kind === 'jointPath') {
        box.append(el('div', { class: 'note', text: `${(step.jointPath.waypoints || []).length} joint waypoints: drawn with the motion; `
          + 'open them as a request of their own to edit them' }));
        box.append(this.errorSlot(`${base}.jointPath`));
      }
      box.append(this.scalarRow(`${base}.motion.durationS`, 'duration', 's',
        { testid: `step-${i}-durationS`, placeholder: "the request's" }));
      box.append(this.scalarRow(`${base}.blendTolerance`, 'blend to the next', 'm',
        { testid: `step-${i}-blendTolerance`, placeholder: 'absent: rest' }));
      card.append(box);
    });
    return card;
  }

  // The request's robot model (a built-in one by name, or inline), or null.
  robotModel() {
    const spec = this.request.robot;
    if (!spec) return null;
    return spec.model || this.robots.find((r) => r.name === spec.name) || null;
  }

  // A joint path: the blend tolerance and a table of the waypoints, a row each (one input
  // per joint, `stop`, insert after, remove), a column per joint of the robot (or per value
  // of the longest waypoint, if more). The server's messages go under each row: its
  // `jointPath.waypoints[i].positions[j]` at that row, the input marked.
  jointPathCard() {
    const jointPath = this.request.jointPath;
    jointPath.waypoints ??= [];
    const waypoints = jointPath.waypoints;
    const card = el('fieldset', { class: 'settings joint-path', 'data-field': 'jointPath', 'data-testid': 'joint-path' },
      el('legend', { text: 'joint path' }));
    card.append(this.errorSlot('jointPath'));
    card.append(el('div', { class: 'note', text: 'joint waypoints passed without stopping, on blends within the '
      + 'tolerance of each interior one; the first and last met exactly, a stop rests there' }));
    card.append(this.scalarRow('jointPath.blendTolerance', 'blend tolerance', 'rad',
      { testid: 'jointPath-blendTolerance', placeholder: '0: rest at each',
        title: 'the largest joint-space distance (over all joints, rad and m together) at which the path passes an interior waypoint' }));
    card.append(this.errorSlot('jointPath.waypoints'));

    const model = this.robotModel();
    const names = (model?.links?.length ? model.links : model?.joints || []).map((j) => j.name || '');
    const limits = model?.limits || [];
    const columns = Math.max(names.length, limits.length, ...waypoints.map((w) => (w.positions || []).length), 1);
    const table = el('table', { class: 'waypoints', 'data-testid': 'waypoints' });
    const head = el('tr', {}, el('th', { text: '#' }));
    for (let j = 0; j < columns; ++j) {
      const l = limits[j];
      const range = l ? ` [${l.minPosition ?? 0}, ${l.maxPosition ?? 0}]` : '';
      head.append(el('th', { text: `j${j}`, title: `joint ${j}${names[j] ? ` ${names[j]}` : ''}${range} [rad or m]` }));
    }
    head.append(el('th', { text: 'stop', title: 'rest at this waypoint' }), el('th'));
    table.append(el('thead', {}, head));
    const body = el('tbody');
    const edit = (action) => () => {
      action();
      this.render(this.request);
      this.onChange('structure');
    };
    waypoints.forEach((waypoint, i) => {
      const base = `jointPath.waypoints[${i}]`;
      const row = el('tr', { 'data-testid': `waypoint-${i}`, 'data-field': base }, el('td', { class: 'index', text: `${i}` }));
      for (let j = 0; j < columns; ++j) row.append(el('td', {}, this.jointInput(i, j)));
      const stop = el('input', { type: 'checkbox', 'data-field': `${base}.stop`, 'data-testid': `waypoint-${i}-stop`,
        title: `rest at waypoint ${i}` });
      stop.checked = Boolean(waypoint.stop);
      stop.addEventListener('change', () => {
        setField(this.request, `${base}.stop`, stop.checked ? true : undefined);
        this.onChange('value');
      });
      const insert = el('button', { type: 'button', class: 'small', text: '+', 'data-testid': `waypoint-${i}-insert`,
        title: i < waypoints.length - 1 ? `insert a waypoint halfway to waypoint ${i + 1}` : 'add a copy of this waypoint after it' });
      insert.addEventListener('click', edit(() => waypoints.splice(i + 1, 0, midWaypoint(waypoint, waypoints[i + 1]))));
      const remove = el('button', { type: 'button', class: 'small', text: '✕', 'data-testid': `waypoint-${i}-remove`,
        title: `remove waypoint ${i}` });
      remove.disabled = waypoints.length <= 2;
      remove.addEventListener('click', edit(() => waypoints.splice(i, 1)));
      row.append(el('td', {}, stop), el('td', { class: 'actions' }, insert, remove));
      body.append(row);
      // The messages of this waypoint: the row's, its count's, each value's.
      const slots = el('td', { colspan: String(columns + 3) }, this.errorSlot(base), this.errorSlot(`${base}.positions`));
      for (let j = 0; j < columns; ++j) slots.append(this.errorSlot(`${base}.positions[${j}]`));
      body.append(el('tr', { class: 'waypoint-errors' }, slots));
    });
    table.append(body);
    card.append(el('div', { class: 'table-wrap' }, table));
    const add = el('button', { type: 'button', 'data-testid': 'waypoint-add', text: '+ add a waypoint at the end' });
    add.addEventListener('click', edit(() => waypoints.push(midWaypoint(waypoints[waypoints.length - 1]))));
    card.append(add);
    return card;
  }

  // The value of joint j at waypoint i: an empty box is 0 (a waypoint gives every joint),
  // a value past the end of a short list fills the values before it with 0.
  jointInput(i, j) {
    const field = `jointPath.waypoints[${i}].positions[${j}]`;
    const input = el('input', {
      type: 'text', inputmode: 'decimal', spellcheck: 'false', 'data-field': field,
      'data-testid': `waypoint-${i}-joint-${j}`, 'aria-label': `waypoint ${i} joint ${j}`, placeholder: '—',
      value: formatNumber(getField(this.request, field)),
    });
    fitChars(input);
    input.addEventListener('input', () => {
      const text = input.value.trim();
      const value = text === '' ? 0 : Number(text);
      if (!Number.isFinite(value)) {
        this.setLocalError(field, `"${text}" is not a number`);
        return;
      }
      this.setLocalError(field, null);
      const waypoint = this.request.jointPath.waypoints[i];
      waypoint.positions ??= [];
      while (waypoint.positions.length < j) waypoint.positions.push(0);
      waypoint.positions[j] = value;
      this.onChange('value');
    });
    return input;
  }

  // Comma- or space-separated joint values.
  jointsRow(field, label, testid, placeholder = "the model's home") {
    const current = getField(this.request, field) || [];
    const input = el('input', { type: 'text', 'data-field': field, 'data-testid': testid,
      placeholder, value: current.join(', ') });
    input.addEventListener('input', () => {
      const text = input.value.trim();
      const values = text === '' ? [] : text.split(/[\s,]+/).map(Number);
      if (!values.every(Number.isFinite)) {
        this.setLocalError(field, 'joint values must be numbers [rad or m]');
        return;
      }
      this.setLocalError(field, null);
      setField(this.request, field, values.length ? values : undefined);
      this.onChange('value');
    });
    fitChars(input);
    return el('div', { class: 'row wide-row' }, el('label', { text: label }), input,
      el('span', { class: 'unit', text: 'rad' }), this.errorSlot(field));
  }

  // The unit labels of every frame's κ' and τ', from the path's derivative convention.
  updateDerivativeUnits() {
    const unit = derivativeUnit(this.request);
    for (const span of this.root.querySelectorAll('[data-derivative-unit]')) span.textContent = unit;
  }

  // A value the page cannot send (not a number): shown beside the field at once.
  setLocalError(field, message) {
    if (message) this.localErrors.set(field, message);
    else this.localErrors.delete(field);
    const slot = this.root.querySelector(`[data-error-for="${CSS.escape(field)}"]`);
    if (slot && slot.dataset.source !== 'server') {
      slot.textContent = message || '';
      slot.dataset.source = message ? 'local' : '';
    }
  }

  hasLocalErrors() {
    return this.localErrors.size > 0;
  }

  // Shows the server's field violations beside their inputs: each at the element for its
  // field path, or for the nearest enclosing path that has one. Returns the violations that
  // found no place in the editor.
  showViolations(violations) {
    for (const slot of this.root.querySelectorAll('[data-error-for]')) {
      if (slot.dataset.source === 'server') {
        slot.textContent = this.localErrors.get(slot.dataset.errorFor) || '';
        slot.dataset.source = '';
      }
    }
    for (const input of this.root.querySelectorAll('.invalid')) input.classList.remove('invalid');
    const unplaced = [];
    const placed = new Map();
    for (const v of violations) {
      let field = v.field;
      let slot = null;
      while (field) {
        slot = this.root.querySelector(`[data-error-for="${CSS.escape(field)}"]`);
        if (slot) break;
        field = parentField(field);
      }
      if (!slot) {
        unplaced.push(v);
        continue;
      }
      const prefix = field === v.field ? '' : `${v.field.slice(field.length).replace(/^\./, '')}: `;
      const text = `${prefix}${v.description}`;
      placed.set(slot, placed.has(slot) ? `${placed.get(slot)}; ${text}` : text);
      const input = this.root.querySelector(`[data-field="${CSS.escape(field)}"]`) ||
        this.root.querySelector(`[data-error-field="${CSS.escape(field)}"]`);
      if (input) input.classList.add('invalid');
    }
    for (const [slot, text] of placed) {
      slot.textContent = text;
      slot.dataset.source = 'server';
    }
    return unplaced;
  }
}

// A waypoint halfway from a to b (rounded to 1e-4), or a copy of a without b; not a stop.
function midWaypoint(a, b) {
  const p = a?.positions || [];
  const q = b?.positions || p;
  return { positions: p.map((v, j) => Number((((v ?? 0) + (q[j] ?? v ?? 0)) / 2).toFixed(4))) };
}

// The form of a path: 'pieces' (a start and pieces) or 'frames' (key frames).
export function pathForm(path) {
  if (path?.frames?.length) return 'frames';
  return path?.start || path?.pieces?.length ? 'pieces' : 'frames';
}

// The fields of PathSpec that belong to one form only.
const FRAMES_ONLY = ['frames', 'blend', 'derivativeConvention', 'closed', 'breakpoints'];
const PIECES_ONLY = ['start', 'pieces', 'transitionTolerance'];

// The kinds of a piece (the PathPiece's oneof), as the select offers them.
export const PIECE_KINDS = [
  ['line', 'line'],
  ['arc', 'arc (radius)'],
  ['helix', 'helix (radius, pitch)'],
  ['clothoid', 'clothoid (end curvature)'],
  ['profile', 'profile (κ(s), τ(s) polynomials)'],
  ['to', 'to a key frame (blend)'],
];

// Each kind's fields: key, label, unit, a list of coefficients.
const PIECE_FIELDS = {
  arc: [['radius', 'radius', 'm']],
  helix: [['radius', 'radius', 'm'], ['pitch', 'pitch (rise per turn)', 'm']],
  clothoid: [['endCurvature', 'end curvature', '1/m']],
  profile: [['curvature', 'κ(s) coefficients', '1/m, 1/m²…', true], ['torsion', 'τ(s) coefficients', '1/m, 1/m²…', true]],
};

export function pieceKind(piece) {
  return PIECE_KINDS.map(([kind]) => kind).find((kind) => piece?.[kind] !== undefined) || '';
}

const cloneJson = (value) => (value === undefined ? undefined : JSON.parse(JSON.stringify(value)));

// A piece of `kind` in place of `old` (its length kept, where it has one); a `to` piece's
// key frame 0.1 m on from `from` ({position, tangent}: where the piece starts).
function newPiece(kind, old, from) {
  const lengthM = old?.lengthM || 0.1;
  switch (kind) {
    case 'arc': return { lengthM, arc: { radius: old?.helix?.radius || 0.05 } };
    case 'helix': return { lengthM, helix: { radius: old?.arc?.radius || 0.05, pitch: 0.02 } };
    case 'clothoid': return { lengthM, clothoid: { endCurvature: 10 } };
    case 'profile': return { lengthM, profile: { curvature: [10], torsion: [] } };
    case 'to': return { to: extrapolatedFrame(from) };
    default: return { lengthM, line: {} };
  }
}

// "a.b[2].c" -> "a.b[2]" -> "a.b" -> "a" -> "".
export function parentField(field) {
  const m = /^(.*?)(\.[^.[\]]+|\[\d+\])$/.exec(field);
  return m ? m[1] : '';
}

function interpolatedFrame(a, b) {
  const p = a.position || {};
  const q = b ? b.position || {} : { x: (p.x ?? 0) + 0.1, y: p.y ?? 0, z: p.z ?? 0 };
  const mid = (key) => Number((((p[key] ?? 0) + (q[key] ?? 0)) / 2).toFixed(4));
  const d = { x: (q.x ?? 0) - (p.x ?? 0), y: (q.y ?? 0) - (p.y ?? 0), z: (q.z ?? 0) - (p.z ?? 0) };
  const n = Math.hypot(d.x, d.y, d.z) || 1;
  const t = (v) => Number((v / n).toFixed(6));
  return { position: { x: mid('x'), y: mid('y'), z: mid('z') }, tangent: { x: t(d.x), y: t(d.y), z: t(d.z) } };
}

function extrapolatedFrame(last) {
  const p = last.position || {};
  const t = last.tangent || { x: 1 };
  return {
    position: { x: Number(((p.x ?? 0) + 0.1 * (t.x ?? 0)).toFixed(4)),
      y: Number(((p.y ?? 0) + 0.1 * (t.y ?? 0)).toFixed(4)),
      z: Number(((p.z ?? 0) + 0.1 * (t.z ?? 0)).toFixed(4)) },
    tangent: { x: t.x ?? 0, y: t.y ?? 0, z: t.z ?? 0 },
  };
}
