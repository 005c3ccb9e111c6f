#!/usr/bin/env node
// Live execution and jogging from Node.js (@grpc/grpc-js and @grpc/proto-loader).
//
//   node geotraj_live.js ADDRESS REQUEST.json
//       Executes the plan of REQUEST.json (a PlanRequest in the proto JSON mapping, e.g.
//       client/grpcurl/plan_panda_path_c.json) with Execute: 1 s in, the speed override goes
//       to 50 %; 2 s in, a pause, and once at rest, 0.5 s later, a resume; then on to the end.
//   node geotraj_live.js ADDRESS --jog ROBOT JOINT [COMMAND] [SECONDS]
//       Jogs one joint (zero-based) of a built-in robot with Jog: COMMAND in [-1, 1] (default
//       0.5) of its maximum velocity times velocityScale, for SECONDS (default 1), then stops.
//
// Both print their progress (a line every 0.25 s of motion) and how the call ended. A
// heartbeat goes out every 100 ms: the server stops the motion and ends the call with ABORTED
// when it hears nothing for the deadman time (1 s by default).
//
// Environment: GEOTRAJ_PROTO_DIR (default: proto/ of this repository), GEOTRAJ_TOKEN (sent as
// `authorization: Bearer <token>`), GEOTRAJ_TLS_CA (a PEM file: TLS instead of plaintext),
// GEOTRAJ_GOOGLEAPIS_DIR (google/rpc/*.proto: an error's field violations are printed).
// Exit status: 0 the motion completed or was stopped, 1 the call failed, 2 bad usage.
'use strict';

const fs = require('node:fs');
const path = require('node:path');

const grpc = require('@grpc/grpc-js');
const protoLoader = require('@grpc/proto-loader');

const PROTO_DIR = process.env.GEOTRAJ_PROTO_DIR || path.join(__dirname, '..', '..', 'proto');
const GOOGLEAPIS_DIR = process.env.GEOTRAJ_GOOGLEAPIS_DIR || '/usr/share/gocode/src/github.com/gogo/googleapis';
const REPORT_EVERY_S = 0.25;
const HEARTBEAT_MS = 100;

function usage() {
  process.stderr.write('usage: geotraj_live.js ADDRESS REQUEST.json\n' +
                       '       geotraj_live.js ADDRESS --jog ROBOT JOINT [COMMAND] [SECONDS]\n');
  process.exit(2);
}

function connect(address) {
  // proto JSON names (camelCase) and enum names, as in the request files.
  const def = protoLoader.loadSync('geotraj/v1/geotraj.proto',
    { keepCase: false, longs: Number, enums: String, defaults: true, oneofs: true, includeDirs: [PROTO_DIR] });
  const { TrajectoryService } = grpc.loadPackageDefinition(def).geotraj.v1;
  const creds = process.env.GEOTRAJ_TLS_CA
    ? grpc.credentials.createSsl(fs.readFileSync(process.env.GEOTRAJ_TLS_CA))
    : grpc.credentials.createInsecure();
  return new TrajectoryService(address, creds);
}

function metadata() {
  const md = new grpc.Metadata();
  if (process.env.GEOTRAJ_TOKEN) md.set('authorization', `Bearer ${process.env.GEOTRAJ_TOKEN}`);
  return md;
}

// The field violations of a google.rpc.BadRequest in the grpc-status-details-bin trailer,
// when the google/rpc protos are at hand (protobufjs comes with @grpc/proto-loader).
function violations(md) {
  const [bin] = md ? md.get('grpc-status-details-bin') : [];
  if (!Buffer.isBuffer(bin) || !fs.existsSync(path.join(GOOGLEAPIS_DIR, 'google/rpc/status.proto'))) return [];
  const protobuf = require('protobufjs');
  const root = new protobuf.Root();
  root.resolvePath = (origin, target) => {
    const candidate = path.join(GOOGLEAPIS_DIR, target);
    return fs.existsSync(candidate) ? candidate : target;
  };
  root.loadSync(['google/rpc/status.proto', 'google/rpc/error_details.proto'], { keepCase: true });
  const status = root.lookupType('google.rpc.Status').decode(bin);
  const BadRequest = root.lookupType('google.rpc.BadRequest');
  return status.details.filter((any) => any.type_url.endsWith('/google.rpc.BadRequest'))
    .flatMap((any) => BadRequest.decode(any.value).field_violations.map((v) => `${v.field}: ${v.description}`));
}

// Runs one live call: `first` is its first message; `onBatch(batch, send)` sees every batch.
// Resolves with the exit status once the call has ended.
function live(client, method, first, onBatch) {
  return new Promise((resolve) => {
    const call = client[method](metadata());
    let ended = false;
    let count = 0;
    let last = null;
    let nextReport = 0;
    const send = (message) => { if (!ended) call.write(message); };
    const heartbeat = setInterval(() => send({ heartbeat: {} }), HEARTBEAT_MS);
    call.on('data', (batch) => {
      for (const sample of batch.samples) {
        count += 1;
        last = sample;
        if (sample.t >= nextReport) {
          nextReport += REPORT_EVERY_S;
          console.log(describe(sample, batch.live));
        }
      }
      onBatch(batch, send);
    });
    call.on('error', () => {});  // the status event says it all
    call.on('status', (status) => {
      ended = true;
      clearInterval(heartbeat);
      call.end();
      const [reason] = status.metadata.get('geotraj-stop-reason');
      const name = Object.keys(grpc.status).find((k) => grpc.status[k] === status.code);
      if (last) console.log(describe(last, null));
      console.log(`${method} ended: ${name}${reason ? ` (${reason})` : ''} after ${count} samples` +
                  (status.code === grpc.status.OK ? '' : `: ${status.details}`));
      for (const v of violations(status.metadata)) console.log(`  ${v}`);
      resolve(status.code === grpc.status.OK ? 0 : 1);
    });
    call.write(first);
  });
}

function fixed(x, digits = 3) {
  return x === undefined || x === null ? '-' : Number(x).toFixed(digits);
}

function describe(sample, status) {
  const joints = sample.joints.map((q) => fixed(q)).join(' ');
  let line = `t ${fixed(sample.t)} s`;
  if (sample.planTime !== undefined) line += `  plan ${fixed(sample.planTime)} s  speed factor ${fixed(sample.speedFactor)}`;
  line += `  joints [${joints}]`;
  if (status) {
    line += `  ${status.state.replace('LIVE_STATE_', '').toLowerCase()}`;
    if (status.limitedJoints.length > 0) line += `  at a limit: joints ${status.limitedJoints.join(', ')}`;
  }
  return line;
}

// Execute: the override to 50 % after 1 s, a pause at 2 s, a resume 0.5 s after coming to rest.
async function execute(client, requestFile) {
  const plan = JSON.parse(fs.readFileSync(requestFile, 'utf8'));
  let started = null;
  let pausedAt = null;
  const steps = { override: false, pause: false, resume: false };
  return live(client, 'Execute', { plan, options: { deadmanS: 1 } }, (batch, send) => {
    const now = Date.now();
    if (started === null) {
      started = now;
      const s = batch.live;
      console.log(`executing: ${fixed(s.planDurationS)} s at full speed; a stop from full speed takes ` +
                  `${fixed(s.stoppingTimeS)} s (bound by ${s.binding})`);
      if (s.accelerationReserve > 0) console.log(`acceleration reserve ${s.accelerationReserve}: ${s.reserveNote}`);
    }
    if (!steps.override && now - started >= 1000) {
      steps.override = true;
      console.log('-> speed override 50 %');
      send({ speedOverride: 50 });
    }
    if (!steps.pause && now - started >= 2000) {
      steps.pause = true;
      console.log('-> pause');
      send({ pause: {} });
    }
    if (steps.pause && pausedAt === null && batch.live.state === 'LIVE_STATE_PAUSED') pausedAt = now;
    if (!steps.resume && pausedAt !== null && now - pausedAt >= 500) {
      steps.resume = true;
      console.log('-> resume');
      send({ resume: {} });
    }
  });
}

// Jog: one joint at `command` for `seconds`, then a stop.
async function jog(client, robot, joint, command, seconds) {
  const { robots } = await new Promise((resolve, reject) =>
    client.ListRobots({}, metadata(), (err, resp) => (err ? reject(err) : resolve(resp))));
  const model = robots.find((m) => m.name === robot);
  if (!model) throw new Error(`no robot ${robot}: the server has ${robots.map((m) => m.name).join(', ')}`);
  if (!(joint >= 0 && joint < model.limits.length)) throw new Error(`${robot} has joints 0..${model.limits.length - 1}`);
  const velocities = model.limits.map((_, j) => (j === joint ? command : 0));
  let started = null;
  let stopped = false;
  console.log(`jogging ${robot} joint ${joint} at ${command} for ${seconds} s`);
  return live(client, 'Jog', { start: { robot: { name: robot }, cycleRateHz: 100, velocityScale: 0.25 } },
    (batch, send) => {
      if (started === null) {
        started = Date.now();
        send({ joints: { velocities } });
      }
      if (!stopped && Date.now() - started >= seconds * 1000) {
        stopped = true;
        console.log('-> stop');
        send({ stop: {} });
      }
    });
}

async function main(argv) {
  if (argv.length < 2) usage();
  const client = connect(argv[0]);
  try {
    if (argv[1] === '--jog') {
      if (argv.length < 4) usage();
      const command = argv[4] === undefined ? 0.5 : Number(argv[4]);
      const seconds = argv[5] === undefined ? 1 : Number(argv[5]);
      if (!Number.isInteger(Number(argv[3])) || !Number.isFinite(command) || !Number.isFinite(seconds)) usage();
      return await jog(client, argv[2], Number(argv[3]), command, seconds);
    }
    return await execute(client, argv[1]);
  } finally {
    client.close();
  }
}

main(process.argv.slice(2)).then((code) => { process.exitCode = code; }, (err) => {
  console.error(`geotraj_live.js: ${err.message}`);
  process.exitCode = 1;
});
