#!/usr/bin/env python3
"""The thesis's speed tables (7.21 and 7.22) through the geotraj CLI, with SVG plots.

Usage: motion_demo.py CLI [OUT_DIR]
  CLI      the geotraj command-line client (e.g. build/client/geotraj)
  OUT_DIR  where the SVG plots go (default out)

For paths A, B, C at 10 s and path C at 5, 10 and 15 s, with TAYLOR_SECOND_ORDER and
ARC_LENGTH timing, the samples are streamed and the speed is measured as the thesis does:
the distance between consecutive samples over the period. The reference is the speed
profile's mean speed over the same period, computed here from the plan (portions between
rests, every ramp 0.75 s long and one peak speed for all portions, erratum of Eq. 6.13).
The paths are planned as the thesis reads them (UNSPECIFIED_CONSTRAINTS_THESIS_ZEROS) with
its ramps as a time (Table 6.2's RampTime, rampTimeS 0.75). The period in which the path
reverses at a cusp is skipped.
The figures are drawn by scripts/geotraj_plot.py (matplotlib, Debian's python3-matplotlib).
"""
import json
import math
import os
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import geotraj_plot as gp  # noqa: E402

REQUESTS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "client", "grpcurl")
RAMP_TIME_S = 0.75  # Table 6.2's RampTime; Table 7.22's peaks satisfy v (T - 1.5 s) = 1.63 m
METHODS = [("TAYLOR_SECOND_ORDER", "Taylor 2nd order", "#d62728"),
           ("ARC_LENGTH", "arc length", "#1f77b4")]
# (path, move time [s]) -> the thesis's maximum velocity, maximum velocity error [m/s] and
# % velocity error (Table 7.21 for the three paths at 10 s, Table 7.22 for path C).
THESIS = {("A", 10): (0.1855, 0.0007, 0.3929), ("B", 10): (0.1899, 0.0015, 0.8135),
          ("C", 10): (0.1918, 0.0026, 1.3387), ("C", 5): (0.4658, 0.0197, 4.2384),
          ("C", 15): (0.1208, 0.0008, 0.6355)}
TABLES = [("Table 7.21: paths A, B, C, move time 10 s", [("A", 10), ("B", 10), ("C", 10)]),
          ("Table 7.22: path C, move times 5, 10, 15 s", [("C", 5), ("C", 10), ("C", 15)])]

NOTE = """\
Note. The measure is the thesis's: the chord between consecutive samples over the period.
A chord is shorter than its arc by about kappa^2 ds^3 / 24, so the measured speed falls
short of the true one by kappa^2 ds^2 / 24 of itself even when every sample is exactly
where the profile puts it. The thesis's curves have curvature up to 86-221 1/m between
the key frames, which at 100 Hz and the peak speed is a few tenths of a percent of the
peak (more at 5 s, where ds is larger). ARC_LENGTH samples are exact along the arc (the core tests check 1e-9 m; the
column "s vs profile" above is the largest gap between the streamed s and the reference
profile computed here), so its error column is the chord's shortfall alone; what
TAYLOR_SECOND_ORDER shows beyond that is the drift of its Taylor steps from the profile
(largest at the corners of the trapezoid, around the sharpest bend and in the last
period, which ends on the end frame).
The peak speeds reproduce the thesis's within 1 % (core test
MotionPlan.ThesisTables721And722PeakSpeeds): the thesis's reading of the frames and ramps
of 0.75 s in each portion. The error columns compare interpolators: the thesis's Taylor
steps against geotraj's exact arc length."""


def run(cli, *args):
    return subprocess.run([cli, *args], check=True, capture_output=True, text=True).stdout


def make_request(tmp, path, duration, method):
    """Writes the demonstration request for PATH with the given move time and timing."""
    with open(os.path.join(REQUESTS, f"plan_demo_path_{path.lower()}.json")) as f:
        req = json.load(f)
    req["path"]["unspecified"] = "UNSPECIFIED_CONSTRAINTS_THESIS_ZEROS"
    req["motion"].pop("rampFraction", None)
    req["motion"].update(durationS=duration, rampTimeS=RAMP_TIME_S,
                         timeParameterization=f"TIME_PARAMETERIZATION_{method}")
    name = os.path.join(tmp, f"{path}_{duration}_{method}.json")
    with open(name, "w") as f:
        json.dump(req, f)
    return name, req


def portions(req, plan):
    """Arc lengths of the portions between rests (the start, the end, every cusp or stop)."""
    frames = req["path"]["frames"]
    lengths, current = [], 0.0
    for seg in plan["segments"]:
        current += seg["arcLength"]
        end = frames[seg.get("toFrame", 0)]
        if end.get("cusp") or end.get("stop"):
            lengths.append(current)
            current = 0.0
    if current > 0.0:
        lengths.append(current)
    return lengths


class Profile:
    """Rest-to-rest trapezoids over the portions; every portion reaches the same peak."""

    def __init__(self, lengths, duration):
        total = sum(lengths)
        self.parts, t0, s0 = [], 0.0, 0.0
        t_b = RAMP_TIME_S
        v_max = total / (duration - len(lengths) * t_b)  # v (T - n t_b) = L
        for length in lengths:
            t_i = length / v_max + t_b
            self.parts.append((t0, t_i, t_b, v_max, v_max / t_b, s0, length))
            t0, s0 = t0 + t_i, s0 + length
        self.peak = max(p[3] for p in self.parts)
        self.rests = [p[0] for p in self.parts[1:]]  # the interior rests (cusps, stops)

    def s(self, t):
        for t0, t_i, t_b, v_max, a, s0, length in self.parts:
            if t <= t0 + t_i:
                tau = min(max(t - t0, 0.0), t_i)
                if tau < t_b:
                    return s0 + 0.5 * a * tau * tau
                if tau <= t_i - t_b:
                    return s0 + 0.5 * a * t_b * t_b + v_max * (tau - t_b)
                return s0 + length - 0.5 * a * (t_i - tau) ** 2
        return self.parts[-1][5] + self.parts[-1][6]


def stream(cli, request):
    """The samples as (t, s, (x, y, z))."""
    lines = run(cli, "stream", request).splitlines()
    head = lines[0].split(",")
    col = {name: head.index(name) for name in ("t", "s", "x", "y", "z")}
    rows = [list(map(float, line.split(","))) for line in lines[1:] if line]
    return [(r[col["t"]], r[col["s"]], (r[col["x"]], r[col["y"]], r[col["z"]])) for r in rows]


def measure(samples, profile):
    """Per period: (midpoint time, measured chord speed, profile's mean speed), or None for
    a period with a rest strictly inside it (the path reverses there)."""
    out = []
    for (t0, _, p0), (t1, _, p1) in zip(samples, samples[1:]):
        if any(t0 < r < t1 for r in profile.rests):
            out.append(None)
            continue
        dt = t1 - t0
        out.append((0.5 * (t0 + t1), math.dist(p0, p1) / dt, (profile.s(t1) - profile.s(t0)) / dt))
    return out


def run_case(cli, tmp, path, duration, method):
    request, req = make_request(tmp, path, duration, method)
    plan = json.loads(run(cli, "--json", "plan", request))
    profile = Profile(portions(req, plan), duration)
    if abs(profile.peak - plan["motion"]["peakSpeed"]) > 1e-9:
        sys.exit(f"motion_demo: reference peak {profile.peak} differs from the plan's "
                 f"{plan['motion']['peakSpeed']} ({path}, {duration} s, {method})")
    samples = stream(cli, request)
    periods = measure(samples, profile)
    valid = [p for p in periods if p]
    error = max(abs(m - r) for _, m, r in valid)
    return {"periods": periods, "peak": profile.peak,
            "measured_peak": max(m for _, m, _ in valid), "error": error,
            "percent": 100.0 * error / profile.peak,
            "s_gap": max(abs(s - profile.s(t)) for t, s, _ in samples), "rests": profile.rests}


def print_tables(results):
    row = "{:<5} {:>9} {:<20} {:>9} {:>10} {:>8} {:>12} | {:>9} {:>10} {:>8}"
    head = row.format("path", "move time", "method", "max vel", "max error", "% error",
                      "s vs profile", "max vel", "max error", "% error")
    for title, cases in TABLES:
        print(f"\n=== {title}")
        print(" " * head.index("|") + "| thesis")
        print(head)
        print(row.format("", "[s]", "", "[m/s]", "[m/s]", "[% peak]", "[m]", "[m/s]", "[m/s]", "[% peak]"))
        for path, duration in cases:
            for method, _, _ in METHODS:
                r = results[path, duration, method]
                thesis = THESIS[path, duration]
                print(row.format(path, duration, method, f"{r['measured_peak']:.4f}",
                                 f"{r['error']:.4f}", f"{r['percent']:.4f}", f"{r['s_gap']:.1e}",
                                 *(f"{x:.4f}" for x in thesis)))
    print()
    print(NOTE)


# --- figures (scripts/geotraj_plot.py) ----------------------------------------------------

def series(periods, value):
    """(t, value) arrays of the periods, NaN where a period is left out (a gap in the line)."""
    t = [p[0] if p else float("nan") for p in periods]
    v = [value(p) if p else float("nan") for p in periods]
    return t, v


def plot(filename, path, duration, results):
    reference = results[path, duration, METHODS[-1][0]]
    t_ref, v_ref = series(reference["periods"], lambda p: p[2])
    measured = []
    for i, (m, name, colour) in enumerate(METHODS):
        t, v = series(results[path, duration, m]["periods"], lambda p: p[1])
        measured.append((f"measured, {name}", t, v, colour, "--" if i else "-"))
    fig = gp.speed_figure(
        f"Path {path}, move time {duration} s: speed measured as the thesis does (chord / period) against the profile",
        ("reference profile (mean speed over each period)", t_ref, v_ref), measured, rests=reference["rests"],
        notes=["the period in which the path reverses at the cusp (frames[2]) is left out"], duration=duration)
    gp.save(fig, filename)


def main():
    if len(sys.argv) not in (2, 3):
        sys.exit(__doc__)
    cli, out = sys.argv[1], sys.argv[2] if len(sys.argv) == 3 else "out"
    os.makedirs(out, exist_ok=True)
    cases = sorted({case for _, cases in TABLES for case in cases})
    with tempfile.TemporaryDirectory() as tmp:
        results = {(p, d, m): run_case(cli, tmp, p, d, m) for p, d in cases for m, _, _ in METHODS}
    print_tables(results)
    print()
    for path, duration in cases:
        name = os.path.join(out, f"speed_path_{path}_{duration}s.svg")
        plot(name, path, duration, results)
        print(f"Wrote {name}")


if __name__ == "__main__":
    main()
