// The PlanRequest the page edits, kept as proto JSON (the form the CLI `geotraj plan FILE`
// and grpcurl take), so fields the editor does not show survive a load and a save.

import demoPathC from '../../client/grpcurl/plan_demo_path_c.json';
import pa10PathC from '../../client/grpcurl/plan_pa10_path_c.json';
import seamUr5e from '../../client/grpcurl/plan_seam_ur5e.json';
import helix from '../../client/grpcurl/plan_helix.json';
import jointPathPanda from '../../client/grpcurl/plan_joint_path_panda.json';

const clone = (value) => JSON.parse(JSON.stringify(value));

// The starting points the start page offers.
export const presets = {
  // Two frames with a tangent only: a straight start to design from.
  empty: () => ({
    path: {
      frames: [
        { position: { x: 0.3, y: -0.2, z: 0.5 }, tangent: { x: 1 } },
        { position: { x: 0.5, y: 0.2, z: 0.5 }, tangent: { y: 1 } },
      ],
    },
    motion: { durationS: 5 },
  }),
  // The thesis's path C (Tables 7.8 and 7.18), client/grpcurl/plan_demo_path_c.json.
  demo: () => clone(demoPathC),
  // Path C on the PA-10, timed by the joint limits (geotraj plan --time-optimal
  // client/grpcurl/plan_pa10_path_c.json).
  pa10TimeOptimal: () => {
    const request = clone(pa10PathC);
    request.optimize = { ...(request.optimize || {}), timing: { timeOptimal: true } };
    return request;
  },
  // A path of pieces: a weld seam (line, arc of 40 mm, line) on the UR5e,
  // client/grpcurl/plan_seam_ur5e.json.
  seamUr5e: () => clone(seamUr5e),
  // A path of pieces: a line, five turns of a helix, a line, client/grpcurl/plan_helix.json.
  helix: () => clone(helix),
  // Joint waypoints (a sampling planner's output) on the Panda, passed without stopping:
  // client/grpcurl/plan_joint_path_panda.json.
  jointPathPanda: () => clone(jointPathPanda),
};

// A joint path (PlanRequest.jointPath: joint waypoints instead of a Cartesian path).
export function isJointPath(request) {
  return Boolean(request?.jointPath);
}

// What a PlanRequest moves along (its oneof of motions, as the server reads it): 'path' (key
// frames or pieces), 'jointPath', 'jointMove', 'linearMove' or 'sequence'.
export function requestKind(request) {
  if (request?.jointPath) return 'jointPath';
  if (request?.sequence?.length) return 'sequence';
  if (request?.jointMove) return 'jointMove';
  if (request?.linearMove) return 'linearMove';
  return 'path';
}

// The kinds in words (a path's form and a step's kind too: StepReport.kind).
export const KIND_NAMES = {
  frames: 'path of key frames',
  pieces: 'path of pieces',
  path: 'path',
  jointPath: 'joint path',
  jointMove: 'joint move',
  linearMove: 'linear move',
  sequence: 'sequence',
  blended: 'blended chain',
};

// The kind of a sequence's step (a SequenceStep's oneof).
export function stepKind(step) {
  for (const kind of ['path', 'jointMove', 'linearMove', 'jointPath']) if (step?.[kind]) return kind;
  return '';
}

// The fields of a PlanRequest (proto JSON names).
const PLAN_FIELDS = ['path', 'motion', 'robot', 'optimize', 'analysisPoints', 'samplesPerBatch', 'pacing',
  'jointMove', 'linearMove', 'sequence', 'jointPath'];

// The JSON values of a text, one after the other (a file of several messages, as grpcurl
// sends a stream's: `{...}\n{...}`); null if it is not JSON values only.
export function jsonValues(text) {
  try {
    return [JSON.parse(text)];
  } catch {
    // Several values, or none: split at the top level below.
  }
  const values = [];
  let depth = 0;
  let inString = false;
  let start = -1;
  for (let i = 0; i < text.length; ++i) {
    const c = text[i];
    if (inString) {
      if (c === '\\') ++i;
      else if (c === '"') inString = false;
    } else if (c === '"') {
      inString = true;
    } else if (c === '{' || c === '[') {
      if (depth++ === 0) start = i;
    } else if (c === '}' || c === ']') {
      if (--depth === 0) {
        try {
          values.push(JSON.parse(text.slice(start, i + 1)));
        } catch {
          return null;
        }
      }
      if (depth < 0) return null;
    } else if (depth === 0 && !/\s/.test(c)) {
      return null;
    }
  }
  return depth === 0 && values.length ? values : null;
}

// What the page makes of a request file (or pasted text) named `name`: {request, note} for a
// PlanRequest (note: what was opened of a message that holds one, as an ExecuteRequest's
// plan), or {error} saying why it opens nothing.
export function openDocument(text, name = 'the text') {
  const values = jsonValues(text);
  if (!values) {
    let why = '';
    try {
      JSON.parse(text);
    } catch (e) {
      why = `: ${e.message}`;
    }
    return { error: `${name} is not JSON${why}` };
  }
  const object = (v) => typeof v === 'object' && v !== null && !Array.isArray(v);
  const first = values[0];
  const jog = (v) => object(v) && ['start', 'joints', 'twist', 'heartbeat', 'stop'].some((k) => k in v) &&
    !PLAN_FIELDS.some((k) => k in v && k !== 'joints');
  if (values.length > 1) {
    if (values.every(jog)) {
      return { error: `${name} holds ${values.length} JogRequest messages (a start, then jog commands): ` +
        'jogging moves the robot live over the gRPC stream TrajectoryService/Jog (grpcurl, geotraj jog), ' +
        'which the page does not drive; it opens PlanRequests' };
    }
    return { error: `${name} holds ${values.length} JSON values: the page opens one PlanRequest` };
  }
  if (!object(first)) return { error: `${name} does not hold a JSON object (a PlanRequest in proto JSON)` };
  const keys = Object.keys(first);
  if ('plan' in first && keys.every((k) => k === 'plan' || k === 'options')) {
    if (!object(first.plan)) return { error: `${name}: an ExecuteRequest whose plan is not an object` };
    return { request: first.plan, note: `${name} is an ExecuteRequest: its plan is opened (the page plans it; ` +
      'executing it live, with its options, is the gRPC stream TrajectoryService/Execute: geotraj execute or grpcurl)' };
  }
  if ('joints' in first && keys.every((k) => k === 'robot' || k === 'joints')) {
    return { error: `${name} is a ForwardKinematicsRequest (a robot and its joint values), not a PlanRequest: ` +
      'the page opens motions to plan; its answer (the tool pose, the Jacobian, the axes) is POST /v1/fk, ' +
      'geotraj fk or grpcurl TrajectoryService/ComputeForwardKinematics' };
  }
  if ('target' in first && keys.every((k) => k === 'robot' || !PLAN_FIELDS.includes(k))) {
    return { error: `${name} is an InverseKinematicsRequest (a robot and a tool pose), not a PlanRequest: ` +
      'the page opens motions to plan; its answer (the joint values) is POST /v1/ik, geotraj ik or grpcurl ' +
      'TrajectoryService/ComputeInverseKinematics' };
  }
  if (jog(first)) {
    return { error: `${name} is a JogRequest: jogging moves the robot live over the gRPC stream ` +
      'TrajectoryService/Jog, which the page does not drive; it opens PlanRequests' };
  }
  const unknown = keys.filter((k) => !PLAN_FIELDS.includes(k));
  if (unknown.length) {
    return { error: `${name} is not a PlanRequest: no field ${unknown.map((k) => `"${k}"`).join(', ')} in a PlanRequest ` +
      `(its fields: ${PLAN_FIELDS.join(', ')})` };
  }
  return { request: first, note: '' };
}

// Field paths as the server writes them: "path.frames[2].curvature".
export function parsePath(field) {
  const parts = [];
  for (const piece of field.split('.')) {
    const m = /^([^[\]]+)((?:\[\d+\])*)$/.exec(piece);
    if (!m) return null;
    parts.push(m[1]);
    for (const index of m[2].matchAll(/\[(\d+)\]/g)) parts.push(Number(index[1]));
  }
  return parts;
}

export function getField(object, field) {
  let value = object;
  for (const key of parsePath(field) || []) {
    if (value === undefined || value === null) return undefined;
    value = value[key];
  }
  return value;
}

// Sets a field (creating the messages on the way); undefined deletes it, and messages left
// empty by the deletion go too, as proto JSON would omit them.
export function setField(object, field, value) {
  const keys = parsePath(field);
  const chain = [object];
  let node = object;
  for (let i = 0; i < keys.length - 1; ++i) {
    if (node[keys[i]] === undefined || node[keys[i]] === null) {
      if (value === undefined) return;
      node[keys[i]] = typeof keys[i + 1] === 'number' ? [] : {};
    }
    node = node[keys[i]];
    chain.push(node);
  }
  const last = keys[keys.length - 1];
  if (value === undefined) {
    delete node[last];
    for (let i = chain.length - 1; i > 0; --i) {
      const here = chain[i];
      if (Array.isArray(here) || Object.keys(here).length) break;
      delete chain[i - 1][keys[i - 1]];
    }
  } else {
    node[last] = value;
  }
}

// What AnalyzePath needs of a plan request: the path and its optimisers of the geometry;
// the robot, motion and timing optimiser only cost time there.
export function analysisRequest(request, points) {
  const analysis = { path: request.path, analysisPoints: points };
  if (request.optimize) {
    const { timing, ...geometry } = request.optimize;
    if (Object.keys(geometry).length) analysis.optimize = geometry;
  }
  return analysis;
}

// The request with one frame constraint replaced (the family view).
export function withConstraint(request, frame, constraint, value) {
  const copy = clone(request);
  copy.path.frames[frame][constraint] = value;
  return copy;
}

// The parameters of a path of pieces the family view sweeps: the piece's length, its shape's
// numbers (an arc's radius keeping its angle, a helix's radius or pitch keeping its turns, a
// clothoid's end curvature) and the path's transition tolerance. [key, label] pairs; keys
// are field paths inside the piece, or 'transitionTolerance' for the path's.
export function pieceParameters(piece) {
  const list = [['lengthM', 'length [m]']];
  if (piece?.arc) list.unshift(['arc.radius', 'radius [m], same angle']);
  if (piece?.helix) list.unshift(['helix.radius', 'radius [m], same turns'], ['helix.pitch', 'pitch [m], same turns']);
  if (piece?.clothoid) list.unshift(['clothoid.endCurvature', 'end curvature [1/m]']);
  list.push(['transitionTolerance', 'transition tolerance [m] (the path\'s)']);
  return list;
}

// The request with one of pieceParameters' values replaced (the family view). An arc keeps
// its angle (its length scales with the radius), a helix its turns (its length is
// turns 2 pi sqrt(r^2 + (pitch / 2 pi)^2)); a value the server would refuse is set as given,
// so the refusal names it.
export function withPieceParameter(request, index, key, value) {
  const copy = clone(request);
  if (key === 'transitionTolerance') {
    copy.path.transitionTolerance = value;
    return copy;
  }
  const piece = copy.path.pieces[index];
  const before = { ...piece.arc, ...piece.helix };
  setField(piece, key, value);
  const valid = Number.isFinite(value) && (key === 'helix.pitch' || value > 0);
  if (key === 'arc.radius' && valid && before.radius > 0 && piece.lengthM > 0) {
    piece.lengthM *= value / before.radius;
  } else if (key.startsWith('helix.') && valid && piece.lengthM > 0) {
    const round = (h) => 2 * Math.PI * Math.hypot(h.radius ?? 0, (h.pitch ?? 0) / (2 * Math.PI));
    const old = round(before);
    if (old > 0) piece.lengthM *= round(piece.helix) / old;
  }
  return copy;
}

// The CLI and grpcurl lines that send the same request.
export function commandLines(grpcAddress, withToken) {
  const plaintext = '-plaintext ';
  const auth = withToken ? `-H "authorization: Bearer $GEOTRAJ_TOKEN" ` : '';
  return [
    `geotraj --server ${grpcAddress} plan request.json`,
    `grpcurl ${plaintext}${auth}-d @ ${grpcAddress} geotraj.v1.TrajectoryService/PlanTrajectory < request.json`,
  ];
}

export const cloneRequest = clone;
