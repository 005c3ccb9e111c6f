// Every request file of client/grpcurl/ opened in the operator's page (Debian's chromium,
// headless, driven by puppeteer-core, against a real geotrajd), as a user opens one: the
// page's `load…` file input. One test per file.
//
// A PlanRequest (POST /v1/plan answers it, asked from here): the page sends the file's
// request unchanged; plans it without an error; names its kind (path of key frames or of
// pieces, joint path, joint move, linear move, sequence) and shows the duration the API
// answers (or no duration for a request without a motion), and for a sequence or a path
// after an approach move each step's kind and duration, as the API answers them; draws the
// path or the tool's path and, with a robot, replays the arm; after `fit view` the motion
// (and the arm) fills a good share of the canvas; every box shows the file's value whole
// (0.106 as 0.106, not cut by the box's width); an edit undone (the undo button, then
// Ctrl+Z after a redo) gives the file's request back.
// A request the API refuses (bad_request.json): each of its field violations shown.
// A file that holds no PlanRequest: an ExecuteRequest opens its plan, saying so; the others
// (forward and inverse kinematics, jog) are refused saying what they are, and the request
// being edited stays.
// Last, a key frame dragged in the 3-D view moves, and undo puts it back.
//
//   cd tests/web && PUPPETEER_SKIP_DOWNLOAD=1 npm ci && \
//     GEOTRAJD=../../build/server/geotrajd GEOTRAJ_WEB_ROOT=../../build/share/geotraj/web \
//     node --test requests.test.js
//
// Environment: as browser.test.js (GEOTRAJD, GEOTRAJ_WEB_ROOT, GEOTRAJ_CHROMIUM,
// GEOTRAJ_WEB_ARTIFACTS).
'use strict';

const { describe, it, before, after } = require('node:test');
const assert = require('node:assert/strict');
const fs = require('node:fs');
const path = require('node:path');

const {
  repo, GEOTRAJD, WEB_ROOT, CHROMIUM, ARTIFACTS, WAIT_MS, freePort, startServer, stopServer, sel, launchBrowser,
} = require('./support');

const REQUESTS = path.join(repo, 'client', 'grpcurl');

// The value at a field path of the page's data-field ("path.frames[1].position.x").
function fieldOf(object, field) {
  let value = object;
  for (const part of field.split('.')) {
    const m = /^([^[\]]+)((?:\[\d+\])*)$/.exec(part);
    if (!m) return undefined;
    value = value?.[m[1]];
    for (const index of m[2].matchAll(/\[(\d+)\]/g)) value = value?.[Number(index[1])];
  }
  return value;
}

// What the file asks, by its own fields: the kind the page must name.
function expectedKind(request) {
  if (request.jointPath) return 'jointPath';
  if (request.sequence?.length) return 'sequence';
  if (request.jointMove) return 'jointMove';
  if (request.linearMove) return 'linearMove';
  return request.path?.frames?.length ? 'frames' : 'pieces';
}

// The JSON API of the server at base, asked from here: [HTTP status, answer].
async function post(base, route, body) {
  const answer = await fetch(new URL(route, base), { method: 'POST', headers: { 'Content-Type': 'application/json' }, body });
  return [answer.status, JSON.parse(await answer.text())];
}

const files = fs.readdirSync(REQUESTS).filter((f) => f.endsWith('.json')).sort();

describe('every request file of client/grpcurl opened in the page', () => {
  let server;
  let browser;
  let page;
  let base;
  const problems = [];
  // The bodies of POST /v1/plan the page sent, in order.
  const sent = [];

  before(async () => {
    assert.ok(fs.existsSync(GEOTRAJD), `geotrajd not found at ${GEOTRAJD}: set GEOTRAJD`);
    assert.ok(fs.existsSync(path.join(WEB_ROOT, 'index.html')), `the built page is not at ${WEB_ROOT}: set GEOTRAJ_WEB_ROOT`);
    assert.ok(fs.existsSync(CHROMIUM), `chromium not found at ${CHROMIUM}: apt-get install chromium, or set GEOTRAJ_CHROMIUM`);
    assert.ok(files.length >= 20, `only ${files.length} request files in ${REQUESTS}`);
    fs.mkdirSync(ARTIFACTS, { recursive: true });
    const webPort = await freePort();
    server = await startServer(webPort);
    base = `http://127.0.0.1:${webPort}/`;
    browser = await launchBrowser();
    page = await browser.newPage();
    await page.setViewport({ width: 1600, height: 1200 });
    page.setDefaultTimeout(WAIT_MS);
    page.on('console', (m) => {
      // A refused request (bad_request.json, an edit the server refuses) is logged by the
      // browser as a failed resource: the page shows it, that is the page working.
      if (m.type() !== 'error' || /Failed to load resource: .* status of 400/.test(m.text())) return;
      problems.push(`console: ${m.text()}`);
    });
    page.on('pageerror', (e) => problems.push(`page error: ${e.message}`));
    page.on('requestfailed', (r) => {
      if (r.failure()?.errorText !== 'net::ERR_ABORTED') problems.push(`request failed: ${r.url()} ${r.failure()?.errorText}`);
    });
    page.on('request', (r) => {
      if (r.method() === 'POST' && /\/v1\/plan$/.test(r.url())) sent.push(JSON.parse(r.postData()));
    });
    await page.goto(base, { waitUntil: 'load' });
    await page.waitForSelector(`${sel('start-page')}[open]`);
    await page.click(sel('start-empty'));
    await page.waitForFunction(() => document.body.dataset.planState === 'ready');
  });

  after(async () => {
    if (browser) await browser.close();
    await stopServer(server);
  });

  async function waitFor(what, fn, arg) {
    try {
      await page.waitForFunction(fn, { timeout: WAIT_MS }, arg);
    } catch (e) {
      const shown = await page.evaluate(() => JSON.stringify({ body: { ...document.body.dataset },
        status: document.querySelector('[data-testid="status"]')?.textContent })).catch(() => '?');
      await page.screenshot({ path: path.join(ARTIFACTS, `requests-timeout-${what}.png`) }).catch(() => {});
      throw new Error(`waiting for ${what}: ${e.message}; the page shows ${shown}; problems: ${problems.join('; ')}`);
    }
  }
  const plans = () => page.$eval('body', (b) => Number(b.dataset.plans || 0));
  async function settled(count) {
    await waitFor('plan', (n) => Number(document.body.dataset.plans || 0) > n &&
      ['ready', 'error'].includes(document.body.dataset.planState), count);
    return page.$eval('body', (b) => b.dataset.planState);
  }
  async function streamed() {
    await waitFor('stream', () => document.body.dataset.streamState === 'ready' &&
      document.querySelector('[data-testid="replay-slider"]').dataset.ready === 'true');
  }
  async function open(file) {
    const n = await plans();
    await page.$eval('body', (b) => { delete b.dataset.openState; });
    await (await page.$(sel('load-file'))).uploadFile(path.join(REQUESTS, file));
    await waitFor('the file opened', () => Boolean(document.body.dataset.openState));
    return n;
  }
  const dataValue = (testid) => page.$eval(sel(testid), (e) => Number(e.dataset.value));
  // The editor's boxes: field, text, and whether the text is wider than the box.
  const boxes = () => page.$$eval(`${sel('editor')} input[type=text][data-field]`, (l) => l.map((e) => ({
    field: e.dataset.field, value: e.value, cut: e.scrollWidth > e.clientWidth + 1, testid: e.dataset.testid || '' })));
  // The bounding box of the coloured pixels of the view's canvas (the curve, the tool's
  // path, the arm; not the white background nor grey), as fractions of its width and height,
  // and whether it touches the canvas's edges.
  const colouredBox = () => page.$eval(`${sel('view3d')} canvas`, (canvas) => {
    const copy = document.createElement('canvas');
    copy.width = canvas.width;
    copy.height = canvas.height;
    const ctx = copy.getContext('2d');
    ctx.drawImage(canvas, 0, 0);
    const { data } = ctx.getImageData(0, 0, copy.width, copy.height);
    let [x0, y0, x1, y1] = [Infinity, Infinity, -Infinity, -Infinity];
    for (let y = 0; y < copy.height; ++y) {
      for (let x = 0; x < copy.width; ++x) {
        const i = 4 * (y * copy.width + x);
        const r = data[i];
        const g = data[i + 1];
        const b = data[i + 2];
        if (Math.max(r, g, b) - Math.min(r, g, b) < 60) continue;
        x0 = Math.min(x0, x); x1 = Math.max(x1, x); y0 = Math.min(y0, y); y1 = Math.max(y1, y);
      }
    }
    return { width: (x1 - x0) / copy.width, height: (y1 - y0) / copy.height,
      edge: x0 <= 0 || y0 <= 0 || x1 >= copy.width - 1 || y1 >= copy.height - 1 };
  });
  // The last request the page sent to POST /v1/plan once it has planned every edit (an
  // edit schedules its plan at once: the page is 'scheduled' or 'planning' until the last
  // one is in).
  async function lastSent() {
    await waitFor('the plans of the edits', () => ['ready', 'error'].includes(document.body.dataset.planState));
    return sent[sent.length - 1];
  }

  for (const file of files) {
    it(file, async () => {
      const text = fs.readFileSync(path.join(REQUESTS, file), 'utf8');
      let asked = null;
      try {
        asked = JSON.parse(text);
      } catch {
        asked = null;  // several messages (a stream's), or no JSON
      }
      const [status, answer] = asked ? await post(base, 'v1/plan', text) : [0, null];
      const notPlanRequest = !asked || (status === 400 && /is not a geotraj\.v1\.PlanRequest/.test(answer.message));

      if (notPlanRequest && !(asked && typeof asked.plan === 'object')) {
        // No PlanRequest in the file: refused, saying what the file is; the request being
        // edited stays, and nothing is sent.
        const kindBefore = await page.$eval('body', (b) => b.dataset.requestKind);
        const n = await plans();
        const sentBefore = sent.length;
        await open(file);
        assert.equal(await page.$eval('body', (b) => b.dataset.openState), 'refused');
        const said = await page.$eval(sel('general-errors'), (e) => e.textContent);
        assert.match(said, new RegExp(`^${file.replace('.', '\\.')} `), said);
        const kinds = { fk_: /ForwardKinematicsRequest/, ik_: /InverseKinematicsRequest/, jog_: /JogRequest/ };
        const expected = Object.entries(kinds).find(([prefix]) => file.startsWith(prefix))?.[1] ?? /not a PlanRequest/;
        assert.match(said, expected);
        assert.match(await page.$eval(sel('status'), (e) => e.textContent), expected);
        await new Promise((r) => setTimeout(r, 200));
        assert.equal(await plans(), n);
        assert.equal(sent.length, sentBefore);
        assert.equal(await page.$eval('body', (b) => b.dataset.requestKind), kindBefore);
        await page.screenshot({ path: path.join(ARTIFACTS, `request-${file.replace(/\.json$/, '')}.png`) });
        assert.deepEqual(problems, []);
        return;
      }

      // An ExecuteRequest: its plan is what the page opens and plans.
      const request = notPlanRequest ? asked.plan : asked;
      const [planStatus, planned] = notPlanRequest ? await post(base, 'v1/plan', JSON.stringify(request)) : [status, answer];
      const n = await open(file);
      assert.equal(await page.$eval('body', (b) => b.dataset.openState), 'opened');
      const state = await settled(n);
      // The request sent is the file's (the ExecuteRequest's plan), field for field.
      assert.deepEqual(sent[sent.length - 1], request);
      const note = await page.$eval(sel('open-note'), (e) => (e.hidden ? '' : e.textContent));
      if (notPlanRequest) assert.match(note, /ExecuteRequest: its plan is opened/);
      else assert.equal(note, '');

      if (planStatus !== 200) {
        // Refused by the server: each field violation shown, at its box or listed.
        assert.equal(state, 'error');
        const violations = (planned.details || []).flatMap((d) => d.fieldViolations || []);
        assert.ok(violations.length > 0, `the API's answer has no field violation: ${JSON.stringify(planned)}`);
        const shown = await page.evaluate(() => [
          ...[...document.querySelectorAll('[data-testid="editor"] [data-error-for]')].filter((e) => e.textContent)
            .map((e) => ({ at: e.dataset.errorFor, text: e.textContent })),
          ...[...document.querySelectorAll('[data-testid="general-errors"] li')].map((e) => ({ at: '', text: e.textContent }))]);
        for (const v of violations) {
          assert.ok(shown.some((s) => s.text.includes(v.description) &&
            (s.at === v.field || v.field.startsWith(`${s.at}.`) || v.field.startsWith(`${s.at}[`) || s.text.startsWith(v.field))),
          `${v.field}: ${v.description} is not shown; shown: ${JSON.stringify(shown)}`);
        }
        if (file === 'bad_request.json') assert.equal(violations.length, 4);
        // At its box, where it has one: the tangents and the torsion of the frames.
        const marked = await page.$$eval(`${sel('editor')} .invalid`, (l) => l.length);
        assert.ok(marked >= 1, 'no box marked');
        await page.screenshot({ path: path.join(ARTIFACTS, `request-${file.replace(/\.json$/, '')}.png`) });
        assert.deepEqual(problems, []);
        return;
      }

      assert.equal(state, 'ready', await page.$eval(sel('status'), (e) => e.textContent));
      assert.equal(await page.$eval(sel('general-errors'), (e) => e.textContent), '');

      // The kind, the duration and the steps, as the API answers them.
      const kind = await page.$eval(sel('plan-kind'), (e) => ({ kind: e.dataset.kind, steps: Number(e.dataset.steps),
        text: e.textContent }));
      assert.equal(kind.kind, expectedKind(request));
      assert.doesNotMatch(kind.text, /undefined/);
      if (planned.motion) {
        assert.equal(await dataValue('plan-duration'), planned.motion.durationS);
      } else {
        assert.equal(await page.$(sel('plan-duration')), null, 'a duration shown for a plan without a motion');
        assert.match(await page.$eval(sel('plan-no-motion'), (e) => e.textContent), /geometry only/);
      }
      const steps = planned.steps || [];
      assert.equal(kind.steps, steps.length);
      if (request.sequence) {
        assert.match(kind.text, new RegExp(`sequence of ${request.sequence.length} steps`));
        assert.ok(steps.length >= 1);
        assert.equal(await page.$$eval(`${sel('step-readout')} tbody tr`, (l) => l.length), steps.length);
      }
      if (request.robot?.approach && request.path) assert.ok(steps.length === 2, `${steps.length} steps for a path after its approach`);
      for (const step of steps) {
        const i = step.index ?? 0;
        assert.equal(await dataValue(`plan-step-${i}`), step.durationS, `step ${i}'s duration`);
        assert.equal(await page.$eval(sel(`plan-step-${i}`), (e) => e.dataset.kind), step.kind);
      }
      if (request.path && !steps.length) {
        assert.equal(await dataValue('plan-arc-length'), planned.arcLength);
        assert.equal(await dataValue('plan-segments'), planned.segments.length);
      } else if (request.path) {
        const pathStep = steps.find((s) => s.kind === 'path');
        assert.equal(await dataValue('plan-arc-length'), pathStep.arcLength);
        assert.ok(await dataValue('plan-arc-length') > 0);
      }

      // The geometry: the path (analysed) or the tool's path (from the samples), the arm.
      if (request.motion) await streamed();
      const view = await page.$eval(sel('view3d'), (e) => ({ ...e.dataset }));
      assert.ok(Number(view.curvePoints) > 10, `the curve has ${view.curvePoints} points`);
      assert.equal(view.curveKind, request.path ? 'path' : 'tool');
      if (request.robot && request.motion) assert.ok(Number(view.robotLinks) >= 6, `the arm has ${view.robotLinks} links`);
      if (steps.length > 1) assert.equal(view.stepMarks, String(steps.length));

      // Fit view: the motion fills the canvas (the curve alone without a robot; with one, the
      // arm's sweep as well).
      // Measured without the grid, the axes and the frames' arrows (unticked, then ticked
      // again).
      await page.click(sel('show-grid'));
      await page.click(sel('show-frames'));
      await page.click('[data-action=fit]');
      await new Promise((r) => setTimeout(r, 300));
      const box = await colouredBox();
      await page.click(sel('show-grid'));
      await page.click(sel('show-frames'));
      const curveBox = JSON.parse(await page.$eval(sel('view3d'), (e) => e.dataset.curveBox));
      assert.ok(curveBox.every((v) => v >= -0.001 && v <= 1.001), `the curve runs off the canvas: ${curveBox}`);
      const share = Math.max(box.width, box.height);
      assert.ok(share >= 0.6, `after fit view the motion spans ${box.width.toFixed(2)} x ${box.height.toFixed(2)} of the canvas`);
      assert.equal(box.edge, false, 'after fit view the motion runs off the canvas');
      if (!request.robot) {
        const curveShare = Math.max(curveBox[2] - curveBox[0], curveBox[3] - curveBox[1]);
        assert.ok(curveShare >= 0.6, `after fit view the curve spans ${curveBox}`);
      }

      // Every box shows its value of the file, whole.
      const shown = await boxes();
      let compared = 0;
      for (const b of shown) {
        const value = fieldOf(request, b.field);
        if (typeof value === 'number') {
          assert.equal(b.value, String(value), `${b.field}`);
          ++compared;
        } else if (Array.isArray(value) && value.every((v) => typeof v === 'number')) {
          assert.equal(b.value, value.join(', '), `${b.field}`);
          ++compared;
        }
        assert.equal(b.cut, false, `${b.field} "${b.value}" is wider than its box`);
      }
      assert.ok(compared >= 3, `only ${compared} boxes hold a value of the file`);

      // Every choice readable whole: the chosen option's text (measured in the select's font)
      // within the select, its arrow aside; the limits' row labels within their chart.
      const cutChoices = await page.$$eval('select', (list) => {
        const ctx = document.createElement('canvas').getContext('2d');
        return list.filter((s) => s.offsetParent !== null && s.selectedIndex >= 0).map((s) => {
          const style = getComputedStyle(s);
          ctx.font = `${style.fontWeight} ${style.fontSize} ${style.fontFamily}`;
          const text = s.options[s.selectedIndex].text;
          return { text, need: ctx.measureText(text).width, have: s.clientWidth - 24 };
        }).filter((c) => c.need > c.have);
      });
      assert.deepEqual(cutChoices, []);
      const cutLabels = await page.$$eval('[data-testid="plot-binding"] svg text', (list) => list
        .map((t) => ({ text: t.textContent, x: t.getBBox().x })).filter((t) => t.x < -0.5));
      assert.deepEqual(cutLabels, []);

      // Undo: an edit, undone, gives the file's request back; redone, the edit again.
      const edited = shown.find((b) => typeof fieldOf(request, b.field) === 'number' && b.testid);
      assert.ok(edited, 'no box to edit');
      const before = edited.value;
      const changed = String(Number(before) + 0.5);
      const input = await page.$(sel(edited.testid));
      await input.click();
      await input.evaluate((e) => e.select());
      await page.keyboard.type(changed);
      assert.equal(await page.$eval(sel(edited.testid), (e) => e.value), changed);
      assert.equal(fieldOf(await lastSent(), edited.field), Number(changed));
      await page.click(sel('undo'));
      assert.deepEqual(await lastSent(), request);
      assert.equal(await page.$eval(sel(edited.testid), (e) => e.value), before);
      await page.click(sel('redo'));
      assert.equal(fieldOf(await lastSent(), edited.field), Number(changed));
      assert.equal(await page.$eval(sel(edited.testid), (e) => e.value), changed);
      await page.keyboard.down('Control');
      await page.keyboard.press('z');
      await page.keyboard.up('Control');
      assert.deepEqual(await lastSent(), request);
      assert.equal(await page.$eval(sel(edited.testid), (e) => e.value), before);
      if (request.motion) await streamed();
      await page.screenshot({ path: path.join(ARTIFACTS, `request-${file.replace(/\.json$/, '')}.png`) });
      assert.deepEqual(problems, []);
    });
  }

  it('moves a key frame dragged in the 3-D view, and undo puts it back', async () => {
    const file = 'plan_demo_path_c.json';
    const request = JSON.parse(fs.readFileSync(path.join(REQUESTS, file), 'utf8'));
    const n = await open(file);
    assert.equal(await settled(n), 'ready');
    await streamed();
    await page.click('[data-action=fit]');
    await new Promise((r) => setTimeout(r, 300));
    const where = JSON.parse(await page.$eval(sel('view3d'), (e) => e.dataset.framesScreen));
    assert.equal(where.length, request.path.frames.length);
    const rect = await page.$eval(sel('view3d'), (e) => {
      const r = e.getBoundingClientRect();
      return { x: r.left, y: r.top, width: r.width, height: r.height };
    });
    const [fx, fy] = where[1];
    const x = rect.x + fx * rect.width;
    const y = rect.y + fy * rect.height;
    await page.mouse.move(x, y);
    await page.mouse.down();
    await page.mouse.move(x + 30, y + 10, { steps: 5 });
    await page.mouse.move(x + 60, y + 20, { steps: 5 });
    await page.mouse.up();
    const moved = await lastSent();
    const p = moved.path.frames[1].position;
    const q = request.path.frames[1].position;
    const d = Math.hypot(p.x - q.x, (p.y ?? 0) - (q.y ?? 0), (p.z ?? 0) - (q.z ?? 0));
    assert.ok(d > 0.01, `frame 1 moved ${d} m`);
    assert.equal(await page.$eval(sel('frame-1-input-position-x'), (e) => Number(e.value)), p.x);
    // Only frame 1's position changed.
    const rest = JSON.parse(JSON.stringify(moved));
    rest.path.frames[1].position = q;
    assert.deepEqual(rest, request);
    await page.click(sel('undo'));
    assert.deepEqual(await lastSent(), request);
    assert.equal(await page.$eval(sel('frame-1-input-position-x'), (e) => e.value), String(q.x));
    assert.deepEqual(problems, []);
  });
});
