// geotraj from Node.js: @grpc/grpc-js and @grpc/proto-loader against a real geotrajd.
//
// Starts geotrajd on a free loopback port, then checks what a Node client relies on:
// ListRobots, a plan (client/grpcurl/plan_demo_path_a.json), the same request streamed,
// INVALID_ARGUMENT with its google.rpc.BadRequest decoded from the grpc-status-details-bin
// trailer (client/grpcurl/bad_request.json), a deadline that runs out mid-stream, and a
// stream cancelled by the client. Runner: node:test (built in).
//
//   cd tests/interop/node && npm ci && GEOTRAJD=../../../build/server/geotrajd npm test
//
// Environment (ctest sets all of them; the defaults suit a run from the source tree):
//   GEOTRAJD               the server binary (default: build/server/geotrajd)
//   GEOTRAJ_PROTO_DIR      holds geotraj/v1/geotraj.proto (default: proto/)
//   GEOTRAJ_GOOGLEAPIS_DIR holds google/rpc/{status,error_details}.proto
//   GEOTRAJ_GRPC_PROTO_DIR holds grpc/health/v1/health.proto
//   GEOTRAJ_EXAMPLES_DIR   the request files (default: client/grpcurl/)
//   GEOTRAJ_TOKEN          optional: sent as `authorization: Bearer <token>` on every call
'use strict';

const { describe, it, before, after } = require('node:test');
const assert = require('node:assert/strict');
const fs = require('node:fs');
const path = require('node:path');

const grpc = require('@grpc/grpc-js');
const protoLoader = require('@grpc/proto-loader');

const {
  env, GEOTRAJD, PROTO_DIR, LOADER_OPTIONS,
  example, metadata, deadlineIn, startServer, stopServer, unary,
} = require('./support.js');
const protobuf = require('protobufjs');

const GOOGLEAPIS_DIR = env('GEOTRAJ_GOOGLEAPIS_DIR', '/usr/share/gocode/src/github.com/gogo/googleapis');
const GRPC_PROTO_DIR = env('GEOTRAJ_GRPC_PROTO_DIR',
  '/usr/share/gocode/src/google.golang.org/grpc/debian/missing-sources/grpc/grpc-proto/master');

// proto JSON (camelCase names, enum names) is what proto-loader takes with keepCase false.

function loadServices() {
  const def = protoLoader.loadSync(['geotraj/v1/geotraj.proto', 'grpc/health/v1/health.proto'],
    { ...LOADER_OPTIONS, includeDirs: [PROTO_DIR, GRPC_PROTO_DIR] });
  const loaded = grpc.loadPackageDefinition(def);
  return { Trajectory: loaded.geotraj.v1.TrajectoryService, Health: loaded.grpc.health.v1.Health };
}

// google.rpc.Status and its details, straight from the .proto files with protobufjs (the
// library under proto-loader): the grpc-status-details-bin trailer is a serialized Status.
function loadRpcTypes() {
  const root = new protobuf.Root();
  root.resolvePath = (origin, target) => {
    for (const dir of [GOOGLEAPIS_DIR, PROTO_DIR]) {
      const candidate = path.join(dir, target);
      if (fs.existsSync(candidate)) return candidate;
    }
    return target;  // google/protobuf/*.proto: protobufjs has them built in
  };
  root.loadSync(['google/rpc/status.proto', 'google/rpc/error_details.proto'], { keepCase: true });
  return { Status: root.lookupType('google.rpc.Status'), BadRequest: root.lookupType('google.rpc.BadRequest') };
}

// Reads a whole server stream: resolves with the samples, or rejects with the call's error
// (which carries the samples received before it as err.samples).
function streamAll(client, request, options = {}) {
  return new Promise((resolve, reject) => {
    const samples = [];
    const call = client.StreamSamples(request, metadata(), options);
    call.on('data', (batch) => samples.push(...batch.samples));
    call.on('error', (err) => { err.samples = samples; reject(err); });
    call.on('end', () => resolve(samples));
  });
}

// Every number in a decoded message must be finite.
function assertFinite(value, where) {
  if (typeof value === 'number') {
    assert.ok(Number.isFinite(value), `${where} is ${value}`);
  } else if (Array.isArray(value)) {
    value.forEach((v, i) => assertFinite(v, `${where}[${i}]`));
  } else if (value !== null && typeof value === 'object') {
    for (const [k, v] of Object.entries(value)) assertFinite(v, `${where}.${k}`);
  }
}

describe('geotrajd from @grpc/grpc-js', () => {
  let server;
  let client;
  let health;
  let rpcTypes;

  before(async () => {
    const { Trajectory, Health } = loadServices();
    rpcTypes = loadRpcTypes();
    server = await startServer();
    client = new Trajectory(server.address, grpc.credentials.createInsecure());
    health = new Health(server.address, grpc.credentials.createInsecure());
    await new Promise((resolve, reject) =>
      client.waitForReady(deadlineIn(30000), (err) => (err ? reject(err) : resolve())));
  });

  after(async () => {
    if (client) client.close();
    if (health) health.close();
    if (server) await stopServer(server.proc);
  });

  it('reports SERVING on the standard health service', async () => {
    const resp = await unary(health, 'Check', { service: 'geotraj.v1.TrajectoryService' });
    assert.equal(resp.status, 'SERVING');
  });

  it('lists the built-in robots', async () => {
    const resp = await unary(client, 'ListRobots', {});
    const byName = Object.fromEntries(resp.robots.map((m) => [m.name, m]));
    assert.deepEqual(Object.keys(byName).sort(), ['iiwa14', 'pa10', 'panda', 'ur5', 'ur5e']);
    for (const [name, dof] of [['pa10', 7], ['ur5', 6], ['panda', 7], ['iiwa14', 7], ['ur5e', 6]]) {
      const m = byName[name];
      // DH tables as links, URDF arms as joints (names and kinds).
      const chain = m.links.length > 0 ? m.links : m.joints;
      assert.deepEqual([chain.length, m.limits.length, m.home.length], [dof, dof, dof], name);
      if (m.joints.length > 0) chain.forEach((j) => assert.ok(j.name.length > 0, `${name} joint without a name`));
      assert.ok(m.description.length > 0, `${name} has no description`);
      m.limits.forEach((lim, j) => {
        assert.ok(lim.minPosition < lim.maxPosition, `${name} joint ${j}`);
        assert.ok(lim.maxVelocity > 0 && lim.maxAcceleration > 0, `${name} joint ${j}`);
        assert.ok(lim.minPosition <= m.home[j] && m.home[j] <= lim.maxPosition, `${name} home ${j}`);
      });
    }
  });

  const planRequest = () => example('plan_demo_path_a.json');

  it('plans demo path A (plan_demo_path_a.json)', async () => {
    const request = planRequest();
    const resp = await unary(client, 'PlanTrajectory', request, { deadline: deadlineIn(60000) });
    assert.ok(resp.arcLength > 0, `arc length ${resp.arcLength}`);
    assert.equal(resp.frames.length, request.path.frames.length);
    assert.equal(resp.segments.length, request.path.frames.length - 1);
    const sum = resp.segments.reduce((acc, seg) => acc + seg.arcLength, 0);
    assert.ok(Math.abs(sum - resp.arcLength) <= 1e-12 * resp.arcLength, `segments sum to ${sum}`);
    assert.ok(resp.closedLoop.maxError < 1e-9,
      `closed-loop error ${resp.closedLoop.maxError} at ${resp.closedLoop.worstField}`);
    // 10 s at 100 Hz, both ends included.
    const { durationS, cycleRateHz } = request.motion;
    assert.equal(resp.motion.durationS, durationS);
    assert.equal(resp.motion.sampleCount, Math.round(durationS * cycleRateHz) + 1);
    assertFinite(resp, 'PlanResponse');
  });

  it('streams the same request: duration * rate + 1 samples, t strictly increasing', async () => {
    const request = planRequest();
    const plan = await unary(client, 'PlanTrajectory', request, { deadline: deadlineIn(60000) });
    const samples = await streamAll(client, request, { deadline: deadlineIn(60000) });
    const { durationS, cycleRateHz } = request.motion;
    assert.equal(samples.length, Math.round(durationS * cycleRateHz) + 1);
    assert.equal(samples.length, plan.motion.sampleCount);
    assert.equal(samples[0].t, 0);
    assert.ok(Math.abs(samples[samples.length - 1].t - durationS) < 1e-9);
    samples.forEach((smp, i) => {
      assertFinite(smp, `samples[${i}]`);
      if (i > 0) {
        assert.ok(smp.t > samples[i - 1].t, `t not increasing at sample ${i}`);
        assert.ok(Math.abs(smp.t - samples[i - 1].t - 1 / cycleRateHz) < 1e-9, `period at sample ${i}`);
        assert.ok(smp.s >= samples[i - 1].s, `s decreasing at sample ${i}`);
      }
      const q = smp.orientation;
      assert.ok(Math.abs(Math.hypot(q.w, q.x, q.y, q.z) - 1) < 1e-9, `quaternion of sample ${i}`);
    });
    assert.ok(Math.abs(samples[samples.length - 1].s - plan.arcLength) < 1e-9 * plan.arcLength);
    assert.equal(samples[0].speed, 0);
  });

  it('answers bad_request.json with INVALID_ARGUMENT and a google.rpc.BadRequest', async () => {
    const err = await unary(client, 'PlanTrajectory', example('bad_request.json')).then(
      () => assert.fail('bad_request.json was accepted'), (e) => e);
    assert.equal(err.code, grpc.status.INVALID_ARGUMENT, err.message);
    const [bin] = err.metadata.get('grpc-status-details-bin');
    assert.ok(Buffer.isBuffer(bin), 'no grpc-status-details-bin trailer');
    const status = rpcTypes.Status.decode(bin);
    assert.equal(status.code, grpc.status.INVALID_ARGUMENT);
    assert.equal(status.message, err.details);
    const violations = {};
    for (const any of status.details) {
      if (any.type_url.endsWith('/google.rpc.BadRequest')) {
        for (const v of rpcTypes.BadRequest.decode(any.value).field_violations) violations[v.field] = v.description;
      }
    }
    // The four mistakes of the file, named by their proto JSON field paths.
    assert.deepEqual(Object.keys(violations).sort(), [
      'analysisPoints', 'path.frames[0].tangent', 'path.frames[1].torsion', 'path.frames[2].tangent']);
    assert.match(violations['path.frames[1].torsion'], /curvature/);
    assert.match(violations['path.frames[0].tangent'], /unit/);
  });

  it('ends a real-time stream that outlives its deadline with DEADLINE_EXCEEDED', async () => {
    const request = planRequest();
    request.motion.durationS = 3600;  // an hour, sent in real time
    request.pacing = 'STREAM_PACING_REAL_TIME';
    const start = process.hrtime.bigint();
    const err = await streamAll(client, request, { deadline: deadlineIn(1000) }).then(
      () => assert.fail('the stream ended normally'), (e) => e);
    const elapsed = Number(process.hrtime.bigint() - start) / 1e9;
    assert.equal(err.code, grpc.status.DEADLINE_EXCEEDED, err.message);
    assert.ok(elapsed < 10, `the deadline took ${elapsed} s`);
    // Samples are sent when due: none of those received (about 100, the first second's)
    // lies past the deadline.
    for (const smp of err.samples) assert.ok(smp.t <= elapsed, `sample at t=${smp.t} after ${elapsed} s`);
    // The server goes on serving.
    const plan = await unary(client, 'PlanTrajectory', planRequest());
    assert.ok(plan.closedLoop.maxError < 1e-9);
  });

  it('cancels a stream from the client mid-way', async () => {
    const request = planRequest();
    request.motion.durationS = 3600;  // 360,001 samples at 100 Hz, as fast as possible
    request.samplesPerBatch = 100;
    const { received, err } = await new Promise((resolve) => {
      let count = 0;
      const call = client.StreamSamples(request, metadata());
      call.on('data', (batch) => {
        count += batch.samples.length;
        if (count >= 1000) call.cancel();
      });
      call.on('error', (e) => resolve({ received: count, err: e }));
      call.on('end', () => resolve({ received: count, err: null }));
    });
    assert.ok(err, 'the stream ended without an error');
    assert.equal(err.code, grpc.status.CANCELLED, err.message);
    assert.ok(received >= 1000 && received < 360001, `received ${received}`);
    const plan = await unary(client, 'PlanTrajectory', planRequest());
    assert.ok(plan.closedLoop.maxError < 1e-9);
  });
});
