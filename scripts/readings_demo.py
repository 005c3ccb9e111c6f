#!/usr/bin/env python3
"""The three readings of unspecified constraints side by side on the thesis's demonstration.

Usage: readings_demo.py CLI
  CLI  the geotraj command-line client (e.g. build/client/geotraj)

For paths A, B, C (Tables 7.8, 7.18, with 7.2.8's kappa' = tau' = 0 at frames 2 and 3) under
SMOOTHEST (the default), THESIS_ZEROS and LOWEST_DEGREE: the peak curvature between the
frames (AnalyzePath, 20001 points), the arc length, the peak speed of the 10 s motion, the
PA-10's largest joint velocity and acceleration usage at 10 s (reportOnly), and the
time-optimal duration on the PA-10 (durationS 0). Only the Python standard library.
"""
import json
import os
import subprocess
import sys
import tempfile

REQUESTS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "client", "grpcurl")
READINGS = ["SMOOTHEST", "THESIS_ZEROS", "LOWEST_DEGREE"]


def call(cli, args, request, tmp):
    name = os.path.join(tmp, "request.json")
    with open(name, "w") as f:
        json.dump(request, f)
    done = subprocess.run([cli, "--json", *args, name], capture_output=True, text=True)
    if done.returncode != 0:
        return None, done.stderr.strip().splitlines()[-1] if done.stderr.strip() else "failed"
    return json.loads(done.stdout), None


def main():
    cli = sys.argv[1]
    print("\n=== The three readings of unspecified constraints (PathSpec.unspecified), paths A, B, C")
    print("path  reading         peak kappa [1/m]  length [m]  peak speed [m/s]  PA-10 10 s: vel / acc usage"
          "  time-optimal [s]")
    with tempfile.TemporaryDirectory() as tmp:
        for path in "ABC":
            with open(os.path.join(REQUESTS, f"plan_demo_path_{path.lower()}.json")) as f:
                base = json.load(f)
            for reading in READINGS:
                req = json.loads(json.dumps(base))
                req["path"]["unspecified"] = "UNSPECIFIED_CONSTRAINTS_" + reading
                analysis = dict(req, analysisPoints=20001)
                analysis.pop("motion", None)
                profile, err = call(cli, ["analyze"], analysis, tmp)
                peak = max(p.get("curvature", 0.0) for p in profile["points"]) if profile else float("nan")
                length = profile.get("arcLength", 0.0) if profile else float("nan")
                timed = dict(req, motion={"durationS": 10, "cycleRateHz": 100},
                             robot={"name": "pa10", "reportOnly": True})
                plan, err = call(cli, ["plan"], timed, tmp)
                speed = plan["motion"].get("peakSpeed", 0.0) if plan else float("nan")
                joints = plan.get("robot", {}).get("joints", []) if plan else []
                vel = max((j.get("velocityUsage", 0.0) for j in joints), default=float("nan"))
                acc = max((j.get("accelerationUsage", 0.0) for j in joints), default=float("nan"))
                fastest = dict(req, motion={"durationS": 0, "cycleRateHz": 100}, robot={"name": "pa10"})
                fast, ferr = call(cli, ["plan"], fastest, tmp)
                duration = f"{fast['motion']['durationS']:.3f}" if fast else "refused: " + ferr[:60]
                print(f"{path:4}  {reading:14}  {peak:16.1f}  {length:10.4f}  {speed:16.4f}  "
                      f"{vel * 100:10.0f} % / {acc * 100:5.0f} %  {duration:>16}")
    print("Usage is the peak over the joints of |qd| / limit and |qdd| / limit (the thesis publishes no\n"
          "acceleration limits: geotraj's assumed ones, docs/kinematics.md).")


if __name__ == "__main__":
    main()
