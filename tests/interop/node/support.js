// What the Node interop tests share: the environment ctest sets, the example requests, the
// call metadata, and geotrajd started on a free loopback port and stopped with SIGTERM.
'use strict';

const { spawn } = require('node:child_process');
const fs = require('node:fs');
const path = require('node:path');
const readline = require('node:readline');

const grpc = require('@grpc/grpc-js');

const repo = path.resolve(__dirname, '..', '..', '..');
const env = (name, fallback) => process.env[name] || fallback;
const GEOTRAJD = env('GEOTRAJD', path.join(repo, 'build', 'server', 'geotrajd'));
const PROTO_DIR = env('GEOTRAJ_PROTO_DIR', path.join(repo, 'proto'));
const EXAMPLES_DIR = env('GEOTRAJ_EXAMPLES_DIR', path.join(repo, 'client', 'grpcurl'));

const LOADER_OPTIONS = { keepCase: false, longs: Number, enums: String, defaults: true, oneofs: true };

function example(name) {
  return JSON.parse(fs.readFileSync(path.join(EXAMPLES_DIR, name), 'utf8'));
}

// The call's metadata: the bearer token of GEOTRAJ_TOKEN, when set.
function metadata() {
  const md = new grpc.Metadata();
  if (process.env.GEOTRAJ_TOKEN) md.set('authorization', `Bearer ${process.env.GEOTRAJ_TOKEN}`);
  return md;
}

function deadlineIn(ms) {
  return new Date(Date.now() + ms);
}

// Starts geotrajd on 127.0.0.1:0 and resolves with its process and address, read from the
// line "geotrajd: serving ... on HOST:PORT".
function startServer() {
  return new Promise((resolve, reject) => {
    if (!fs.existsSync(GEOTRAJD)) {
      reject(new Error(`geotrajd not found at ${GEOTRAJD}: set GEOTRAJD`));
      return;
    }
    const proc = spawn(GEOTRAJD, ['--address', '127.0.0.1:0'], {
      env: { ...process.env, GEOTRAJ_PLAINTEXT: 'true' },
      stdio: ['ignore', 'pipe', 'pipe'],
    });
    let stderr = '';
    proc.stderr.on('data', (chunk) => { stderr += chunk; });
    const timer = setTimeout(() => {
      proc.kill('SIGKILL');
      reject(new Error(`geotrajd did not report its address within 30 s; stderr: ${stderr}`));
    }, 30000);
    proc.on('exit', (code, signal) => {
      clearTimeout(timer);
      reject(new Error(`geotrajd exited early (code ${code}, signal ${signal}); stderr: ${stderr}`));
    });
    const lines = readline.createInterface({ input: proc.stdout });
    lines.on('line', (line) => {
      const m = /^geotrajd: serving .* on (\S+:\d+)/.exec(line);
      if (m) {
        clearTimeout(timer);
        resolve({ proc, address: m[1] });
      }
    });
  });
}

// SIGTERM, then SIGKILL if it has not exited within 30 s.
function stopServer(proc) {
  return new Promise((resolve) => {
    if (proc.exitCode !== null || proc.signalCode !== null) { resolve(); return; }
    const timer = setTimeout(() => proc.kill('SIGKILL'), 30000);
    proc.removeAllListeners('exit');
    proc.on('exit', () => { clearTimeout(timer); resolve(); });
    proc.kill('SIGTERM');
  });
}

// A unary call as a promise.
function unary(client, method, request, options = {}) {
  return new Promise((resolve, reject) => {
    client[method](request, metadata(), options, (err, response) => (err ? reject(err) : resolve(response)));
  });
}

module.exports = {
  repo, env, GEOTRAJD, PROTO_DIR, EXAMPLES_DIR, LOADER_OPTIONS,
  example, metadata, deadlineIn, startServer, stopServer, unary,
};
