// The family view (thesis Ch. 4): one constraint of one key frame swept over a range, N
// curves planned (POST /v1/analyze, one call each) and overlaid in the 3-D view, with a
// legend of each value, its arc length and its peak curvature.

import * as api from './api.js';
import { analysisRequest, withConstraint } from './request.js';
import { fmt } from './plots.js';

export const FAMILY_CONSTRAINTS = [
  ['curvature', 'curvature κ [1/m]'],
  ['torsion', 'torsion τ [1/m]'],
  ['curvatureDerivative', "curvature derivative κ'"],
  ['torsionDerivative', "torsion derivative τ'"],
  ['tangentScale', 'tangent scale [m]'],
];

// Blue to red over the family.
function familyColor(k, n) {
  const t = n <= 1 ? 0 : k / (n - 1);
  const hue = 230 - 230 * t;
  return `hsl(${hue}, 75%, 45%)`;
}

export class Family {
  constructor(root, view, getRequest) {
    this.root = root;
    this.view = view;
    this.getRequest = getRequest;
    this.form = root.querySelector('form');
    this.frame = root.querySelector('[name=frame]');
    this.constraint = root.querySelector('[name=constraint]');
    this.from = root.querySelector('[name=from]');
    this.to = root.querySelector('[name=to]');
    this.count = root.querySelector('[name=count]');
    this.legend = root.querySelector('.family-legend');
    this.status = root.querySelector('.family-status');
    for (const [value, text] of FAMILY_CONSTRAINTS) {
      const option = document.createElement('option');
      option.value = value;
      option.textContent = text;
      this.constraint.append(option);
    }
    this.form.addEventListener('submit', (e) => {
      e.preventDefault();
      this.run();
    });
    root.querySelector('[data-action=clear]').addEventListener('click', () => this.clear());
    this.frame.addEventListener('change', () => this.suggestRange());
    this.constraint.addEventListener('change', () => this.suggestRange());
    this.generation = 0;
  }

  // The frame choices follow the request's frames.
  updateFrames(frames) {
    const current = this.frame.value;
    this.frame.replaceChildren();
    frames.forEach((_, i) => {
      const option = document.createElement('option');
      option.value = String(i);
      option.textContent = `frame ${i}`;
      this.frame.append(option);
    });
    if (current && Number(current) < frames.length) this.frame.value = current;
    else if (frames.length > 1) this.frame.value = String(Math.min(1, frames.length - 1));
    if (!this.from.value && !this.to.value) this.suggestRange();
  }

  // A range around the frame's current value: half to one and a half times it.
  suggestRange() {
    const frames = this.getRequest()?.path?.frames || [];
    const f = frames[Number(this.frame.value)];
    if (!f) return;
    const key = this.constraint.value;
    const v = f[key];
    if (typeof v === 'number' && v !== 0) {
      this.from.value = String(Number((v * 0.5).toPrecision(4)));
      this.to.value = String(Number((v * 1.5).toPrecision(4)));
    } else {
      this.from.value = key === 'tangentScale' ? '0.1' : '0';
      this.to.value = key === 'tangentScale' ? '0.5' : '20';
    }
  }

  clear() {
    ++this.generation;
    this.view.setFamily([]);
    this.legend.replaceChildren();
    this.status.textContent = '';
    this.root.dataset.curves = '0';
  }

  async run() {
    const request = this.getRequest();
    const frame = Number(this.frame.value);
    const key = this.constraint.value;
    const a = Number(this.from.value);
    const b = Number(this.to.value);
    const n = Math.max(2, Math.min(50, Math.round(Number(this.count.value) || 5)));
    if (!request?.path?.frames?.[frame] || !Number.isFinite(a) || !Number.isFinite(b)) {
      this.status.textContent = 'pick a frame and a numeric range';
      return;
    }
    const generation = ++this.generation;
    const values = Array.from({ length: n }, (_, k) => a + ((b - a) * k) / (n - 1));
    this.status.textContent = `planning ${n} curves…`;
    this.root.dataset.curves = '0';
    const results = await api.mapLimited(values, 2, async (value) => {
      try {
        const profile = await api.analyze(analysisRequest(withConstraint(request, frame, key, value), 201));
        return { value, profile };
      } catch (error) {
        return { value, error };
      }
    });
    if (generation !== this.generation) return;
    const ok = results.filter((r) => r.profile);
    const curves = ok.map((r, k) => ({ points: r.profile.points || [], color: familyColor(k, ok.length), r }));
    this.view.setFamily(curves);
    this.legend.replaceChildren();
    for (const c of curves) {
      const li = document.createElement('li');
      const swatch = document.createElement('span');
      swatch.className = 'swatch';
      swatch.style.background = c.color;
      const peak = Math.max(0, ...c.points.map((p) => p.curvature ?? 0));
      li.append(swatch, document.createTextNode(
        `${key} = ${fmt(c.r.value)}: length ${fmt(c.r.profile.arcLength ?? 0)} m, peak κ ${fmt(peak)} 1/m`));
      this.legend.append(li);
    }
    for (const r of results.filter((x) => x.error)) {
      const li = document.createElement('li');
      li.className = 'violation';
      const why = r.error.fieldViolations?.map((v) => `${v.field}: ${v.description}`).join('; ') || r.error.summary || r.error.message;
      li.textContent = `${key} = ${fmt(r.value)}: refused (${why})`;
      this.legend.append(li);
    }
    this.root.dataset.curves = String(curves.length);
    this.status.textContent = `${curves.length} of ${n} curves drawn (frame ${frame}, ${key} from ${fmt(a)} to ${fmt(b)})`;
    this.status.setAttribute('data-value', String(curves.length));
  }
}
