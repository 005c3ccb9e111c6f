#!/usr/bin/env python3
"""Draws paths as SVG in two projections (top view x-y and side view x-z).

Usage: plot_paths.py OUT.svg LABEL=REQUEST.json:PROFILE.json [...]
  REQUEST.json  a PlanRequest in the proto JSON mapping (its key frames are drawn)
  PROFILE.json  the AnalyzePath response (PathProfile) for it (`geotraj analyze --json`)
Only the Python standard library is used.
"""
import json
import sys

COLOURS = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b"]
PANEL = 420  # px, square plotting area of each projection
MARGIN = 50


def vec(d, name):
    v = d.get(name, {}) or {}
    return (float(v.get("x", 0.0)), float(v.get("y", 0.0)), float(v.get("z", 0.0)))


def load(arg):
    label, files = arg.split("=", 1)
    req_file, prof_file = files.split(":", 1)
    with open(req_file) as f:
        req = json.load(f)
    with open(prof_file) as f:
        prof = json.load(f)
    frames = req.get("path", req).get("frames", [])
    points = [vec(p, "position") for p in prof.get("points", [])]
    keys = [(vec(fr, "position"), vec(fr, "tangent"), bool(fr.get("cusp", False))) for fr in frames]
    return label, points, keys


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    out = sys.argv[1]
    paths = [load(a) for a in sys.argv[2:]]
    views = [("top view (x right, y up)", 0, 1), ("side view (x right, z up)", 0, 2)]
    svg = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{2 * PANEL + 3 * MARGIN}" '
           f'height="{PANEL + 2 * MARGIN + 20 * len(paths)}" font-family="sans-serif" font-size="12">',
           '<rect width="100%" height="100%" fill="white"/>']
    for v, (title, a, b) in enumerate(views):
        xs = [p[a] for _, pts, keys in paths for p in pts + [k[0] for k in keys]]
        ys = [p[b] for _, pts, keys in paths for p in pts + [k[0] for k in keys]]
        lo_x, hi_x, lo_y, hi_y = min(xs), max(xs), min(ys), max(ys)
        span = max(hi_x - lo_x, hi_y - lo_y, 1e-9) * 1.1
        cx, cy = (lo_x + hi_x) / 2, (lo_y + hi_y) / 2
        ox = MARGIN + v * (PANEL + MARGIN)

        def to_px(p, ox=ox, cx=cx, cy=cy, span=span, a=a, b=b):
            return (ox + (p[a] - cx) / span * PANEL + PANEL / 2, MARGIN + PANEL / 2 - (p[b] - cy) / span * PANEL)

        svg.append(f'<rect x="{ox}" y="{MARGIN}" width="{PANEL}" height="{PANEL}" fill="none" stroke="#999"/>')
        svg.append(f'<text x="{ox}" y="{MARGIN - 8}">{title}; square {span:.3g} m wide</text>')
        for i, (label, pts, keys) in enumerate(paths):
            colour = COLOURS[i % len(COLOURS)]
            d = " ".join(f"{x:.2f},{y:.2f}" for x, y in map(to_px, pts))
            svg.append(f'<polyline points="{d}" fill="none" stroke="{colour}" stroke-width="1.5"/>')
        for n, (p, t, cusp) in enumerate(paths[0][2]):
            x, y = to_px(p)
            tip = to_px(tuple(p[k] + 0.06 * span * t[k] for k in range(3)))
            svg.append(f'<line x1="{x:.2f}" y1="{y:.2f}" x2="{tip[0]:.2f}" y2="{tip[1]:.2f}" stroke="black"/>')
            svg.append(f'<circle cx="{x:.2f}" cy="{y:.2f}" r="4" fill="{"orange" if cusp else "black"}"/>')
            svg.append(f'<text x="{x + 6:.2f}" y="{y - 6:.2f}">{n + 1}{" (cusp)" if cusp else ""}</text>')
    for i, (label, _, _) in enumerate(paths):
        y = PANEL + 2 * MARGIN + 20 * i - 10
        svg.append(f'<line x1="{MARGIN}" y1="{y}" x2="{MARGIN + 30}" y2="{y}" stroke="{COLOURS[i % len(COLOURS)]}" stroke-width="3"/>')
        svg.append(f'<text x="{MARGIN + 40}" y="{y + 4}">{label}</text>')
    svg.append("</svg>")
    with open(out, "w") as f:
        f.write("\n".join(svg) + "\n")


if __name__ == "__main__":
    main()
