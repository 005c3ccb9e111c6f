#!/usr/bin/env python3
"""The thesis's demonstration on the Mitsubishi PA-10 in joint space, through the geotraj CLI.

Usage: robot_demo.py CLI [OUT_DIR]
  CLI      the geotraj command-line client (e.g. build/client/geotraj)
  OUT_DIR  where the SVG plots go (default out)

For paths A, B, C at 10 s (Tables 7.8 and 7.18, 100 Hz) with the built-in "pa10" model:
PlanTrajectory's joint report (limit margins, IK residuals, joint-interpolation deviation,
manipulability), then the joint samples streamed and plotted against time (positions,
velocities, accelerations), with the joint limits. Only the Python standard library.
"""
import csv
import io
import json
import os
import subprocess
import sys
import tempfile

REQUESTS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "client", "grpcurl")
COLOURS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f"]
W, LEFT, RIGHT, PANEL_H, TOP = 980, 90, 200, 210, 40


def run(cli, *args):
    done = subprocess.run([cli, *args], capture_output=True, text=True)
    if done.returncode != 0:
        sys.stderr.write(done.stderr)
        raise SystemExit(f"robot_demo: '{' '.join(args[:2])}' failed")
    return done.stdout


def request_for(tmp, path):
    with open(os.path.join(REQUESTS, f"plan_demo_path_{path.lower()}.json")) as f:
        req = json.load(f)
    req["motion"] = {"durationS": 10, "cycleRateHz": 100}
    # reportOnly: the limits are reported, not enforced, so that the margins (and what
    # breaks them) are shown and the joints can be plotted.
    req["robot"] = {"name": "pa10", "reportOnly": True}
    name = os.path.join(tmp, f"robot_{path}.json")
    with open(name, "w") as f:
        json.dump(req, f)
    return name


def ticks(lo, hi, n=5):
    if hi <= lo:
        return [lo]
    step = (hi - lo) / n
    return [lo + i * step for i in range(n + 1)]


def panel(svg, y0, title, unit, t, series, limits):
    w = W - LEFT - RIGHT
    lo = min(min(s) for s in series)
    hi = max(max(s) for s in series)
    for lim in limits:
        lo, hi = min(lo, lim), max(hi, lim)
    if hi - lo < 1e-12:
        hi, lo = hi + 1, lo - 1
    pad = 0.05 * (hi - lo)
    lo, hi = lo - pad, hi + pad
    t_max = t[-1] if t[-1] > 0 else 1.0
    px = lambda x: LEFT + w * x / t_max
    py = lambda v: y0 + PANEL_H * (hi - v) / (hi - lo)
    svg.append(f'<rect x="{LEFT}" y="{y0}" width="{w}" height="{PANEL_H}" fill="none" stroke="#999"/>')
    for v in ticks(lo, hi):
        svg.append(f'<text x="{LEFT - 6}" y="{py(v) + 4:.1f}" text-anchor="end">{v:.3g}</text>')
        svg.append(f'<line x1="{LEFT}" x2="{LEFT + w}" y1="{py(v):.1f}" y2="{py(v):.1f}" stroke="#eee"/>')
    for x in ticks(0, t_max):
        svg.append(f'<text x="{px(x):.1f}" y="{y0 + PANEL_H + 15}" text-anchor="middle">{x:.3g}</text>')
    svg.append(f'<text transform="translate({LEFT - 62},{y0 + PANEL_H / 2}) rotate(-90)" '
               f'text-anchor="middle">{title} [{unit}]</text>')
    for j, s in enumerate(series):
        step = max(1, len(s) // 1500)
        d = " ".join(f"{px(t[k]):.1f},{py(s[k]):.1f}" for k in range(0, len(s), step))
        svg.append(f'<polyline points="{d}" fill="none" stroke="{COLOURS[j % len(COLOURS)]}" stroke-width="1.3"/>')


def plot(filename, path, t, q, qd, qdd, model):
    duration = t[-1]
    n = len(q)
    h = TOP + 3 * (PANEL_H + 40) + 20
    svg = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{h}" font-family="sans-serif" '
           f'font-size="12">', f'<rect width="{W}" height="{h}" fill="white"/>',
           f'<text x="{LEFT}" y="24" font-size="15">PA-10 joint trajectories, thesis path {path}, {duration:.3g} s, 100 Hz '
           f'(margins to the limits: see the plan report)</text>']
    panel(svg, TOP, "joint position", "rad", t, q, [])
    panel(svg, TOP + PANEL_H + 40, "joint velocity", "rad/s", t, qd, [])
    panel(svg, TOP + 2 * (PANEL_H + 40), "joint acceleration", "rad/s^2", t, qdd, [])
    for j in range(n):
        y = TOP + 20 + 18 * j
        x = W - RIGHT + 8
        svg.append(f'<line x1="{x}" x2="{x + 24}" y1="{y}" y2="{y}" stroke="{COLOURS[j % len(COLOURS)]}" '
                   f'stroke-width="2"/>')
        lim = model["limits"][j]
        svg.append(f'<text x="{x + 30}" y="{y + 4}">joint {j} (|qd| &lt;= {lim["maxVelocity"]:.3g})</text>')
    svg.append("</svg>")
    with open(filename, "w") as f:
        f.write("\n".join(svg) + "\n")


def time_optimal(cli, tmp, model, out):
    """Thesis 6.4 made explicit: the fastest timing of each path within the PA-10's joint
    limits (exact time-optimal parameterisation), against the thesis's fixed 10 s."""
    print("\n=== Time-optimal timing on the PA-10 (durationS 0: the joint limits set the time)")
    print(f"{'path':>4} {'thesis':>8} {'time-optimal':>13} {'feasible':>9}   tightest margins (joint: kind usage)")
    for path in "ABC":
        with open(os.path.join(REQUESTS, f"plan_demo_path_{path.lower()}.json")) as f:
            req = json.load(f)
        req["motion"] = {"durationS": 0, "cycleRateHz": 100}
        req["robot"] = {"name": "pa10"}
        name = os.path.join(tmp, f"topp_{path}.json")
        with open(name, "w") as f:
            json.dump(req, f)
        plan = json.loads(run(cli, "--json", "plan", name))
        robot = plan["robot"]
        top = sorted(robot["joints"], key=lambda j: -max(j.get("velocityUsage", 0), j.get("accelerationUsage", 0)))[:3]
        margins = ", ".join(f"{j.get('joint', 0)}: vel {100 * j.get('velocityUsage', 0):.0f}% "
                            f"acc {100 * j.get('accelerationUsage', 0):.0f}%" for j in top)
        print(f"{path:>4} {10:>7.2f}s {plan['motion']['durationS']:>12.3f}s {str(robot.get('feasible', False)):>9}   "
              f"{margins}")
        if path == "C":
            print("\nPath C, which limit binds where (PlanResponse.optimization.timing.binding):")
            print(run(cli, "plan", "--time-optimal", name).split("which limit binds where:\n", 1)[1].split("\n\n", 1)[0])
            rows = list(csv.DictReader(io.StringIO(run(cli, "stream", name))))
            n = len(model["links"])
            t = [float(r["t"]) for r in rows]
            series = [[[float(r[f"{k}{j}"]) for r in rows] for j in range(n)] for k in ("q", "qd", "qdd")]
            file = os.path.join(out, "joints_path_c_time_optimal.svg")
            plot(file, "C (time-optimal)", t, *series, model)
            print(f"wrote {file} ({len(rows)} samples): every joint velocity and acceleration within its limit")


def main():
    if len(sys.argv) < 2:
        raise SystemExit(__doc__)
    cli = sys.argv[1]
    out = sys.argv[2] if len(sys.argv) > 2 else "out"
    os.makedirs(out, exist_ok=True)
    robots = json.loads(run(cli, "--json", "robots"))
    model = next(m for m in robots["robots"] if m["name"] == "pa10")
    print("\n=== The PA-10 (built-in model 'pa10')")
    print(run(cli, "robots").split("\n\n")[0].split("ur5")[0].rstrip())
    with tempfile.TemporaryDirectory() as tmp:
        for path in "ABC":
            req = request_for(tmp, path)
            print(f"\n=== Thesis path {path} on the PA-10, 10 s at 100 Hz: joint-limit margins and IK residuals")
            report = run(cli, "plan", req)
            print(report[report.index("\nmotion:") + 1:].rstrip())
            rows = list(csv.DictReader(io.StringIO(run(cli, "stream", req))))
            n = len(model["links"])
            t = [float(r["t"]) for r in rows]
            q = [[float(r[f"q{j}"]) for r in rows] for j in range(n)]
            qd = [[float(r[f"qd{j}"]) for r in rows] for j in range(n)]
            qdd = [[float(r[f"qdd{j}"]) for r in rows] for j in range(n)]
            name = os.path.join(out, f"joints_path_{path.lower()}.svg")
            plot(name, path, t, q, qd, qdd, model)
            print(f"wrote {name} ({len(rows)} samples)")
        time_optimal(cli, tmp, model, out)


if __name__ == "__main__":
    main()
