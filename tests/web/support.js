// What the browser tests share: where the server, the built page and the browser are (from
// the environment ctest sets, with defaults for a run from the source tree), a free port, a
// geotrajd serving the page, and headless chromium.
//
// Environment:
//   GEOTRAJD              the server binary (default: build/server/geotrajd)
//   GEOTRAJ_WEB_ROOT      the built page (default: build/share/geotraj/web)
//   GEOTRAJ_CHROMIUM      the browser (default: /usr/bin/chromium)
//   GEOTRAJ_WEB_ARTIFACTS where screenshots go (default: build/tests/web/artifacts)
'use strict';

const { spawn } = require('node:child_process');
const net = require('node:net');
const path = require('node:path');
const readline = require('node:readline');

const puppeteer = require('puppeteer-core');

const repo = path.resolve(__dirname, '..', '..');
const env = (name, fallback) => process.env[name] || fallback;
const GEOTRAJD = env('GEOTRAJD', path.join(repo, 'build', 'server', 'geotrajd'));
const WEB_ROOT = env('GEOTRAJ_WEB_ROOT', path.join(repo, 'build', 'share', 'geotraj', 'web'));
const CHROMIUM = env('GEOTRAJ_CHROMIUM', '/usr/bin/chromium');
const ARTIFACTS = env('GEOTRAJ_WEB_ARTIFACTS', path.join(repo, 'build', 'tests', 'web', 'artifacts'));
const WAIT_MS = 60000;

// A TCP port that was free a moment ago on 127.0.0.1.
function freePort() {
  return new Promise((resolve, reject) => {
    const server = net.createServer();
    server.once('error', reject);
    server.listen(0, '127.0.0.1', () => {
      const { port } = server.address();
      server.close(() => resolve(port));
    });
  });
}

// Starts geotrajd with its gRPC port on 127.0.0.1:0 and the page on webPort; resolves when
// it reports that it serves.
function startServer(webPort, extraEnv = {}) {
  return new Promise((resolve, reject) => {
    const proc = spawn(GEOTRAJD, ['--address', '127.0.0.1:0', '--web-address', `127.0.0.1:${webPort}`,
      '--web-root', WEB_ROOT], {
      env: { ...process.env, GEOTRAJ_PLAINTEXT: 'true', ...extraEnv },
      stdio: ['ignore', 'pipe', 'pipe'],
    });
    let stderr = '';
    proc.stderr.on('data', (chunk) => { stderr += chunk; });
    const timer = setTimeout(() => {
      proc.kill('SIGKILL');
      reject(new Error(`geotrajd did not report serving within 30 s; stderr: ${stderr}`));
    }, 30000);
    proc.on('exit', (code, signal) => {
      clearTimeout(timer);
      reject(new Error(`geotrajd exited early (code ${code}, signal ${signal}); stderr: ${stderr}`));
    });
    readline.createInterface({ input: proc.stdout }).on('line', (line) => {
      if (/^geotrajd: serving .* on (\S+:\d+)/.test(line)) {
        clearTimeout(timer);
        resolve(proc);
      }
    });
  });
}

function stopServer(proc) {
  return new Promise((resolve) => {
    if (!proc || proc.exitCode !== null || proc.signalCode !== null) { resolve(); return; }
    const timer = setTimeout(() => proc.kill('SIGKILL'), 30000);
    proc.removeAllListeners('exit');
    proc.on('exit', () => { clearTimeout(timer); resolve(); });
    proc.kill('SIGTERM');
  });
}

const sel = (testid) => `[data-testid="${testid}"]`;

function launchBrowser() {
  return puppeteer.launch({
    executablePath: CHROMIUM,
    headless: true,
    // --no-sandbox: the tests run as root (CI); swiftshader: WebGL without a GPU.
    args: ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
      '--window-size=1600,1200', '--disable-dev-shm-usage'],
  });
}

module.exports = {
  repo, GEOTRAJD, WEB_ROOT, CHROMIUM, ARTIFACTS, WAIT_MS, freePort, startServer, stopServer, sel, launchBrowser,
};
