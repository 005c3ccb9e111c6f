#!/usr/bin/env python3
"""scripts/geotraj_plot.py on made-up data: a helix (constant curvature r / (r^2 + c^2) and
torsion c / (r^2 + c^2)) with three key frames, a two-joint robot whose acceleration limit
the samples break eight-fold, and a binding report. Checks what a reader looks for in the
SVGs (axis labels with units, one marker per key frame, the limit lines by id, the
overshoot written out), that the files are reproducible byte for byte and carry no date,
and the effective joint limits of a RobotSpec.

Usage: test_geotraj_plot.py [SCRIPTS_DIR]   (default: ../../scripts from this file)
"""
import math
import os
import sys
import tempfile
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
SCRIPTS = sys.argv.pop(1) if len(sys.argv) > 1 else os.path.join(HERE, "..", "..", "scripts")
sys.path.insert(0, SCRIPTS)
import geotraj_plot as gp  # noqa: E402

R, C = 0.1, 0.02  # helix radius and pitch / 2 pi [m]
KAPPA, TAU = R / (R * R + C * C), C / (R * R + C * C)


def helix_profile(n=201, turns=2):
    """A PathProfile of a helix over u in [0, 2] (two segments, three key frames)."""
    pts, length = [], 2 * math.pi * turns * math.hypot(R, C)
    for k in range(n):
        u = 2.0 * k / (n - 1)
        phi = 2 * math.pi * turns * u / 2
        h = math.hypot(R, C)
        pts.append({
            "u": u, "s": length * u / 2, "segment": min(int(u), 1),
            "position": {"x": R * math.cos(phi), "y": R * math.sin(phi), "z": C * phi},
            "tangent": {"x": -R * math.sin(phi) / h, "y": R * math.cos(phi) / h, "z": C / h},
            "normal": {"x": -math.cos(phi), "y": -math.sin(phi), "z": 0.0},
            "curvature": KAPPA, "torsion": TAU, "curvatureDerivative": 0.0, "torsionDerivative": 0.0,
            "speed": length / 2})
    return {"points": pts, "arcLength": length}


def request():
    frames = []
    prof = helix_profile(3)
    for k, p in enumerate(prof["points"]):
        frames.append({"position": p["position"], "tangent": p["tangent"], "normal": p["normal"]})
    frames[1]["curvature"] = KAPPA
    frames[1]["torsion"] = TAU
    return {"path": {"frames": frames}, "motion": {"durationS": 0, "maxSpeed": 0.5},
            "robot": {"name": "two", "velocityScale": 0.5, "jointLimits": [{"joint": "elbow", "maxAcceleration": 4}]}}


MODEL = {"name": "two", "links": [{"name": "shoulder"}, {"name": "elbow"}],
         "limits": [{"minPosition": -2, "maxPosition": 2, "maxVelocity": 2, "maxAcceleration": 10},
                    {"minPosition": -1, "maxPosition": 1, "maxVelocity": 3, "maxAcceleration": 5, "maxJerk": 100}]}


def write_samples(path, n=301, duration=3.0):
    head = "t,u,s,segment,x,y,z,qw,qx,qy,qz,vx,vy,vz,ax,ay,az,speed,wx,wy,wz,q0,q1,qd0,qd1,qdd0,qdd1"
    with open(path, "w") as f:
        f.write(head + "\n")
        for k in range(n):
            t = duration * k / (n - 1)
            u = 2.0 * t / duration
            phi = 2 * math.pi * u
            v = 0.3 * math.sin(math.pi * t / duration)
            row = [t, u, u, min(int(u), 1), R * math.cos(phi), R * math.sin(phi), C * phi, 1, 0, 0, 0,
                   0, 0, 0, 0.1, 0, 0, v, 0, 0, 0,
                   0.5 * math.sin(t), 0.2 * t, 0.5 * math.cos(t), 0.2, -0.5 * math.sin(t), 32.0 * math.sin(3 * t)]
            f.write(",".join(f"{x:.17g}" for x in row) + "\n")


PLAN = {"arcLength": helix_profile()["arcLength"], "motion": {"durationS": 3.0},
        "warnings": [{"code": "PLAN_WARNING_CODE_TIGHT_BEND", "segment": 1, "s": 0.9, "message": "tight"}],
        "robot": {"feasible": False, "binding": [
            {"kind": "BINDING_KIND_JOINT_VELOCITY", "joint": 0, "tStart": 0, "tEnd": 1.2, "usage": 1.0},
            {"kind": "BINDING_KIND_JOINT_ACCELERATION", "joint": 1, "tStart": 1.2, "tEnd": 3.0, "usage": 0.97}]}}


class PlotModule(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        cls.dir = cls.tmp.name
        cls.samples = os.path.join(cls.dir, "samples.csv")
        write_samples(cls.samples)
        cls.files = gp.request_figures(request(), PLAN, [helix_profile()], gp.read_samples(cls.samples), MODEL,
                                       os.path.join(cls.dir, "a"), "helix")

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def svg(self, suffix):
        with open(os.path.join(self.dir, "a", f"helix_{suffix}.svg"), encoding="utf-8") as f:
            return f.read()

    def test_every_figure_that_applies(self):
        names = sorted(os.path.basename(f) for f in self.files)
        self.assertEqual(names, ["helix_binding.svg", "helix_geometry.svg", "helix_joints.svg", "helix_path.svg",
                                 "helix_speed.svg"])

    def test_path_views_mark_each_key_frame_once_per_view(self):
        svg = self.svg("path")
        for view in ("3d", "top", "side"):
            self.assertEqual(svg.count(f'id="keyframe-{view}-'), 3, view)
        for label in ("x [m]", "y [m]", "z [m]", "top view (x-y)", "side view (x-z)", "warning 0"):
            self.assertIn(label, svg)
        self.assertIn('id="warning-top-0"', svg)

    def test_geometry_axes_have_units(self):
        svg = self.svg("geometry")
        for label in ("arc length s [m]", "κ [1/m]", "τ [1/m]", "dκ/ds [1/m²]", "dτ/ds [1/m²]"):
            self.assertIn(label, svg)

    def test_joint_limits_drawn_and_overshoot_written(self):
        svg = self.svg("joints")
        for j in (0, 1):
            for key in ("q", "qd", "qdd"):
                for side in ("min", "max"):
                    self.assertIn(f'id="limit-{key}-j{j}-{side}"', svg)
        self.assertIn('id="limit-qdd-usage-max"', svg)
        self.assertIn("q̈ [rad/s²]", svg)
        self.assertIn("time t [s]", svg)
        # elbow: 32 rad/s^2 against its limit of 4 from jointLimits: 800 %.
        self.assertIn("joint 1 elbow at 800 %", svg)
        self.assertIn("beyond its limit", svg)

    def test_speed_and_binding(self):
        speed = self.svg("speed")
        self.assertIn('id="limit-speed"', speed)
        self.assertIn("speed [m/s]", speed)
        binding = self.svg("binding")
        self.assertIn('id="binding-0"', binding)
        self.assertIn('id="binding-1"', binding)
        self.assertIn("joint 1 elbow acceleration", binding)

    def test_reproducible_without_date(self):
        again = gp.request_figures(request(), PLAN, [helix_profile()], gp.read_samples(self.samples), MODEL,
                                   os.path.join(self.dir, "b"), "helix")
        for first, second in zip(sorted(self.files), sorted(again)):
            with open(first, "rb") as f, open(second, "rb") as g:
                self.assertEqual(f.read(), g.read(), first)
        self.assertNotIn("<dc:date>", self.svg("path"))

    def test_track_geometry_from_samples_is_the_helix(self):
        # A helix at constant speed: kappa = r / (r^2 + c^2) from v and a exactly, tau from the
        # jerk by central differences (second order in the step).
        n, w = 2001, 2.0  # samples, angular rate [rad/s]
        cols = {k: [] for k in ("t", "x", "y", "z", "vx", "vy", "vz", "ax", "ay", "az")}
        for k in range(n):
            t = 3.0 * k / (n - 1)
            phi = w * t
            for key, value in (("t", t), ("x", R * math.cos(phi)), ("y", R * math.sin(phi)), ("z", C * phi),
                               ("vx", -R * w * math.sin(phi)), ("vy", R * w * math.cos(phi)), ("vz", C * w),
                               ("ax", -R * w * w * math.cos(phi)), ("ay", -R * w * w * math.sin(phi)), ("az", 0.0)):
                cols[key].append(value)
        track = gp.Profile.from_samples({k: gp.np.array(v) for k, v in cols.items()})
        self.assertLess(float(gp.np.max(gp.np.abs(track.kappa - KAPPA))), 1e-9 * KAPPA)
        inner = track.tau[1:-1]  # one-sided differences at the ends
        self.assertLess(float(gp.np.max(gp.np.abs(inner - TAU))), 1e-4 * TAU)
        self.assertAlmostEqual(track.length, 3.0 * w * math.hypot(R, C), delta=1e-4)

    def test_effective_limits(self):
        lim = gp.effective_limits(MODEL, request()["robot"])
        self.assertEqual([x["velocity"] for x in lim], [1.0, 1.5])   # velocityScale 0.5
        self.assertEqual([x["acceleration"] for x in lim], [10.0, 4.0])  # elbow from jointLimits
        self.assertEqual(lim[1]["jerk"], 100.0)


if __name__ == "__main__":
    unittest.main()
