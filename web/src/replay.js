// Replay of a streamed motion: a time slider and play/pause over the samples of
// POST /v1/stream; with a robot the arm is drawn as capsules through its joint axis
// origins (POST /v1/fk: axes[].origin, then pose.position for the tool), computed at up to
// FK_POINTS sample times and interpolated between them.

import * as THREE from 'three';
import * as api from './api.js';
import { fmt } from './plots.js';

const FK_POINTS = 120;

// The part of a RobotSpec that forward kinematics reads.
export function fkRobot(spec) {
  const out = {};
  for (const key of ['name', 'model', 'urdf', 'baseLink', 'tipLink', 'base', 'tool']) {
    if (spec[key] !== undefined) out[key] = spec[key];
  }
  return out;
}

const v3 = (p) => new THREE.Vector3(p?.x ?? 0, p?.y ?? 0, p?.z ?? 0);

export class Replay {
  constructor({ slider, play, time, tool, status }, view) {
    this.slider = slider;
    this.playButton = play;
    this.timeLabel = time;
    this.toolLabel = tool;
    this.status = status;
    this.view = view;
    this.samples = [];
    this.fk = new Map();
    this.playing = false;
    this.generation = 0;
    slider.addEventListener('input', () => this.seek(Number(slider.value)));
    play.addEventListener('click', () => (this.playing ? this.pause() : this.play()));
    this.clear('no motion to replay');
  }

  clear(message) {
    this.pause();
    this.samples = [];
    this.fk.clear();
    this.slider.disabled = true;
    this.playButton.disabled = true;
    this.status.textContent = message || '';
    this.timeLabel.textContent = '';
    this.toolLabel.textContent = '';
    this.view.setRobot(null);
    this.view.setToolMarker(null);
    this.slider.dataset.ready = 'false';
  }

  // samples: Sample[]; robot: the request's RobotSpec or null. Resolves when the arm's
  // forward kinematics are in.
  async load(samples, robot) {
    const generation = ++this.generation;
    const wasPlaying = this.playing;
    this.pause();
    this.samples = samples;
    this.robot = robot;
    this.fk = new Map();
    if (!samples.length) {
      this.clear('the stream sent no samples');
      return;
    }
    const end = samples[samples.length - 1].t ?? 0;
    this.slider.min = '0';
    this.slider.max = String(end);
    this.slider.step = String(Math.max(1e-3, end / 1000));
    this.slider.disabled = false;
    this.playButton.disabled = false;
    const t = Math.min(Number(this.slider.value) || 0, end);
    this.slider.value = String(t);
    if (robot && samples[0].joints?.length) {
      this.status.textContent = 'computing the arm\'s forward kinematics…';
      const step = Math.max(1, Math.ceil((samples.length - 1) / (FK_POINTS - 1)));
      const indices = [];
      for (let i = 0; i < samples.length; i += step) indices.push(i);
      if (indices[indices.length - 1] !== samples.length - 1) indices.push(samples.length - 1);
      const spec = fkRobot(robot);
      try {
        await api.mapLimited(indices, 4, async (i) => {
          if (generation !== this.generation) return;
          const answer = await api.forwardKinematics({ robot: spec, joints: samples[i].joints });
          if (generation !== this.generation) return;
          this.fk.set(i, armPoints(answer, robot));
        });
      } catch (e) {
        if (generation === this.generation) this.status.textContent = `forward kinematics failed: ${e.summary || e.message}`;
        return;
      }
      if (generation !== this.generation) return;
      this.fkIndices = indices;
      this.status.textContent = `${samples.length} samples, the arm at ${indices.length} of them (interpolated between)`;
    } else {
      this.fkIndices = null;
      this.view.setRobot(null);
      this.status.textContent = `${samples.length} samples (no robot: the tool point only)`;
    }
    this.slider.dataset.ready = 'true';
    this.seek(t);
    if (wasPlaying) this.play();
  }

  indexAt(t) {
    const s = this.samples;
    let lo = 0;
    let hi = s.length - 1;
    while (lo < hi) {
      const mid = (lo + hi + 1) >> 1;
      if ((s[mid].t ?? 0) <= t) lo = mid;
      else hi = mid - 1;
    }
    return lo;
  }

  // The arm's points at sample i: from its FK when computed there, else interpolated
  // between the nearest computed samples.
  armAt(i) {
    if (this.fk.has(i)) return { points: this.fk.get(i), exact: true };
    const idx = this.fkIndices;
    let k = 0;
    while (k < idx.length - 1 && idx[k + 1] < i) ++k;
    const a = idx[k];
    const b = idx[Math.min(k + 1, idx.length - 1)];
    const pa = this.fk.get(a);
    const pb = this.fk.get(b);
    if (!pa || !pb) return null;
    const f = b === a ? 0 : (i - a) / (b - a);
    return { points: pa.map((p, j) => p.clone().lerp(pb[j], f)), exact: false };
  }

  seek(t) {
    if (!this.samples.length) return;
    const i = this.indexAt(t);
    const sample = this.samples[i];
    this.current = i;
    this.timeLabel.textContent = `t = ${fmt(sample.t ?? 0)} s of ${fmt(this.samples[this.samples.length - 1].t ?? 0)} s`;
    let tool = v3(sample.position);
    if (this.fkIndices) {
      const arm = this.armAt(i);
      if (arm) {
        this.view.setRobot(arm.points);
        tool = arm.points[arm.points.length - 1];
      }
      this.view.setToolMarker(null);
    } else {
      this.view.setToolMarker(tool);
    }
    const label = this.toolLabel;
    label.dataset.x = String(tool.x);
    label.dataset.y = String(tool.y);
    label.dataset.z = String(tool.z);
    label.dataset.t = String(sample.t ?? 0);
    label.textContent = `tool (${fmt(tool.x)}, ${fmt(tool.y)}, ${fmt(tool.z)}) m, speed ${fmt(sample.speed ?? 0)} m/s`;
  }

  play() {
    if (!this.samples.length || this.playing) return;
    this.playing = true;
    this.playButton.textContent = '⏸ pause';
    const end = Number(this.slider.max);
    if (Number(this.slider.value) >= end) this.slider.value = '0';
    let last = performance.now();
    const tick = (now) => {
      if (!this.playing) return;
      const dt = (now - last) / 1000;
      last = now;
      let t = Number(this.slider.value) + dt;
      if (t >= end) t = end;
      this.slider.value = String(t);
      this.seek(t);
      if (t >= end) {
        this.pause();
        return;
      }
      this.frame = requestAnimationFrame(tick);
    };
    this.frame = requestAnimationFrame(tick);
  }

  pause() {
    this.playing = false;
    if (this.frame) cancelAnimationFrame(this.frame);
    this.frame = null;
    this.playButton.textContent = '▶ play';
  }
}

// The arm drawn from a ForwardKinematicsResponse: the base's foot on the floor, the joint
// axis origins, then the tool.
function armPoints(answer, robot) {
  const points = (answer.axes || []).map((a) => v3(a.origin));
  const base = v3(robot.base?.position ?? robot.model?.base?.position);
  if (!points.length || points[0].distanceTo(base) > 1e-6) points.unshift(base);
  points.push(v3(answer.pose?.position));
  return points;
}
