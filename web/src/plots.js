// The 2-D plots (uPlot): curvature and torsion along s, their derivatives, the tool speed
// against the speed profile, the joints' positions, velocities and accelerations with their
// limits, and the binding-limit timeline of a time-optimal plan. Every plot has a title,
// axes with units and a legend; key frames are vertical lines on the plots over s, the
// waypoints of a joint path on the plots over time (when the motion passes them).

import uPlot from 'uplot';
import { PALETTE } from './colormap.js';

const el = (tag, className, text) => {
  const node = document.createElement(tag);
  if (className) node.className = className;
  if (text !== undefined) node.textContent = text;
  return node;
};

const num = (v) => (typeof v === 'number' && Number.isFinite(v) ? v : null);

// Vertical dashed lines at the key frames' arc lengths (or the waypoints' times), labelled
// with the frame's (waypoint's) index.
function frameLinesPlugin(getMarks) {
  return {
    hooks: {
      draw: [(u) => {
        const marks = getMarks();
        if (!marks || !marks.length) return;
        const { ctx } = u;
        const { top, height } = u.bbox;
        ctx.save();
        ctx.strokeStyle = 'rgba(0,0,0,0.35)';
        ctx.fillStyle = 'rgba(0,0,0,0.6)';
        ctx.setLineDash([4, 4]);
        ctx.lineWidth = 1;
        ctx.font = `${Math.round(10 * uPlot.pxRatio)}px sans-serif`;
        for (const m of marks) {
          const x = Math.round(u.valToPos(m.x, 'x', true));
          if (x < u.bbox.left || x > u.bbox.left + u.bbox.width) continue;
          ctx.beginPath();
          ctx.moveTo(x, top);
          ctx.lineTo(x, top + height);
          ctx.stroke();
          ctx.fillText(m.label, x + 3 * uPlot.pxRatio, top + 12 * uPlot.pxRatio);
        }
        ctx.restore();
      }],
    },
  };
}

// Dashed horizontal lines at each joint's limits, in the joint's colour.
function limitLinesPlugin(getLimits) {
  return {
    hooks: {
      draw: [(u) => {
        const limits = getLimits();
        if (!limits) return;
        const { ctx } = u;
        const { left, width } = u.bbox;
        ctx.save();
        ctx.setLineDash([6, 4]);
        ctx.lineWidth = 1.2 * uPlot.pxRatio;
        limits.forEach((pair, j) => {
          if (!pair || !u.series[j + 1]?.show) return;
          ctx.strokeStyle = PALETTE[j % PALETTE.length];
          for (const v of pair) {
            if (!Number.isFinite(v)) continue;
            const y = Math.round(u.valToPos(v, 'y', true));
            ctx.beginPath();
            ctx.moveTo(left, y);
            ctx.lineTo(left + width, y);
            ctx.stroke();
          }
        });
        ctx.restore();
      }],
    },
  };
}

// The width of a y axis from its widest tick value (uPlot's default, 50 px, cuts values such
// as -0.0012 or 1500): ticks, gap and the text measured in the axis's font.
function axisSize(u, values, axisIdx, cycleNum) {
  const axis = u.axes[axisIdx];
  if (cycleNum > 1 && axis._size) return axis._size;
  let size = (axis.ticks?.size ?? 10) + (axis.gap ?? 5);
  const longest = (values || []).reduce((a, v) => (String(v ?? '').length > a.length ? String(v ?? '') : a), '');
  if (longest) {
    u.ctx.save();
    u.ctx.font = axis.font?.[0] ?? `${Math.round(12 * uPlot.pxRatio)}px sans-serif`;
    size += u.ctx.measureText(longest).width / uPlot.pxRatio;
    u.ctx.restore();
  }
  return Math.ceil(size) + 6;
}

// Every y axis of `options` sized by axisSize, its label given room (labelSize).
function sizedAxes(axes) {
  return axes.map((a, i) => (i === 0 ? a : { size: axisSize, labelSize: 20, ...a }));
}

class Chart {
  constructor(parent, testid, title, note) {
    this.card = el('div', 'plot-card');
    this.card.dataset.testid = testid;
    this.card.setAttribute('data-testid', testid);
    this.title = title;
    this.body = el('div', 'plot-body');
    this.baseNote = note || '';
    this.note = el('div', 'plot-note', this.baseNote);
    this.card.append(this.body, this.note);
    parent.append(this.card);
    this.plot = null;
  }

  width() {
    return Math.max(280, (this.card.clientWidth || 480) - 16);
  }

  empty(message) {
    this.plot?.destroy();
    this.plot = null;
    this.body.replaceChildren(el('div', 'plot-title', this.title), el('div', 'plot-empty', message));
    this.card.dataset.series = '0';
  }

  show(options, data) {
    this.plot?.destroy();
    this.body.replaceChildren();
    this.options = { title: this.title, width: this.width(), height: 240, ...options,
      axes: options.axes ? sizedAxes(options.axes) : undefined };
    this.plot = new uPlot(this.options, data, this.body);
    this.card.dataset.series = String(data.length - 1);
  }

  resize() {
    if (this.plot) this.plot.setSize({ width: this.width(), height: 240 });
  }
}

const SPEED_NOTE = 'The sampled tool speed |v| and the profile ds/dt from the samples\' arc length; they differ where u(t) does not follow s(t).';
const SPEED_NOTE_JOINTS = 'The tool speed |v| of the samples (the tool where the joints take it: a joint path has no arc length to profile). Numbered: when the motion passes each waypoint.';
const WAYPOINT_NOTE = ' Numbered: when the motion passes each waypoint.';

const series = (label, color, scale, extra = {}) => ({ label, stroke: color, width: 1.5,
  ...(scale ? { scale } : {}), spanGaps: false, points: { show: false }, ...extra });

export class Plots {
  constructor(root) {
    this.root = root;
    this.frameMarks = [];
    this.timeMarks = [];
    this.curvature = new Chart(root, 'plot-curvature', 'Curvature and torsion along the path',
      'Dashed: key frames (arc length s at each).');
    this.derivatives = new Chart(root, 'plot-derivatives', 'Derivatives of curvature and torsion along the path',
      'Per metre of arc, whatever the request\'s convention.');
    this.speed = new Chart(root, 'plot-speed', 'Tool speed against the speed profile', SPEED_NOTE);
    this.jointPos = new Chart(root, 'plot-joint-positions', 'Joint positions', 'Dashed: position limits.');
    this.jointVel = new Chart(root, 'plot-joint-velocities', 'Joint velocities', 'Dashed: ±velocity limits.');
    this.jointAcc = new Chart(root, 'plot-joint-accelerations', 'Joint accelerations', 'Dashed: ±acceleration limits.');
    this.jointTau = new Chart(root, 'plot-joint-torques', 'Joint torques',
      'With the payload, under gravity. Dashed: ±torque limits (the model\'s maxTorque).');
    this.binding = el('div', 'plot-card binding-card');
    this.binding.setAttribute('data-testid', 'plot-binding');
    root.append(this.binding);
    this.charts = [this.curvature, this.derivatives, this.speed, this.jointPos, this.jointVel, this.jointAcc, this.jointTau];
    new ResizeObserver(() => this.charts.forEach((c) => c.resize())).observe(root);
    this.setProfile(null);
    this.setSamples(null, null);
    this.setBinding(null, 0);
  }

  // frameS: arc length [m] of every key frame.
  setFrameMarks(frameS) {
    this.frameMarks = frameS.map((x, i) => ({ x, label: `${i}` }));
  }

  // t: the times [s] at which the motion passes the waypoints of a joint path, or at which
  // the steps of a sequence start ([] for none); labels: each mark's (default w0, w1, ...).
  setTimeMarks(t, labels = null) {
    this.timeMarks = t.map((x, i) => ({ x, label: labels?.[i] ?? `w${i}` }));
  }

  // points: PathProfile.points, or null (then `message` says why there is none).
  setProfile(points, message = 'no path profile yet') {
    if (!points || points.length < 2) {
      this.curvature.empty(message);
      this.derivatives.empty(message);
      return;
    }
    const s = points.map((p) => p.s ?? 0);
    const marks = () => this.frameMarks;
    this.curvature.show({
      scales: { x: { time: false }, k: {}, t: {} },
      axes: [
        { label: 'arc length s [m]' },
        { label: 'curvature κ [1/m]', scale: 'k', stroke: PALETTE[0] },
        { label: 'torsion τ [1/m]', scale: 't', side: 1, stroke: PALETTE[1], grid: { show: false } },
      ],
      series: [{ label: 's [m]' }, series('κ [1/m]', PALETTE[0], 'k'), series('τ [1/m]', PALETTE[1], 't')],
      plugins: [frameLinesPlugin(marks)],
    }, [s, points.map((p) => num(p.curvature)), points.map((p) => num(p.torsion))]);
    this.derivatives.show({
      scales: { x: { time: false }, k: {}, t: {} },
      axes: [
        { label: 'arc length s [m]' },
        { label: "dκ/ds [1/m²]", scale: 'k', stroke: PALETTE[2] },
        { label: "dτ/ds [1/m²]", scale: 't', side: 1, stroke: PALETTE[4], grid: { show: false } },
      ],
      series: [{ label: 's [m]' }, series("dκ/ds [1/m²]", PALETTE[2], 'k'), series("dτ/ds [1/m²]", PALETTE[4], 't')],
      plugins: [frameLinesPlugin(marks)],
    }, [s, points.map((p) => num(p.curvatureDerivative)), points.map((p) => num(p.torsionDerivative))]);
  }

  // samples: the streamed Sample list; robot: {names, limits: JointLimits[]} or null.
  setSamples(samples, robot) {
    if (!samples || samples.length < 2) {
      this.speed.empty('no motion: give the request a motion (duration) to stream its samples');
      for (const c of [this.jointPos, this.jointVel, this.jointAcc, this.jointTau]) c.empty('no robot samples: choose a robot');
      return;
    }
    const t = samples.map((x) => x.t ?? 0);
    const timeMarks = () => this.timeMarks;
    // The profile ds/dt needs the samples' arc length s: a joint path's samples have none.
    const alongPath = samples.some((x) => x.s !== undefined);
    const profile = samples.map((x, i) => {
      const a = samples[Math.max(0, i - 1)];
      const b = samples[Math.min(samples.length - 1, i + 1)];
      const dt = (b.t ?? 0) - (a.t ?? 0);
      return dt > 0 && (a.step ?? 0) === (b.step ?? 0) ? Math.abs(((b.s ?? 0) - (a.s ?? 0)) / dt) : null;
    });
    this.speed.title = alongPath ? 'Tool speed against the speed profile' : 'Tool speed';
    this.speed.show({
      scales: { x: { time: false } },
      axes: [{ label: 'time t [s]' }, { label: 'speed [m/s]' }],
      series: [{ label: 't [s]' }, series('tool speed |v| [m/s]', PALETTE[0]),
        ...(alongPath ? [series('profile ds/dt [m/s]', PALETTE[1], undefined, { dash: [6, 4] })] : [])],
      plugins: [frameLinesPlugin(timeMarks)],
    }, [t, samples.map((x) => x.speed ?? 0), ...(alongPath ? [profile] : [])]);
    this.speed.note.textContent = alongPath ? SPEED_NOTE : SPEED_NOTE_JOINTS;

    const n = samples[0].joints ? samples[0].joints.length : 0;
    if (!n) {
      for (const c of [this.jointPos, this.jointVel, this.jointAcc, this.jointTau]) c.empty('no robot in the request: choose one to see its joints');
      return;
    }
    const names = robot?.names || [];
    const limits = robot?.limits || [];
    const jointSeries = Array.from({ length: n }, (_, j) =>
      series(`${j}${names[j] ? ` ${names[j]}` : ''}`, PALETTE[j % PALETTE.length]));
    const column = (key, j) => samples.map((x) => num(x[key]?.[j]) ?? 0);
    const make = (chart, key, unit, what, limitPair) => {
      chart.note.textContent = chart.baseNote + (this.timeMarks.length ? WAYPOINT_NOTE : '');
      const bands = limits.length ? limits.map((l, j) => limitPair(l, j)) : null;
      const data = [t, ...Array.from({ length: n }, (_, j) => column(key, j))];
      let lo = Infinity;
      let hi = -Infinity;
      for (const col of data.slice(1)) for (const v of col) { if (v < lo) lo = v; if (v > hi) hi = v; }
      for (const pair of bands || []) for (const v of pair || []) if (Number.isFinite(v)) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
      if (!(hi > lo)) { hi = lo + 1; }
      const pad = (hi - lo) * 0.05;
      chart.show({
        scales: { x: { time: false }, y: { range: [lo - pad, hi + pad] } },
        axes: [{ label: 'time t [s]' }, { label: `${what} [${unit}]` }],
        series: [{ label: 't [s]' }, ...jointSeries.map((s) => ({ ...s }))],
        plugins: [limitLinesPlugin(() => bands), frameLinesPlugin(timeMarks)],
      }, data);
    };
    make(this.jointPos, 'joints', 'rad', 'joint position',
      (l) => [l.minPosition ?? 0, l.maxPosition ?? 0]);
    make(this.jointVel, 'jointVelocities', 'rad/s', 'joint velocity',
      (l) => [-(l.maxVelocity ?? 0) * (robot.velocityScale ?? 1), (l.maxVelocity ?? 0) * (robot.velocityScale ?? 1)]);
    make(this.jointAcc, 'jointAccelerations', 'rad/s²', 'joint acceleration',
      // No band where the model has no acceleration limit (a URDF as shipped: maxAcceleration 0
      // in ListRobots; the request's jointLimits or jointLimitsYaml give the plan's).
      (l) => (l.maxAcceleration > 0
        ? [-l.maxAcceleration * (robot.accelerationScale ?? 1), l.maxAcceleration * (robot.accelerationScale ?? 1)]
        : null));
    // Torques: a model with mass properties (the Panda, the UR5e, a URDF with <inertial>).
    if (samples[0].jointTorques?.length === n) {
      make(this.jointTau, 'jointTorques', 'N m', 'joint torque',
        (l) => (Number.isFinite(l.maxTorque) ? [-l.maxTorque, l.maxTorque] : null));
    } else {
      this.jointTau.empty('no torques: the model has no mass properties (docs/dynamics.md)');
    }
  }

  // stretches: BindingStretch[] (RobotReport.binding, TimingReport.binding or MotionSummary.binding); names: joint
  // names; duration [s].
  setBinding(stretches, duration, names = [], source = '') {
    const card = this.binding;
    card.replaceChildren(el('div', 'plot-title', 'Most used limits along the motion'));
    if (!stretches || !stretches.length) {
      card.append(el('div', 'plot-empty',
        'no limit report: a plan with a robot (or time-optimal timing) reports which limit is most used where'));
      card.dataset.stretches = '0';
      return;
    }
    const describe = (b) => bindingName(b, names);
    const kinds = [...new Set(stretches.map(describe))];
    const end = Math.max(duration || 0, ...stretches.map((b) => b.tEnd ?? 0)) || 1;
    const rowH = 24;
    // Room for the longest row label (13 px text: about 7.5 px a character).
    const left = Math.max(120, Math.ceil(Math.max(...kinds.map((k) => k.length)) * 7.5) + 14);
    const width = left + 420;
    const plotW = width - left - 20;
    const height = kinds.length * rowH + 50;
    const ns = 'http://www.w3.org/2000/svg';
    const svg = document.createElementNS(ns, 'svg');
    svg.setAttribute('viewBox', `0 0 ${width} ${height}`);
    svg.setAttribute('class', 'binding-svg');
    svg.setAttribute('role', 'img');
    const add = (tag, attrs, text) => {
      const node = document.createElementNS(ns, tag);
      for (const [k, v] of Object.entries(attrs)) node.setAttribute(k, v);
      if (text !== undefined) node.textContent = text;
      svg.append(node);
      return node;
    };
    kinds.forEach((k, r) => {
      add('text', { x: left - 6, y: 20 + r * rowH + 14, 'text-anchor': 'end', class: 'row-label' }, k);
      add('line', { x1: left, x2: left + plotW, y1: 20 + r * rowH + rowH, y2: 20 + r * rowH + rowH, class: 'row-line' });
    });
    stretches.forEach((b, i) => {
      const r = kinds.indexOf(describe(b));
      const x0 = left + ((b.tStart ?? 0) / end) * plotW;
      const x1 = left + ((b.tEnd ?? 0) / end) * plotW;
      const rect = add('rect', { x: x0, y: 20 + r * rowH + 3, width: Math.max(1.5, x1 - x0), height: rowH - 6,
        fill: PALETTE[r % PALETTE.length], 'fill-opacity': 0.35 + 0.65 * Math.min(1, b.usage ?? 0) });
      const tip = document.createElementNS(ns, 'title');
      tip.textContent = `${describe(b)}: t ${fmt(b.tStart)}-${fmt(b.tEnd)} s, usage ${fmt((b.usage ?? 0) * 100)} %`;
      rect.append(tip);
      rect.setAttribute('data-index', String(i));
    });
    const axisY = 20 + kinds.length * rowH + 4;
    add('line', { x1: left, x2: left + plotW, y1: axisY, y2: axisY, class: 'axis' });
    const step = niceStep(end / 6);
    for (let v = 0; v <= end + 1e-9; v += step) {
      const x = left + (v / end) * plotW;
      add('line', { x1: x, x2: x, y1: axisY, y2: axisY + 4, class: 'axis' });
      add('text', { x, y: axisY + 15, 'text-anchor': 'middle', class: 'tick' }, fmt(v));
    }
    add('text', { x: left + plotW / 2, y: height - 2, 'text-anchor': 'middle', class: 'axis-label' }, 'time t [s]');
    card.append(svg);
    const legend = el('div', 'plot-note',
      `${source}: the most used limit on each stretch, "binding" where it is at 100 % (it sets the pace there); ` +
      'opacity = usage (value / limit).');
    card.append(legend);
    const list = el('ol', 'binding-list');
    stretches.forEach((b, i) => {
      const item = el('li', '', `${fmt(b.tStart)}-${fmt(b.tEnd)} s: ${describe(b)} at ${fmt((b.usage ?? 0) * 100)} % ` +
        `(${fmt(b.value)} of ${fmt(b.limit)})${isBinding(b) ? ', binding' : ''}`);
      item.setAttribute('data-testid', `binding-stretch-${i}`);
      list.append(item);
    });
    card.append(list);
    card.dataset.stretches = String(stretches.length);
  }
}

const KIND_NAMES = {
  BINDING_KIND_JOINT_VELOCITY: 'velocity',
  BINDING_KIND_JOINT_ACCELERATION: 'acceleration',
  BINDING_KIND_JOINT_JERK: 'jerk',
  BINDING_KIND_JOINT_TORQUE: 'torque',
  BINDING_KIND_CARTESIAN_SPEED: 'Cartesian speed',
  BINDING_KIND_CARTESIAN_TANGENTIAL_ACCELERATION: 'tangential acceleration',
  BINDING_KIND_CARTESIAN_CENTRIPETAL_ACCELERATION: 'centripetal acceleration κv²',
  BINDING_KIND_CARTESIAN_JERK: 'Cartesian jerk',
  BINDING_KIND_ANGULAR_SPEED: 'angular speed',
  BINDING_KIND_ANGULAR_ACCELERATION: 'angular acceleration',
};

// A limit binds (sets the pace) only where it is used whole: usage 1 to the planner's
// checking tolerance.
export const BINDING_USAGE = 0.999;
export function isBinding(b) {
  return (b.usage ?? 0) >= BINDING_USAGE;
}

export function bindingName(b, names = []) {
  const kind = KIND_NAMES[b.kind] || b.kind || 'unspecified';
  if (b.kind && b.kind.startsWith('BINDING_KIND_JOINT_')) {
    const j = b.joint ?? 0;
    return `joint ${j}${names[j] ? ` (${names[j]})` : ''} ${kind}`;
  }
  return kind;
}

function niceStep(raw) {
  const p = 10 ** Math.floor(Math.log10(raw || 1));
  for (const m of [1, 2, 5, 10]) if (m * p >= raw) return m * p;
  return 10 * p;
}

export function fmt(v) {
  if (typeof v !== 'number' || !Number.isFinite(v)) return v === undefined ? '0' : String(v);
  const a = Math.abs(v);
  if (a !== 0 && (a < 1e-3 || a >= 1e5)) return v.toExponential(3);
  return Number(v.toPrecision(4)).toString();
}
