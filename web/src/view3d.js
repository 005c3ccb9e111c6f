// The 3-D view (three.js, z up as the robots' world frame W): the curve coloured by
// curvature, torsion or speed with its colour bar (a path of pieces drawn segment by
// segment: exact pieces thick, transitions dashed in their own colour, blends as a key-frame
// path's), or, for a joint path, the tool's path from the samples coloured by its speed with
// the tool at each waypoint marked; the key frames with their T, N, B arrows, cusps,
// inflections and plan warnings marked, a family of curves, and the robot as capsules. Orbit (left drag), pan (right
// drag), zoom (wheel). Lengths in metres.

import * as THREE from 'three';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
import { Line2 } from 'three/examples/jsm/lines/Line2.js';
import { LineGeometry } from 'three/examples/jsm/lines/LineGeometry.js';
import { LineMaterial } from 'three/examples/jsm/lines/LineMaterial.js';
import { CSS2DRenderer, CSS2DObject } from 'three/examples/jsm/renderers/CSS2DRenderer.js';
import { makeScale } from './colormap.js';

export const FRAME_COLORS = { T: 0xd62728, N: 0x2ca02c, B: 0x1f77b4 };

// What the curve can be coloured by: label, unit, diverging scale.
export const COLOR_MODES = {
  curvature: { label: 'curvature κ', unit: '1/m', diverging: false },
  torsion: { label: 'torsion τ', unit: '1/m', diverging: true },
  speed: { label: 'tool speed', unit: 'm/s', diverging: false },
  parametricSpeed: { label: 'parametric speed |dp/du|', unit: 'm per unit u', diverging: false },
};

// How a path of pieces draws each kind of segment (PlanResponse.segments[].kind): width in
// pixels, dashed, a colour of its own (else the colour scale's); legend and tooltip text.
export const SEGMENT_STYLES = {
  SEGMENT_KIND_PIECE: { key: 'piece', width: 7, dashed: false, color: null,
    label: 'exact piece', title: 'a piece from its natural equations (line, arc, helix, clothoid, profile): thick' },
  SEGMENT_KIND_TRANSITION: { key: 'transition', width: 3, dashed: true, color: 0xe91e63,
    label: 'transition', title: 'a transition where curvature or torsion jumps between pieces: dashed, pink' },
  SEGMENT_KIND_BLEND: { key: 'blend', width: 4, dashed: false, color: null,
    label: 'blend to a key frame', title: 'a blend to the key frame of a `to` piece: drawn as a key-frame path' },
};

const v3 = (p) => new THREE.Vector3(p?.x ?? 0, p?.y ?? 0, p?.z ?? 0);

function label(text, className) {
  const div = document.createElement('div');
  div.className = `label3d ${className || ''}`;
  div.textContent = text;
  return new CSS2DObject(div);
}

function disposeGroup(group) {
  for (const child of [...group.children]) {
    child.traverse((o) => {
      o.geometry?.dispose?.();
      if (o.material && !o.userData.sharedMaterial) o.material.dispose?.();
      if (o.element) o.element.remove();
    });
    group.remove(child);
  }
}

export class View3D {
  constructor(container, colorBar) {
    this.container = container;
    this.colorBar = colorBar;
    this.renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
    this.renderer.setPixelRatio(Math.min(2, window.devicePixelRatio || 1));
    this.renderer.setClearColor(0xffffff);
    container.append(this.renderer.domElement);
    this.renderer.domElement.setAttribute('data-testid', 'view3d-canvas');
    this.labels = new CSS2DRenderer();
    this.labels.domElement.className = 'labels3d';
    container.append(this.labels.domElement);

    this.scene = new THREE.Scene();
    this.camera = new THREE.PerspectiveCamera(40, 1, 0.001, 100);
    this.camera.up.set(0, 0, 1);
    this.camera.position.set(1.6, -1.4, 1.3);
    this.controls = new OrbitControls(this.camera, this.labels.domElement);
    this.controls.target.set(0.3, 0, 0.5);
    this.controls.addEventListener('change', () => this.render());
    this.scene.add(new THREE.AmbientLight(0xffffff, 1.2));
    const sun = new THREE.DirectionalLight(0xffffff, 1.8);
    sun.position.set(2, -3, 4);
    this.scene.add(sun);

    this.grid = new THREE.Group();
    this.curve = new THREE.Group();
    this.frames = new THREE.Group();
    this.marks = new THREE.Group();
    this.family = new THREE.Group();
    this.robot = new THREE.Group();
    this.waypoints = new THREE.Group();
    this.trace = new THREE.Group();
    this.stepMarks = new THREE.Group();
    this.scene.add(this.grid, this.curve, this.frames, this.marks, this.family, this.robot, this.waypoints, this.trace,
      this.stepMarks);
    this.lineMaterials = [];
    this.colorMode = 'curvature';
    this.showFrames = true;
    this.fitted = false;
    // Points `fit view` frames with the curve (the arm over the motion, an approach's tool
    // path), in W [m].
    this.fitExtra = [];
    this.buildGrid(-0.5, 1, -0.5, 0.5, 1);
    // Key frames dragged with the mouse: onFrameDrag(field, {x, y, z}) when one is let go.
    this.onFrameDrag = null;
    this.pickables = [];
    this.installDrag();

    new ResizeObserver(() => this.resize()).observe(container);
    this.resize();
  }

  resize() {
    const w = this.container.clientWidth || 640;
    const h = this.container.clientHeight || 480;
    this.renderer.setSize(w, h);
    this.labels.setSize(w, h);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
    for (const m of this.lineMaterials) m.resolution.set(w, h);
    this.render();
  }

  render() {
    if (this.pending) return;
    this.pending = true;
    requestAnimationFrame(() => {
      this.pending = false;
      this.renderer.render(this.scene, this.camera);
      this.labels.render(this.scene, this.camera);
      this.publishScreen();
    });
  }

  // Where things are on the canvas, as fractions of its width and height from its top left
  // (data-frames-screen: each key frame's [x, y]; data-curve-box: the drawn curve's bounding
  // box [x0, y0, x1, y1]), for whoever checks the view from outside.
  publishScreen() {
    const project = (p) => {
      const q = p.clone().project(this.camera);
      return [(q.x + 1) / 2, (1 - q.y) / 2];
    };
    this.container.dataset.framesScreen = JSON.stringify(this.pickables.map((m) => project(m.position).map((v) => Number(v.toFixed(4)))));
    const points = this.lastCurve?.points || [];
    if (points.length < 2) {
      delete this.container.dataset.curveBox;
      return;
    }
    const box = [Infinity, Infinity, -Infinity, -Infinity];
    const step = Math.max(1, Math.floor(points.length / 500));
    for (let i = 0; i < points.length; i += step) {
      const [x, y] = project(v3(points[i].position));
      box[0] = Math.min(box[0], x);
      box[1] = Math.min(box[1], y);
      box[2] = Math.max(box[2], x);
      box[3] = Math.max(box[3], y);
    }
    this.container.dataset.curveBox = JSON.stringify(box.map((v) => Number(v.toFixed(4))));
  }

  // Dragging a key frame's dot: the frame follows the mouse in the plane through it facing
  // the camera (the orbit controls wait meanwhile), and onFrameDrag says where it was let go.
  installDrag() {
    const element = this.labels.domElement;
    const raycaster = new THREE.Raycaster();
    const ndc = (e) => {
      const r = element.getBoundingClientRect();
      return new THREE.Vector2(((e.clientX - r.left) / r.width) * 2 - 1, -((e.clientY - r.top) / r.height) * 2 + 1);
    };
    let drag = null;
    this.container.addEventListener('pointerdown', (e) => {
      if (e.button !== 0 || !this.onFrameDrag || !this.pickables.length) return;
      raycaster.setFromCamera(ndc(e), this.camera);
      const hit = raycaster.intersectObjects(this.pickables, false)[0];
      if (!hit) return;
      e.stopPropagation();
      e.preventDefault();
      const normal = this.camera.getWorldDirection(new THREE.Vector3());
      drag = { mesh: hit.object, plane: new THREE.Plane().setFromNormalAndCoplanarPoint(normal, hit.object.position),
        moved: false, pointer: e.pointerId };
      this.controls.enabled = false;
      this.container.dataset.dragging = hit.object.userData.field;
    }, { capture: true });
    window.addEventListener('pointermove', (e) => {
      if (!drag) return;
      raycaster.setFromCamera(ndc(e), this.camera);
      const at = raycaster.ray.intersectPlane(drag.plane, new THREE.Vector3());
      if (!at) return;
      drag.moved = true;
      drag.mesh.position.copy(at);
      for (const o of drag.mesh.userData.followers) o.position.copy(at);
      this.render();
    });
    window.addEventListener('pointerup', () => {
      if (!drag) return;
      const { mesh, moved } = drag;
      drag = null;
      this.controls.enabled = true;
      delete this.container.dataset.dragging;
      if (moved) this.onFrameDrag?.(mesh.userData.field, { x: mesh.position.x, y: mesh.position.y, z: mesh.position.z });
    });
  }

  // The floor grid (z = 0) every 0.1 m over [x0, x1] x [y0, y1] (the curve and the origin,
  // the robot's base), coordinates in metres along its edges, the axes of W from the origin,
  // and a z scale up to z1.
  buildGrid(x0, x1, y0, y1, z1) {
    disposeGroup(this.grid);
    const vertices = [];
    const minor = 0.1;
    for (let x = x0; x <= x1 + 1e-9; x += minor) vertices.push(x, y0, 0, x, y1, 0);
    for (let y = y0; y <= y1 + 1e-9; y += minor) vertices.push(x0, y, 0, x1, y, 0);
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute('position', new THREE.Float32BufferAttribute(vertices, 3));
    this.grid.add(new THREE.LineSegments(geometry, new THREE.LineBasicMaterial({ color: 0xdddddd })));
    const span = Math.max(x1 - x0, y1 - y0, z1);
    const step = span > 2.5 ? 0.5 : span > 1.2 ? 0.2 : 0.1;
    const ticks = (a, b) => {
      const out = [];
      for (let v = Math.ceil((a - 1e-9) / step) * step; v <= b + 1e-9; v += step) out.push(Math.abs(v) < 1e-9 ? 0 : v);
      return out;
    };
    const digits = 1;
    for (const x of ticks(x0, x1)) {
      const l = label(x.toFixed(digits), 'tick');
      l.position.set(x, y0 - 0.03, 0);
      this.grid.add(l);
    }
    for (const y of ticks(y0, y1)) {
      const l = label(y.toFixed(digits), 'tick');
      l.position.set(x1 + 0.03, y, 0);
      this.grid.add(l);
    }
    for (const z of ticks(step, z1)) {
      const l = label(z.toFixed(digits), 'tick');
      l.position.set(0, 0, z);
      l.center.set(-0.2, 0.5);
      this.grid.add(l);
    }
    const axes = [[x1, 0, 0, 0xd62728], [0, y1, 0, 0x2ca02c], [0, 0, z1, 0x1f77b4]];
    for (const [x, y, z, color] of axes) {
      const line = new THREE.BufferGeometry().setFromPoints([new THREE.Vector3(), new THREE.Vector3(x, y, z)]);
      this.grid.add(new THREE.Line(line, new THREE.LineBasicMaterial({ color })));
    }
    const zl = label('z [m]', 'axis');
    zl.position.set(0, 0, z1 + 0.05);
    this.grid.add(zl);
    const xl = label('x [m]', 'axis');
    xl.position.set((x0 + x1) / 2, y0 - 0.12, 0);
    const yl = label('y [m]', 'axis');
    yl.position.set(x1 + 0.14, (y0 + y1) / 2, 0);
    this.grid.add(xl, yl);
    for (const o of this.grid.children) o.visible = this.gridVisible !== false;
  }

  // The floor grid, its coordinates and the axes of W shown or not.
  setGridVisible(visible) {
    this.gridVisible = visible;
    for (const o of this.grid.children) o.visible = visible;
    this.render();
  }

  // The grid around positions (and the origin), on 0.1 m lines with 0.1 m to spare.
  gridAround(positions) {
    const box = new THREE.Box3().setFromPoints([...positions, new THREE.Vector3()]);
    const down = (v) => Math.floor(v * 10 - 1e-6) / 10 - 0.1;
    const up = (v) => Math.ceil(v * 10 + 1e-6) / 10 + 0.1;
    this.buildGrid(down(box.min.x), up(box.max.x), down(box.min.y), up(box.max.y), Math.max(0.2, up(box.max.z)));
  }

  // dashed: true, or {dashSize, gapSize} in metres.
  makeLine(points, colors, width, dashed) {
    const geometry = new LineGeometry();
    geometry.setPositions(points.flatMap((p) => [p.x, p.y, p.z]));
    if (colors) geometry.setColors(colors);
    const material = new LineMaterial({
      linewidth: width, vertexColors: Boolean(colors), color: colors ? 0xffffff : 0x888888,
      dashed: Boolean(dashed), dashSize: dashed?.dashSize ?? 0.01, gapSize: dashed?.gapSize ?? 0.006, worldUnits: false,
    });
    material.resolution.set(this.container.clientWidth || 640, this.container.clientHeight || 480);
    this.lineMaterials.push(material);
    material.addEventListener('dispose', () => {
      this.lineMaterials = this.lineMaterials.filter((m) => m !== material);
    });
    const line = new Line2(geometry, material);
    line.computeLineDistances();
    return line;
  }

  // The values the curve is coloured by (mode), at each profile point.
  colorValues(points, speedAtS, mode) {
    switch (mode) {
      case 'torsion': return points.map((p) => (p.torsion ?? NaN));
      case 'speed': return speedAtS ? points.map((p) => speedAtS(p.s ?? 0)) : points.map((p) => p.speed ?? 0);
      case 'parametricSpeed': return points.map((p) => p.speed ?? 0);
      default: return points.map((p) => p.curvature ?? NaN);
    }
  }

  // profile: PathProfile.points; speedAtS: the tool speed [m/s] at arc length s from the
  // streamed samples, or null (speed then falls back to |dp/du|); segmentKinds: the kind of
  // each segment of a path of pieces (PlanResponse.segments[].kind), or null: one line.
  // toolPath: the points are where the tool went ({position, speed}: the samples of a joint
  // path, which has no Cartesian path), coloured by the tool's speed whatever the mode.
  setCurve(points, speedAtS, segmentKinds = null, toolPath = false) {
    disposeGroup(this.curve);
    this.lastCurve = { points, speedAtS, segmentKinds, toolPath };
    this.container.dataset.curveKind = toolPath ? 'tool' : 'path';
    if (!points || points.length < 2) {
      this.container.dataset.curvePoints = '0';
      this.setSegmentLegend(null);
      this.updateColorBar(null);
      this.render();
      return;
    }
    let mode = toolPath ? 'speed' : this.colorMode;
    if (mode === 'speed' && !speedAtS && !toolPath) mode = 'parametricSpeed';
    const values = this.colorValues(points, speedAtS, mode);
    const scale = makeScale(values, COLOR_MODES[mode].diverging);
    const colors = values.flatMap((v) => scale.color(v));
    const positions = points.map((p) => v3(p.position));
    if (segmentKinds) this.addSegments(points, positions, colors, segmentKinds);
    else this.curve.add(this.makeLine(positions, colors, 4));
    this.setSegmentLegend(segmentKinds ? this.curve.children.map((line) => line.userData.kind) : null);
    this.container.dataset.curvePoints = String(points.length);
    // A signature of the drawn curve, so that a change of its shape can be seen from outside.
    let sum = 0;
    positions.forEach((p, i) => { sum += (i + 1) * (p.x * 3 + p.y * 5 + p.z * 7); });
    this.container.dataset.curveSignature = sum.toPrecision(12);
    this.updateColorBar(scale, mode);
    if (!this.fitted) this.fit(positions);
    this.render();
  }

  // One line per segment (the profile points of that segment and the next one's first, so
  // that the lines meet), styled by its kind (SEGMENT_STYLES); a segment without points is
  // not drawn.
  addSegments(points, positions, colors, kinds) {
    let first = 0;
    while (first < points.length) {
      const segment = points[first].segment ?? 0;
      let end = first;
      while (end < points.length && (points[end].segment ?? 0) === segment) ++end;
      const last = Math.min(end, points.length - 1);
      const style = SEGMENT_STYLES[kinds[segment]] || SEGMENT_STYLES.SEGMENT_KIND_BLEND;
      const run = positions.slice(first, last + 1);
      if (run.length >= 2) {
        let length = 0;
        for (let k = 1; k < run.length; ++k) length += run[k].distanceTo(run[k - 1]);
        const dash = style.dashed
          ? { dashSize: Math.min(0.01, Math.max(0.001, length / 9)), gapSize: Math.min(0.006, Math.max(0.0007, length / 14)) }
          : false;
        const line = this.makeLine(run, style.color === null ? colors.slice(3 * first, 3 * (last + 1)) : null,
          style.width, dash);
        if (style.color !== null) line.material.color.set(style.color);
        line.userData.kind = style.key;
        line.userData.segment = segment;
        this.curve.add(line);
      }
      first = end;
    }
  }

  // The legend of a path of pieces' segments (drawn: the kind of each line drawn, in order;
  // null: a key-frame path, no legend). The counts are on the view too (data-drawn-*), with
  // the kinds in order (data-segment-kinds).
  setSegmentLegend(drawn) {
    const legend = this.segmentLegend;
    const data = this.container.dataset;
    if (!drawn) {
      if (legend) legend.hidden = true;
      delete data.segmentKinds;
      for (const style of Object.values(SEGMENT_STYLES)) delete data[`drawn${capitalised(style.key)}s`];
      return;
    }
    data.segmentKinds = drawn.join(',');
    for (const style of Object.values(SEGMENT_STYLES)) {
      const count = drawn.filter((kind) => kind === style.key).length;
      data[`drawn${capitalised(style.key)}s`] = String(count);
      const item = legend?.querySelector(`[data-kind="${style.key}"]`);
      if (item) {
        item.querySelector('.count').textContent = String(count);
        item.classList.toggle('none', count === 0);
      }
    }
    if (legend) legend.hidden = false;
  }

  // element: where setSegmentLegend writes (an item per kind: a swatch, its label, its count).
  attachSegmentLegend(element) {
    this.segmentLegend = element;
    element.replaceChildren();
    for (const style of Object.values(SEGMENT_STYLES)) {
      const item = document.createElement('div');
      item.dataset.kind = style.key;
      item.setAttribute('data-testid', `legend-segment-${style.key}`);
      item.title = style.title;
      const swatch = document.createElement('span');
      swatch.className = `segment ${style.key}`;
      const text = document.createElement('span');
      text.textContent = `${style.label} ×`;
      const count = document.createElement('span');
      count.className = 'count';
      count.textContent = '0';
      item.append(swatch, text, count);
      element.append(item);
    }
    element.hidden = true;
  }

  // speedAtS: the tool speed lookup for the 'speed' mode (null: none streamed yet).
  setColorMode(mode, speedAtS) {
    this.colorMode = mode;
    if (this.lastCurve) {
      this.setCurve(this.lastCurve.points, speedAtS ?? this.lastCurve.speedAtS, this.lastCurve.segmentKinds,
        this.lastCurve.toolPath);
    }
  }

  updateColorBar(scale, mode) {
    const bar = this.colorBar;
    bar.replaceChildren();
    if (!scale) return;
    const info = COLOR_MODES[mode];
    const title = document.createElement('div');
    title.className = 'title';
    title.textContent = `${info.label} [${info.unit}]`;
    const canvas = document.createElement('canvas');
    canvas.width = 200;
    canvas.height = 12;
    const ctx = canvas.getContext('2d');
    for (let x = 0; x < canvas.width; ++x) {
      ctx.fillStyle = scale.css(x / (canvas.width - 1));
      ctx.fillRect(x, 0, 1, canvas.height);
    }
    const ticks = document.createElement('div');
    ticks.className = 'ticks';
    for (const t of [0, 0.25, 0.5, 0.75, 1]) {
      const span = document.createElement('span');
      const value = scale.lo + (scale.hi - scale.lo) * t;
      span.textContent = formatTick(Math.abs(value) < 1e-9 * (scale.hi - scale.lo) ? 0 : value);
      if (scale.clipped && t === 1) span.textContent = `≥ ${span.textContent}`;
      if (scale.clipped && scale.diverging && t === 0) span.textContent = `≤ ${span.textContent}`;
      ticks.append(span);
    }
    bar.append(title, canvas, ticks);
    bar.dataset.mode = mode;
  }

  // frames: the request's key frames (positions and the operator's T, N, B);
  // warnings: PlanResponse.warnings placed on the profile by u; labels: each frame's tag
  // (default: its index).
  // fields: each frame's field path in the request (path.frames[i], path.start, ...), for
  // dragging it (none: not draggable).
  setFrames(frames, warnings, profilePoints, scaleHint, labels = null, fields = null) {
    disposeGroup(this.frames);
    disposeGroup(this.marks);
    this.pickables = [];
    // Arrows a tenth of the path's size, within 4 to 15 cm.
    const length = Math.min(0.15, Math.max(0.04, (scaleHint || 0.5) * 0.1));
    frames.forEach((frame, i) => {
      const p = v3(frame.position);
      const t = v3(frame.tangent).normalize();
      const dirs = [['T', t]];
      if (frame.normal) {
        const n = v3(frame.normal).normalize();
        dirs.push(['N', n]);
        const b = frame.binormal ? v3(frame.binormal).normalize() : t.clone().cross(n).normalize();
        dirs.push(['B', b]);
      }
      if (this.showFrames) {
        for (const [name, d] of dirs) {
          if (d.lengthSq() < 1e-12) continue;
          this.frames.add(new THREE.ArrowHelper(d, p, length, FRAME_COLORS[name], length * 0.25, length * 0.12));
        }
      }
      const tag = label(labels?.[i] ?? `${i}`, 'frame');
      tag.position.copy(p);
      tag.center.set(-0.3, 1.2);
      this.frames.add(tag);
      const dot = new THREE.Mesh(new THREE.SphereGeometry(length * 0.08, 12, 8),
        new THREE.MeshStandardMaterial({ color: 0x222222 }));
      dot.position.copy(p);
      this.frames.add(dot);
      if (fields?.[i]) {
        // What the mouse picks: a ball about the dot, larger than it, not drawn.
        const handle = new THREE.Mesh(new THREE.SphereGeometry(length * 0.3, 10, 8),
          new THREE.MeshBasicMaterial({ visible: false }));
        handle.position.copy(p);
        handle.userData = { field: fields[i], followers: [dot, tag] };
        this.frames.add(handle);
        this.pickables.push(handle);
      }
      if (frame.cusp) this.addMark(p, 0xc2185b, 'cusp', length, 'cusp');
      if (frame.inflection) this.addMark(p, 0xef6c00, 'inflection', length, 'inflection');
      if (frame.stop) this.addMark(p, 0x555555, 'stop', length, 'stop');
    });
    (warnings || []).forEach((w, k) => {
      const at = pointAtU(profilePoints, w.u ?? 0);
      if (!at) return;
      this.addMark(v3(at.position), 0xd32f2f, `⚠ ${k + 1}`, length, 'warning');
    });
    this.container.dataset.frames = String(frames.length);
    this.render();
  }

  addMark(p, color, text, length, kind) {
    const geometry = kind === 'warning' ? new THREE.TetrahedronGeometry(length * 0.22)
      : new THREE.OctahedronGeometry(length * 0.2);
    const mesh = new THREE.Mesh(geometry, new THREE.MeshStandardMaterial({ color, transparent: true, opacity: 0.85 }));
    mesh.position.copy(p);
    this.marks.add(mesh);
    const tag = label(text, `mark ${kind}`);
    tag.position.copy(p);
    tag.center.set(0.5, -0.6);
    this.marks.add(tag);
  }

  // curves: [{points: PathPoint[], color: css colour, width: px (default 2), dashed}];
  // frame: optional, a frame drawn with the family ({position, axes: [['T', {x, y, z}], ...],
  // length [m]}: the key frame of a local family, its T, N, B). data-family-curves: the
  // polylines drawn.
  setFamily(curves, frame = null) {
    disposeGroup(this.family);
    let drawn = 0;
    for (const c of curves) {
      if (!c.points || c.points.length < 2) continue;
      const line = this.makeLine(c.points.map((p) => v3(p.position)), null, c.width ?? 2,
        c.dashed ? { dashSize: 0.006, gapSize: 0.004 } : false);
      line.material.color.set(c.color);
      this.family.add(line);
      ++drawn;
    }
    this.container.dataset.familyFrame = (frame?.axes || []).map(([name]) => name).join(',');
    if (frame) {
      const p = v3(frame.position);
      const length = frame.length ?? 0.05;
      for (const [name, d] of frame.axes || []) {
        const dir = v3(d).normalize();
        if (dir.lengthSq() < 1e-12) continue;
        this.family.add(new THREE.ArrowHelper(dir, p, length, FRAME_COLORS[name], length * 0.25, length * 0.12));
      }
    }
    this.container.dataset.familyCurves = String(drawn);
    this.render();
  }

  // The waypoints of a joint path: [{position: the tool there (forward kinematics of the
  // waypoint), passed: the tool where the motion passes nearest the waypoint (or null), label,
  // stop}], or null. Each drawn as a dot in a translucent ball about the tool's position,
  // tagged, with a thin line to where the motion passes; the tags follow showFrames.
  // data-waypoints: the count drawn.
  setWaypoints(waypoints) {
    disposeGroup(this.waypoints);
    this.lastWaypoints = waypoints;
    const list = waypoints || [];
    const positions = list.map((w) => v3(w.position));
    const size = Math.min(0.03, Math.max(0.012, extentOf(positions) * 0.03));
    const ball = new THREE.SphereGeometry(size, 20, 14);
    const dot = new THREE.SphereGeometry(size * 0.22, 12, 8);
    list.forEach((w, i) => {
      const p = positions[i];
      const color = w.stop ? 0x555555 : 0x6a1b9a;
      const shell = new THREE.Mesh(ball, new THREE.MeshStandardMaterial({ color, transparent: true, opacity: 0.25,
        depthWrite: false }));
      shell.position.copy(p);
      const centre = new THREE.Mesh(dot, new THREE.MeshStandardMaterial({ color }));
      centre.position.copy(p);
      this.waypoints.add(shell, centre);
      if (w.passed) {
        const q = v3(w.passed);
        if (q.distanceTo(p) > 1e-6) {
          this.waypoints.add(new THREE.Line(new THREE.BufferGeometry().setFromPoints([p, q]),
            new THREE.LineBasicMaterial({ color })));
        }
      }
      if (this.showFrames) {
        const tag = label(w.label ?? `${i}`, `waypoint${w.stop ? ' stop' : ''}`);
        tag.position.copy(p);
        tag.center.set(-0.3, 1.2);
        this.waypoints.add(tag);
      }
    });
    this.container.dataset.waypoints = String(list.length);
    this.render();
  }

  // points: joint axis origins (base first) then the tool position, in W [m].
  setRobot(points) {
    if (!points) {
      disposeGroup(this.robot);
      this.robotParts = null;
      this.container.dataset.robotLinks = '0';
      this.render();
      return;
    }
    const links = points.length - 1;
    if (!this.robotParts || this.robotParts.links.length !== links) {
      disposeGroup(this.robot);
      const linkMaterial = new THREE.MeshStandardMaterial({ color: 0xf0a030, transparent: true, opacity: 0.8 });
      const jointMaterial = new THREE.MeshStandardMaterial({ color: 0x37474f });
      const toolMaterial = new THREE.MeshStandardMaterial({ color: 0xd32f2f });
      const cylinder = new THREE.CylinderGeometry(0.025, 0.025, 1, 16);
      const sphere = new THREE.SphereGeometry(0.035, 16, 12);
      this.robotParts = { links: [], joints: [] };
      for (let i = 0; i < links; ++i) {
        const mesh = new THREE.Mesh(cylinder, linkMaterial);
        this.robotParts.links.push(mesh);
        this.robot.add(mesh);
      }
      for (let i = 0; i < points.length; ++i) {
        const mesh = new THREE.Mesh(i === points.length - 1 ? new THREE.SphereGeometry(0.02, 12, 8) : sphere,
          i === points.length - 1 ? toolMaterial : jointMaterial);
        this.robotParts.joints.push(mesh);
        this.robot.add(mesh);
      }
    }
    this.container.dataset.robotLinks = String(links);
    const up = new THREE.Vector3(0, 1, 0);
    points.forEach((p, i) => this.robotParts.joints[i].position.copy(p));
    for (let i = 0; i < links; ++i) {
      const a = points[i];
      const b = points[i + 1];
      const mesh = this.robotParts.links[i];
      const d = b.clone().sub(a);
      const len = d.length();
      mesh.visible = len > 1e-6;
      if (!mesh.visible) continue;
      mesh.position.copy(a).addScaledVector(d, 0.5);
      mesh.quaternion.setFromUnitVectors(up, d.divideScalar(len));
      mesh.scale.set(1, len, 1);
    }
    this.render();
  }

  // The tool's position during a replay without a robot.
  setToolMarker(p) {
    if (!this.toolMarker) {
      this.toolMarker = new THREE.Mesh(new THREE.SphereGeometry(0.012, 16, 12),
        new THREE.MeshStandardMaterial({ color: 0xd32f2f }));
      this.scene.add(this.toolMarker);
    }
    this.toolMarker.visible = Boolean(p);
    this.toolMarker.scale.setScalar(this.markerScale ?? 1);
    if (p) this.toolMarker.position.copy(p);
    this.render();
  }

  // The motion in view: the camera, looking from where it looks now (from the front right
  // and above the first time), at the distance where the bounding box of `positions` (the
  // curve or the tool's path, and the arm over the motion when it is shown) fills the
  // canvas; the origin counts only when it is among them.
  fit(positions) {
    this.gridAround(positions);
    const box = new THREE.Box3().setFromPoints(positions);
    const center = box.getCenter(new THREE.Vector3());
    // The tool's ball (12 mm about a metre of motion) in proportion to what is framed.
    this.markerScale = Math.min(1, Math.max(0.1, box.getSize(new THREE.Vector3()).length()));
    this.toolMarker?.scale.setScalar(this.markerScale);
    const dir = this.fitted ? this.camera.position.clone().sub(this.controls.target) : new THREE.Vector3(1, -1.3, 0.9);
    if (dir.lengthSq() < 1e-18) dir.set(1, -1.3, 0.9);
    dir.normalize();
    // The points across the view's axes: the centre of their extent, and the distance at
    // which the widest of them fits the horizontal and the vertical field of view, 8 % to
    // spare, and the arm's girth (4 cm) beyond its axes when it is among them.
    const pad = this.fitExtra.length ? 0.04 : 0;
    const forward = dir.clone().negate();
    const right = new THREE.Vector3().crossVectors(forward, this.camera.up).normalize();
    if (right.lengthSq() < 1e-12) right.set(1, 0, 0);
    const up = new THREE.Vector3().crossVectors(right, forward).normalize();
    const tanV = Math.tan(THREE.MathUtils.degToRad(this.camera.fov) / 2);
    const tanH = tanV * this.camera.aspect;
    const across = positions.map((p) => {
      const d = new THREE.Vector3(p.x, p.y, p.z).sub(center);
      return [d.dot(right), d.dot(up), d.dot(forward)];
    });
    const mid = (k) => (Math.min(...across.map((a) => a[k])) + Math.max(...across.map((a) => a[k]))) / 2;
    const [ma, mb] = [mid(0), mid(1)];
    center.addScaledVector(right, ma).addScaledVector(up, mb);
    let distance = 0.05;
    for (const [a, b, depth] of across) {
      distance = Math.max(distance, ((Math.abs(a - ma) + pad) * 1.08) / tanH - depth,
        ((Math.abs(b - mb) + pad) * 1.08) / tanV - depth);
    }
    this.controls.target.copy(center);
    this.camera.position.copy(center).addScaledVector(dir, distance);
    this.camera.near = Math.max(1e-4, distance / 1000);
    this.camera.far = Math.max(100, distance * 20);
    this.camera.updateProjectionMatrix();
    this.controls.update();
    this.fitted = true;
    this.render();
  }

  // A thin grey line of the whole motion's tool path ({position} points: a path's approach
  // move with the path), or null.
  setTrace(points) {
    disposeGroup(this.trace);
    if (points?.length >= 2) {
      const line = this.makeLine(points.map((p) => v3(p.position)), null, 2, { dashSize: 0.01, gapSize: 0.006 });
      line.material.color.set(0x607d8b);
      this.trace.add(line);
    }
    this.container.dataset.tracePoints = String(points?.length || 0);
    this.render();
  }

  // Where the steps of a motion end: [{position, label}] (a small square dot and its label),
  // or null. data-step-marks: the count drawn.
  setStepMarks(marks) {
    disposeGroup(this.stepMarks);
    const list = marks || [];
    const size = Math.min(0.012, Math.max(0.004, extentOf(list.map((m) => v3(m.position))) * 0.015));
    for (const m of list) {
      const p = v3(m.position);
      const box = new THREE.Mesh(new THREE.BoxGeometry(size, size, size), new THREE.MeshStandardMaterial({ color: 0x37474f }));
      box.position.copy(p);
      this.stepMarks.add(box);
      if (this.showFrames) {
        const tag = label(m.label, 'step');
        tag.position.copy(p);
        tag.center.set(-0.1, -0.4);
        this.stepMarks.add(tag);
      }
    }
    this.container.dataset.stepMarks = String(list.length);
    this.render();
  }

  // The camera towards `center` ({x, y, z}) from where it looks now, at the distance where a
  // sphere of `radius` [m] about it fills the view (the curve as a whole again: refit()).
  focus(center, radius) {
    const c = v3(center);
    const dir = this.camera.position.clone().sub(this.controls.target);
    if (dir.lengthSq() < 1e-18) dir.set(1, -1.3, 0.9);
    dir.normalize();
    const fov = THREE.MathUtils.degToRad(this.camera.fov);
    this.controls.target.copy(c);
    this.camera.position.copy(c).addScaledVector(dir, (Math.max(0.01, radius) / Math.sin(fov / 2)) * 1.05);
    this.controls.update();
    this.render();
  }

  refit() {
    if (this.lastCurve?.points?.length) this.fit([...this.lastCurve.points.map((p) => v3(p.position)), ...this.fitExtra.map(v3)]);
    this.render();
  }
}

// The diagonal of the box about positions [m] (0.5 without any).
function extentOf(positions) {
  if (!positions.length) return 0.5;
  return new THREE.Box3().setFromPoints(positions).getSize(new THREE.Vector3()).length();
}

// The profile point nearest global parameter u.
export function pointAtU(points, u) {
  if (!points || !points.length) return null;
  let best = points[0];
  for (const p of points) if (Math.abs((p.u ?? 0) - u) < Math.abs((best.u ?? 0) - u)) best = p;
  return best;
}

const capitalised = (word) => word.charAt(0).toUpperCase() + word.slice(1);

export function formatTick(value) {
  if (value === 0) return '0';
  const a = Math.abs(value);
  if (a >= 1e4 || a < 1e-3) return value.toExponential(1);
  if (a >= 100) return value.toFixed(0);
  if (a >= 10) return value.toFixed(1);
  return value.toPrecision(3).replace(/\.?0+$/, '');
}
