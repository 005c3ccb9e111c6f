// geotraj's live calls from Node.js: Execute and Jog on @grpc/grpc-js against a real geotrajd.
//
// Starts geotrajd on a free loopback port, then drives the two bidirectional streams as a
// controller would and checks every set point they send:
//   - Execute of client/grpcurl/plan_panda_path_c.json (time-optimal, 1 kHz) and of an
//     S-curve joint move, the override to 50 % and back, a pause and a resume: joint velocity
//     (first differences), acceleration (second differences) and jerk (differences of the
//     streamed accelerations) within the limits ListRobots states, the speed factor at 0.5,
//     the plan time advancing at the speed factor, the motion continuous across the resume,
//     the call ending OK with `geotraj-stop-reason: completed`;
//   - a stop: the final sample at rest, OK and `stopped`, within the stopping time reported;
//   - the deadman: no message for deadmanS, ABORTED and `deadman`, the last sample at rest;
//   - Jog of one joint into its position limit: it stops there and never passes it;
//   - a cancelled Execute: the server goes on serving;
//   - the example client/node/geotraj_live.js, run once in each mode.
// Runner: node:test (built in). Environment as for geotraj_client.test.js (ctest sets it):
//   GEOTRAJD, GEOTRAJ_PROTO_DIR, GEOTRAJ_EXAMPLES_DIR, GEOTRAJ_TOKEN (optional).
'use strict';

const { describe, it, before, after } = require('node:test');
const assert = require('node:assert/strict');
const { execFile } = require('node:child_process');
const path = require('node:path');

const grpc = require('@grpc/grpc-js');
const protoLoader = require('@grpc/proto-loader');

const {
  repo, GEOTRAJD, PROTO_DIR, EXAMPLES_DIR, LOADER_OPTIONS,
  example, metadata, deadlineIn, startServer, stopServer, unary,
} = require('./support.js');

const EXAMPLE = path.join(repo, 'client', 'node', 'geotraj_live.js');
// Where this test found its packages: the example runs with the same NODE_PATH.
const NODE_MODULES = path.resolve(path.dirname(require.resolve('@grpc/grpc-js/package.json')), '..', '..');


// The acceleration reserve every Execute here asks for: a plan timed by the limits is made
// within 1 - reserve of every acceleration and jerk limit (MotionSpec.accelerationScale,
// ExecuteOptions.accelerationReserve).
const RESERVE = 0.1;
// Slack of the checks by finite differences: velocities are exact (the mean value theorem),
// second differences average the acceleration over two periods, and so on.
const VELOCITY_SLACK = 1e-4;
const ACCELERATION_SLACK = 0.02;
const JERK_SLACK = 0.02;

function loadService() {
  const def = protoLoader.loadSync('geotraj/v1/geotraj.proto', { ...LOADER_OPTIONS, includeDirs: [PROTO_DIR] });
  return grpc.loadPackageDefinition(def).geotraj.v1.TrajectoryService;
}

function streamAll(client, request) {
  return new Promise((resolve, reject) => {
    const samples = [];
    const call = client.StreamSamples(request, metadata(), { deadline: deadlineIn(60000) });
    call.on('data', (batch) => samples.push(...batch.samples));
    call.on('error', reject);
    call.on('end', () => resolve(samples));
  });
}

// One live call (Execute or Jog): writes `first` and the messages `after`, then a heartbeat every `heartbeatMs` (0:
// none) until the call ends; `onBatch(batch, ctl)` sees every batch, ctl.send writes a
// message, ctl.cancel cancels. Resolves (never rejects) once the status has come, with every
// sample, every batch ({first, count, live}: its samples are samples[first, first + count)),
// the status code, its details and the trailer geotraj-stop-reason.
function liveCall(client, method, first, { heartbeatMs = 100, onBatch = () => {}, after = [], deadlineMs = 60000 } = {}) {
  return new Promise((resolve) => {
    const call = client[method](metadata(), { deadline: deadlineIn(deadlineMs) });
    const result = { samples: [], batches: [], sent: [], code: null, details: '', reason: undefined };
    let ended = false;
    const send = (message) => {
      if (ended) return;
      result.sent.push({ message, afterSample: result.samples.length });
      call.write(message);
    };
    const heartbeat = heartbeatMs > 0 ? setInterval(() => { if (!ended) call.write({ heartbeat: {} }); }, heartbeatMs) : null;
    const ctl = { send, cancel: () => call.cancel(), result };
    call.on('data', (batch) => {
      result.batches.push({ first: result.samples.length, count: batch.samples.length, live: batch.live });
      result.samples.push(...batch.samples);
      onBatch(batch, ctl);
    });
    call.on('error', () => {});  // the status event carries it
    call.on('status', (status) => {
      ended = true;
      if (heartbeat) clearInterval(heartbeat);
      call.end();
      result.code = status.code;
      result.details = status.details;
      [result.reason] = status.metadata.get('geotraj-stop-reason');
      setImmediate(() => resolve(result));
    });
    call.write(first);
    after.forEach(send);
  });
}

function codeName(code) {
  return Object.keys(grpc.status).find((k) => grpc.status[k] === code);
}

function assertStatus(result, code, reason) {
  assert.equal(codeName(result.code), codeName(code), `status ${codeName(result.code)}: ${result.details}`);
  assert.equal(result.reason, reason, `geotraj-stop-reason ${result.reason} (${result.details})`);
}

function assertAtRest(sample, where) {
  assert.ok(sample.jointVelocities.every((v) => v === 0), `${where}: joint velocities ${sample.jointVelocities}`);
  assert.ok(sample.jointAccelerations.every((a) => a === 0), `${where}: joint accelerations ${sample.jointAccelerations}`);
  assert.equal(sample.speed, 0, `${where}: tool speed`);
  if (sample.speedFactor !== undefined) assert.equal(sample.speedFactor, 0, `${where}: speed factor`);
}

// Every set point against the joint limits, by finite differences at the period h:
// positions within [min, max]; first differences / h within maxVelocity * velocityScale;
// second differences / h^2 within maxAcceleration (2 % slack); differences of the streamed
// accelerations / h within jerkBound[j] (2 % slack) where it is finite; and the streamed
// velocities and accelerations themselves within the limits. Returns the worst usages.
function checkJointLimits(samples, limits, rate, { jerkBound, velocityScale = 1, label }) {
  const h = 1 / rate;
  const worst = { velocity: [0], acceleration: [0], jerk: [0], streamedAcceleration: [0] };
  const note = (kind, usage, k, j) => { if (usage > worst[kind][0]) worst[kind] = [usage, k, j]; };
  samples.forEach((smp, k) => {
    limits.forEach((lim, j) => {
      const q = smp.joints[j];
      assert.ok(q >= lim.minPosition && q <= lim.maxPosition, `${label}: joint ${j} at ${q} outside its limits, sample ${k}`);
      const vmax = lim.maxVelocity * velocityScale;
      assert.ok(Math.abs(smp.jointVelocities[j]) <= vmax * (1 + 1e-9), `${label}: streamed velocity, sample ${k} joint ${j}`);
      note('streamedAcceleration', Math.abs(smp.jointAccelerations[j]) / lim.maxAcceleration, k, j);
      if (k >= 1) {
        const prev = samples[k - 1];
        note('velocity', Math.abs(q - prev.joints[j]) / h / vmax, k, j);
        if (Number.isFinite(jerkBound[j])) {
          note('jerk', Math.abs(smp.jointAccelerations[j] - prev.jointAccelerations[j]) / h / jerkBound[j], k, j);
        }
      }
      if (k >= 2) {
        const d2 = q - 2 * samples[k - 1].joints[j] + samples[k - 2].joints[j];
        note('acceleration', Math.abs(d2) / (h * h) / lim.maxAcceleration, k, j);
      }
    });
  });
  const where = (kind) => `${label}: worst ${kind} usage ${worst[kind][0]} at sample ${worst[kind][1]}, joint ${worst[kind][2]}`;
  assert.ok(worst.velocity[0] <= 1 + VELOCITY_SLACK, where('velocity'));
  assert.ok(worst.acceleration[0] <= 1 + ACCELERATION_SLACK, where('acceleration'));
  assert.ok(worst.jerk[0] <= 1 + JERK_SLACK, where('jerk'));
  assert.ok(worst.streamedAcceleration[0] <= 1 + 1e-6, where('streamedAcceleration'));
  return worst;
}

// Samples: t = k / rate exactly; the plan time never goes back and advances by the speed
// factor (the trapezoid of its two ends, to 1e-3 of a period); the speed factor in [0, 1].
function checkTiming(samples, rate, label) {
  const h = 1 / rate;
  samples.forEach((smp, k) => {
    assert.ok(Math.abs(smp.t - k * h) < 1e-9, `${label}: sample ${k} at t = ${smp.t}`);
    assert.ok(smp.speedFactor >= 0 && smp.speedFactor <= 1, `${label}: speed factor ${smp.speedFactor} at sample ${k}`);
    if (k === 0) return;
    const prev = samples[k - 1];
    const advance = smp.planTime - prev.planTime;
    assert.ok(advance >= 0, `${label}: the plan time goes back at sample ${k}`);
    // The final sample is written at rest (speed factor 0) where the plan ends.
    if (k < samples.length - 1) {
      const expected = h * (prev.speedFactor + smp.speedFactor) / 2;
      assert.ok(Math.abs(advance - expected) <= 1e-3 * h,
        `${label}: plan time advances ${advance} s at sample ${k}, the speed factor says ${expected} s`);
    }
  });
}

// The batches' states in order, repeats folded: ['RUNNING', 'PAUSING', ...].
function stateSequence(result) {
  const states = [];
  for (const b of result.batches) {
    const s = b.live.state.replace('LIVE_STATE_', '');
    if (states[states.length - 1] !== s) states.push(s);
  }
  return states;
}

describe('geotrajd live calls (Execute, Jog) from @grpc/grpc-js', () => {
  let server;
  let client;
  let robots;

  before(async () => {
    const Trajectory = loadService();
    server = await startServer();
    client = new Trajectory(server.address, grpc.credentials.createInsecure());
    await new Promise((resolve, reject) =>
      client.waitForReady(deadlineIn(30000), (err) => (err ? reject(err) : resolve())));
    const listed = await unary(client, 'ListRobots', {});
    robots = Object.fromEntries(listed.robots.map((m) => [m.name, m]));
  });

  after(async () => {
    if (client) client.close();
    if (server) await stopServer(server.proc);
  });

  // The plan Execute runs, streamed by StreamSamples at the speed scale the reserve leaves:
  // its duration at the request's cycle rate, and each joint's own largest jerk, the largest
  // difference of its accelerations one period apart, taken at every tenth of a period (the
  // plan streamed at 10 times the rate: a plan whose accelerations step gives differences
  // that depend on where the samples fall about the step; a time-optimal timing made at 10
  // times the rate lasts some 1e-4 s less, the same steps).
  const references = new Map();
  async function reference(request) {
    const key = JSON.stringify(request);
    if (!references.has(key)) {
      const scaled = structuredClone(request);
      scaled.motion.accelerationScale = (scaled.motion.accelerationScale || 1) * (1 - RESERVE);
      // Execute times a path jerk-limited for a robot with jerk limits (the Panda's).
      if (scaled.path) scaled.optimize = { ...(scaled.optimize || {}), timing: { jerkLimited: true } };
      const samples = await streamAll(client, scaled);
      const rate = request.motion.cycleRateHz;
      scaled.motion.cycleRateHz = 10 * rate;
      const fine = await streamAll(client, scaled);
      const jerk = fine[0].joints.map((_, j) => {
        let peak = 0;
        for (let k = 10; k < fine.length; k++) {
          peak = Math.max(peak, Math.abs(fine[k].jointAccelerations[j] - fine[k - 10].jointAccelerations[j]) * rate);
        }
        return peak;
      });
      references.set(key, { duration: samples[samples.length - 1].t, jerk });
    }
    return references.get(key);
  }

  // Each joint's jerk bound: its maxJerk (none: unchecked). Execute times a path for a robot
  // with jerk limits jerk-limited, and refuses a plan whose own jerk breaks them.
  function jerkBounds(robot) {
    return robot.limits.map((lim) => (lim.maxJerk === undefined ? Infinity : lim.maxJerk));
  }

  // Override to 50 % (from plan time 0.2 s), held 0.1 s at speed factor 0.5, back to 100 %;
  // at speed factor 0.8 a pause; 0.2 s at rest; a resume; on to the end.
  async function overridePauseResume(request, label) {
    const robot = robots[request.robot.name];
    const rate = request.motion.cycleRateHz;
    const ref = await reference(request);
    const marks = {};
    let phase = 'full';
    const result = await liveCall(client, 'Execute', { plan: request, options: { accelerationReserve: RESERVE } }, {
      onBatch(batch, { send, result: r }) {
        const last = batch.samples[batch.samples.length - 1];
        const next = (name, message) => {
          if (message) send(message);
          phase = name;
          marks[name] = { sample: r.samples.length - 1, t: last.t };
        };
        if (phase === 'full' && last.planTime >= 0.2) next('slowing', { speedOverride: 50 });
        else if (phase === 'slowing' && last.speedFactor === 0.5) next('half');
        else if (phase === 'half' && last.t - marks.half.t >= 0.1) next('speeding', { speedOverride: 100 });
        else if (phase === 'speeding' && last.speedFactor >= 0.8) next('pausing', { pause: {} });
        else if (phase === 'pausing' && batch.live.state === 'LIVE_STATE_PAUSED') next('paused');
        else if (phase === 'paused' && last.t - marks.paused.t >= 0.2) next('resumed', { resume: {} });
      },
    });
    assertStatus(result, grpc.status.OK, 'completed');
    assert.equal(phase, 'resumed', `${label}: the plan ended in phase ${phase}`);
    const { samples, batches } = result;
    const status = batches[batches.length - 1].live;
    assert.ok(Math.abs(status.planDurationS - ref.duration) < 1e-9,
      `${label}: Execute's plan lasts ${status.planDurationS} s, StreamSamples' at the reserve's speed scale ${ref.duration} s`);

    checkTiming(samples, rate, label);
    const worst = checkJointLimits(samples, robot.limits, rate, { jerkBound: jerkBounds(robot, ref), label });

    // The override: the speed factor reaches 0.5 and holds it while the status says 50 %.
    const half = samples.slice(marks.half.sample, marks.speeding.sample + 1);
    assert.ok(half.length >= 0.1 * rate, `${label}: ${half.length} samples at speed factor 0.5`);
    half.forEach((smp) => assert.equal(smp.speedFactor, 0.5, `${label}: speed factor ${smp.speedFactor} at t = ${smp.t}`));
    const at50 = batches.filter((b) => b.first >= marks.half.sample && b.first + b.count <= marks.speeding.sample);
    assert.ok(at50.length > 0 && at50.every((b) => b.live.speedOverride === 50), `${label}: LiveStatus.speedOverride`);
    assert.equal(batches[0].live.speedOverride, 100);
    assert.equal(samples[0].speedFactor, 1, `${label}: the first sample's speed factor`);

    // The pause: state PAUSING then PAUSED, at rest on the path, holding the same set point.
    assert.deepEqual(stateSequence(result), ['RUNNING', 'PAUSING', 'PAUSED', 'RUNNING', 'COMPLETED'], label);
    // (A batch's state is the one after its last sample: the paused samples are those from
    // the one where the speed factor reaches 0 on.)
    let firstPaused = marks.pausing.sample;
    while (samples[firstPaused].speedFactor !== 0) firstPaused += 1;
    let lastPaused = firstPaused;
    while (samples[lastPaused + 1].speedFactor === 0) lastPaused += 1;
    assert.ok(lastPaused >= marks.resumed.sample, `${label}: moving again at sample ${lastPaused + 1} before the resume`);
    assert.ok(lastPaused - firstPaused + 1 >= 0.2 * rate, `${label}: ${lastPaused - firstPaused + 1} paused samples`);
    const held = samples[firstPaused];
    for (let k = firstPaused; k <= lastPaused; k++) {
      assertAtRest(samples[k], `${label}: paused sample ${k}`);
      assert.deepEqual(samples[k].joints, held.joints, `${label}: the paused set point moves at sample ${k}`);
      assert.equal(samples[k].planTime, held.planTime);
    }
    // The resume: from the paused point, the speed factor rising from 0, the plan time going on
    // from where it stopped (the limit checks above span the resume, so the joints' velocity and
    // acceleration are continuous across it).
    const resumed = samples.slice(lastPaused + 1);
    assert.ok(resumed[0].planTime - held.planTime <= resumed[0].speedFactor / rate + 1e-12,
      `${label}: the plan time jumps at the resume`);
    assert.ok(resumed[0].speedFactor < 0.01, `${label}: the speed factor jumps to ${resumed[0].speedFactor} at the resume`);
    const fastest = Math.max(...resumed.map((smp) => smp.speedFactor));
    assert.ok(fastest >= 0.5, `${label}: the speed factor reaches only ${fastest} after the resume`);

    // Completed: the plan's last point, at rest.
    const final = samples[samples.length - 1];
    assert.equal(status.state, 'LIVE_STATE_COMPLETED');
    assert.ok(Math.abs(final.planTime - status.planDurationS) < 1e-12, `${label}: ends at plan time ${final.planTime}`);
    assertAtRest(final, `${label}: the final sample`);
    return { worst, ref, fastest, samples: samples.length, pausedAt: held.planTime, duration: status.planDurationS };
  }

  function report(t, label, run) {
    const usage = (kind) => `${run.worst[kind][0].toFixed(4)} (joint ${run.worst[kind][2]})`;
    t.diagnostic(`${label}: ${run.samples} samples, plan ${run.duration.toFixed(4)} s, paused at plan time ` +
                 `${run.pausedAt.toFixed(4)} s, speed factor after the resume up to ${run.fastest}; worst usage: ` +
                 `velocity ${usage('velocity')}, acceleration ${usage('acceleration')}, jerk ${usage('jerk')}`);
  }

  it('executes plan_panda_path_c.json: override 50 % and back, pause, resume, within the limits', async (t) => {
    const request = example('plan_panda_path_c.json');
    const run = await overridePauseResume(request, 'path C');
    report(t, 'path C', run);
    const { worst, ref } = run;
    const panda = robots.panda;
    t.diagnostic(`path C: the plan's own jerk / maxJerk per joint: ${ref.jerk.map((j, i) => (j / panda.limits[i].maxJerk).toFixed(3)).join(' ')}`);
    // The jerk-limited time-optimal plan keeps every maxJerk, and so does its live execution.
    assert.ok(ref.jerk.every((jerk, j) => jerk <= panda.limits[j].maxJerk * 1.02),
      `the plan's own jerk passes maxJerk: ${ref.jerk}`);
  });

  it('executes a jerk-limited plan (S-curve joint move) with every joint within its maxJerk', async (t) => {
    const request = {
      jointMove: { goal: [2.6, 0.5, -2.6, -0.5, 2.6, 3.5, -2.6] },
      robot: { name: 'panda', initialJoints: [-2.6, -0.5, 2.6, -2.8, -2.6, 0.3, 2.6] },
      motion: { durationS: 0, cycleRateHz: 1000, profile: 'MOTION_PROFILE_S_CURVE' },
    };
    const run = await overridePauseResume(request, 'S-curve joint move');
    report(t, 'S-curve joint move', run);
    const { worst, ref } = run;
    const panda = robots.panda;
    ref.jerk.forEach((jerk, j) => assert.ok(jerk <= panda.limits[j].maxJerk, `the plan's own jerk, joint ${j}`));
    // maxJerk itself was the bound (jerkBounds), and one joint comes close to it.
    assert.ok(worst.jerk[0] > 0.9, `jerk usage ${worst.jerk[0]}`);
  });

  it('stops on request: final sample at rest, OK `stopped`, within the stopping time reported', async (t) => {
    const request = example('plan_panda_path_c.json');
    const rate = request.motion.cycleRateHz;
    const ref = await reference(request);
    let stopSent = null;
    const result = await liveCall(client, 'Execute', { plan: request, options: { accelerationReserve: RESERVE } }, {
      onBatch(batch, { send, result: r }) {
        const last = batch.samples[batch.samples.length - 1];
        if (stopSent === null && last.planTime >= 0.5) {
          stopSent = { sample: r.samples.length - 1 };
          send({ stop: {} });
        }
      },
    });
    assertStatus(result, grpc.status.OK, 'stopped');
    const { samples, batches } = result;
    checkTiming(samples, rate, 'stop');
    checkJointLimits(samples, robots.panda.limits, rate, { jerkBound: jerkBounds(robots.panda, ref), label: 'stop' });
    assert.deepEqual(stateSequence(result), ['RUNNING', 'STOPPING', 'STOPPED']);
    const final = samples[samples.length - 1];
    assertAtRest(final, 'the final sample');
    assert.ok(final.planTime < batches[0].live.planDurationS, 'the stop came after the end of the plan');

    // The stop took effect after the last RUNNING batch: from its last sample the motion took
    // at most the stopping time that batch reported, plus two batch periods.
    const running = batches.filter((b) => b.live.state === 'LIVE_STATE_RUNNING');
    const lastRunning = running[running.length - 1];
    const from = samples[lastRunning.first + lastRunning.count - 1];
    const batchPeriod = Math.max(Math.round(rate * 0.01), ...batches.map((b) => b.count)) / rate;
    const took = final.t - from.t;
    const predicted = lastRunning.live.stoppingTimeS;
    assert.ok(predicted > 0 && took <= predicted + 2 * batchPeriod,
      `the stop took ${took} s, the stopping time reported was ${predicted} s`);
    assert.ok(final.planTime - from.planTime <= lastRunning.live.stoppingPlanTimeS + 2 * batchPeriod,
      `the stop covered ${final.planTime - from.planTime} s of plan time, ${lastRunning.live.stoppingPlanTimeS} s reported`);
    // The server acted on the stop soon after the last sample the client had seen then (the
    // bound leaves room for a loaded machine).
    const late = from.t - samples[stopSent.sample].t;
    assert.ok(late < 0.5, `the stop took effect ${late} s after the sample it was sent on`);
    t.diagnostic(`stop sent at t = ${samples[stopSent.sample].t} s, effective after t = ${from.t} s; took ${took.toFixed(4)} s ` +
                 `(reported ${predicted.toFixed(4)} s), ${(final.planTime - from.planTime).toFixed(4)} s of plan time ` +
                 `(reported ${lastRunning.live.stoppingPlanTimeS.toFixed(4)} s)`);
    // Slowing down only, on the path.
    const stopping = samples.slice(lastRunning.first + lastRunning.count);
    stopping.forEach((smp, i) => {
      if (i > 0) assert.ok(smp.speedFactor <= stopping[i - 1].speedFactor, `the speed factor rises while stopping (${i})`);
    });
  });

  it('stops for the deadman: no message for deadmanS 0.3, ABORTED `deadman`, last sample at rest', async (t) => {
    const request = example('plan_panda_path_c.json');
    const rate = request.motion.cycleRateHz;
    const ref = await reference(request);
    const result = await liveCall(client, 'Execute',
      { plan: request, options: { deadmanS: 0.3, accelerationReserve: RESERVE } }, { heartbeatMs: 0 });
    assertStatus(result, grpc.status.ABORTED, 'deadman');
    assert.match(result.details, /deadman/);
    const { samples, batches } = result;
    checkTiming(samples, rate, 'deadman');
    checkJointLimits(samples, robots.panda.limits, rate, { jerkBound: jerkBounds(robots.panda, ref), label: 'deadman' });
    assert.deepEqual(stateSequence(result), ['RUNNING', 'STOPPING', 'STOPPED']);
    assertAtRest(samples[samples.length - 1], 'the last sample');
    // The stop began once the deadman time had passed (sample times are the server's clock).
    const stopping = batches.find((b) => b.live.state !== 'LIVE_STATE_RUNNING');
    const began = samples[stopping.first].t;
    assert.ok(began >= 0.3 - 0.1 && began <= 0.3 + 0.5, `the deadman stop began at t = ${began} s`);
    t.diagnostic(`deadman: the stop began at t = ${began} s, at rest at t = ${samples[samples.length - 1].t} s`);
  });

  it('jogs one joint into its position limit: it stops there, never past it; then a stop ends OK', async (t) => {
    const panda = robots.panda;
    const joint = 3;  // panda_joint4: [-3.0718, -0.0698], home -2.356
    const lim = panda.limits[joint];
    const rate = 200;
    const velocityScale = 0.5;
    const command = panda.limits.map((_, j) => (j === joint ? -1 : 0));
    let restSince = null;
    let stopped = false;
    const result = await liveCall(client, 'Jog',
      { start: { robot: { name: 'panda' }, cycleRateHz: rate, velocityScale } }, {
        // The command right behind `start` (the server holds it until the robot is set up),
        // then heartbeats only: the joint keeps pushing into its limit.
        after: [{ joints: { velocities: command } }],
        onBatch(batch, { send }) {
          const last = batch.samples[batch.samples.length - 1];
          const atRest = last.jointVelocities[joint] === 0 && last.jointAccelerations[joint] === 0;
          if (restSince === null && atRest && batch.live.limitedJoints.includes(joint)) restSince = last.t;
          if (!stopped && restSince !== null && last.t - restSince >= 0.2) {
            stopped = true;
            send({ stop: {} });
          }
        },
      });
    assertStatus(result, grpc.status.OK, 'stopped');
    assert.ok(stopped, 'the joint never came to rest at its limit');
    const { samples, batches } = result;
    const jerkBound = panda.limits.map((l) => (l.maxJerk === undefined ? Infinity : l.maxJerk));
    checkJointLimits(samples, panda.limits, rate, { jerkBound, velocityScale, label: 'jog' });
    samples.forEach((smp, k) => {
      assert.ok(Math.abs(smp.t - (k + 1) / rate) < 1e-9, `jog sample ${k} at t = ${smp.t}`);
      // Never past the limit, and the other joints never move.
      assert.ok(smp.joints[joint] >= lim.minPosition, `joint ${joint} at ${smp.joints[joint]} past ${lim.minPosition}`);
      smp.joints.forEach((q, j) => { if (j !== joint) assert.equal(q, panda.home[j], `joint ${j} moved`); });
    });
    // It got there at full jog speed, braked, and came to rest at the limit.
    const peak = Math.max(...samples.map((smp) => Math.abs(smp.jointVelocities[joint])));
    assert.ok(Math.abs(peak - lim.maxVelocity * velocityScale) < 1e-9, `peak jog velocity ${peak}`);
    const final = samples[samples.length - 1];
    assertAtRest(final, 'the final jog sample');
    assert.ok(final.joints[joint] - lim.minPosition < 1e-6, `came to rest at ${final.joints[joint]}, limit ${lim.minPosition}`);
    t.diagnostic(`jog: joint ${joint} at rest ${final.joints[joint] - lim.minPosition} rad above its limit from t = ${restSince} s`);
    const holding = samples.filter((smp) => smp.t >= restSince);
    assert.ok(holding.length >= 0.2 * rate);
    holding.forEach((smp) => assert.equal(smp.joints[joint], final.joints[joint], 'the joint moves at its limit'));
    // LiveStatus: jogging, the joint reported limited from the braking on (and no other one),
    // then stopped.
    assert.deepEqual(stateSequence(result).slice(0, 1), ['JOGGING']);
    assert.equal(batches[batches.length - 1].live.state, 'LIVE_STATE_STOPPED');
    batches.forEach((b) => b.live.limitedJoints.forEach((j) => assert.equal(j, joint, 'another joint is limited')));
    const firstLimited = batches.findIndex((b) => b.live.limitedJoints.includes(joint));
    assert.ok(firstLimited > 0, 'the joint was never reported limited');
    assert.ok(samples[batches[firstLimited].first].jointVelocities[joint] !== 0, 'reported limited only once at rest');
    assert.ok(batches.slice(firstLimited).every((b) => b.live.limitedJoints.includes(joint) || b.live.state !== 'LIVE_STATE_JOGGING'),
      'the limited joint was released while still pushing into its limit');
  });

  it('keeps serving after an Execute cancelled by the client mid-way', async () => {
    const request = example('plan_panda_path_c.json');
    const result = await liveCall(client, 'Execute', { plan: request }, {
      onBatch(batch, { cancel, result: r }) {
        if (r.samples.length >= 300 && r.samples.length - batch.samples.length < 300) cancel();
      },
    });
    assert.equal(codeName(result.code), 'CANCELLED', result.details);
    assert.ok(result.samples.length >= 300 && result.samples.length < 3000, `${result.samples.length} samples`);
    // The server goes on: a unary call, and a new Execute stopped as soon as it is sent.
    const listed = await unary(client, 'ListRobots', {});
    assert.ok(listed.robots.length > 0);
    const again = await liveCall(client, 'Execute', { plan: request }, { after: [{ stop: {} }] });
    assertStatus(again, grpc.status.OK, 'stopped');
    assertAtRest(again.samples[again.samples.length - 1], 'the final sample after a stop at once');
  });

  it('runs the example client/node/geotraj_live.js (execute, then jog)', async () => {
    const run = (args) => new Promise((resolve) => {
      execFile(process.execPath, [EXAMPLE, server.address, ...args], {
        env: { ...process.env, NODE_PATH: NODE_MODULES, GEOTRAJ_PROTO_DIR: PROTO_DIR },
        timeout: 60000,
      }, (err, stdout, stderr) => resolve({ code: err ? err.code : 0, stdout, stderr }));
    });
    const executed = await run([path.join(EXAMPLES_DIR, 'plan_panda_path_c.json')]);
    assert.equal(executed.code, 0, `exit ${executed.code}\n${executed.stdout}\n${executed.stderr}`);
    for (const line of ['-> speed override 50 %', '-> pause', '-> resume', 'Execute ended: OK (completed)']) {
      assert.ok(executed.stdout.includes(line), `no "${line}" in\n${executed.stdout}`);
    }
    assert.match(executed.stdout, /speed factor 0\.500 .* running/);
    assert.match(executed.stdout, /speed factor 0\.000 .* paused/);
    const jogged = await run(['--jog', 'panda', '0', '0.5', '0.5']);
    assert.equal(jogged.code, 0, `exit ${jogged.code}\n${jogged.stdout}\n${jogged.stderr}`);
    assert.ok(jogged.stdout.includes('Jog ended: OK (stopped)'), jogged.stdout);
  });
});
