#!/usr/bin/env python3
"""geotraj's figures, drawn with matplotlib: paths, their geometry, speeds, joints and limits.

Importable (scripts/plot_paths.py, motion_demo.py, robot_demo.py and plot_live.py draw with
it) and runnable: `geotraj plot` runs

  geotraj_plot.py request --request REQUEST.json --plan PLAN.json --out DIR [--name STEM]
                  [--profile PROFILE.json ...] [--samples SAMPLES.csv] [--robot MODEL.json] [--png]

  REQUEST.json  the PlanRequest (proto JSON) that was planned
  PLAN.json     its PlanResponse (`geotraj --json plan`)
  PROFILE.json  the PathProfile of each of its paths (`geotraj --json analyze`), in order
  SAMPLES.csv   its samples as `geotraj stream` prints them
  MODEL.json    the robot's RobotModel (proto JSON, as `geotraj --json robots` lists them),
                before the request's jointLimits, velocityScale and accelerationScale

and draws into DIR the figures that apply: STEM_path.svg and STEM_geometry.svg always,
STEM_speed.svg with samples, STEM_joints.svg with joint samples and a model,
STEM_binding.svg when the plan reports which limit binds (a time-optimal timing). It prints
one line per file written.

Figures are SVG (PNG beside them with --png), drawn by the Agg backend, reproducible: the
SVG ids come from a fixed salt and the files carry no date. Units are SI and every axis
says its unit. Elements that a reader (or a test) looks for carry an SVG id (a matplotlib
gid): `keyframe-<view>-<i>` for key frame i in each view, `limit-<q|qd|qdd>-j<j>-<min|max>`
for joint j's limits, `limit-<q|qd|qdd>-usage-<min|max>` for the 0 / 100 % lines,
`peak-<q|qd|qdd>` for the worst joint written out, `limit-speed`, `limit-acceleration`,
`binding-<k>` for binding stretch k, `warning-<view>-<k>` for plan warning k.

Needs Debian's python3-matplotlib (and python3-numpy, which it brings).
"""
import argparse
import csv
import json
import os
import sys
import textwrap

MISSING = ("matplotlib is missing: install Debian's python3-matplotlib "
           "(apt-get install -y python3-matplotlib) and run with /usr/bin/python3")
try:
    import matplotlib
    import numpy as np
except ImportError:  # the one dependency beyond the standard library
    sys.stderr.write(f"geotraj_plot: {MISSING}\n")
    sys.exit(3)

matplotlib.use("Agg")  # no display: files only
from matplotlib.figure import Figure  # noqa: E402  (after the backend is chosen)
from matplotlib.ticker import MaxNLocator, ScalarFormatter  # noqa: E402
import mpl_toolkits.mplot3d  # noqa: E402,F401  (registers the "3d" projection)

# Reproducible output: SVG ids from a fixed salt, text kept as text (searchable, small).
STYLE = {
    "svg.hashsalt": "geotraj",
    "svg.fonttype": "none",
    "font.family": "DejaVu Sans",
    "font.size": 9,
    "axes.titlesize": 10,
    "axes.labelsize": 9,
    "legend.fontsize": 8,
    "axes.grid": True,
    "grid.color": "#e6e6e6",
    "grid.linewidth": 0.6,
    "axes.formatter.useoffset": False,
    "axes.formatter.limits": (-4, 5),
    "figure.dpi": 100,
    "savefig.dpi": 100,
    "path.simplify": True,
    "lines.linewidth": 1.3,
}
matplotlib.rcParams.update(STYLE)

COLOURS = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2", "#7f7f7f",
           "#bcbd22", "#17becf"]
LIMIT_RED = "#c00000"
CUSP_COLOUR = "#ff7f0e"
INFLECTION_COLOUR = "#2ca02c"
WARNING_COLOUR = "#d62728"
DECIMATE_BUCKETS = 1200  # min/max buckets per curve: peaks kept, files small


# --- output -------------------------------------------------------------------------------

def new_figure(width, height):
    """A figure [in] laid out by the constrained layout (labels and legends never clipped)."""
    return Figure(figsize=(width, height), layout="constrained")


def save(fig, path, png=False):
    """Writes `fig` as SVG (and PNG beside it with `png`) without a date; returns the files."""
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    fig.savefig(path, format="svg", metadata={"Date": None})
    files = [path]
    if png:
        png_path = os.path.splitext(path)[0] + ".png"
        fig.savefig(png_path, format="png", metadata={"Software": None})
        files.append(png_path)
    return files


def nice_axis(ax, x=True, y=True, nbins=7):
    """Ticks at 1, 2, 2.5 or 5 times a power of ten, without an offset."""
    for on, axis in ((x, ax.xaxis), (y, ax.yaxis)):
        if on:
            axis.set_major_locator(MaxNLocator(nbins=nbins, steps=[1, 2, 2.5, 5, 10]))
            fmt = ScalarFormatter(useOffset=False)
            fmt.set_powerlimits((-4, 5))
            axis.set_major_formatter(fmt)


def wrap_notes(lines, width_in):
    """Notes broken into lines that fit a figure `width_in` [in] wide at 8 pt."""
    out = []
    for line in lines:
        out += textwrap.wrap(line, max(40, int(width_in * 15))) or [""]
    return out


def add_notes(fig, gs_cell, lines):
    """Lines of text (wrap_notes) in their own strip of the layout (warnings, what was left
    out); the text never squeezes the panels."""
    ax = fig.add_subplot(gs_cell)
    ax.axis("off")
    text = ax.text(0.0, 1.0, "\n".join(lines), va="top", ha="left", fontsize=8, transform=ax.transAxes)
    text.set_in_layout(False)
    return ax


# --- data helpers -------------------------------------------------------------------------

def vec(d, name):
    v = (d or {}).get(name) or {}
    return np.array([float(v.get("x", 0.0)), float(v.get("y", 0.0)), float(v.get("z", 0.0))])


def opt(d, name):
    """An optional number of proto JSON: NaN when absent."""
    v = (d or {}).get(name)
    return float("nan") if v is None else float(v)


def decimate(x, y, buckets=DECIMATE_BUCKETS):
    """The first and last point and, per bucket of samples, its minimum and maximum in order:
    the peaks survive, the drawing stays small. NaN (gaps) kept as gaps."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    n = len(x)
    if n <= 2 * buckets or np.isnan(y).any():
        return x, y
    edges = np.linspace(0, n, buckets + 1).astype(int)
    keep = {0, n - 1}
    for lo, hi in zip(edges[:-1], edges[1:]):
        if hi > lo:
            seg = y[lo:hi]
            keep.add(lo + int(np.argmin(seg)))
            keep.add(lo + int(np.argmax(seg)))
    idx = np.array(sorted(keep))
    return x[idx], y[idx]


def robust_limits(values, spread=20.0):
    """(lo, hi, clipped): the view of `values` (NaN ignored, 0 included); a few spikes far
    beyond the bulk (more than `spread` times its 99th percentile) are left off-scale."""
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return -1.0, 1.0, False
    lo, hi = min(0.0, float(v.min())), max(0.0, float(v.max()))
    bulk = float(np.percentile(np.abs(v), 99))
    clipped = False
    if bulk > 0 and max(abs(lo), abs(hi)) > spread * bulk:
        lo, hi = max(lo, -3 * bulk), min(hi, 3 * bulk)
        clipped = True
    if hi - lo < 1e-12:
        lo, hi = lo - 1.0, hi + 1.0
    pad = 0.06 * (hi - lo)
    return lo - pad, hi + pad, clipped


def frame_label(i, frame):
    marks = [name for name in ("cusp", "inflection", "stop") if frame.get(name)]
    return f"{i}" + (f" ({', '.join(marks)})" if marks else "")


def path_frames(request):
    """The key frames of the request's paths: [(label prefix, frames)], one per path."""
    if request.get("sequence"):
        return [(f"sequence[{i}].", step["path"].get("frames", [])) for i, step in enumerate(request["sequence"])
                if step.get("path")]
    if request.get("path"):
        return [("", request["path"].get("frames", []))]
    return []


# --- profile (AnalyzePath) ------------------------------------------------------------------

class Profile:
    """A PathProfile as arrays: u, s [m], positions [m], T, N, kappa [1/m], tau [1/m],
    kappa_ds, tau_ds [1/m^2] (NaN where undefined)."""

    def __init__(self, profile):
        pts = profile.get("points", [])
        self.u = np.array([float(p.get("u", 0.0)) for p in pts])
        self.s = np.array([float(p.get("s", 0.0)) for p in pts])
        self.p = np.array([vec(p, "position") for p in pts]).reshape(-1, 3)
        self.T = np.array([vec(p, "tangent") for p in pts]).reshape(-1, 3)
        self.N = np.array([vec(p, "normal") for p in pts]).reshape(-1, 3)
        self.kappa = np.array([opt(p, "curvature") for p in pts])
        self.tau = np.array([opt(p, "torsion") for p in pts])
        self.kappa_ds = np.array([opt(p, "curvatureDerivative") for p in pts])
        self.tau_ds = np.array([opt(p, "torsionDerivative") for p in pts])
        self.length = float(profile.get("arcLength", self.s[-1] if len(self.s) else 0.0))

    @classmethod
    def from_samples(cls, samples):
        """The geometry of the tool's track from streamed samples: s by the chords between
        samples [m], kappa = |v x a| / |v|^3, tau = (v x a) . j / |v x a|^2 with the jerk j by
        central differences of a over t, d/ds of both by differences; u is the sample index.
        Undefined (NaN) where |v| is below 1e-9 of its peak (the tool at rest)."""
        prof = cls({"points": []})
        t = samples["t"]
        p = np.stack([samples["x"], samples["y"], samples["z"]], axis=1)
        v = np.stack([samples["vx"], samples["vy"], samples["vz"]], axis=1)
        a = np.stack([samples["ax"], samples["ay"], samples["az"]], axis=1)
        j = np.gradient(a, t, axis=0)
        speed = np.linalg.norm(v, axis=1)
        moving = speed > 1e-9 * max(float(speed.max()), 1e-300)
        c = np.cross(v, a)
        c2 = np.einsum("ij,ij->i", c, c)
        with np.errstate(divide="ignore", invalid="ignore"):
            kappa = np.where(moving, np.sqrt(c2) / speed ** 3, np.nan)
            bent = moving & (c2 > 1e-18 * max(float(c2.max()), 1e-300))
            tau = np.where(bent, np.einsum("ij,ij->i", c, j) / c2, np.nan)
            T = np.where(moving[:, None], v / speed[:, None], 0.0)
            B = np.where(bent[:, None], c / np.sqrt(c2)[:, None], 0.0)
        prof.s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])
        prof.u = np.arange(len(t), dtype=float)
        prof.p, prof.T, prof.N = p, T, np.cross(B, T)
        prof.kappa, prof.tau = kappa, tau
        ds = np.gradient(prof.s)
        with np.errstate(divide="ignore", invalid="ignore"):
            prof.kappa_ds = np.where(ds > 0, np.gradient(kappa) / ds, np.nan)
            prof.tau_ds = np.where(ds > 0, np.gradient(tau) / ds, np.nan)
        prof.length = float(prof.s[-1])
        return prof

    def s_at_u(self, u):
        return float(np.interp(u, self.u, self.s))

    def point_at_s(self, s):
        return np.array([np.interp(s, self.s, self.p[:, k]) for k in range(3)])

    def flips(self, frames):
        """Where the curve itself has a cusp (the tangent turns back between two points) or an
        inflection (the normal turns over while the tangent goes on), away from key frames
        that ask for one: [(kind, s)]."""
        out = []
        marked = {i for i, f in enumerate(frames) if f.get("cusp") or f.get("inflection")}
        for k in range(len(self.u) - 1):
            lo, hi = self.u[k], self.u[k + 1]
            if any(lo <= i <= hi for i in marked):
                continue
            t_dot = float(self.T[k] @ self.T[k + 1])
            n_dot = float(self.N[k] @ self.N[k + 1])
            defined = np.linalg.norm(self.N[k]) > 0.5 and np.linalg.norm(self.N[k + 1]) > 0.5
            if t_dot < 0.0:
                out.append(("cusp", 0.5 * (self.s[k] + self.s[k + 1])))
            elif defined and n_dot < -0.5:
                out.append(("inflection", 0.5 * (self.s[k] + self.s[k + 1])))
        return out


# --- path views ---------------------------------------------------------------------------

VIEWS = [("3d", "3-D view", None), ("top", "top view (x-y)", (0, 1)), ("side", "side view (x-z)", (0, 2))]
AXIS_NAMES = ["x [m]", "y [m]", "z [m]"]


def _equal_3d(ax, pts):
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre, half = (lo + hi) / 2, max(float((hi - lo).max()) / 2, 1e-6) * 1.05
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_box_aspect((1, 1, 1))


def path_figure(paths, frames, title, warnings=(), notes=(), views=("3d", "top", "side")):
    """The path in 3-D and in top and side views, coordinates in metres, equal aspect.

    paths: [{"label", "points": (n, 3) [m], optional "profile": Profile}]; the first one's
    profile places the warnings and the curve's own cusps and inflections.
    frames: the key frames (request JSON) to mark, numbered from 0 as in the request, with
    their tangents; cusps, inflections and stops marked apart.
    warnings: [{"s" [m], "message", "segment"}] (PlanResponse.warnings).
    """
    chosen = [v for v in VIEWS if v[0] in views]
    frame_pts = np.array([vec(f, "position") for f in frames]).reshape(-1, 3)
    all_pts = np.vstack([p["points"] for p in paths if len(p["points"])] + ([frame_pts] if len(frame_pts) else []))
    span = max(float(np.ptp(all_pts, axis=0).max()), 1e-6)
    profile = next((p["profile"] for p in paths if p.get("profile") is not None), None)
    flips = profile.flips(frames) if profile is not None else []
    warn_pts = [(k, w, profile.point_at_s(w.get("s", 0.0))) for k, w in enumerate(warnings)] if profile else []

    note_lines = list(notes)
    for k, w in enumerate(warnings):
        note_lines.append(f"warning {k} (segment {w.get('segment', 0)}, s = {w.get('s', 0.0):.3f} m): "
                          f"{w.get('message', w.get('code', ''))}")
    note_lines = wrap_notes(note_lines, 5.0 * len(chosen))
    n_notes = len(note_lines)
    fig = new_figure(5.0 * len(chosen), 5.4 + 0.17 * n_notes)
    gs = fig.add_gridspec(2, len(chosen), height_ratios=[5.0, 0.25 + 0.17 * n_notes])
    fig.suptitle(title)
    handles = {}
    for col, (view, view_title, axes) in enumerate(chosen):
        if view == "3d":
            ax = fig.add_subplot(gs[0, col], projection="3d")
        else:
            ax = fig.add_subplot(gs[0, col])
        ax.set_title(view_title)

        def xy(p, axes=axes):
            p = np.atleast_2d(p)
            return [p[:, k] for k in ((0, 1, 2) if axes is None else axes)]

        for i, path in enumerate(paths):
            colour = path.get("colour", COLOURS[i % len(COLOURS)])
            line, = ax.plot(*xy(path["points"]), color=colour, lw=1.5, label=path["label"])
            handles.setdefault(path["label"], line)
        for i, f in enumerate(frames):
            p = frame_pts[i]
            kind = "cusp" if f.get("cusp") else "inflection" if f.get("inflection") else "stop" if f.get("stop") else ""
            style = {"cusp": ("D", CUSP_COLOUR), "inflection": ("^", INFLECTION_COLOUR), "stop": ("s", "#444444"),
                     "": ("o", "black")}[kind]
            m, = ax.plot(*xy(p), marker=style[0], color=style[1], ms=7, ls="none", gid=f"keyframe-{view}-{i}",
                         label=f"key frame{' (' + kind + ')' if kind else ''}", zorder=5)
            handles.setdefault(m.get_label(), m)
            tip = p + 0.07 * span * vec(f, "tangent")
            ax.plot(*xy(np.vstack([p, tip])), color=style[1], lw=1.0, zorder=4)
            if axes is None:
                ax.text(*(p + 0.02 * span), frame_label(i, f), fontsize=8)
            else:
                ax.annotate(frame_label(i, f), xy=(p[axes[0]], p[axes[1]]), xytext=(5, 5),
                            textcoords="offset points", fontsize=8)
        for kind, s in flips:
            q = profile.point_at_s(s)
            m, = ax.plot(*xy(q), marker="D" if kind == "cusp" else "^", mfc="none", ls="none", ms=8,
                         mec=CUSP_COLOUR if kind == "cusp" else INFLECTION_COLOUR,
                         label=f"{kind} of the curve (no key frame asked)")
            handles.setdefault(m.get_label(), m)
        for k, w, q in warn_pts:
            m, = ax.plot(*xy(q), marker="X", color=WARNING_COLOUR, ms=9, ls="none", gid=f"warning-{view}-{k}",
                         label="plan warning", zorder=6)
            handles.setdefault(m.get_label(), m)
            if axes is not None:
                ax.annotate(f"warning {k}", xy=(q[axes[0]], q[axes[1]]), xytext=(6, -12),
                            textcoords="offset points", fontsize=8, color=WARNING_COLOUR)
        if axes is None:
            _equal_3d(ax, all_pts)
            ax.set_xlabel(AXIS_NAMES[0])
            ax.set_ylabel(AXIS_NAMES[1])
            ax.set_zlabel(AXIS_NAMES[2])
            for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
                axis.set_major_locator(MaxNLocator(nbins=5, steps=[1, 2, 2.5, 5, 10]))
        else:
            ax.set_xlabel(AXIS_NAMES[axes[0]])
            ax.set_ylabel(AXIS_NAMES[axes[1]])
            ax.set_aspect("equal", adjustable="datalim")
            nice_axis(ax)
    legend_ax = add_notes(fig, gs[1, :], note_lines)
    legend_ax.legend(list(handles.values()), list(handles.keys()), loc="upper right", ncol=min(4, len(handles)),
                     frameon=False)
    return fig


# --- curvature and torsion along s ----------------------------------------------------------

GEOMETRY_PANELS = [("kappa", "curvature κ", "κ [1/m]"), ("tau", "torsion τ", "τ [1/m]"),
                   ("kappa_ds", "derivative of curvature dκ/ds", "dκ/ds [1/m²]"),
                   ("tau_ds", "derivative of torsion dτ/ds", "dτ/ds [1/m²]")]


def geometry_figure(profiles, title, frames=(), warnings=(), notes=()):
    """Curvature, torsion and their derivatives per metre of arc against the arc length s.

    profiles: [{"label", "profile": Profile}]; the first one's key frames (u = 0, 1, ...)
    are drawn as vertical lines numbered as in the request, the request's own curvature and
    torsion at each frame (`frames`, both convention-free) as markers on them. Spikes far
    above the rest (torsion where the curvature nearly vanishes) are left off-scale and
    their peak written on the panel."""
    note_lines = wrap_notes(notes, 10.5)
    fig = new_figure(10.5, 9.6 + 0.17 * len(note_lines))
    gs = fig.add_gridspec(5, 1, height_ratios=[1, 1, 1, 1, 0.05 + 0.1 * len(note_lines)])
    fig.suptitle(title)
    first = profiles[0]["profile"] if profiles else None
    frame_s = []
    if first is not None and len(first.u) and frames:
        n_frames = min(int(round(first.u[-1])) + 1, len(frames))
        frame_s = [first.s_at_u(i) for i in range(n_frames)]
    axes = []
    for row, (attr, name, unit) in enumerate(GEOMETRY_PANELS):
        ax = fig.add_subplot(gs[row, 0], sharex=axes[0] if axes else None)
        axes.append(ax)
        ax.set_title(name, loc="left")
        values = []
        for i, entry in enumerate(profiles):
            prof = entry["profile"]
            y = getattr(prof, attr)
            values.append(y)
            ax.plot(prof.s, y, color=entry.get("colour", COLOURS[i % len(COLOURS)]), label=entry["label"])
        lo, hi, clipped = robust_limits(np.concatenate(values) if values else [])
        ax.set_ylim(lo, hi)
        if clipped:
            for entry in profiles:
                prof = entry["profile"]
                y = getattr(prof, attr)
                if np.isfinite(y).any():
                    k = int(np.nanargmax(np.abs(y)))
                    ax.annotate(f"off scale: peak {y[k]:.4g} {unit.split('[')[1][:-1]} at s = {prof.s[k]:.3f} m",
                                xy=(prof.s[k], hi if y[k] > 0 else lo), xytext=(8, -14 if y[k] > 0 else 6),
                                textcoords="offset points", fontsize=8, color=WARNING_COLOUR,
                                arrowprops={"arrowstyle": "->", "color": WARNING_COLOUR})
                    break
        ax.axhline(0.0, color="#999999", lw=0.6)
        for i, s in enumerate(frame_s):
            f = frames[i] if i < len(frames) else {}
            colour = CUSP_COLOUR if f.get("cusp") else INFLECTION_COLOUR if f.get("inflection") else "#555555"
            ax.axvline(s, color=colour, ls=":", lw=1.0, gid=f"keyframe-{attr}-{i}")
            if row == 0:
                ax.annotate(frame_label(i, f), xy=(s, 1.0), xycoords=("data", "axes fraction"), xytext=(2, -10),
                            textcoords="offset points", fontsize=8, color=colour)
            asked = {"kappa": "curvature", "tau": "torsion"}.get(attr)
            if asked and f.get(asked) is not None:
                ax.plot([s], [float(f[asked])], marker="o", mfc="none", mec="black", ms=7, ls="none",
                        label="asked at the key frame" if i == min(k for k, g in enumerate(frames) if g.get(asked)
                                                                    is not None) else None)
        for k, w in enumerate(warnings):
            ax.axvline(w.get("s", 0.0), color=WARNING_COLOUR, lw=1.0, ls="--",
                       label="plan warning" if k == 0 else None)
        ax.set_ylabel(unit)
        nice_axis(ax)
        if row < 3:
            ax.tick_params(labelbottom=False)
        own = {entry["label"] for entry in profiles}
        labels = [h.get_label() for h in ax.get_lines() if not h.get_label().startswith("_")]
        if row == 0 or any(lab not in own for lab in labels):
            ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    axes[-1].set_xlabel("arc length s [m]")
    if note_lines:
        add_notes(fig, gs[4, 0], note_lines)
    return fig


# --- panels over time -----------------------------------------------------------------------

def series_panel(ax, series=(), limits=(), vlines=(), title=None, ylabel=None, xlabel=None, ylim=None, xlim=None,
                 legend=True, spans=()):
    """One panel: series {"x", "y", "label", "colour", "lw", "ls", "gid"}, horizontal limit
    lines {"y", "label", "colour", "gid", "ls"}, vertical marks {"x", "label", "colour"},
    shaded spans {"y0", "y1", "colour", "label"}."""
    if title:
        ax.set_title(title, loc="left")
    for sp in spans:
        ax.axhspan(sp["y0"], sp["y1"], color=sp.get("colour", LIMIT_RED), alpha=sp.get("alpha", 0.08), lw=0,
                   label=sp.get("label"))
    for s in series:
        x, y = decimate(s["x"], s["y"]) if s.get("decimate", True) else (s["x"], s["y"])
        ax.plot(x, y, color=s.get("colour"), lw=s.get("lw", 1.3), ls=s.get("ls", "-"), label=s.get("label"),
                gid=s.get("gid"), drawstyle=s.get("drawstyle", "default"))
    for h in limits:
        ax.axhline(h["y"], color=h.get("colour", LIMIT_RED), ls=h.get("ls", "--"), lw=h.get("lw", 1.1),
                   label=h.get("label"), gid=h.get("gid"))
    for v in vlines:
        ax.axvline(v["x"], color=v.get("colour", "#888888"), ls=v.get("ls", ":"), lw=1.1, label=v.get("label"),
                   gid=v.get("gid"))
        if v.get("text"):
            ax.annotate(v["text"], xy=(v["x"], 1.0), xycoords=("data", "axes fraction"), xytext=(2, -10),
                        textcoords="offset points", fontsize=8, color=v.get("colour", "#888888"))
    if xlim is not None:
        ax.set_xlim(*xlim)
    if ylim is not None:
        ax.set_ylim(*ylim)
    if ylabel:
        ax.set_ylabel(ylabel)
    if xlabel:
        ax.set_xlabel(xlabel)
    nice_axis(ax)
    if legend and any(line.get_label() and not line.get_label().startswith("_") for line in
                      ax.get_lines() + list(ax.patches)):
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)


def stacked_figure(title, panels, notes=(), xlabel="time t [s]", width=10.5, panel_height=2.3, xlim=None):
    """Panels stacked over one x axis (its label on the last); each panel's keywords go to
    series_panel (a panel may give its own xlim); notes under the title."""
    n = len(panels)
    note_lines = wrap_notes(notes, width)
    fig = new_figure(width, panel_height * n + 0.6 + 0.16 * len(note_lines))
    ratios = ([0.05 + 0.12 * len(note_lines)] if note_lines else []) + [1.0] * n
    gs = fig.add_gridspec(len(ratios), 1, height_ratios=ratios)
    fig.suptitle(title)
    offset = 0
    if note_lines:
        add_notes(fig, gs[0, 0], note_lines)
        offset = 1
    axes = []
    for i, panel in enumerate(panels):
        own_x = panel.get("xlim") is not None
        share = axes[0] if axes and not own_x else None
        ax = fig.add_subplot(gs[offset + i, 0], sharex=share)
        kwargs = dict(panel)
        if kwargs.get("xlim") is None:
            kwargs["xlim"] = xlim
        kwargs["xlabel"] = panel.get("xlabel", xlabel if (i == n - 1 or own_x) else None)
        series_panel(ax, **kwargs)
        axes.append(ax)
    return fig, axes


# --- speed ----------------------------------------------------------------------------------

def speed_figure(title, reference, measured, rests=(), notes=(), max_speed=None, duration=None):
    """Speed against its profile, and the difference. reference: (label, t, v) of the profile
    [s, m/s]; measured: [(label, t, v, colour, ls)] with NaN where a period is left out."""
    label, t_ref, v_ref = reference
    t_ref, v_ref = np.asarray(t_ref, float), np.asarray(v_ref, float)
    speed = [{"x": t_ref, "y": v_ref, "label": label, "colour": "black", "lw": 2.6}]
    error = []
    for name, t, v, colour, ls in measured:
        t, v = np.asarray(t, float), np.asarray(v, float)
        speed.append({"x": t, "y": v, "label": name, "colour": colour, "ls": ls, "lw": 1.3})
        error.append({"x": t, "y": v - np.interp(t, t_ref, v_ref), "label": name, "colour": colour, "lw": 1.2})
    limits = [{"y": max_speed, "label": "maxSpeed", "gid": "limit-speed"}] if max_speed else []
    marks = [{"x": r, "label": "rest (cusp or stop)" if k == 0 else None, "colour": CUSP_COLOUR} for k, r in
             enumerate(rests)]
    xlim = (0.0, duration) if duration else None
    fig, _ = stacked_figure(title, [
        {"series": speed, "limits": limits, "vlines": marks, "title": "tool speed", "ylabel": "speed [m/s]"},
        {"series": error, "limits": [{"y": 0.0, "colour": "#999999", "ls": "-", "lw": 0.8}], "vlines": marks,
         "title": "measured − profile", "ylabel": "speed error [m/s]"},
    ], notes=notes, panel_height=2.8, xlim=xlim)
    return fig


# --- joints ---------------------------------------------------------------------------------

def joint_names(model):
    """The joints' names from a RobotModel (JSON): its links' or joints' names, else J0..."""
    items = model.get("links") or model.get("joints") or []
    return [it.get("name") or f"J{j}" for j, it in enumerate(items)]


def joint_unit(model):
    items = model.get("links") or model.get("joints") or []
    kinds = {("m" if it.get("jointType") == "JOINT_TYPE_PRISMATIC" else "rad") for it in items}
    return kinds.pop() if len(kinds) == 1 else "rad or m"


def effective_limits(model, robot=None):
    """The model's joint limits after a request's RobotSpec (JSON) changes them: jointLimits
    by name, then velocityScale on velocities and accelerationScale on accelerations and
    jerks. [{"min", "max", "velocity", "acceleration", "jerk", "continuous"}] per joint."""
    robot = robot or {}
    names = joint_names(model)
    items = model.get("links") or model.get("joints") or []
    out = []
    for j, lim in enumerate(model.get("limits", [])):
        cont = j < len(items) and items[j].get("jointType") == "JOINT_TYPE_CONTINUOUS"
        out.append({"min": float(lim.get("minPosition", 0.0)), "max": float(lim.get("maxPosition", 0.0)),
                    "velocity": float(lim.get("maxVelocity", 0.0)),
                    "acceleration": float(lim.get("maxAcceleration", 0.0)),
                    "jerk": float(lim["maxJerk"]) if lim.get("maxJerk") is not None else None, "continuous": cont})
    for named in robot.get("jointLimits", []):
        if named.get("joint") in names:
            lim = out[names.index(named["joint"])]
            for key, field in (("velocity", "maxVelocity"), ("acceleration", "maxAcceleration"), ("jerk", "maxJerk")):
                if named.get(field) is not None:
                    lim[key] = float(named[field])
    vs, as_ = float(robot.get("velocityScale", 1.0)), float(robot.get("accelerationScale", 1.0))
    for lim in out:
        lim["velocity"] *= vs
        lim["acceleration"] *= as_
        if lim["jerk"] is not None:
            lim["jerk"] *= as_
    return out


def _worst(values, limits, key, t):
    """(usage, joint, t) of the largest |value| / limit over the joints."""
    best = (0.0, 0, 0.0)
    for j, y in enumerate(values):
        if limits[j][key] > 0 and len(y):
            k = int(np.argmax(np.abs(y)))
            u = abs(float(y[k])) / limits[j][key]
            if u > best[0]:
                best = (u, j, float(t[k]))
    return best


def joints_figure(title, t, q, qd, qdd, limits, names=None, unit="rad", notes=()):
    """Joint positions, velocities and accelerations against time with the model's limits.

    Left: the values [unit, unit/s, unit/s²] with each joint's limits as dashed lines in the
    joint's colour (ids limit-q-jJ-min/max, limit-qd-jJ-min/max, limit-qdd-jJ-min/max).
    Right: the same as a fraction of each joint's limit [%] (positions: 0 % at the lower
    limit, 100 % at the upper one), the limits at 0/100 % or ±100 % (ids
    limit-q-usage-min/max, limit-qd-usage-min/max, limit-qdd-usage-min/max), outside them
    shaded, and the worst joint's peak written on the panel: an overshoot is seen at once.
    t [s]; q, qd, qdd: one sequence per joint; limits: effective_limits()."""
    n = len(q)
    names = names or [f"J{j}" for j in range(n)]
    t = np.asarray(t, float)
    q, qd, qdd = ([np.asarray(y, float) for y in arr] for arr in (q, qd, qdd))
    u = unit
    rows = [("q", "position", f"q [{u}]", q, None),
            ("qd", "velocity", f"q̇ [{u}/s]", qd, "velocity"),
            ("qdd", "acceleration", f"q̈ [{u}/s²]", qdd, "acceleration")]
    note_lines = wrap_notes(notes, 14.5)
    fig = new_figure(14.5, 8.8 + 0.16 * len(note_lines))
    # A strip for the notes and the joints' legend, then the three rows.
    ratios = [0.12 + 0.12 * len(note_lines), 1, 1, 1]
    gs = fig.add_gridspec(len(ratios), 2, height_ratios=ratios, width_ratios=[1.15, 1])
    fig.suptitle(title)
    legend_ax = add_notes(fig, gs[0, :], note_lines)
    off = 1
    first = None
    for r, (key, word, ylabel, values, lim_key) in enumerate(rows):
        ax = fig.add_subplot(gs[off + r, 0], sharex=first)
        ax_u = fig.add_subplot(gs[off + r, 1], sharex=first or ax)
        first = first or ax
        ax.set_title(f"joint {word}", loc="left")
        for j in range(n):
            colour = COLOURS[j % len(COLOURS)]
            x, y = decimate(t, values[j])
            ax.plot(x, y, color=colour, label=f"{j} {names[j]}")
            lim = limits[j] if j < len(limits) else None
            if lim is None:
                continue
            if lim_key is None:
                if lim["continuous"]:
                    continue
                lo, hi = lim["min"], lim["max"]
                usage = (values[j] - lo) / (hi - lo) * 100.0 if hi > lo else values[j] * 0.0
            else:
                lo, hi = -lim[lim_key], lim[lim_key]
                usage = values[j] / hi * 100.0 if hi > 0 else values[j] * 0.0
            ax.axhline(hi, color=colour, ls="--", lw=0.9, alpha=0.85, gid=f"limit-{key}-j{j}-max")
            ax.axhline(lo, color=colour, ls="--", lw=0.9, alpha=0.85, gid=f"limit-{key}-j{j}-min")
            xu, yu = decimate(t, usage)
            ax_u.plot(xu, yu, color=colour)
        # The joint-limit lines' legend entry (one for all).
        ax.plot([], [], color="#555555", ls="--", lw=0.9, label="limits (dashed, joint's colour)")
        lo_u, hi_u = (0.0, 100.0) if lim_key is None else (-100.0, 100.0)
        ax_u.axhline(hi_u, color=LIMIT_RED, ls="--", lw=1.2, gid=f"limit-{key}-usage-max", label="limit")
        ax_u.axhline(lo_u, color=LIMIT_RED, ls="--", lw=1.2, gid=f"limit-{key}-usage-min")
        y0, y1 = ax_u.get_ylim()
        top, bottom = max(y1, hi_u * 1.08 + 2), min(y0, lo_u - 8 if lim_key is None else lo_u * 1.08 - 2)
        ax_u.axhspan(hi_u, top, color=LIMIT_RED, alpha=0.08, lw=0, label="beyond the limit")
        ax_u.axhspan(bottom, lo_u, color=LIMIT_RED, alpha=0.08, lw=0)
        ax_u.set_ylim(bottom, top)
        if lim_key is not None and limits:
            worst, wj, wt = _worst(values, limits, lim_key, t)
            state = "beyond its limit" if worst > 1.0 + 1e-9 else "within its limit"
            peak = ax_u.set_title(f"joint {word} / limit: largest joint {wj} {names[wj] if wj < len(names) else ''} "
                                  f"at {100 * worst:.0f} % (t = {wt:.2f} s), {state}", loc="left",
                                  color=LIMIT_RED if worst > 1.0 + 1e-9 else "black")
            peak.set_gid(f"peak-{key}")
        elif limits:
            # The joint nearest a position limit: its least distance as a share of its range.
            near = (1.0, 0, 0.0, 0.0)  # (least share to a limit, joint, t, share of range)
            for j in range(n):
                lim = limits[j] if j < len(limits) else None
                if lim is None or lim["continuous"] or lim["max"] <= lim["min"]:
                    continue
                share = (values[j] - lim["min"]) / (lim["max"] - lim["min"])
                edge = np.minimum(share, 1.0 - share)
                k = int(np.argmin(edge))
                if edge[k] < near[0]:
                    near = (float(edge[k]), j, float(t[k]), float(share[k]))
            outside = near[0] < 0.0
            title = ax_u.set_title(f"joint position in its range: nearest a limit joint {near[1]} "
                                   f"{names[near[1]] if near[1] < len(names) else ''} at {100 * near[3]:.0f} % "
                                   f"(t = {near[2]:.2f} s){', beyond its range' if outside else ''}",
                                   loc="left", color=LIMIT_RED if outside else "black")
            title.set_gid("peak-q")
        ax_u.set_ylabel("of range [%]" if lim_key is None else "of limit [%]")
        ax.set_ylabel(ylabel)
        nice_axis(ax)
        nice_axis(ax_u)
        if r == 0:
            ax_u.legend(loc="lower right", frameon=True, framealpha=0.8)
        if r == len(rows) - 1:
            ax.set_xlabel("time t [s]")
            ax_u.set_xlabel("time t [s]")
    first.set_xlim(float(t[0]), float(t[-1]))
    # One legend of the joints, in the strip above the panels.
    handles, labels = first.get_legend_handles_labels()
    legend_ax.legend(handles, labels, loc="lower center", ncol=min(8, n + 1), frameon=False)
    return fig


# --- binding limits -------------------------------------------------------------------------

BINDING_WORDS = {
    "BINDING_KIND_JOINT_VELOCITY": "velocity", "BINDING_KIND_JOINT_ACCELERATION": "acceleration",
    "BINDING_KIND_JOINT_JERK": "jerk", "BINDING_KIND_CARTESIAN_SPEED": "tool speed (maxSpeed)",
    "BINDING_KIND_CARTESIAN_TANGENTIAL_ACCELERATION": "tangential acceleration (maxAcceleration)",
    "BINDING_KIND_CARTESIAN_CENTRIPETAL_ACCELERATION": "centripetal acceleration κv² (maxAcceleration)",
    "BINDING_KIND_CARTESIAN_JERK": "tool jerk (maxJerk)", "BINDING_KIND_ANGULAR_SPEED": "angular speed",
    "BINDING_KIND_ANGULAR_ACCELERATION": "angular acceleration",
}
BINDING_COLOURS = {"velocity": "#1f77b4", "acceleration": "#d62728", "jerk": "#9467bd"}


def binding_label(stretch, names=()):
    kind = stretch.get("kind", "BINDING_KIND_UNSPECIFIED")
    word = BINDING_WORDS.get(kind, kind)
    if kind.startswith("BINDING_KIND_JOINT_"):
        j = int(stretch.get("joint", 0))
        name = f" {names[j]}" if j < len(names) else ""
        return f"joint {j}{name} {word}"
    return word


def binding_figure(title, stretches, names=(), notes=(), duration=None):
    """Which limit binds where: one row per limit with its stretches as bars over time, and
    each stretch's usage (value / limit) [%] against time, the limit at 100 %.
    stretches: BindingStretch JSON (PlanResponse.optimization.timing.binding, .robot.binding
    or, without a robot, .motion.binding)."""
    labels = []
    for st in stretches:
        lab = binding_label(st, names)
        if lab not in labels:
            labels.append(lab)
    note_lines = wrap_notes(notes, 11.0)
    fig = new_figure(11.0, 2.2 + 0.32 * len(labels) + 2.6 + 0.16 * len(note_lines))
    ratios = ([0.05 + 0.12 * len(note_lines)] if note_lines else []) + [0.6 + 0.3 * len(labels), 2.4]
    gs = fig.add_gridspec(len(ratios), 1, height_ratios=ratios)
    fig.suptitle(title)
    off = 0
    if note_lines:
        add_notes(fig, gs[0, 0], note_lines)
        off = 1
    ax = fig.add_subplot(gs[off, 0])
    ax_u = fig.add_subplot(gs[off + 1, 0], sharex=ax)
    for k, st in enumerate(stretches):
        lab = binding_label(st, names)
        row = labels.index(lab)
        t0, t1 = float(st.get("tStart", 0.0)), float(st.get("tEnd", 0.0))
        kind = st.get("kind", "")
        colour = next((c for w, c in BINDING_COLOURS.items() if kind.endswith(w.upper())), "#7f7f7f")
        ax.broken_barh([(t0, max(t1 - t0, 1e-9))], (row - 0.35, 0.7), facecolors=colour, edgecolor="white",
                       gid=f"binding-{k}")
        usage = 100.0 * float(st.get("usage", 0.0))
        ax_u.plot([t0, t1], [usage, usage], color=colour, lw=2.2)
        if t1 - t0 > 0.04 * (duration or (t1 or 1.0)):
            ax.text(0.5 * (t0 + t1), row, f"{usage:.0f} %", ha="center", va="center", fontsize=7, color="white")
    ax.set_yticks(range(len(labels)))
    ax.set_yticklabels(labels)
    ax.set_ylim(len(labels) - 0.4, -0.6)
    ax.grid(axis="y", visible=False)
    ax.set_title("the limit that binds (or is the most used), stretch by stretch", loc="left")
    ax.tick_params(labelbottom=False)
    nice_axis(ax, y=False)
    for w, c in BINDING_COLOURS.items():
        ax_u.plot([], [], color=c, lw=2.2, label=f"joint {w}")
    ax_u.plot([], [], color="#7f7f7f", lw=2.2, label="Cartesian or angular")
    ax_u.axhline(100.0, color=LIMIT_RED, ls="--", lw=1.1, gid="limit-binding-usage", label="limit")
    ax_u.set_ylim(0.0, max(105.0, ax_u.get_ylim()[1]))
    ax_u.set_title("usage of the binding limit on each stretch", loc="left")
    ax_u.set_ylabel("value / limit [%]")
    ax_u.set_xlabel("time t [s]")
    if duration:
        ax_u.set_xlim(0.0, duration)
    nice_axis(ax_u)
    ax_u.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    return fig


# --- samples ---------------------------------------------------------------------------------

def read_samples(path):
    """`geotraj stream`'s CSV as {column: numpy array}."""
    with open(path, newline="") as f:
        head = next(csv.reader(f), None)
        if head is None:
            return {}
        data = np.loadtxt(f, delimiter=",", ndmin=2).reshape(-1, len(head))
    return {name: data[:, k] for k, name in enumerate(head)}


def joint_columns(samples, prefix):
    out, j = [], 0
    while f"{prefix}{j}" in samples:
        out.append(samples[f"{prefix}{j}"])
        j += 1
    return out


def motion_figure(title, samples, motion=None, frame_times=(), notes=()):
    """The tool's speed over time as planned (the samples' speed) against the speed measured
    between samples (chord / period, as the thesis measures it), and the tool's whole
    acceleration, with the request's Cartesian limits (maxSpeed, maxAcceleration)."""
    motion = motion or {}
    t = samples["t"]
    p = np.stack([samples["x"], samples["y"], samples["z"]], axis=1)
    a = np.sqrt(samples["ax"] ** 2 + samples["ay"] ** 2 + samples["az"] ** 2)
    dt = np.diff(t)
    chord = np.linalg.norm(np.diff(p, axis=0), axis=1) / np.where(dt > 0, dt, np.nan)
    mid = 0.5 * (t[1:] + t[:-1])
    v = samples["speed"]
    floor = 0.02 * float(v.max()) if len(v) else 0.0
    rests = [float(t[k]) for k in range(1, len(t) - 1) if v[k] <= v[k - 1] and v[k] <= v[k + 1] and v[k] <= floor]
    marks = [{"x": r, "label": "rest" if k == 0 else None, "colour": CUSP_COLOUR} for k, r in enumerate(rests)]
    marks += [{"x": ft, "label": "key frame" if k == 0 else None, "colour": "#555555", "gid": f"keyframe-t-{i}",
               "text": str(i)} for k, (i, ft) in enumerate(frame_times)]
    speed_limits = [{"y": float(motion["maxSpeed"]), "label": "maxSpeed", "gid": "limit-speed"}] \
        if motion.get("maxSpeed") else []
    acc_limits = [{"y": float(motion["maxAcceleration"]), "label": "maxAcceleration", "gid": "limit-acceleration"}] \
        if motion.get("maxAcceleration") else []
    fig, _ = stacked_figure(title, [
        {"series": [{"x": t, "y": samples["speed"], "label": "planned speed (samples)", "colour": "black", "lw": 2.4},
                    {"x": mid, "y": chord, "label": "measured: chord / period", "colour": COLOURS[0], "lw": 1.1}],
         "limits": speed_limits, "vlines": marks, "title": "tool speed", "ylabel": "speed [m/s]"},
        {"series": [{"x": t, "y": a, "label": "|a| (tangential and centripetal)", "colour": COLOURS[1]}],
         "limits": acc_limits, "vlines": marks, "title": "tool acceleration", "ylabel": "|a| [m/s²]"},
    ], notes=notes, panel_height=2.7, xlim=(float(t[0]), float(t[-1])))
    return fig


# --- `geotraj plot`: one request -------------------------------------------------------------

def load_json(path):
    with open(path) as f:
        return json.load(f)


def request_figures(request, plan, profiles, samples, model, out_dir, stem, png=False):
    """Draws every figure that applies to one planned request; returns the files written."""
    written = []
    frames_by_path = path_frames(request)
    # Warnings of the top-level path are placed on it; a sequence's (each along its own
    # step's path) are listed.
    warnings = list(plan.get("warnings", []))
    notes = [f"sequence step {step.get('index', 0)}, segment {w.get('segment', 0)}, s = {w.get('s', 0.0):.3f} m: "
             f"{w.get('message', w.get('code', ''))}" for step in plan.get("steps", []) for w in step.get("warnings", [])]
    kind = ("sequence" if request.get("sequence") else "joint move" if request.get("jointMove")
            else "linear move" if request.get("linearMove") else "path")
    robot = request.get("robot") or {}
    motion = request.get("motion") or {}
    robot_name = robot.get("name") or (model or {}).get("name") or ("URDF robot" if robot.get("urdf") else "")
    subject = f"{stem}: {kind}" + (f" on {robot_name}" if robot_name else "")
    profs = [Profile(p) for p in profiles]

    # The path: the analysed curve of each path; the tool's track from the samples as well
    # when the motion is more than the one path (a sequence, an approach, a move).
    paths = []
    for i, prof in enumerate(profs):
        prefix = frames_by_path[i][0] if i < len(frames_by_path) else ""
        paths.append({"label": f"{prefix}path" if prefix else "path", "points": prof.p, "profile": prof})
    frames = frames_by_path[0][1] if frames_by_path else []
    has_samples = samples is not None and len(samples.get("t", [])) > 0
    if has_samples and (not paths or plan.get("steps")):
        track = np.stack([samples["x"], samples["y"], samples["z"]], axis=1)
        paths.append({"label": "tool track (samples)", "points": track, "colour": "#7f7f7f"})
    if len(frames_by_path) > 1:
        notes.insert(0, f"key frames of {frames_by_path[0][0].rstrip('.')} numbered; the sequence has "
                        f"{len(frames_by_path)} paths")
    length = plan.get("arcLength") or sum(s.get("arcLength", 0.0) for s in plan.get("steps", []))
    if paths:
        fig = path_figure(paths, frames, f"{subject}, arc length {float(length):.4g} m", warnings=warnings,
                          notes=notes)
        written += save(fig, os.path.join(out_dir, f"{stem}_path.svg"), png)
    if profs:
        entries = [{"label": paths[i]["label"], "profile": prof} for i, prof in enumerate(profs)]
        fig = geometry_figure(entries, f"{subject}: curvature and torsion along the path (AnalyzePath, "
                                       f"{len(profs[0].u)} points)", frames=frames, warnings=warnings)
        written += save(fig, os.path.join(out_dir, f"{stem}_geometry.svg"), png)
    elif has_samples and len(samples["t"]) > 3:
        # No path to analyse (a move): the tool track's geometry from the samples.
        track = Profile.from_samples(samples)
        fig = geometry_figure([{"label": "tool track (samples)", "profile": track}],
                              f"{subject}: curvature and torsion of the tool's track (from the samples)",
                              notes=["κ = |v × a| / |v|³ from the samples' velocity and acceleration; τ and the "
                                     "derivatives by finite differences; undefined (left out) where the tool stands "
                                     "still"])
        written += save(fig, os.path.join(out_dir, f"{stem}_geometry.svg"), png)
    duration = float((plan.get("motion") or {}).get("durationS", 0.0))
    if has_samples:
        frame_times = []
        if profs and not request.get("sequence"):
            for i in range(int(round(profs[0].u[-1])) + 1):
                k = int(np.searchsorted(samples["u"], i - 1e-9))
                if k < len(samples["t"]):
                    frame_times.append((i, float(samples["t"][k])))
        fig = motion_figure(f"{subject}: speed, {duration:.4g} s, {len(samples['t'])} samples", samples, motion,
                            frame_times)
        written += save(fig, os.path.join(out_dir, f"{stem}_speed.svg"), png)
        q = joint_columns(samples, "q")
        if q and model:
            limits = effective_limits(model, robot)
            names = joint_names(model)
            report = plan.get("robot") or {}
            state = "within its limits" if report.get("feasible") else "limits broken (reportOnly)"
            fig = joints_figure(f"{subject}: joints, {duration:.4g} s, {state}", samples["t"], q,
                                joint_columns(samples, "qd"), joint_columns(samples, "qdd"), limits, names,
                                joint_unit(model))
            written += save(fig, os.path.join(out_dir, f"{stem}_joints.svg"), png)
    timing = ((plan.get("optimization") or {}).get("timing") or {}).get("binding", [])
    time_optimal = bool(((request.get("optimize") or {}).get("timing") or {}).get("timeOptimal")) or (
        "motion" in request and float(motion.get("durationS", 0.0)) == 0.0)
    # Measured on the samples: the robot report's (joints and tool), else the tool's alone.
    measured = (plan.get("robot") or {}).get("binding") or (plan.get("motion") or {}).get("binding", [])
    stretches = timing or (measured if time_optimal else [])
    if stretches:
        names = joint_names(model) if model else []
        fig = binding_figure(f"{subject}: which limit binds, time-optimal in {duration:.4g} s", stretches, names,
                             duration=duration)
        written += save(fig, os.path.join(out_dir, f"{stem}_binding.svg"), png)
    return written


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    req = sub.add_parser("request", help="the figures of one planned request (what `geotraj plot` runs)")
    req.add_argument("--request", required=True)
    req.add_argument("--plan", required=True)
    req.add_argument("--profile", action="append", default=[])
    req.add_argument("--samples")
    req.add_argument("--robot")
    req.add_argument("--out", required=True)
    req.add_argument("--name", default="plot")
    req.add_argument("--png", action="store_true")
    args = parser.parse_args(argv)
    request, plan = load_json(args.request), load_json(args.plan)
    profiles = [load_json(p) for p in args.profile]
    samples = read_samples(args.samples) if args.samples else None
    model = load_json(args.robot) if args.robot else None
    os.makedirs(args.out, exist_ok=True)
    for path in request_figures(request, plan, profiles, samples, model, args.out, args.name, args.png):
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
