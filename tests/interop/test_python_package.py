#!/usr/bin/env python3
"""The Python package client/python (`geotraj`) installed as a user installs it, then used
against a real geotrajd.

Copies the package and proto/ as a fresh clone has them (no build/, no generated stubs),
makes a venv with --system-site-packages (Debian's python3-grpcio, python3-protobuf and
python3-numpy), installs the package offline:

    V/bin/pip install --no-index --no-build-isolation <copy>/client/python

and, with the venv's python and outside the source tree, runs this file again (--inside),
whose tests use the installed package: the thesis's demo paths planned and streamed (NumPy
shapes, finite values, the duration the plan announces, velocities against finite differences
of the positions within h/2 max|a|), CSV written and read back exactly, the bad request's four
field violations and a PreconditionFailure as GeotrajError, forward and inverse kinematics
round trips with the Jacobian against finite differences, Execute under an override, a pause,
a resume and a stop, a jog, an analysis; and checks that need no server (requests as dicts and
files, errors, CSV). Outside it: `import geotraj` without grpcio, numpy or protobuf says what
to install, and the two examples run on the installed package.

Run: test_python_package.py --source . --server build/server/geotrajd --scratch /tmp/geotraj-pkg
"""
import argparse
import csv
import io
import json
import os
import re
import shutil
import subprocess
import sys
import unittest

import geotrajd_process

ARGS = None
DEMO = ("plan_demo_path_a.json", "plan_demo_path_b.json", "plan_demo_path_c.json")
COLUMNS = ["t", "u", "s", "segment", "x", "y", "z", "qw", "qx", "qy", "qz", "vx", "vy", "vz", "ax", "ay", "az",
           "speed"]


def clean_env(**extra):
    """The environment without what would make pip reach for an index or wheels elsewhere, or
    Python look at other packages."""
    env = {k: v for k, v in os.environ.items()
           if not k.startswith("PIP_") and k not in ("PYTHONPATH", "PYTHONHOME", "GEOTRAJ_PY_STUBS",
                                                     "GEOTRAJ_ADDRESS", "GEOTRAJ_TOKEN", "VIRTUAL_ENV")}
    env.update(extra)
    return env


def geotrajd(server, log_path):
    """geotrajd on 127.0.0.1:0 without the caller's token or TLS settings."""
    env = {k: v for k, v in os.environ.items()
           if not k.startswith("GEOTRAJ_AUTH") and not k.startswith("GEOTRAJ_TLS")}
    return geotrajd_process.start_geotrajd(server, log_path, env=env)


# =============================================================================================
# Outside: the venv, the install, the import errors, the examples.
# =============================================================================================

class InstalledPackage(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        scratch = os.path.abspath(ARGS.scratch)
        shutil.rmtree(scratch, ignore_errors=True)
        os.makedirs(scratch)
        cls.scratch = scratch
        # A fresh clone's files: the package's sources and proto/, nothing that a build wrote.
        clone = os.path.join(scratch, "clone")
        ignore = shutil.ignore_patterns("build", "dist", "*.egg-info", "__pycache__", "gen", "*_pb2.py",
                                        "*_pb2_grpc.py", "*.csv")
        shutil.copytree(os.path.join(ARGS.source, "client", "python"), os.path.join(clone, "client", "python"),
                        ignore=ignore)
        shutil.copytree(os.path.join(ARGS.source, "proto"), os.path.join(clone, "proto"), ignore=ignore)
        cls.venv = os.path.join(scratch, "venv")
        cls.python = os.path.join(cls.venv, "bin", "python")
        subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", cls.venv], check=True,
                       capture_output=True, text=True, env=clean_env())
        cls.install = subprocess.run(
            [os.path.join(cls.venv, "bin", "pip"), "install", "--no-index", "--no-build-isolation",
             os.path.join(clone, "client", "python")],
            capture_output=True, text=True, timeout=600, cwd=scratch, env=clean_env())
        if cls.install.returncode != 0:
            raise RuntimeError(f"pip install failed:\n{cls.install.stdout}\n{cls.install.stderr}")
        cls.proc, cls.address, cls.log = geotrajd(ARGS.server, os.path.join(scratch, "geotrajd.log"))

    @classmethod
    def tearDownClass(cls):
        cls.proc.terminate()
        cls.proc.wait(timeout=30)
        cls.log.close()

    def run_python(self, *args, timeout=300, **kwargs):
        return subprocess.run([self.python, *args], capture_output=True, text=True, timeout=timeout,
                              cwd=kwargs.pop("cwd", self.scratch), env=clean_env(**kwargs))

    def test_installed_in_the_venv_with_its_stubs(self):
        self.assertIn("Successfully installed geotraj", self.install.stdout)
        res = self.run_python("-c", "import geotraj, geotraj.v1.geotraj_pb2 as g, geotraj._rpc.status_pb2 as s; "
                                    "print(geotraj.__file__); print(g.__file__); print(s.__file__); "
                                    "print(geotraj.__version__)")
        self.assertEqual(res.returncode, 0, res.stderr)
        package, stubs, rpc, version = res.stdout.split()
        site = os.path.join(self.venv, "lib")
        for path in (package, stubs, rpc):
            self.assertTrue(path.startswith(site), f"{path} is not in the venv")
        with open(os.path.join(ARGS.source, "CMakeLists.txt")) as f:
            project = re.search(r"project\(geotraj VERSION (\S+)", f.read()).group(1)
        self.assertEqual(version, project)
        res = self.run_python("-m", "pip", "show", "geotraj")
        requires = re.search(r"(?m)^Requires: (.*)$", res.stdout).group(1)
        self.assertEqual(sorted(r.strip() for r in requires.split(",")), ["grpcio", "numpy", "protobuf"])

    def test_missing_dependency_names_what_to_install(self):
        # Each dependency hidden from the import system in turn: one ImportError that names the
        # Debian package and the pip requirement, raised from geotraj's own check.
        for module, deb, pip in (("grpc", "python3-grpcio", "grpcio"), ("numpy", "python3-numpy", "numpy"),
                                 ("google.protobuf", "python3-protobuf", "protobuf>=3.20")):
            hide = ("import sys, importlib.abc\n"
                    "class Hide(importlib.abc.MetaPathFinder):\n"
                    f"    def find_spec(self, name, path=None, target=None):\n"
                    f"        if name == {module!r} or name.startswith({module + '.'!r}):\n"
                    f"            raise ModuleNotFoundError(f'No module named {{name!r}}', name=name)\n"
                    "sys.meta_path.insert(0, Hide())\n"
                    "import geotraj\n")
            res = self.run_python("-c", hide)
            self.assertEqual(res.returncode, 1, res.stdout + res.stderr)
            last = res.stderr.strip().splitlines()[-1]
            self.assertTrue(last.startswith("ImportError: geotraj needs"), res.stderr)
            self.assertIn(f"apt-get install {deb}", last)
            self.assertIn(f"pip install '{pip}'", last)
            self.assertIn("--system-site-packages", last)
            self.assertNotIn("During handling", res.stderr)  # no chained traceback from deep inside
            self.assertNotIn("_pb2", res.stderr)

    def test_source_tree_without_stubs_says_how_to_get_them(self):
        # The clone's package imported from its directory, uninstalled and with no stubs
        # generated there: the ImportError says where stubs come from.
        clone = os.path.join(self.scratch, "clone", "client", "python")
        res = subprocess.run([sys.executable, "-c", "import geotraj"], capture_output=True, text=True, cwd=clone,
                             env=clean_env(GEOTRAJ_PY_STUBS=os.path.join(self.scratch, "no-stubs")), timeout=60)
        self.assertEqual(res.returncode, 1, res.stdout + res.stderr)
        last = res.stderr.strip().splitlines()[-1]
        self.assertTrue(last.startswith("ImportError: geotraj: the generated gRPC stubs are missing"), res.stderr)
        for words in ("pip install ./client/python", "client/python/gen", "$GEOTRAJ_PY_STUBS"):
            self.assertIn(words, last)

    def test_the_client_from_outside_the_source_tree(self):
        script = os.path.join(self.scratch, "installed_client_checks.py")
        shutil.copyfile(os.path.abspath(__file__), script)
        here = os.path.dirname(os.path.abspath(__file__))
        shutil.copyfile(os.path.join(here, "geotrajd_process.py"), os.path.join(self.scratch, "geotrajd_process.py"))
        res = self.run_python(script, "--inside", "--address", self.address, "--source", ARGS.source,
                              "--scratch", self.scratch, "--server", ARGS.server)
        sys.stderr.write(res.stderr)
        self.assertEqual(res.returncode, 0, res.stdout + res.stderr)
        self.assertRegex(res.stderr, r"Ran \d+ tests")

    def run_example(self, example, *args):
        """An example of client/python run by the venv's python as a script (its directory first
        on sys.path, as when run from a shell); prints which geotraj it imported to stderr."""
        path = os.path.join(ARGS.source, "client", "python", example)
        wrapper = ("import os, runpy, sys\n"
                   f"sys.argv = [{path!r}] + sys.argv[1:]\n"
                   f"sys.path.insert(0, {os.path.dirname(path)!r})\n"
                   "try:\n"
                   "    runpy.run_path(sys.argv[0], run_name='__main__')\n"
                   "except SystemExit as e:\n"
                   "    print('geotraj from', sys.modules['geotraj'].__file__, file=sys.stderr)\n"
                   "    raise\n")
        return self.run_python("-c", wrapper, *args, GEOTRAJ_PY_STUBS=os.path.join(self.scratch, "no-stubs"))

    def test_examples_on_the_installed_package(self):
        out = os.path.join(self.scratch, "path_b.csv")
        res = self.run_example("geotraj_example.py", "--server", self.address, "--request",
                               os.path.join(ARGS.source, "client", "grpcurl", "plan_demo_path_b.json"), "--csv", out)
        self.assertEqual(res.returncode, 0, res.stdout + res.stderr)
        self.assertIn(f"stream: 1001 samples written to {out}", res.stdout)
        self.assertIn(f"geotraj from {os.path.join(self.venv, 'lib')}", res.stderr)
        with open(out, newline="") as f:
            rows = list(csv.reader(f))
        self.assertEqual(rows[0], COLUMNS)
        self.assertEqual(len(rows), 1002)
        res = self.run_example("geotraj_live.py", "--address", self.address, "jog", "--robot", "panda", "--joint", "3",
                               "--seconds", "0.3", "--csv", "-")
        self.assertEqual(res.returncode, 0, res.stdout + res.stderr)
        self.assertIn("end: stopped (OK)", res.stderr)  # the progress goes to stderr with '-'
        self.assertIn(f"geotraj from {os.path.join(self.venv, 'lib')}", res.stderr)
        rows = list(csv.reader(io.StringIO(res.stdout)))
        count = int(re.search(r"end: stopped \(OK\), (\d+) samples", res.stderr).group(1))
        self.assertEqual(len(rows), count + 1)
        self.assertEqual(rows[0], COLUMNS + [f"q{j}" for j in range(7)])  # Jog's set points carry no torques
        moved = re.search(r"joint 3: from (\S+) to (\S+) rad", res.stderr)
        self.assertAlmostEqual(float(rows[1][18 + 3]), float(moved.group(1)), places=6)
        self.assertAlmostEqual(float(rows[-1][18 + 3]), float(moved.group(2)), places=6)


# =============================================================================================
# Inside: the installed package, run by the venv's python.
# =============================================================================================

def request_path(name):
    return os.path.join(ARGS.source, "client", "grpcurl", name)


class Offline(unittest.TestCase):
    """What needs no server."""

    def test_requests_as_message_dict_and_file(self):
        import geotraj
        from geotraj import pb
        with open(request_path("plan_demo_path_a.json")) as f:
            as_dict = json.load(f)
        from_file = geotraj.as_message(request_path("plan_demo_path_a.json"), pb.PlanRequest)
        from_dict = geotraj.as_message(as_dict, pb.PlanRequest)
        self.assertEqual(from_file, from_dict)
        self.assertIs(geotraj.as_message(from_file, pb.PlanRequest), from_file)
        self.assertEqual(len(from_file.path.frames), 4)
        self.assertEqual(geotraj.to_dict(from_file), geotraj.to_dict(from_dict))
        bad = dict(as_dict, motion={"durationS": "ten"})
        with self.assertRaises(ValueError) as ctx:
            geotraj.as_message(bad, pb.PlanRequest)
        self.assertIn("durationS", str(ctx.exception))
        self.assertIn("geotraj.v1.PlanRequest", str(ctx.exception))
        with self.assertRaises(ValueError) as ctx:
            geotraj.as_message({"pathh": {}}, pb.PlanRequest)
        self.assertIn("pathh", str(ctx.exception))
        with self.assertRaises(TypeError) as ctx:
            geotraj.as_message(pb.ListRobotsRequest(), pb.PlanRequest)
        self.assertIn("geotraj.v1.ListRobotsRequest", str(ctx.exception))
        with self.assertRaises(TypeError):
            geotraj.as_message(42, pb.PlanRequest)
        with self.assertRaises(FileNotFoundError):
            geotraj.as_message(os.path.join(ARGS.scratch, "no-such.json"), pb.PlanRequest)

    def test_error_text(self):
        import grpc
        import geotraj
        e = geotraj.GeotrajError(grpc.StatusCode.INVALID_ARGUMENT, "invalid request: 1 problem",
                                 [("path.frames[0].tangent", "is required")],
                                 [("JOINT_VELOCITY", "joint 1", "over its limit")])
        self.assertEqual(e.code_name, "INVALID_ARGUMENT")
        self.assertEqual(e.field_violations, [("path.frames[0].tangent", "is required")])
        self.assertEqual(e.field_violations[0].field, "path.frames[0].tangent")
        self.assertEqual(e.precondition_violations[0].subject, "joint 1")
        self.assertIn("  path.frames[0].tangent: is required", str(e))
        self.assertEqual(e.describe().splitlines(),
                         ["error: INVALID_ARGUMENT: invalid request: 1 problem", "bad request, field violations:",
                          "  path.frames[0].tangent: is required", "precondition failure, violations:",
                          "  [JOINT_VELOCITY] joint 1: over its limit"])

    def test_csv_rejects_what_it_did_not_write(self):
        import geotraj
        with self.assertRaisesRegex(ValueError, "header starts"):
            geotraj.Samples.read_csv(io.StringIO("a,b,c\n1,2,3\n"))
        with self.assertRaisesRegex(ValueError, "unexpected columns after `speed`: \\['q0', 'q2'\\]"):
            geotraj.Samples.read_csv(io.StringIO(",".join(COLUMNS + ["q0", "q2"]) + "\n"))
        with self.assertRaisesRegex(ValueError, "row 1: 3 values for 18 columns"):
            geotraj.Samples.read_csv(io.StringIO(",".join(COLUMNS) + "\n1,2,3\n"))
        self.assertEqual(geotraj.csv_header(2, 2, True), COLUMNS + ["q0", "q1", "tau0", "tau1", "step"])

    def test_unreachable_server(self):
        import geotraj
        with geotraj.Client("127.0.0.1:1", timeout=3) as client:
            with self.assertRaises(geotraj.GeotrajError) as ctx:
                client.list_robots()
        self.assertIn(ctx.exception.code_name, ("UNAVAILABLE", "DEADLINE_EXCEEDED"))


class AgainstGeotrajd(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        import geotraj
        cls.client = geotraj.Client(ARGS.address, timeout=120)
        cls.client.wait_ready(30)

    @classmethod
    def tearDownClass(cls):
        cls.client.close()

    def test_the_installed_package_is_used(self):
        import geotraj
        self.assertTrue(geotraj.__file__.startswith(sys.prefix), geotraj.__file__)
        package_source = os.path.join(os.path.abspath(ARGS.source), "client", "python") + os.sep
        self.assertFalse(os.path.abspath(geotraj.__file__).startswith(package_source), geotraj.__file__)

    def check_samples(self, name, samples, plan):
        import numpy as np
        n = plan.motion.sample_count
        self.assertEqual(len(samples), n, name)
        joints = samples.joint_count
        for field, shape in (("t", (n,)), ("u", (n,)), ("s", (n,)), ("segment", (n,)), ("step", (n,)),
                             ("position", (n, 3)), ("orientation", (n, 4)), ("velocity", (n, 3)),
                             ("acceleration", (n, 3)), ("angular_velocity", (n, 3)), ("speed", (n,)),
                             ("q", (n, joints)), ("qd", (n, joints)), ("qdd", (n, joints))):
            value = getattr(samples, field)
            self.assertEqual(value.shape, shape, f"{name}: {field}")
            self.assertTrue(np.all(np.isfinite(value)), f"{name}: {field} not finite")
        self.assertEqual(samples.torques.shape[0], n)
        self.assertIn(samples.torques.shape[1], (0, joints))
        self.assertEqual(samples.t[0], 0.0)
        self.assertAlmostEqual(samples.duration, plan.motion.duration_s, delta=1e-9)
        h = np.diff(samples.t)
        self.assertTrue(np.all(h > 0), f"{name}: time not increasing")
        np.testing.assert_allclose(np.linalg.norm(samples.orientation, axis=1), 1.0, atol=1e-9)
        np.testing.assert_allclose(samples.speed, np.linalg.norm(samples.velocity, axis=1), atol=1e-9)
        # The central difference is the mean velocity over [t-h, t+h]: within h/2 max|a| of v(t)
        # (max|a| over the samples, with 10 % for what lies between them).
        span = (samples.t[2:] - samples.t[:-2])[:, None]
        fd = (samples.position[2:] - samples.position[:-2]) / span
        bound = h.max() / 2 * 1.1 * np.linalg.norm(samples.acceleration, axis=1).max() + 1e-9
        worst = np.abs(fd - samples.velocity[1:-1]).max()
        self.assertLessEqual(worst, bound, f"{name}: velocity against finite differences of position")
        if joints:
            fdq = (samples.q[2:] - samples.q[:-2]) / span
            bound_q = h.max() / 2 * 1.1 * np.abs(samples.qdd).max(axis=0) + 1e-9
            self.assertTrue(np.all(np.abs(fdq - samples.qd[1:-1]).max(axis=0) <= bound_q),
                            f"{name}: joint velocities against finite differences of the joints")
        print(f"[ measured ] {name}: {n} samples, {samples.duration:.4f} s, velocity vs differences "
              f"{worst:.3g} m/s (bound {bound:.3g})", file=sys.stderr)

    def test_demo_paths_planned_and_streamed(self):
        for name in DEMO:
            plan = self.client.plan(request_path(name))
            self.assertEqual(len(plan.segments), 3, name)
            self.assertLess(plan.closed_loop.max_error, 1e-9)
            samples = self.client.stream(request_path(name))
            self.check_samples(name, samples, plan)
            self.assertEqual(samples.joint_count, 0)
            self.assertAlmostEqual(samples.s[-1], plan.arc_length, delta=1e-9 * plan.arc_length)
            self.assertEqual(sorted(set(samples.segment.tolist())), [0, 1, 2])

    def test_robot_plans_streamed(self):
        for name in ("plan_joint_path_panda.json", "sequence_blended_ur5.json", "plan_panda_path_c.json"):
            plan = self.client.plan(request_path(name))
            samples = self.client.stream(request_path(name))
            self.check_samples(name, samples, plan)
            self.assertGreater(samples.joint_count, 0)
        self.assertEqual(samples.joint_count, 7)  # the Panda's

    def test_csv_written_and_read_back(self):
        import numpy as np
        import geotraj
        for name, steps, torques in (("plan_joint_path_panda.json", False, 7), ("sequence_blended_ur5.json", True, 0),
                                     ("plan_demo_path_c.json", False, 0)):
            samples = self.client.stream(request_path(name))
            self.assertEqual(samples.steps, steps, name)
            out = os.path.join(ARGS.scratch, name.replace(".json", ".csv"))
            samples.write_csv(out)
            with open(out, newline="") as f:
                rows = list(csv.reader(f))
            joints = samples.joint_count
            self.assertEqual(rows[0], COLUMNS + [f"q{j}" for j in range(joints)] + [f"tau{j}" for j in range(torques)]
                             + (["step"] if steps else []), name)
            self.assertEqual(len(rows), len(samples) + 1)
            back = geotraj.Samples.read_csv(out)
            for field in ("t", "u", "s", "segment", "step", "position", "orientation", "velocity", "acceleration",
                          "speed", "q", "torques"):
                self.assertTrue(np.array_equal(getattr(back, field), getattr(samples, field)), f"{name}: {field}")
            self.assertEqual(back.steps, steps)
            # Streamed straight to CSV: the same text.
            text = io.StringIO()
            count = self.client.stream_csv(request_path(name), text)
            self.assertEqual(count, len(samples))
            with open(out, newline="") as f:
                self.assertEqual(text.getvalue(), f.read(), name)
            if steps:
                self.assertEqual(sorted(set(back.step.tolist())), [0, 1, 2, 3])

    def test_bad_request_raises_with_field_violations(self):
        import grpc
        import geotraj
        fields = ["path.frames[0].tangent", "path.frames[1].torsion", "path.frames[2].tangent", "analysisPoints"]
        # StreamSamples also needs the motion that the file does not give: a fifth problem.
        for call, expected in ((self.client.plan, fields), (self.client.analyze, fields),
                               (self.client.stream, fields + ["motion"])):
            with self.assertRaises(geotraj.GeotrajError) as ctx:
                call(request_path("bad_request.json"))
            e = ctx.exception
            self.assertEqual(e.code, grpc.StatusCode.INVALID_ARGUMENT)
            self.assertIn(f"{len(expected)} problems", e.message)
            self.assertEqual([f for f, _ in e.field_violations], expected)
            self.assertTrue(all(d for _, d in e.field_violations))
            self.assertIn("got (2, 0, 0) of length 2", e.field_violations[0].description)
            self.assertEqual(e.precondition_violations, [])

    def test_precondition_failure(self):
        # Path A in the thesis's 10 s is too fast for the PA-10: FAILED_PRECONDITION with the
        # joints' violations in a google.rpc.PreconditionFailure.
        import grpc
        import geotraj
        with open(request_path("plan_demo_path_a.json")) as f:
            request = json.load(f)
        request["robot"] = {"name": "pa10"}
        with self.assertRaises(geotraj.GeotrajError) as ctx:
            self.client.plan(request)
        e = ctx.exception
        self.assertEqual(e.code, grpc.StatusCode.FAILED_PRECONDITION)
        self.assertGreater(len(e.precondition_violations), 0)
        for v in e.precondition_violations:
            self.assertRegex(v.subject, r"^joint \d$")
            self.assertIn("sample", v.description)
        request["robot"]["reportOnly"] = True
        report = self.client.plan(request).robot
        self.assertEqual([(v.type, v.subject) for v in e.precondition_violations],
                         [(geotraj.pb.LimitKind.Name(x.kind), f"joint {x.joint}") for x in report.violations])

    def test_forward_and_inverse_kinematics(self):
        import numpy as np
        rng = np.random.default_rng(7)
        robots = self.client.robots()
        self.assertTrue({"pa10", "ur5", "panda"} <= set(robots))
        for name in ("ur5", "panda", "pa10"):
            model = robots[name]
            lo = np.array([lim.min_position for lim in model.limits])
            hi = np.array([lim.max_position for lim in model.limits])
            q = lo + (hi - lo) * rng.uniform(0.3, 0.7, size=len(lo))
            fk = self.client.forward_kinematics(name, q)
            self.assertEqual(fk.jacobian.shape, (6, len(q)))
            self.assertEqual(fk.axes.shape, (len(q), 2, 3))
            self.assertTrue(fk.within_limits)
            self.assertAlmostEqual(float(np.linalg.norm(fk.orientation)), 1.0, delta=1e-12)
            # The Jacobian's linear rows against central differences of the tool position.
            eps = 1e-6
            for j in range(len(q)):
                dq = np.zeros(len(q))
                dq[j] = eps
                d = (self.client.forward_kinematics(name, q + dq).position
                     - self.client.forward_kinematics(name, q - dq).position) / (2 * eps)
                np.testing.assert_allclose(fk.jacobian[:3, j], d, atol=1e-7, err_msg=f"{name} joint {j}")
            # Back from the pose: every solution reaches it; seeded at q, the first is q.
            ik = self.client.inverse_kinematics(name, fk.position, fk.orientation, all_solutions=True)
            self.assertTrue(ik.reachable, name)
            self.assertEqual(ik.solutions.shape[1], len(q))
            for sol in ik.solutions:
                back = self.client.forward_kinematics(name, sol)
                self.assertLess(np.linalg.norm(back.position - fk.position), 1e-8, name)
                self.assertGreater(abs(float(np.dot(back.orientation, fk.orientation))), 1 - 1e-12, name)
            seeded = self.client.inverse_kinematics(name, fk.position, fk.orientation, seed=q)
            np.testing.assert_allclose(seeded.solutions[0], q, atol=1e-6, err_msg=name)
        far = self.client.inverse_kinematics("ur5", (2.0, 0.0, 0.5))
        self.assertFalse(far.reachable)
        self.assertEqual(far.solutions.shape, (0, 6))
        self.assertEqual(far.closest.shape, (6,))
        fk_request = self.client.forward_kinematics({"robot": {"name": "ur5"}, "joints": [0, -1.2, 1.3, -1.6, -1.5, 0]})
        self.assertEqual(fk_request.jacobian.shape, (6, 6))

    def test_execute_with_override_pause_resume_and_stop(self):
        import numpy as np
        import geotraj
        execution = self.client.execute(request_path("joint_move_pa10.json"))
        states, sent = [], {}
        script = [("override", 0.3, lambda: execution.set_override(50)), ("pause", 1.4, execution.pause),
                  ("resume", 2.4, execution.resume), ("stop", 2.7, execution.stop)]
        with execution:
            for batch in execution:
                last = batch.samples[-1]
                states.append(execution.state)
                while script and last.t >= script[0][1]:
                    what, _, control = script.pop(0)
                    control()
                    sent[what] = last.t
        self.assertEqual(list(sent), ["override", "pause", "resume", "stop"])
        self.assertEqual(execution.stop_reason, "stopped")
        self.assertEqual(execution.state, "stopped")
        self.assertIn("paused", states)
        samples = execution.samples()
        t, factor, plan_time = samples.t, samples.speed_factor, samples.plan_time
        self.assertEqual(len(samples), execution.sample_count)
        self.assertEqual(samples.q.shape, (len(samples), 7))
        self.assertIsNotNone(factor)
        np.testing.assert_array_equal(factor[t <= sent["override"]], 1.0)
        before_pause = factor[(t > sent["override"]) & (t <= sent["pause"])]
        self.assertTrue(np.any(np.abs(before_pause - 0.5) < 1e-9), "the override never reached 50 %")
        self.assertTrue(np.all(before_pause >= 0.5 - 1e-9))
        held = (t > sent["pause"]) & (t <= sent["resume"]) & (factor == 0.0)
        self.assertGreater(np.count_nonzero(held), 10, "never held at rest in the pause")
        self.assertEqual(np.ptp(plan_time[held]), 0.0)
        self.assertTrue(np.any(factor[t > sent["resume"]] > 0.0), "no motion after the resume")
        self.assertTrue(np.all(np.diff(plan_time) >= 0))
        self.assertLess(plan_time[-1], 2.2)  # stopped before the plan's end (2.3 s at full speed)
        self.assertEqual(factor[-1], 0.0)
        np.testing.assert_allclose(samples.qd[-1], 0.0, atol=1e-9)
        # A bad control message: INVALID_ARGUMENT naming the field, the motion at rest first.
        execution = self.client.execute(request_path("joint_move_pa10.json"), record=False)
        with self.assertRaises(geotraj.GeotrajError) as ctx:
            for batch in execution:
                if batch.samples[-1].t > 0.2:
                    execution.set_override(150)
        self.assertEqual(ctx.exception.code_name, "INVALID_ARGUMENT")
        self.assertEqual(ctx.exception.stop_reason, "invalid")
        self.assertEqual([f for f, _ in ctx.exception.field_violations], ["speedOverride"])

    def test_jog(self):
        import numpy as np
        jog = self.client.jog("panda", record=True)
        commanded = stopping = False
        with jog:
            for batch in jog:
                if not commanded:
                    jog.joints([0, 0, 0, 0.5, 0, 0, 0])
                    commanded = True
                if not stopping and batch.samples[-1].t >= 0.4:
                    jog.stop()
                    stopping = True
        self.assertEqual(jog.stop_reason, "stopped")
        samples = jog.samples()
        self.assertGreater(samples.q[-1, 3] - samples.q[0, 3], 0.05)
        np.testing.assert_allclose(samples.q[-1, [0, 1, 2, 4, 5, 6]], samples.q[0, [0, 1, 2, 4, 5, 6]], atol=1e-12)
        np.testing.assert_allclose(samples.qd[-1], 0.0, atol=1e-9)

    def test_analyze(self):
        import numpy as np
        profile = self.client.analyze(request_path("plan_demo_path_a.json"), points=201)
        plan = self.client.plan(request_path("plan_demo_path_a.json"))
        self.assertEqual(profile.position.shape, (201, 3))
        self.assertAlmostEqual(profile.arc_length, plan.arc_length, delta=1e-9)
        self.assertEqual(profile.s[0], 0.0)
        self.assertAlmostEqual(profile.s[-1], plan.arc_length, delta=1e-9)
        self.assertTrue(np.all(np.diff(profile.s) >= 0))
        np.testing.assert_allclose(profile.position[0], (0.106, 0, 0.975), atol=1e-12)
        np.testing.assert_allclose(np.linalg.norm(profile.tangent, axis=1), 1.0, atol=1e-9)
        self.assertGreater(np.count_nonzero(np.isfinite(profile.curvature)), 190)


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--source", required=True, help="the repository's root")
    parser.add_argument("--server", required=True, help="the geotrajd binary")
    parser.add_argument("--scratch", required=True, help="a directory the test may empty and fill")
    parser.add_argument("--inside", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--address", help=argparse.SUPPRESS)
    ARGS, rest = parser.parse_known_args()
    ARGS.source = os.path.abspath(ARGS.source)
    if not ARGS.inside:
        # What a venv that builds the package needs from Debian: ensurepip's wheels (python3-venv),
        # bdist_wheel (python3-wheel) and NumPy (python3-numpy).
        probe = subprocess.run([sys.executable, "-c", "import ensurepip, wheel, numpy, grpc, google.protobuf"],
                               capture_output=True, text=True)
        if probe.returncode != 0:
            print(f"skipped: {sys.executable} cannot make the venv or build the package "
                  f"({probe.stderr.strip().splitlines()[-1]}); Debian: apt-get install python3-venv python3-wheel "
                  "python3-numpy", file=sys.stderr)
            sys.exit(77)
    if ARGS.inside:
        suite = unittest.TestSuite([unittest.defaultTestLoader.loadTestsFromTestCase(c)
                                    for c in (Offline, AgainstGeotrajd)])
        sys.exit(0 if unittest.TextTestRunner(verbosity=2).run(suite).wasSuccessful() else 1)
    del Offline, AgainstGeotrajd  # run by the venv's python, through InstalledPackage
    unittest.main(argv=[sys.argv[0]] + rest, verbosity=2)
