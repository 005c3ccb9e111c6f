#!/usr/bin/env python3
"""Thesis Appendix B.3 (Table B.1) through the geotraj CLI: peak torsion and curvature of the
trapezoid blend with the uniform breakpoints (B.10), the thesis's hand-tuned ones (B.11,
B.13) and the optimised ones (PlanRequest.optimize.breakpoints).

Usage: appendix_b_table.py CLI [--server HOST:PORT]
  CLI  the geotraj command-line client (e.g. build/client/geotraj)

Each row's request is in client/grpcurl/appendix_b_*.json (analysisPoints 40001: 20000 points
per segment). The peaks are measured as the optimiser measures them: the largest |torsion|
(where the curve has a normal) and curvature over each segment, its frames included (their
values are fixed by the constraints, so no breakpoint changes them). The
optimised row's breakpoints come from `plan` (PlanResponse.optimization.breakpoints, a
BreakpointReport); its profile from `analyze` of the same request (an analysis of a request
with `optimize` uses the optimised path). Only the Python standard library is used.
"""
import json
import os
import subprocess
import sys

REQUESTS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "client", "grpcurl")
ROWS = [("uniform (B.10)", "appendix_b_uniform.json"),
        ("hand-tuned (B.11)", "appendix_b_b11.json"),
        ("staggered (B.13)", "appendix_b_b13.json"),
        ("optimised", "appendix_b_optimized.json")]


def call(cli, extra, command, request):
    out = subprocess.run([cli, *extra, "--json", command, os.path.join(REQUESTS, request)],
                         check=True, capture_output=True, text=True).stdout
    return json.loads(out)


def peak(points, value):
    """Largest value(point) over the profile, the frames (integer u) included."""
    return max((value(p) for p in points), default=0.0)


def breakpoint_text(entries):
    rows = []
    for e in entries:
        seg = e.get("segment", 0)
        if e.get("all"):
            rows.append(f"  segment {seg} all: " + " ".join(f"{u:.3f}" for u in e["all"]))
        for axis in ("x", "y", "z"):
            if e.get(axis):
                rows.append(f"  segment {seg} {axis}:   " + " ".join(f"{u:.3f}" for u in e[axis]))
    return rows or ["  uniform k/9 on every segment and axis (B.10)"]


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    cli, extra = sys.argv[1], sys.argv[2:]
    print(f"{'breakpoints':<18} {'peak |tau| [1/m]':>17} {'peak kappa [1/m]':>17}")
    details = []
    for name, request in ROWS:
        profile = call(cli, extra, "analyze", request)
        points = profile.get("points", [])
        tau = peak(points, lambda p: abs(p.get("torsion", 0.0)))
        kappa = peak(points, lambda p: p.get("curvature", 0.0))
        print(f"{name:<18} {tau:>17.4f} {kappa:>17.4f}")
        with open(os.path.join(REQUESTS, request)) as f:
            entries = json.load(f)["path"].get("breakpoints", [])
        if "optimize" in json.load(open(os.path.join(REQUESTS, request))):
            report = call(cli, extra, "plan", request).get("optimization", {}).get("breakpoints", {})
            entries = report.get("breakpoints", [])
            details.append(f"{name}: {report.get('status', '?')}, objective {report.get('objectiveBefore', 0):.4f}"
                           f" -> {report.get('objectiveAfter', 0):.4f} in {report.get('seconds', 0):.3f} s,"
                           f" {report.get('iterations', 0)} evaluations")
        details.append(f"{name}:")
        details.extend(breakpoint_text(entries))
    print()
    print("\n".join(details))


if __name__ == "__main__":
    main()
