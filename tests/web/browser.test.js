// The operator's page in a real browser: Debian's chromium, headless, driven by
// puppeteer-core, against a real geotrajd serving the built page (--web-root) and its JSON
// API (--web-address). Runner: node:test (built in).
//
// Checks: the page loads without console errors; the thesis's path C renders (a non-empty
// WebGL canvas; screenshot in the artifacts folder); a curvature typed for frame 2 is the
// curvature achieved there; an invalid value shows the server's field message beside its
// field; the family view draws N curves; switching the reading of unspecified constraints
// changes the curve; a request file loads, and the commands that send it are shown; the
// PA-10's time-optimal plan shows its binding limits, and its replay moves the arm; path C
// typed into the empty start field by field achieves at frames 1 and 2 the curvature and
// torsion the API answers for client/grpcurl/plan_demo_path_c.json, saves as that file, and
// reads frame 0's curvature as the API does under every reading of unspecified constraints;
// with a server that checks tokens, the token typed in the page goes with every call; a
// weld seam built as a path of pieces in the editor (start frame, line, arc, line, transition
// tolerance) plans to 5 segments, drawn as 3 exact pieces and 2 transitions, as the API
// plans the same request, and a negative arc radius shows the server's message at that
// piece's radius; the helix and the seam files fill the pieces editor (start page, load…),
// and the family view sweeps the seam's arc radius (each member bent as 1/r);
// the family's local mode at path C's frame 1 draws 6 members x 2 branches on the circles of
// radius 1/κ tangent to T at the frame, the backward branch leaving along -T, both branches
// along -T at the cusp (frame 2), the forward one towards -N at an inflection, and lists a
// value the server refuses; the Panda joint path of the start page fills the waypoint
// editor, plans to the duration the API answers for its file, draws the tool's path and the
// waypoints, replays the arm and passes every interior waypoint within the blend tolerance;
// a waypoint value out of its joint's limits (and a negative tolerance) shows the server's
// message at that input; removing a waypoint plans again as the API plans the file without it.
//
//   cd tests/web && PUPPETEER_SKIP_DOWNLOAD=1 npm ci && \
//     GEOTRAJD=../../build/server/geotrajd GEOTRAJ_WEB_ROOT=../../build/share/geotraj/web npm test
//
// Environment (ctest sets them; the defaults suit a run from the source tree):
//   GEOTRAJD              the server binary (default: build/server/geotrajd)
//   GEOTRAJ_WEB_ROOT      the built page (default: build/share/geotraj/web)
//   GEOTRAJ_CHROMIUM      the browser (default: /usr/bin/chromium)
//   GEOTRAJ_WEB_ARTIFACTS where screenshots go (default: build/tests/web/artifacts)
//   GEOTRAJ_UI_FIGURES    optional: also write docs/ui.md's figures (ui_*.png) there
'use strict';

const { describe, it, before, after } = require('node:test');
const assert = require('node:assert/strict');
const fs = require('node:fs');
const path = require('node:path');

const {
  repo, GEOTRAJD, WEB_ROOT, CHROMIUM, ARTIFACTS, WAIT_MS, freePort, startServer, stopServer, sel, launchBrowser,
} = require('./support');

const FIGURES = process.env.GEOTRAJ_UI_FIGURES || '';

// A geotrajd (with `extraEnv`) and chromium on a page of 1600 x 1200 that records in
// `problems` every console error that `tolerated(message)` does not excuse, every page error
// and every failed request but those the page aborts itself (a replan supersedes its calls).
async function openPage(problems, extraEnv, tolerated) {
  const webPort = await freePort();
  const server = await startServer(webPort, extraEnv);
  const browser = await launchBrowser();
  const page = await browser.newPage();
  await page.setViewport({ width: 1600, height: 1200 });
  page.on('console', (m) => {
    if (m.type() !== 'error' || tolerated(m)) return;
    problems.push(`console: ${m.text()} (${m.location()?.url || ''})`);
  });
  page.on('pageerror', (e) => problems.push(`page error: ${e.message}`));
  page.on('requestfailed', (r) => {
    if (r.failure()?.errorText !== 'net::ERR_ABORTED') problems.push(`request failed: ${r.url()} ${r.failure()?.errorText}`);
  });
  page.setDefaultTimeout(WAIT_MS);
  return { server, browser, page, base: `http://127.0.0.1:${webPort}/` };
}

// The browser logs every 4xx answer as "Failed to load resource"; a refused request the
// page shows beside its fields (400 from an API route) is the page working.
// The describe block's own geotrajd, chromium and page (openPage), opened before its tests
// and handed to `set`, closed after them.
function usePage(problems, tolerated, set) {
  let opened = null;
  before(async () => {
    assert.ok(fs.existsSync(CHROMIUM), `chromium not found at ${CHROMIUM}: apt-get install chromium`);
    fs.mkdirSync(ARTIFACTS, { recursive: true });
    opened = await openPage(problems, {}, tolerated);
    set(opened);
  });
  after(async () => {
    if (opened?.browser) await opened.browser.close();
    await stopServer(opened?.server);
  });
}

const refusedPlan = (m) =>
  /Failed to load resource: .* status of 400/.test(m.text()) && /\/v1\/(plan|analyze)$/.test(m.location()?.url || '');

// What the tests do on a page (the page that pageOf() returns when called, and the list of
// problems its openPage records): waiting on the page's own state, typing, reading values,
// screenshots, seeking the replay.
function pageHelpers(pageOf, problems) {
  // Waits for fn(arg) in the page; a timeout fails with what the page shows, and a
  // screenshot (timeout-<what>.png) in the artifacts folder.
  async function waitFor(what, fn, arg) {
    try {
      await pageOf().waitForFunction(fn, { timeout: WAIT_MS }, arg);
    } catch (e) {
      const shown = await pageOf().evaluate(() => JSON.stringify({
        body: { ...document.body.dataset },
        status: document.querySelector('[data-testid="status"]')?.textContent,
        errors: document.querySelector('[data-testid="general-errors"]')?.textContent,
        replay: document.querySelector('[data-testid="replay-status"]')?.textContent,
      })).catch((why) => `(page unreadable: ${why.message})`);
      await pageOf().screenshot({ path: path.join(ARTIFACTS, `timeout-${what}.png`) }).catch(() => {});
      throw new Error(`waiting for ${what}: ${e.message}; the page shows ${shown}; problems so far: ${problems.join('; ')}`);
    }
  }
  const plans = () => pageOf().$eval('body', (b) => Number(b.dataset.plans || 0));
  // Waits for a plan after `before` plans that is the page's latest, and returns its state.
  async function settled(beforeCount) {
    await waitFor('plan', (n) => {
      const d = document.body.dataset;
      return Number(d.plans || 0) > n && (d.planState === 'ready' || d.planState === 'error');
    }, beforeCount);
    return pageOf().$eval('body', (b) => b.dataset.planState);
  }
  async function streamed() {
    await waitFor('stream', () => document.body.dataset.streamState === 'ready' &&
      document.querySelector('[data-testid="replay-slider"]').dataset.ready === 'true');
  }
  async function typeInto(testid, text) {
    const input = await pageOf().$(sel(testid));
    assert.ok(input, `no element ${testid}`);
    // Focused and its text selected by the element itself: a triple click on a loaded
    // machine can arrive as separate clicks and leave part of the old text to type after.
    await input.click();
    await input.evaluate((e) => e.select());
    await pageOf().keyboard.press('Backspace');
    await input.type(text);
    // Read again: a re-render while typing (the robots' list arriving on a loaded machine)
    // replaces the element, and the page carries the text being typed over to the new one.
    assert.equal(await pageOf().$eval(sel(testid), (e) => e.value), text, `${testid} after typing`);
  }
  const dataValue = (testid) => pageOf().$eval(sel(testid), (e) => Number(e.dataset.value));
  const signature = () => pageOf().$eval(sel('view3d'), (e) => e.dataset.curveSignature || '');
  // A screenshot in the artifacts folder (of an element, or the page; fullPage: all of
  // it), copied to docs/ui.md's figures when GEOTRAJ_UI_FIGURES asks and `figure` is true.
  async function screenshot(name, { element, fullPage = false, figure = true } = {}) {
    const file = path.join(ARTIFACTS, `${name}.png`);
    if (element) await (await pageOf().$(element)).screenshot({ path: file });
    else await pageOf().screenshot({ path: file, fullPage });
    if (FIGURES && figure) fs.copyFileSync(file, path.join(FIGURES, `ui_${name}.png`));
  }
  // The view's WebGL canvas read back: the fraction of its pixels drawn (not the white
  // background), and the count of pixels in the transitions' pink (#e91e63: red, little
  // green, blue well above green; the red of the tool and the T arrows has blue and green
  // alike, viridis is never this red).
  const canvasPixels = () => pageOf().$eval(`${sel('view3d')} canvas`, (canvas) => {
    const copy = document.createElement('canvas');
    copy.width = canvas.width;
    copy.height = canvas.height;
    const ctx = copy.getContext('2d');
    ctx.drawImage(canvas, 0, 0);
    const { data } = ctx.getImageData(0, 0, copy.width, copy.height);
    let drawn = 0;
    let pink = 0;
    for (let i = 0; i < data.length; i += 4) {
      if (data[i] < 240 || data[i + 1] < 240 || data[i + 2] < 240) ++drawn;
      if (data[i] > 190 && data[i + 1] < 80 && data[i + 2] - data[i + 1] > 35) ++pink;
    }
    return { drawn: drawn / (data.length / 4), pink };
  });
  // The server's messages shown in the editor, by the field they stand at.
  const shownErrors = () => pageOf().$$eval(`${sel('editor')} [data-error-for]`, (l) => l
    .filter((e) => e.textContent).map((e) => `${e.dataset.errorFor}: ${e.textContent}`));
  async function seek(t) {
    await pageOf().$eval(sel('replay-slider'), (s, value) => {
      s.value = String(value);
      s.dispatchEvent(new Event('input'));
    }, t);
    return pageOf().$eval(sel('replay-tool'), (e) => [Number(e.dataset.x), Number(e.dataset.y), Number(e.dataset.z)]);
  }
  // The page at `base` from its start page's "Start empty", planned, with the built-in
  // robots arrived (they re-render the editor when they arrive: before typing, not during).
  async function startEmpty(base) {
    await pageOf().goto(base, { waitUntil: 'load' });
    await pageOf().waitForSelector(`${sel('start-page')}[open]`);
    const n = await plans();
    await pageOf().click(sel('start-empty'));
    assert.equal(await settled(n), 'ready');
    await waitFor('robots', () => document.querySelector('[data-testid="robot-name"]')?.options.length > 1);
  }
  return { waitFor, plans, settled, streamed, typeInto, dataValue, signature, screenshot, canvasPixels, shownErrors, seek,
    startEmpty };
}

// What POST /v1/plan answers for `request` on the server at `base`, asked from here (Node's
// fetch): the page's numbers are checked against it.
async function planOf(base, request) {
  const answer = await fetch(new URL('v1/plan', base), {
    method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify(request),
  });
  const text = await answer.text();
  assert.equal(answer.status, 200, `POST /v1/plan: ${text}`);
  return JSON.parse(text);
}

describe('the operator page in chromium', () => {
  let server;
  let browser;
  let page;
  let base;
  const problems = [];  // console errors, page errors, failed requests

  before(async () => {
    assert.ok(fs.existsSync(GEOTRAJD), `geotrajd not found at ${GEOTRAJD}: set GEOTRAJD`);
    assert.ok(fs.existsSync(path.join(WEB_ROOT, 'index.html')),
      `the built page is not at ${WEB_ROOT} (build the geotraj_web target): set GEOTRAJ_WEB_ROOT`);
    // No browser, no test: a machine without chromium fails here, loudly.
    assert.ok(fs.existsSync(CHROMIUM),
      `chromium not found at ${CHROMIUM}: apt-get install chromium (scripts/install-deps.sh), or set GEOTRAJ_CHROMIUM`);
    fs.mkdirSync(ARTIFACTS, { recursive: true });
    if (FIGURES) fs.mkdirSync(FIGURES, { recursive: true });
    ({ server, browser, page, base } = await openPage(problems, {}, refusedPlan));
  });

  after(async () => {
    if (browser) await browser.close();
    await stopServer(server);
  });

  const { waitFor, plans, settled, streamed, typeInto, dataValue, signature, screenshot, canvasPixels, seek } =
    pageHelpers(() => page, problems);

  it('loads with the start page and no console errors', async () => {
    await page.goto(base, { waitUntil: 'load' });
    await page.waitForSelector(`${sel('start-page')}[open]`);
    assert.deepEqual(problems, []);
  });

  it("renders the thesis's demonstration path on a non-empty WebGL canvas", async () => {
    const n = await plans();
    await page.click(sel('start-demo'));
    assert.equal(await settled(n), 'ready');
    const points = await page.$eval(sel('view3d'), (e) => Number(e.dataset.curvePoints || 0));
    assert.ok(points > 100, `the curve has ${points} points`);
    assert.equal(await page.$eval(sel('view3d'), (e) => e.dataset.frames), '4');
    await streamed();
    // Pixels that differ from the white background, read back from the WebGL canvas.
    await new Promise((r) => setTimeout(r, 300));
    const coloured = (await canvasPixels()).drawn;
    assert.ok(coloured > 0.01, `only ${(coloured * 100).toFixed(3)} % of the canvas is drawn`);
    assert.match(await page.$eval(sel('colorbar'), (e) => e.textContent), /curvature κ \[1\/m\]/);
    await screenshot('overview');
    assert.deepEqual(problems, []);
  });

  it('achieves at frame 2 the curvature typed for it', async () => {
    const before = await signature();
    const n = await plans();
    await typeInto('frame-2-input-curvature', '15');
    assert.equal(await settled(n), 'ready');
    assert.notEqual(await signature(), before, 'the curve did not change');
    for (const id of ['frame-2-curvature', 'frame-2-curvature-approach', 'frame-2-curvature-leave']) {
      const value = await dataValue(id);
      assert.ok(Math.abs(value - 15) <= 1e-6 * 15, `${id} is ${value}, not 15`);
    }
    // What the operator waited (reported, not asserted: timing belongs to the benchmarks).
    const status = await page.$eval(sel('status'), (e) => e.textContent);
    console.log(`[ measured ] curvature edit of path C: ${status}`);
  });

  it("shows the server's field violation beside the field", async () => {
    const n = await plans();
    await typeInto('frame-1-input-tangentScale', '-0.25');
    assert.equal(await settled(n), 'error');
    const slot = '[data-error-for="path.frames[1].tangentScale"]';
    const message = await page.$eval(slot, (e) => e.textContent);
    assert.ok(message.length > 0, 'no message beside path.frames[1].tangentScale');
    await screenshot('field_error', { element: sel('frame-1') });
    const m = await plans();
    await typeInto('frame-1-input-tangentScale', '0.25');
    assert.equal(await settled(m), 'ready');
    assert.equal(await page.$eval(slot, (e) => e.textContent), '');
  });

  it('replays the samples: the tool moves with the slider', async () => {
    await streamed();
    const a = await seek(2);
    const b = await seek(6);
    const d = Math.hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]);
    assert.ok(d > 1e-3, `the tool is at ${a} and ${b}`);
  });

  it('draws a family of N curves', async () => {
    await page.select(sel('family-frame'), '1');
    await page.select(sel('family-constraint'), 'curvature');
    await typeInto('family-from', '10');
    await typeInto('family-to', '30');
    await typeInto('family-count-input', '5');
    await page.click(sel('family-run'));
    await waitFor('family', () => document.querySelector('[data-testid="family"]').dataset.curves === '5');
    assert.equal(await page.$eval(sel('view3d'), (e) => e.dataset.familyCurves), '5');
    assert.equal(await page.$$eval(`${sel('family-legend')} li:not(.violation)`, (l) => l.length), 5);
    await screenshot('family');
  });

  it('changes the curve with the reading of unspecified constraints', async () => {
    const before = await signature();
    const length = await dataValue('plan-arc-length');
    const n = await plans();
    await page.select(sel('path-unspecified'), 'UNSPECIFIED_CONSTRAINTS_LOWEST_DEGREE');
    assert.equal(await settled(n), 'ready');
    assert.notEqual(await signature(), before, 'the curve did not change');
    assert.notEqual(await dataValue('plan-arc-length'), length);
  });

  it('loads a request file and shows the commands that send it', async () => {
    const n = await plans();
    const input = await page.$(sel('load-file'));
    await input.uploadFile(path.join(repo, 'client', 'grpcurl', 'plan_demo_path_a.json'));
    assert.equal(await settled(n), 'ready');
    const asked = JSON.parse(fs.readFileSync(path.join(repo, 'client', 'grpcurl', 'plan_demo_path_a.json'), 'utf8'));
    assert.equal(await page.$eval(sel('view3d'), (e) => e.dataset.frames), String(asked.path.frames.length));
    await page.click(sel('copy-command'));
    const lines = await page.$eval(sel('command-lines'), (e) => e.textContent);
    assert.match(lines, /^geotraj --server \S+ plan request\.json$/m);
    assert.match(lines, /grpcurl .*-d @ \S+ geotraj\.v1\.TrajectoryService\/PlanTrajectory < request\.json/);
    await page.click('[data-action=close-commands]');
  });

  it("shows the binding limits of the PA-10's time-optimal plan, and replays the arm", async () => {
    await page.click('[data-action=start]');
    const n = await plans();
    await page.click(sel('start-pa10'));
    assert.equal(await settled(n), 'ready');
    const stretches = await page.$eval(sel('plot-binding'), (e) => Number(e.dataset.stretches || 0));
    assert.ok(stretches > 0, 'no binding stretch shown');
    assert.match(await page.$eval(sel('binding-stretch-0'), (e) => e.textContent), /joint \d|speed|acceleration/);
    // "binding" is said of a limit at 100 % only: a time-optimal plan has one, and no stretch
    // below 99.9 % is called so.
    const items = await page.$$eval(`${sel('plot-binding')} [data-testid^="binding-stretch-"]`,
      (l) => l.map((e) => e.textContent));
    assert.ok(items.some((t) => t.endsWith(', binding')), `no stretch at 100 %: ${items}`);
    for (const t of items) {
      const usage = Number(/ at ([0-9.e+-]+) %/.exec(t)?.[1]);  // 4 digits shown
      if (Math.abs(usage - 99.9) > 0.01) assert.equal(t.endsWith(', binding'), usage >= 99.9, t);
    }
    assert.ok(await dataValue('plan-time-optimal') > 0);
    await streamed();
    assert.ok(await page.$eval(sel('plot-joint-positions'), (e) => Number(e.dataset.series)) === 7);
    // The PA-10 has no mass properties: no torques, and the page says why.
    assert.equal(await page.$eval(sel('plot-joint-torques'), (e) => Number(e.dataset.series)), 0);
    assert.match(await page.$eval(sel('plot-joint-torques'), (e) => e.textContent), /no mass properties/);
    const duration = await dataValue('plan-duration');
    const a = await seek(duration * 0.25);
    const b = await seek(duration * 0.75);
    const d = Math.hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]);
    assert.ok(d > 1e-3, `the arm's tool is at ${a} and ${b}`);
    const links = await page.$eval(sel('view3d'), (e) => Number(e.dataset.robotLinks || 0));
    assert.ok(links >= 7, `the arm is drawn with ${links} links`);
    await screenshot('pa10', { fullPage: true });
    await screenshot('pa10_plots', { element: sel('plots'), figure: false });
  });

  it('logged no console error on the way', () => {
    assert.deepEqual(problems, []);
  });
});

// The thesis's path C typed in by an operator, through the page only: from the empty start,
// frames added to four, every value of client/grpcurl/plan_demo_path_c.json typed into its
// field (the derivative convention and blend chosen in their selects, the cusp ticked), the
// readout at frames 1 and 2 against what POST /v1/plan answers for the file itself, the saved
// request against the file; then each reading of unspecified constraints against the API
// for the file with that reading; then the PA-10's time-optimal start, its binding joint
// limit named and its arm moved by the replay slider.
describe('path C typed into the editor by hand', () => {
  const demoFile = path.join(repo, 'client', 'grpcurl', 'plan_demo_path_c.json');
  const asked = JSON.parse(fs.readFileSync(demoFile, 'utf8'));
  const downloads = path.join(ARTIFACTS, 'typed_path_c_saved');
  let server;
  let browser;
  let page;
  let base;
  const problems = [];
  const { waitFor, plans, settled, streamed, typeInto, dataValue, screenshot, startEmpty } = pageHelpers(
    () => page, problems);

  before(async () => {
    assert.ok(fs.existsSync(CHROMIUM), `chromium not found at ${CHROMIUM}: apt-get install chromium`);
    fs.mkdirSync(ARTIFACTS, { recursive: true });
    // A fresh folder: chromium would name a second download "request (1).json".
    fs.rmSync(downloads, { recursive: true, force: true });
    fs.mkdirSync(downloads, { recursive: true });
    // Intermediate values (a normal half typed, a curvature' before its curvature) are
    // refused with 400 and shown beside their fields: the page working.
    ({ server, browser, page, base } = await openPage(problems, {}, refusedPlan));
    // The page's "save" is a download: into `downloads`, under the name the page gives it.
    const session = await browser.target().createCDPSession();
    await session.send('Browser.setDownloadBehavior', { behavior: 'allow', downloadPath: downloads });
  });

  after(async () => {
    if (browser) await browser.close();
    await stopServer(server);
  });

  // Equal to 1e-9 relative (absolute below 1).
  function assertClose(actual, expected, what) {
    assert.equal(typeof expected, 'number', `${what}: the API answers ${expected}`);
    assert.ok(Math.abs(actual - expected) <= 1e-9 * Math.max(1, Math.abs(expected)),
      `${what} reads ${actual}, the API answers ${expected}`);
  }
  const frameCount = () => page.$$eval(`${sel('editor')} fieldset.frame`, (f) => f.length);
  // Polls a condition of this process (a file written by chromium) until it holds.
  async function until(what, check) {
    const deadline = Date.now() + WAIT_MS;
    while (!check()) {
      if (Date.now() > deadline) throw new Error(`waiting for ${what}`);
      await new Promise((r) => setTimeout(r, 50));
    }
  }
  // A PlanRequest in proto JSON with what proto3 leaves implicit written the same way on
  // both sides: a Vec3's absent components are 0, a false bool is absent. Optional scalars
  // stay as they are: absent is not 0 there.
  function canonical(request) {
    const out = JSON.parse(JSON.stringify(request));
    for (const frame of out.path?.frames || []) {
      for (const key of ['position', 'tangent', 'normal', 'binormal']) {
        if (frame[key]) frame[key] = { x: frame[key].x ?? 0, y: frame[key].y ?? 0, z: frame[key].z ?? 0 };
      }
      for (const key of ['cusp', 'inflection', 'stop', 'easeOrientation']) if (frame[key] === false) delete frame[key];
    }
    if (out.path?.closed === false) delete out.path.closed;
    return out;
  }

  it("achieves at frames 1 and 2 what the API answers for path C's file, and saves the file", async () => {
    await startEmpty(base);
    let n = await plans();
    assert.equal(await frameCount(), 2);
    const frames = asked.path.frames;
    assert.equal(frames.length, 4);
    while (await frameCount() < frames.length) await page.click(sel('frame-add'));
    assert.equal(await frameCount(), 4);

    n = await plans();
    // The path's selects: the empty start's defaults are not the file's convention and blend.
    assert.notEqual(await page.$eval(sel('path-derivativeConvention'), (s) => s.value), asked.path.derivativeConvention);
    for (const [testid, key] of [['path-derivativeConvention', 'derivativeConvention'], ['path-blend', 'blend'],
      ['path-unspecified', 'unspecified']]) {
      const wanted = asked.path[key] ?? '';
      if (await page.$eval(sel(testid), (s) => s.value) !== wanted) await page.select(sel(testid), wanted);
    }
    // κ' and τ' are now per unit u, and their fields say so.
    assert.deepEqual(await page.$$eval(`${sel('frame-1')} [data-derivative-unit]`, (u) => u.map((e) => e.textContent)),
      ['1/m per u', '1/m per u']);

    for (const [i, frame] of frames.entries()) {
      // The binormal is under "binormal, leaving scale, tool orientation".
      const more = `${sel(`frame-${i}`)} details.more`;
      if ((frame.binormal || frame.leaveTangentScale !== undefined) && !await page.$eval(more, (d) => d.open)) {
        await page.click(`${more} > summary`);
      }
      for (const vector of ['position', 'tangent', 'normal', 'binormal']) {
        if (!frame[vector]) continue;
        for (const axis of ['x', 'y', 'z']) {
          await typeInto(`frame-${i}-input-${vector}-${axis}`, String(frame[vector][axis] ?? 0));
        }
      }
      // Curvature first: torsion and the derivatives need it.
      for (const key of ['curvature', 'torsion', 'curvatureDerivative', 'torsionDerivative', 'tangentScale',
        'leaveTangentScale']) {
        if (frame[key] !== undefined) await typeInto(`frame-${i}-input-${key}`, String(frame[key]));
      }
      for (const mark of ['cusp', 'inflection', 'stop']) {
        const box = sel(`frame-${i}-input-${mark}`);
        if (Boolean(frame[mark]) !== await page.$eval(box, (c) => c.checked)) await page.click(box);
      }
    }
    assert.ok(await page.$eval(sel('frame-2-input-cusp'), (c) => c.checked), 'frame 2 is not a cusp');
    for (const [key, value] of Object.entries(asked.motion)) await typeInto(`motion-${key}`, String(value));
    assert.equal(await settled(n), 'ready');
    assert.equal(await page.$eval(sel('view3d'), (e) => e.dataset.frames), '4');
    assert.match(await page.$eval(sel('frame-2-row'), (e) => e.cells[0].textContent), /cusp/);

    // The thesis's frames 2 and 3 (1-based): what the page reads, what the API answers for
    // the file, and what the file asks.
    const answer = await planOf(base, asked);
    for (const i of [1, 2]) {
      for (const key of ['curvature', 'torsion']) {
        for (const side of ['approach', 'leave']) {
          assertClose(await dataValue(`frame-${i}-${key}-${side}`), answer.frames[i][side]?.[key],
            `frame ${i} ${key} (${side})`);
        }
        const shown = await dataValue(`frame-${i}-${key}`);
        assertClose(shown, answer.frames[i].leave[key], `frame ${i} ${key}`);
        assert.ok(Math.abs(shown - frames[i][key]) <= 1e-6 * Math.abs(frames[i][key]),
          `frame ${i} ${key} reads ${shown}, the file asks ${frames[i][key]}`);
      }
    }
    await streamed();
    // The view was fitted to the empty start's curve: framed again as the operator would.
    await page.click('[data-action=fit]');
    await screenshot('typed_path_c', { figure: false });

    // The request as saved is the file, field for field.
    await page.click(sel('save'));
    const saved = path.join(downloads, 'request.json');
    await until(`${saved} from the page's save`, () => fs.existsSync(saved));
    assert.deepEqual(canonical(JSON.parse(fs.readFileSync(saved, 'utf8'))), canonical(asked));
    assert.deepEqual(problems, []);
  });

  it("reads frame 0's unconstrained curvature as the API does under every reading of unspecified constraints", async () => {
    assert.equal(asked.path.frames[0].curvature, undefined, 'frame 0 of the file is not unconstrained');
    const options = await page.$$eval(`${sel('path-unspecified')} option`, (o) => o.map((e) => e.value));
    assert.ok(options.length >= 3, `the select offers ${options}`);
    // Each selection a change: the current value last.
    const current = await page.$eval(sel('path-unspecified'), (s) => s.value);
    const readings = new Map();
    for (const value of [...options.filter((v) => v !== current), current]) {
      const n = await plans();
      await page.select(sel('path-unspecified'), value);
      const label = value || '(default)';
      assert.equal(await settled(n), 'ready', `unspecified ${label}`);
      const request = JSON.parse(JSON.stringify(asked));
      if (value) request.path.unspecified = value;
      const expected = (await planOf(base, request)).frames[0].leave?.curvature;
      const shown = await page.$eval(sel('frame-0-curvature'), (e) => e.dataset.value);
      if (expected === undefined) assert.equal(shown, '', `frame 0 curvature under ${label}`);
      else assertClose(Number(shown), expected, `frame 0 curvature under ${label}`);
      readings.set(label, shown);
    }
    assert.ok(new Set(readings.values()).size >= 2,
      `frame 0's curvature reads the same under every reading: ${JSON.stringify([...readings])}`);
    console.log(`[ measured ] frame 0 curvature of typed path C by reading: ${JSON.stringify(Object.fromEntries(readings))}`);
    await screenshot('typed_path_c_readout', { element: sel('readout'), figure: false });
  });

  it("names the joint limit that binds on the PA-10's time-optimal path C, and its replay moves the arm", async () => {
    await page.click('[data-action=start]');
    await page.waitForSelector(`${sel('start-page')}[open]`);
    const n = await plans();
    await page.click(sel('start-pa10'));
    assert.equal(await settled(n), 'ready');
    const jointLimit = /\bjoint \d+\b.*\b(velocity|acceleration)\b/;
    const stretches = await page.$$eval(`${sel('plot-binding')} [data-testid^="binding-stretch-"]`,
      (l) => l.map((e) => e.textContent));
    assert.ok(stretches.some((t) => jointLimit.test(t)), `no binding stretch names a joint limit: ${stretches}`);
    const rows = await page.$$eval(`${sel('plot-binding')} svg text.row-label`, (l) => l.map((e) => e.textContent));
    assert.ok(rows.some((t) => jointLimit.test(t)), `no row of the timeline names a joint limit: ${rows}`);

    // The slider dragged as an operator would: a click at a quarter and at three quarters.
    // (After the samples: the joint plots above the timeline are drawn from them.)
    await streamed();
    await screenshot('typed_pa10_binding', { element: sel('plot-binding'), figure: false });
    const slider = await page.$(sel('replay-slider'));
    const toolAt = async (fraction) => {
      const box = await slider.boundingBox();
      await slider.click({ offset: { x: box.width * fraction, y: box.height / 2 } });
      return page.$eval(sel('replay-tool'), (e) => ({ text: e.textContent, t: Number(e.dataset.t) }));
    };
    const early = await toolAt(0.25);
    const late = await toolAt(0.75);
    assert.ok(late.t > early.t, `the slider went from t = ${early.t} to t = ${late.t} s`);
    assert.match(early.text, /^tool \(/);
    assert.notEqual(late.text, early.text, `the tool stays at ${early.text}`);
    await screenshot('typed_pa10_replay', { figure: false });
    assert.deepEqual(problems, []);
  });
});

// The family view's local mode (thesis Ch. 4, Figs. 4.10-4.27) on path C: for a key frame,
// one of κ, τ, κ', τ' swept and, for each value, the local curve of the frame's natural
// equations integrated by the server forward and backward from the frame (POST /v1/analyze
// of a path of one profile piece per branch). Checked on what the page drew (data-local):
// the counts, the circles a constant curvature gives, the directions the branches leave
// in, at an ordinary frame, a cusp and an inflection, and a value the server refuses.
describe('the local family of a key frame', () => {
  const asked = JSON.parse(fs.readFileSync(path.join(repo, 'client', 'grpcurl', 'plan_demo_path_c.json'), 'utf8'));
  let page;
  let base;
  const problems = [];
  const { waitFor, plans, settled, typeInto, screenshot } = pageHelpers(() => page, problems);

  // A sweep value the server refuses answers 400 and is listed as refused: the page working.
  usePage(problems, refusedPlan, (opened) => ({ page, base } = opened));

  const v = (p) => [p?.x ?? 0, p?.y ?? 0, p?.z ?? 0];
  const sub = (a, b) => a.map((x, i) => x - b[i]);
  const dotp = (a, b) => a.reduce((sum, x, i) => sum + x * b[i], 0);
  const unitv = (a) => a.map((x) => x / Math.hypot(...a));
  // The key frame i of path C's file: p, unit T and N.
  const fileFrame = (i) => {
    const f = asked.path.frames[i];
    return { p: v(f.position), T: unitv(v(f.tangent)), N: unitv(v(f.normal)) };
  };
  // Runs the local family at `frame` over curvature [from, to] in `count` values and
  // returns what the page drew (data-local), once the status says so.
  async function drawLocal(frame, from, to, count, expectDrawn = count) {
    await page.select(sel('family-frame'), String(frame));
    await page.select(sel('family-constraint'), 'curvature');
    await typeInto('family-from', String(from));
    await typeInto('family-to', String(to));
    await typeInto('family-count-input', String(count));
    const runs = await page.$eval(sel('family'), (e) => Number(e.dataset.runs || 0));
    await page.click(sel('family-run'));
    await waitFor(`local family at frame ${frame}`, (previous) =>
      Number(document.querySelector('[data-testid="family"]').dataset.runs || 0) > previous, runs);
    assert.match(await page.$eval(sel('family-status'), (e) => e.textContent), /local curves drawn/);
    assert.equal(await page.$eval(sel('family'), (e) => e.dataset.curves), String(expectDrawn));
    return JSON.parse(await page.$eval(sel('family'), (e) => e.dataset.local));
  }
  // Every point of `points` ([x, y, z, s]) within 1e-6 m of the circle of radius r about c,
  // and the last one 0.1 m of arc from the frame.
  function assertOnCircle(points, c, r, what) {
    assert.equal(points.length, 101, `${what}: ${points.length} points`);
    let worst = 0;
    for (const q of points) worst = Math.max(worst, Math.abs(Math.hypot(...sub(q.slice(0, 3), c)) - r));
    assert.ok(worst <= 1e-6, `${what}: ${worst} m off the circle of radius ${r} m`);
    assert.ok(Math.abs(points[100][3] - 0.1) <= 1e-9, `${what}: ends at s = ${points[100][3]} m, not 0.1 m`);
  }
  // The direction a branch leaves p in: its second point minus p.
  const leaving = (points, p) => sub(points[1].slice(0, 3), p);

  it('draws 6 members x 2 branches at frame 1, on the circles of radius 1/κ tangent to T at p', async () => {
    await page.goto(`${base}#demo`, { waitUntil: 'load' });
    assert.equal(await settled(0), 'ready');
    assert.equal(await page.$eval(sel('family-local'), (e) => e.hidden), true, 'the local inputs show in the path mode');
    await page.select(sel('family-mode'), 'local');
    assert.equal(await page.$eval(sel('family-local'), (e) => e.hidden), false);
    // The local mode sweeps κ, τ, κ', τ' only.
    assert.deepEqual(await page.$$eval(`${sel('family-constraint')} option:not([disabled])`, (o) => o.map((e) => e.value)),
      ['curvature', 'torsion', 'curvatureDerivative', 'torsionDerivative']);
    assert.equal(await page.$eval(sel('family-half-length'), (e) => e.value), '0.1');
    await typeInto('family-local-torsion', '0');

    const drawn = await drawLocal(1, 5, 30, 6);
    assert.equal(await page.$eval(sel('family'), (e) => e.dataset.branches), '12');
    assert.equal(await page.$eval(sel('view3d'), (e) => e.dataset.familyCurves), '12');
    assert.equal(await page.$eval(sel('view3d'), (e) => e.dataset.familyFrame), 'T,N,B');
    assert.equal(await page.$$eval(`${sel('family-legend')} li:not(.violation)`, (l) => l.length), 6);
    assert.equal(await page.$$eval(`${sel('family-legend')} li.violation`, (l) => l.length), 0);
    assert.equal(drawn.members.length, 6);

    const { p, T, N } = fileFrame(1);
    drawn.members.forEach((m, k) => {
      const kappa = 5 + 5 * k;
      assert.ok(Math.abs(m.value - kappa) <= 1e-12, `member ${k} is κ = ${m.value}`);
      assert.deepEqual([m.values.torsion, m.values.curvatureDerivative, m.values.torsionDerivative], [0, 0, 0]);
      // The centre p + N/κ of the osculating circle, from path C's file, not from the page.
      const c = p.map((x, i) => x + N[i] / kappa);
      assertOnCircle(m.forward.points, c, 1 / kappa, `κ = ${kappa} forward`);
      assertOnCircle(m.backward.points, c, 1 / kappa, `κ = ${kappa} backward`);
      assert.ok(Math.hypot(...sub(m.forward.points[0].slice(0, 3), p)) <= 1e-12, 'the forward branch starts off p');
      assert.ok(dotp(leaving(m.forward.points, p), T) > 0, `κ = ${kappa}: the forward branch does not leave along T`);
      assert.ok(dotp(leaving(m.backward.points, p), T) < 0, `κ = ${kappa}: the backward branch does not leave along -T`);
    });
    await screenshot('family_local', { figure: false });
    assert.deepEqual(problems, []);
  });

  it("leaves towards -T on both branches at path C's cusp (frame 2)", async () => {
    assert.equal(asked.path.frames[2].cusp, true);
    // The torsion held is the frame's own again (-100 1/m).
    await typeInto('family-local-torsion', '');
    const drawn = await drawLocal(2, 5, 30, 6);
    assert.equal(drawn.cusp, true);
    assert.equal(await page.$eval(sel('family'), (e) => e.dataset.branches), '12');
    const { p, T } = fileFrame(2);
    for (const m of drawn.members) {
      assert.equal(m.values.torsion, asked.path.frames[2].torsion);
      assert.ok(dotp(leaving(m.forward.points, p), T) < 0, `κ = ${m.value}: the forward branch leaves along T at the cusp`);
      assert.ok(dotp(leaving(m.backward.points, p), T) < 0, `κ = ${m.value}: the backward branch leaves along T at the cusp`);
    }
    assert.match(await page.$eval(sel('family-note'), (e) => e.textContent), /cusp/);
  });

  it('bends the forward branch towards -N at an inflection', async () => {
    let n = await plans();
    await page.click(sel('frame-1-input-inflection'));
    await settled(n);
    await typeInto('family-local-torsion', '0');
    const drawn = await drawLocal(1, 5, 30, 6);
    assert.equal(drawn.inflection, true);
    const { p, N } = fileFrame(1);
    for (const m of drawn.members) {
      const r = 1 / m.value;
      assertOnCircle(m.forward.points, p.map((x, i) => x - N[i] * r), r, `κ = ${m.value} forward, inflection`);
      assertOnCircle(m.backward.points, p.map((x, i) => x + N[i] * r), r, `κ = ${m.value} backward, inflection`);
    }
    n = await plans();
    await page.click(sel('frame-1-input-inflection'));
    await settled(n);
  });

  it('lists a value the server refuses with its reason', async () => {
    // A curvature of 1e6 1/m turns the frame 1e5 rad over 0.1 m: more than the server follows.
    await drawLocal(1, 5, 1e6, 2, 1);
    assert.equal(await page.$eval(sel('family'), (e) => e.dataset.branches), '2');
    const refused = await page.$$eval(`${sel('family-legend')} li.violation`, (l) => l.map((e) => e.textContent));
    assert.equal(refused.length, 1, `refused: ${refused}`);
    assert.match(refused[0], /^κ = 1\.000e\+6 1\/m: refused \(.*turns/);
    assert.deepEqual(problems, []);
  });
});

// A server that checks tokens (GEOTRAJ_AUTH_TOKEN): without the token the page says the
// calls are unauthenticated; with it typed in the token field, every call carries it.
describe('the operator page with a server that checks tokens', () => {
  const TOKEN = 'web-test-token-1234';
  let server;
  let browser;
  let page;
  let base;
  const problems = [];

  before(async () => {
    assert.ok(fs.existsSync(CHROMIUM), `chromium not found at ${CHROMIUM}: apt-get install chromium`);
    // The 401s before the token is given are what this test is about.
    ({ server, browser, page, base } = await openPage(problems, { GEOTRAJ_AUTH_TOKEN: TOKEN }, (m) =>
      /Failed to load resource: .* status of 401/.test(m.text())));
  });

  after(async () => {
    if (browser) await browser.close();
    await stopServer(server);
  });

  it('says the calls need a token, then plans with the token given', async () => {
    await page.goto(`${base}#demo`, { waitUntil: 'load' });
    await page.waitForFunction(() => document.body.dataset.planState === 'error');
    assert.match(await page.$eval(sel('general-errors'), (e) => e.textContent), /UNAUTHENTICATED/);
    const n = await page.$eval('body', (b) => Number(b.dataset.plans || 0));
    await page.type(sel('token'), TOKEN);
    await page.$eval(sel('token'), (e) => e.dispatchEvent(new Event('change')));
    await page.waitForFunction((k) => Number(document.body.dataset.plans || 0) > k &&
      document.body.dataset.planState === 'ready', {}, n);
    assert.equal(await page.evaluate(() => sessionStorage.getItem('geotraj.token')), TOKEN);
    assert.equal(await page.$eval(sel('general-errors'), (e) => e.textContent), '');
    assert.deepEqual(problems, []);
  });
});

// A path of pieces typed in by an operator: from the empty start, the editor switched to
// pieces, the start frame and a weld seam (line 0.1 m, arc of radius 0.04 m over a quarter
// turn, line 0.1 m) with a transition tolerance of 0.1 mm; what the page shows against
// what POST /v1/plan answers for that request; then a refused radius at its input; then
// the start page's helix and the seam's file in the pieces editor.
describe('a path of pieces built in the editor', () => {
  const seam = {
    start: { position: { x: 0.5, y: 0, z: 0.3 }, tangent: { x: 1 }, normal: { y: 1 } },
    pieces: [
      { lengthM: 0.1, line: {} },
      { lengthM: 0.0628318530717959, arc: { radius: 0.04 } },
      { lengthM: 0.1, line: {} },
    ],
    transitionTolerance: 0.0001,
  };
  let page;
  let base;
  const problems = [];
  const { waitFor, plans, settled, typeInto, dataValue, screenshot, canvasPixels, shownErrors, startEmpty } =
    pageHelpers(() => page, problems);

  // Half-typed values (a start position on its way, a piece before its kind's fields) are
  // refused with 400 and shown beside their fields: the page working.
  usePage(problems, refusedPlan, (opened) => ({ page, base } = opened));

  const viewData = () => page.$eval(sel('view3d'), (e) => ({ ...e.dataset }));
  const pieceKinds = () => page.$$eval(`${sel('editor')} fieldset.piece`, (l) => l.map((f) => f.dataset.kind));
  const legendHidden = () => page.$eval(sel('legend-segments'), (e) => e.hidden);

  it('plans the weld seam typed as pieces: 5 segments, 3 drawn as exact pieces and 2 as transitions', async () => {
    await startEmpty(base);
    let n = await plans();
    // A path of key frames: one line as before, no legend of segment kinds.
    assert.equal((await viewData()).segmentKinds, undefined);
    assert.equal(await legendHidden(), true);

    n = await plans();
    await page.select(sel('path-form'), 'pieces');
    assert.equal(await page.$eval(sel('editor'), (e) => e.dataset.pathForm), 'pieces');
    assert.equal(await page.$(sel('frame-0')), null, 'the key frames are still shown');
    // The empty start's two frames, as a start and a piece `to` the second.
    assert.deepEqual(await pieceKinds(), ['to']);
    await settled(n);

    n = await plans();
    for (const [vector, value] of Object.entries(seam.start)) {
      for (const axis of ['x', 'y', 'z']) await typeInto(`start-input-${vector}-${axis}`, String(value[axis] ?? 0));
    }
    await page.select(sel('piece-0-kind'), 'line');
    await typeInto('piece-0-input-lengthM', '0.1');
    await page.click(sel('piece-add'));
    await page.click(sel('piece-add'));
    assert.deepEqual(await pieceKinds(), ['line', 'line', 'line']);
    await page.select(sel('piece-1-kind'), 'arc');
    assert.deepEqual(await pieceKinds(), ['line', 'arc', 'line']);
    await typeInto('piece-1-input-radius', '0.04');
    await typeInto('piece-1-input-lengthM', '0.0628318530717959');
    await typeInto('path-transitionTolerance', '0.0001');
    assert.equal(await settled(n), 'ready');

    // What the operator sees: 5 segments, drawn as piece, transition, piece, transition,
    // piece, the legend saying so, no error anywhere.
    assert.equal(await dataValue('plan-segments'), 5);
    const drawn = await viewData();
    assert.equal(drawn.segmentKinds, 'piece,transition,piece,transition,piece');
    assert.equal(drawn.drawnPieces, '3');
    assert.equal(drawn.drawnTransitions, '2');
    assert.equal(drawn.drawnBlends, '0');
    assert.equal(await legendHidden(), false);
    assert.match(await page.$eval(sel('legend-segment-piece'), (e) => e.textContent), /exact piece ×\s*3/);
    assert.match(await page.$eval(sel('legend-segment-transition'), (e) => e.textContent), /transition ×\s*2/);
    assert.equal(await page.$eval(sel('general-errors'), (e) => e.textContent), '');
    assert.deepEqual(await shownErrors(), []);
    assert.equal(await page.$eval(sel('status'), (e) => e.dataset.state), 'ready');

    // The request the editor built is the seam: the page's arc length is the API's for it.
    const planned = await planOf(base, { path: seam });
    assert.deepEqual(planned.segments.map((s) => s.kind), ['SEGMENT_KIND_PIECE', 'SEGMENT_KIND_TRANSITION',
      'SEGMENT_KIND_PIECE', 'SEGMENT_KIND_TRANSITION', 'SEGMENT_KIND_PIECE']);
    const length = await dataValue('plan-arc-length');
    assert.ok(Math.abs(length - planned.arcLength) <= 1e-9, `the page plans ${length} m, the API ${planned.arcLength} m`);

    // The transitions are on the canvas, in their colour, once the view frames the seam.
    await page.click('[data-action=fit]');
    await new Promise((r) => setTimeout(r, 300));
    const { pink } = await canvasPixels();
    assert.ok(pink > 30, `${pink} pixels of the transitions' pink on the canvas`);
    await screenshot('pieces', { figure: false });
    assert.deepEqual(problems, []);
  });

  it("shows the server's message for a negative radius at that piece's radius", async () => {
    let n = await plans();
    await typeInto('piece-1-input-radius', '-1');
    assert.equal(await settled(n), 'error');
    const slot = `${sel('piece-1')} [data-error-for="path.pieces[1].radius"]`;
    const message = await page.$eval(slot, (e) => e.textContent);
    assert.match(message, /radius/);
    assert.match(message, /-1\b/);
    assert.ok(await page.$eval(sel('piece-1-input-radius'), (e) => e.classList.contains('invalid')),
      'the radius input is not marked');
    // Placed at the input, not listed (above the editor) with the messages that found no place.
    assert.deepEqual(await page.$$eval(`${sel('general-errors')} li`, (l) => l.map((e) => e.textContent)), []);
    assert.deepEqual((await shownErrors()).map((e) => e.split(':')[0]), ['path.pieces[1].radius']);
    await screenshot('pieces_field_error', { element: sel('piece-1'), figure: false });

    n = await plans();
    await typeInto('piece-1-input-radius', '0.04');
    assert.equal(await settled(n), 'ready');
    assert.equal(await page.$eval(slot, (e) => e.textContent), '');
    assert.equal((await viewData()).drawnTransitions, '2');
  });

  it('gives the key frames back when switched back, drawn as before', async () => {
    const n = await plans();
    await page.select(sel('path-form'), 'frames');
    assert.equal(await settled(n), 'ready');
    assert.equal(await page.$$eval(`${sel('editor')} fieldset.frame`, (f) => f.length), 2);
    assert.equal((await viewData()).segmentKinds, undefined);
    assert.equal(await legendHidden(), true);
    // And the pieces again.
    const m = await plans();
    await page.select(sel('path-form'), 'pieces');
    assert.equal(await settled(m), 'ready');
    assert.deepEqual(await pieceKinds(), ['line', 'arc', 'line']);
  });

  it("fills the pieces editor with the start page's helix and the seam's file", async () => {
    await page.click('[data-action=start]');
    await page.waitForSelector(`${sel('start-page')}[open]`);
    let n = await plans();
    await page.click(sel('start-helix'));
    assert.equal(await settled(n), 'ready');
    assert.equal(await page.$eval(sel('path-form'), (s) => s.value), 'pieces');
    assert.deepEqual(await pieceKinds(), ['line', 'helix', 'line']);
    assert.equal(await page.$eval(sel('piece-1-input-radius'), (e) => e.value), '0.05');
    assert.equal(await page.$eval(sel('piece-1-input-pitch'), (e) => e.value), '0.02');
    assert.equal((await viewData()).segmentKinds, 'piece,transition,piece,transition,piece');

    const file = path.join(repo, 'client', 'grpcurl', 'plan_seam_ur5e.json');
    const asked = JSON.parse(fs.readFileSync(file, 'utf8'));
    n = await plans();
    await (await page.$(sel('load-file'))).uploadFile(file);
    assert.equal(await settled(n), 'ready');
    assert.deepEqual(await pieceKinds(), ['line', 'arc', 'line']);
    assert.equal(await page.$eval(sel('start-input-position-x'), (e) => Number(e.value)), asked.path.start.position.x);
    assert.equal(await page.$eval(sel('piece-1-input-radius'), (e) => Number(e.value)), asked.path.pieces[1].arc.radius);
    assert.equal(await page.$eval(sel('path-transitionTolerance'), (e) => Number(e.value)), asked.path.transitionTolerance);
    assert.equal((await viewData()).drawnTransitions, '2');
    assert.deepEqual(problems, []);
  });

  // The family of a path of pieces: the seam's arc radius swept (the arc keeps its quarter
  // turn), each member re-planned by POST /v1/analyze; each member's peak curvature is its
  // arc's 1/r, or up to 10 % more where a transition overshoots it, and its length the
  // two lines' and the arc's less what the transitions cut short (under 1 mm).
  it("sweeps a piece's parameter in the family view: the seam's arc radius", async () => {
    assert.equal(await page.$eval(sel('family-target'), (e) => e.textContent), 'piece');
    assert.equal(await page.$eval(`${sel('family-mode')} option[value=local]`, (e) => e.disabled), true,
      'the local mode needs key frames');
    await page.select(sel('family-frame'), '1');
    assert.deepEqual(await page.$$eval(`${sel('family-constraint')} option`, (o) => o.map((e) => e.value)),
      ['arc.radius', 'lengthM', 'transitionTolerance']);
    await page.select(sel('family-constraint'), 'arc.radius');
    await typeInto('family-from', '0.02');
    await typeInto('family-to', '0.06');
    await typeInto('family-count-input', '3');
    const runs = await page.$eval(sel('family'), (e) => Number(e.dataset.runs || 0));
    await page.click(sel('family-run'));
    await waitFor('the pieces family', (previous) =>
      Number(document.querySelector('[data-testid="family"]').dataset.runs || 0) > previous, runs);
    assert.match(await page.$eval(sel('family-status'), (e) => e.textContent), /3 of 3 curves drawn \(piece 1, radius/);
    const drawn = JSON.parse(await page.$eval(sel('family'), (e) => e.dataset.drawn));
    assert.deepEqual(drawn.map((d) => Number(d.value.toPrecision(12))), [0.02, 0.04, 0.06]);
    for (const d of drawn) {
      assert.ok(d.peakCurvature >= (1 - 1e-9) / d.value && d.peakCurvature <= 1.1 / d.value,
        `radius ${d.value}: peak curvature ${d.peakCurvature}, not within [1, 1.1] x ${1 / d.value}`);
      const programmed = 0.2 + (Math.PI / 2) * d.value;
      assert.ok(d.arcLength <= programmed && d.arcLength > programmed - 1e-3,
        `radius ${d.value}: length ${d.arcLength} m against ${programmed} m programmed`);
    }
    assert.equal(await page.$eval(sel('view3d'), (e) => e.dataset.familyCurves), '3');
    assert.deepEqual(problems, []);
  });
});

// A joint path (PlanRequest.jointPath: a sampling planner's waypoints, no Cartesian path):
// the start page's Panda pick and place (client/grpcurl/plan_joint_path_panda.json) in the
// waypoint editor, planned as POST /v1/plan plans the file, the tool's path drawn from the
// samples with the tool at each waypoint marked, the arm replayed, every interior waypoint
// passed within the blend tolerance; a waypoint value out of its joint's limits and a
// negative tolerance show the server's messages at their inputs; removing a waypoint plans
// again, as the API plans the file without it.
describe('a joint path of waypoints', () => {
  const file = path.join(repo, 'client', 'grpcurl', 'plan_joint_path_panda.json');
  const asked = JSON.parse(fs.readFileSync(file, 'utf8'));
  let page;
  let base;
  const problems = [];
  const { plans, settled, streamed, typeInto, dataValue, screenshot, canvasPixels, shownErrors, seek } =
    pageHelpers(() => page, problems);

  // The values refused on purpose answer 400, shown at their inputs: the page working.
  usePage(problems, refusedPlan, (opened) => ({ page, base } = opened));

  const viewData = () => page.$eval(sel('view3d'), (e) => ({ ...e.dataset }));
  const editorRows = () => page.$$eval(`${sel('waypoints')} tbody tr[data-testid^="waypoint-"]`, (rows) =>
    rows.map((r) => [...r.querySelectorAll('input[type=text]')].map((i) => Number(i.value))));
  // The readout of where the motion passes each waypoint: [{t, joint, tool}] (joint space
  // [rad] and the tool [m]).
  const passes = () => page.$$eval(`${sel('waypoint-readout')} tbody tr`, (rows) => rows.map((r, i) => {
    const value = (key) => Number(r.querySelector(`[data-testid="pass-${i}-${key}"]`).dataset.value);
    return { t: value('t'), joint: value('joint-distance'), tool: value('tool-distance') };
  }));
  // Where the motion passes waypoint i, as the file asks: exactly at the ends, within the
  // blend tolerance elsewhere (the nearest of the samples at 1 kHz: 1e-3 rad to spare).
  function assertPassed(shown, waypoints, tolerance) {
    assert.equal(shown.length, waypoints.length);
    shown.forEach((p, i) => {
      const allowed = i === 0 || i === waypoints.length - 1 ? 0 : tolerance;
      assert.ok(p.joint <= allowed + 1e-3, `waypoint ${i} passed at ${p.joint} rad, asked within ${allowed}`);
      if (i > 0) assert.ok(p.t > shown[i - 1].t, `waypoint ${i} passed at t = ${p.t} s, before waypoint ${i - 1}`);
      // The tool where the waypoint puts it (forward kinematics), near where the motion passes.
      if (allowed === 0) assert.ok(p.tool <= 1e-9, `the tool ${p.tool} m off waypoint ${i}`);
      else assert.ok(p.tool > 0 && p.tool < 0.05, `the tool ${p.tool} m off waypoint ${i}`);
    });
  }

  it('plans the Panda joint path of the start page: its duration, the tool path and waypoints drawn, the arm replayed', async () => {
    await page.goto(base, { waitUntil: 'load' });
    await page.waitForSelector(`${sel('start-page')}[open]`);
    assert.equal(await page.$eval(sel('start-joint-path'), (b) => b.dataset.start), 'jointPathPanda');
    await page.goto(`${base}#jointPathPanda`, { waitUntil: 'load' });
    assert.equal(await settled(0), 'ready');
    assert.equal(await page.$eval('body', (b) => b.dataset.requestKind), 'jointPath');
    assert.equal(await page.$eval(sel('editor'), (e) => e.dataset.kind), 'jointPath');

    // The editor: a row per waypoint of the file, an input per joint, the tolerance.
    const waypoints = asked.jointPath.waypoints;
    assert.deepEqual(await editorRows(), waypoints.map((w) => w.positions));
    assert.equal(await page.$eval(sel('jointPath-blendTolerance'), (e) => Number(e.value)), asked.jointPath.blendTolerance);
    assert.equal(await page.$eval(sel('waypoint-0-remove'), (b) => b.disabled), false);

    // The plan: the duration the API answers for the file, within every limit.
    const planned = await planOf(base, asked);
    const duration = await dataValue('plan-duration');
    assert.ok(duration > 0, `the duration shown is ${duration}`);
    assert.equal(duration, planned.motion.durationS);
    assert.equal(await dataValue('plan-waypoints'), waypoints.length);
    assert.match(await page.$eval(sel('plan-robot-feasible'), (e) => e.textContent), /panda: within every limit/);
    assert.equal(await page.$eval(sel('general-errors'), (e) => e.textContent), '');
    assert.ok(await page.$eval(sel('plot-binding'), (e) => Number(e.dataset.stretches || 0)) > 0, 'no limit report');

    // The samples: the tool's path drawn from them, coloured by the tool's speed, the
    // waypoints marked; the arm replayed; the joints plotted.
    await streamed();
    const drawn = await viewData();
    assert.equal(drawn.curveKind, 'tool');
    assert.ok(Number(drawn.curvePoints) > 100, `the tool's path has ${drawn.curvePoints} points`);
    assert.equal(drawn.waypoints, String(waypoints.length));
    assert.equal(drawn.frames, '0');
    assert.match(await page.$eval(sel('colorbar'), (e) => e.textContent), /tool speed \[m\/s\]/);
    assert.equal(await page.$eval(sel('plot-joint-positions'), (e) => Number(e.dataset.series)), 7);
    assert.equal(await page.$eval(sel('plot-joint-velocities'), (e) => Number(e.dataset.series)), 7);
    // The Panda's torques (its mass properties), with its torque limits as bands.
    assert.equal(await page.$eval(sel('plot-joint-torques'), (e) => Number(e.dataset.series)), 7);
    assertPassed(await passes(), waypoints, asked.jointPath.blendTolerance);
    const a = await seek(duration * 0.25);
    const b = await seek(duration * 0.75);
    const d = Math.hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]);
    assert.ok(d > 1e-3, `the arm's tool is at ${a} and ${b}`);
    const links = Number(drawn.robotLinks || 0);
    assert.ok(links >= 7, `the arm is drawn with ${links} links`);
    await new Promise((r) => setTimeout(r, 300));
    const coloured = (await canvasPixels()).drawn;
    assert.ok(coloured > 0.01, `only ${(coloured * 100).toFixed(3)} % of the canvas is drawn`);
    await screenshot('joint_path', { fullPage: true, figure: false });
    assert.deepEqual(problems, []);
  });

  it("shows the server's message at a waypoint value out of its joint's limits, and at the tolerance", async () => {
    const input = 'waypoint-3-joint-1';
    const field = 'jointPath.waypoints[3].positions[1]';
    let n = await plans();
    await typeInto(input, '2.5');
    assert.equal(await settled(n), 'error');
    const slot = `${sel('waypoints')} [data-error-for="${field}"]`;
    assert.match(await page.$eval(slot, (e) => e.textContent), /2\.5 is outside joint 1's position limits/);
    assert.ok(await page.$eval(sel(input), (e) => e.classList.contains('invalid')), 'the input is not marked');
    // At the input only: none listed above the editor with the messages that found no place.
    assert.deepEqual((await shownErrors()).map((e) => e.split(':')[0]), [field]);
    assert.deepEqual(await page.$$eval(`${sel('general-errors')} li`, (l) => l.map((e) => e.textContent)), []);
    await screenshot('joint_path_field_error', { element: sel('joint-path'), figure: false });

    n = await plans();
    await typeInto(input, String(asked.jointPath.waypoints[3].positions[1]));
    assert.equal(await settled(n), 'ready');
    assert.equal(await page.$eval(slot, (e) => e.textContent), '');
    assert.equal(await page.$eval(sel(input), (e) => e.classList.contains('invalid')), false);

    n = await plans();
    await typeInto('jointPath-blendTolerance', '-1');
    assert.equal(await settled(n), 'error');
    assert.deepEqual((await shownErrors()).map((e) => e.split(':')[0]), ['jointPath.blendTolerance']);
    n = await plans();
    await typeInto('jointPath-blendTolerance', String(asked.jointPath.blendTolerance));
    assert.equal(await settled(n), 'ready');
    assert.deepEqual(await shownErrors(), []);
    await streamed();
  });

  it('plans again without a waypoint removed, as the API plans the file without it', async () => {
    const before = await dataValue('plan-duration');
    const n = await plans();
    await page.click(sel('waypoint-4-remove'));
    assert.equal(await settled(n), 'ready');
    const waypoints = asked.jointPath.waypoints.filter((_, i) => i !== 4);
    assert.deepEqual(await editorRows(), waypoints.map((w) => w.positions));
    const without = JSON.parse(JSON.stringify(asked));
    without.jointPath.waypoints = waypoints;
    const planned = await planOf(base, without);
    const duration = await dataValue('plan-duration');
    assert.equal(duration, planned.motion.durationS);
    assert.notEqual(duration, before);
    assert.equal(await dataValue('plan-waypoints'), waypoints.length);
    await streamed();
    assert.equal((await viewData()).waypoints, String(waypoints.length));
    assertPassed(await passes(), waypoints, asked.jointPath.blendTolerance);
    assert.deepEqual(problems, []);
  });
});
