#!/usr/bin/env python3
"""The thesis's demonstration on the Mitsubishi PA-10 in joint space, through the geotraj CLI.

Usage: robot_demo.py CLI [OUT_DIR]
  CLI      the geotraj command-line client (e.g. build/client/geotraj)
  OUT_DIR  where the SVG plots go (default out)

For paths A, B, C at 10 s (Tables 7.8 and 7.18, 100 Hz) with the built-in "pa10" model:
PlanTrajectory's joint report (limit margins, IK residuals, joint-interpolation deviation,
manipulability), then the joint samples streamed and plotted against time (positions,
velocities, accelerations), with the joint limits; the time-optimal timing of each path and,
for path C, which limit binds where. The figures are drawn by scripts/geotraj_plot.py
(matplotlib, Debian's python3-matplotlib).
"""
import csv
import io
import json
import os
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import geotraj_plot as gp  # noqa: E402

REQUESTS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "client", "grpcurl")


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


def plot(filename, path, t, q, qd, qdd, model):
    fig = gp.joints_figure(f"PA-10 joint trajectories, thesis path {path}, {t[-1]:.3g} s, 100 Hz "
                           "(margins to the limits: see the plan report)", t, q, qd, qdd, gp.effective_limits(model),
                           gp.joint_names(model), gp.joint_unit(model))
    gp.save(fig, filename)


def time_optimal(cli, tmp, model, out):
    """Thesis 6.4 made explicit: the fastest timing of each path within the PA-10's joint
    limits (exact time-optimal parameterisation), against the thesis's fixed 10 s."""
    print("\n=== Time-optimal timing on the PA-10 (optimize.timing.timeOptimal: the joint limits set the time)")
    print(f"{'path':>4} {'thesis':>8} {'time-optimal':>13} {'feasible':>9}   tightest margins (joint: kind usage)")
    for path in "ABC":
        with open(os.path.join(REQUESTS, f"plan_demo_path_{path.lower()}.json")) as f:
            req = json.load(f)
        req["motion"] = {"durationS": 0, "cycleRateHz": 100}
        req["robot"] = {"name": "pa10"}
        # Explicitly the time-optimal sweep: without it the PA-10 (no jerk limits) is timed
        # jerk-limited under the default bound (docs/kinematics.md), a little slower.
        req["optimize"] = {"timing": {"timeOptimal": True}}
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
            timed = json.loads(run(cli, "--json", "plan", "--time-optimal", name))
            stretches = (timed.get("optimization", {}).get("timing", {}).get("binding")
                         or timed.get("robot", {}).get("binding", []))
            duration = timed["motion"]["durationS"]
            fig = gp.binding_figure(f"PA-10, thesis path C time-optimal in {duration:.3f} s: which limit binds where",
                                    stretches, gp.joint_names(model), duration=duration)
            file = os.path.join(out, "binding_path_c_time_optimal.svg")
            gp.save(fig, file)
            print(f"wrote {file} ({len(stretches)} stretches)")


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
