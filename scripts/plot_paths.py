#!/usr/bin/env python3
"""Draws paths in a 3-D view and in top (x-y) and side (x-z) views, and optionally their
curvature, torsion and derivatives against the arc length (scripts/geotraj_plot.py).

Usage: plot_paths.py OUT.svg [--title TITLE] [--geometry GEOMETRY.svg] [--png]
                     LABEL=REQUEST.json:PROFILE.json[:PLAN.json] [...]
  REQUEST.json  a PlanRequest in the proto JSON mapping (the first one's key frames are drawn)
  PROFILE.json  the AnalyzePath response (PathProfile) for it (`geotraj --json analyze`)
  PLAN.json     optional: its PlanResponse (`geotraj --json plan`), whose warnings are marked
Needs matplotlib (Debian's python3-matplotlib).
"""
import argparse
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import geotraj_plot as gp  # noqa: E402


def load(arg):
    label, files = arg.split("=", 1)
    names = files.split(":")
    with open(names[0]) as f:
        req = json.load(f)
    with open(names[1]) as f:
        prof = gp.Profile(json.load(f))
    plan = {}
    if len(names) > 2:
        with open(names[2]) as f:
            plan = json.load(f)
    return label, req, prof, plan


def main():
    parser = argparse.ArgumentParser(usage=__doc__)
    parser.add_argument("out")
    parser.add_argument("paths", nargs="+")
    parser.add_argument("--title", default="paths")
    parser.add_argument("--geometry")
    parser.add_argument("--png", action="store_true")
    args = parser.parse_args()
    paths = [load(a) for a in args.paths]
    frames = paths[0][1].get("path", paths[0][1]).get("frames", [])
    warnings = paths[0][3].get("warnings", [])
    drawn = [{"label": label, "points": prof.p, "profile": prof} for label, _, prof, _ in paths]
    fig = gp.path_figure(drawn, frames, args.title, warnings=warnings,
                         notes=["key frames numbered from 0 as in the request; the first path's frames and warnings"])
    gp.save(fig, args.out, args.png)
    if args.geometry:
        fig = gp.geometry_figure([{"label": label, "profile": prof} for label, _, prof, _ in paths],
                                 f"{args.title}: curvature and torsion along the path", frames=frames,
                                 warnings=warnings)
        gp.save(fig, args.geometry, args.png)


if __name__ == "__main__":
    main()
