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
