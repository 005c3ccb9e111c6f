#!/usr/bin/env python3
"""The example client client/python/geotraj_example.py run as a user runs it, against a real
geotrajd: a plan streamed to CSV, and a bad request whose field violations it prints. Run by
Debian's python3, where the geotraj package is not installed, the example uses the package
beside it (client/python/geotraj) with the stubs of --stubs.

Run: test_python_example.py --server build/server/geotrajd --stubs build/tests/interop/pystubs
         --example client/python/geotraj_example.py --requests client/grpcurl
"""
import argparse
import csv
import json
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import unittest

import geotrajd_process

ARGS = None


def start_geotrajd(tmp, extra_args, extra_env, dropped):
    """geotrajd on 127.0.0.1:0; its output goes to a file (a pipe that nobody reads could fill
    and block it), whose first line tells the address. Returns (process, address, log)."""
    env = {k: v for k, v in os.environ.items() if k not in dropped and k != "GEOTRAJ_PLAINTEXT"}
    if "--tls-cert" not in extra_args:
        env["GEOTRAJ_PLAINTEXT"] = "true"  # harmless on loopback; excluded with TLS
    env.update(extra_env)
    return geotrajd_process.start_geotrajd(ARGS.server, os.path.join(tmp, "geotrajd.log"), extra_args, env)


class PythonExample(unittest.TestCase):
    CLIENT_ARGS = ()
    # Variables that would make the server ask for tokens or TLS: not in this class's server.
    SERVER_ENV_DROPPED = ("GEOTRAJ_AUTH_TOKEN", "GEOTRAJ_AUTH_TOKENS_FILE", "GEOTRAJ_TLS_CERT",
                          "GEOTRAJ_TLS_KEY", "GEOTRAJ_TLS_CLIENT_CA")
    SERVER_ARGS = ()
    SERVER_ENV = {}

    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        try:
            cls.prepare()
            cls.proc, cls.address, cls.log = start_geotrajd(cls.tmp.name, list(cls.SERVER_ARGS), cls.SERVER_ENV,
                                                            cls.SERVER_ENV_DROPPED)
        except BaseException:
            cls.tmp.cleanup()
            raise

    @classmethod
    def prepare(cls):
        pass

    @classmethod
    def tearDownClass(cls):
        cls.proc.terminate()
        cls.proc.wait(timeout=30)
        cls.log.close()
        cls.tmp.cleanup()

    def run_example(self, *args):
        cmd = [sys.executable, ARGS.example, "--server", self.address, "--stubs", ARGS.stubs, *args]
        cmd += list(self.CLIENT_ARGS)
        env = {k: v for k, v in os.environ.items() if k != "GEOTRAJ_TOKEN"}
        return subprocess.run(cmd, capture_output=True, text=True, timeout=120, env=env)

    def test_plan_and_stream_to_csv(self):
        out = os.path.join(self.tmp.name, "path_a.csv")
        res = self.run_example("--request", os.path.join(ARGS.requests, "plan_demo_path_a.json"), "--csv", out)
        self.assertEqual(res.returncode, 0, res.stderr)
        self.assertIn("plan: 3 segments", res.stdout)
        self.assertIn("1001 samples", res.stdout)
        self.assertIn(f"stream: 1001 samples written to {out}", res.stdout)
        with open(out, newline="") as f:
            rows = list(csv.DictReader(f))
        self.assertEqual(len(rows), 1001)  # 10 s at 100 Hz, both ends
        ts = [float(r["t"]) for r in rows]
        self.assertEqual(ts[0], 0.0)
        self.assertAlmostEqual(ts[-1], 10.0, places=9)
        self.assertTrue(all(b > a for a, b in zip(ts, ts[1:])))
        for r in rows:
            self.assertTrue(all(math.isfinite(float(v)) for v in r.values()))

    def test_robot_joints_in_csv(self):
        res = self.run_example("--request", os.path.join(ARGS.requests, "joint_move_pa10.json"), "--csv", "-")
        self.assertEqual(res.returncode, 0, res.stderr)
        rows = list(csv.reader(res.stdout.splitlines()))
        self.assertEqual(rows[0][-7:], [f"q{j}" for j in range(7)])  # the PA-10's seven joints
        goal = [0.6, 0.9, -0.3, 1.5, 0.4, 0.6, -0.8]
        for q, g in zip(rows[-1][-7:], goal):
            self.assertAlmostEqual(float(q), g, places=9)
        self.assertIn("robot: feasible True", res.stderr)  # the summary goes to stderr with '-'

    def test_joint_path_through_waypoints(self):
        """plan_joint_path_panda.json: nine Panda waypoints passed within their blend tolerance,
        the first and the last met exactly, from the joints of the CSV."""
        with open(os.path.join(ARGS.requests, "plan_joint_path_panda.json")) as f:
            request = json.load(f)
        waypoints = [w["positions"] for w in request["jointPath"]["waypoints"]]
        tolerance = request["jointPath"]["blendTolerance"]
        res = self.run_example("--request", os.path.join(ARGS.requests, "plan_joint_path_panda.json"), "--csv", "-")
        self.assertEqual(res.returncode, 0, res.stderr)
        self.assertIn("plan: no path segments (a joint move or a joint path)", res.stderr)
        rows = list(csv.DictReader(res.stdout.splitlines()))
        q = [[float(r[f"q{j}"]) for j in range(7)] for r in rows]
        for got, want in ((q[0], waypoints[0]), (q[-1], waypoints[-1])):
            for a, b in zip(got, want):
                self.assertAlmostEqual(a, b, places=9)
        # Samples 1 ms apart move at most |v| 1 ms (under 3 mrad on the Panda): the nearest
        # sample is within the tolerance and that much of the path's nearest point.
        for i, w in enumerate(waypoints[1:-1], start=1):
            nearest = min(math.dist(s, w) for s in q)
            self.assertLessEqual(nearest, tolerance + 3e-3, f"waypoint {i}")
            self.assertGreater(nearest, 1e-3, f"waypoint {i} is blended, not met")

    def test_torques_within_a_limit(self):
        """The Panda's pick and place with its rated 3 kg and its shoulder limited to 50 N m: the
        CSV's torques stay within it and reach it (the timing within torques), each joint's
        peak printed with its share of the limit."""
        res = self.run_example("--request", os.path.join(ARGS.requests, "plan_joint_path_panda.json"),
                               "--payload", "3,0,0,0.05", "--max-torque", "panda_joint2=50", "--csv", "-")
        self.assertEqual(res.returncode, 0, res.stderr)
        self.assertRegex(res.stderr, r"joint 1: peak torque 50 N m, 100\.0 % of its limit")
        rows = list(csv.DictReader(res.stdout.splitlines()))
        shoulder = [abs(float(r["tau1"])) for r in rows]
        self.assertLessEqual(max(shoulder), 50.0 * (1 + 1e-9))
        self.assertGreater(max(shoulder), 49.5)
        bad = self.run_example("--request", os.path.join(ARGS.requests, "plan_joint_path_panda.json"),
                               "--max-torque", "panda_joint2", "--no-stream")
        self.assertEqual(bad.returncode, 2)
        self.assertIn("--max-torque takes JOINT=NM", bad.stderr)

    def test_blended_sequence(self):
        res = self.run_example("--request", os.path.join(ARGS.requests, "sequence_blended_ur5.json"), "--csv", "-")
        self.assertEqual(res.returncode, 0, res.stderr)
        self.assertIn("plan: a sequence of 2 motions", res.stderr)
        self.assertIn("steps 1-3 (blended)", res.stderr)
        self.assertEqual(res.stderr.count("corner after step"), 2)
        rows = list(csv.reader(res.stdout.splitlines()))
        self.assertEqual(rows[0][-1], "step")
        self.assertEqual(sorted({r[-1] for r in rows[1:]}), ["0", "1", "2", "3"])

    def test_seam_of_pieces(self):
        """The weld seam of plan_seam_ur5e.json: a line, a quarter arc, a line with two
        transitions. The summary names the pieces and the transitions; the streamed positions
        on the pieces are straight and round (to 1e-9 m), within the tolerance elsewhere, and
        the tool never rests between its ends."""
        with open(os.path.join(ARGS.requests, "plan_seam_ur5e.json")) as f:
            request = json.load(f)
        start = request["path"]["start"]["position"]
        x0, y0, z0 = start["x"], start["y"], start["z"]
        radius = request["path"]["pieces"][1]["arc"]["radius"]
        tolerance = request["path"]["transitionTolerance"]
        res = self.run_example("--request", os.path.join(ARGS.requests, "plan_seam_ur5e.json"), "--csv", "-")
        self.assertEqual(res.returncode, 0, res.stderr)
        self.assertIn("plan: 5 segments", res.stderr)
        self.assertIn("segment 1: ", res.stderr)
        self.assertRegex(res.stderr, r"segment 1: \S+ m \(transition into piece 1\)")
        self.assertRegex(res.stderr, r"segment 2: \S+ m \(piece 1\)")
        pieces = {0: "line", 2: "arc", 4: "line"}
        rows = list(csv.DictReader(res.stdout.splitlines()))
        self.assertGreater(len(rows), 1000)
        for k, r in enumerate(rows):
            # The seam's own coordinates: along +y from the start, then towards +x.
            a, b, z = float(r["y"]) - y0, float(r["x"]) - x0, float(r["z"]) - z0
            first = math.hypot(max(0.0, a - 0.1, -a), b)
            arc = abs(math.hypot(a - 0.1, b - radius) - radius) if a >= 0.1 and b <= radius else math.inf
            last = math.hypot(a - 0.1 - radius, max(0.0, b - radius - 0.1, radius - b))
            d = math.hypot(min(first, arc, last), z)
            seg = int(r["segment"])
            if seg in pieces:
                self.assertLess(d, 1e-9, f"sample {k} on the {pieces[seg]} of segment {seg}")
            else:
                self.assertLessEqual(d, tolerance, f"sample {k} in the transition {seg}")
            if 0 < k < len(rows) - 1:
                self.assertGreater(float(r["speed"]), 0.0, f"sample {k} at rest")

    def test_bad_request_prints_field_violations(self):
        res = self.run_example("--request", os.path.join(ARGS.requests, "bad_request.json"))
        self.assertEqual(res.returncode, 1, res.stdout + res.stderr)
        self.assertIn("error: INVALID_ARGUMENT", res.stderr)
        self.assertIn("bad request, field violations:", res.stderr)
        for field in ("path.frames[0].tangent", "path.frames[1].torsion", "path.frames[2].tangent", "analysisPoints"):
            self.assertRegex(res.stderr, rf"(?m)^  {re.escape(field)}: \S")


def server_supports(*flags):
    help_text = subprocess.run([ARGS.server, "--help"], capture_output=True, text=True).stdout
    return all(flag in help_text for flag in flags)


class PythonExampleTlsAndToken(PythonExample):
    """The same, over TLS with a bearer token (--tls-ca, --token), where geotrajd has them."""
    TOKEN = "interop-example-token-0123456789"
    CLIENT_ARGS = ("--token", TOKEN)

    @classmethod
    def setUpClass(cls):
        if not server_supports("--tls-cert", "--auth-tokens-file"):
            raise unittest.SkipTest("this geotrajd has no --tls-cert or --auth-tokens-file")
        if shutil.which("openssl") is None:
            raise unittest.SkipTest("openssl not found (it makes the test's certificate)")
        super().setUpClass()

    @classmethod
    def prepare(cls):
        cert, key = os.path.join(cls.tmp.name, "cert.pem"), os.path.join(cls.tmp.name, "key.pem")
        subprocess.run(["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "1",
                        "-keyout", key, "-out", cert, "-subj", "/CN=geotrajd-interop",
                        "-addext", "subjectAltName=IP:127.0.0.1"], check=True, capture_output=True)
        cls.SERVER_ARGS = ("--tls-cert", cert, "--tls-key", key)
        cls.SERVER_ENV = {"GEOTRAJ_AUTH_TOKEN": cls.TOKEN}
        cls.CLIENT_ARGS = ("--token", cls.TOKEN, "--tls-ca", cert)

    def test_refused_without_the_token(self):
        cert = self.CLIENT_ARGS[-1]
        for extra in ((), ("--token", "not-the-token-0123456789abcdef")):
            cmd = [sys.executable, ARGS.example, "--server", self.address, "--stubs", ARGS.stubs,
                   "--tls-ca", cert, "--no-stream", *extra]
            env = {k: v for k, v in os.environ.items() if k != "GEOTRAJ_TOKEN"}
            res = subprocess.run(cmd, capture_output=True, text=True, timeout=60, env=env)
            self.assertEqual(res.returncode, 1, res.stdout + res.stderr)
            self.assertIn("error: UNAUTHENTICATED", res.stderr)

    def test_refused_without_tls(self):
        cmd = [sys.executable, ARGS.example, "--server", self.address, "--stubs", ARGS.stubs,
               "--token", self.TOKEN, "--no-stream", "--timeout", "10"]
        res = subprocess.run(cmd, capture_output=True, text=True, timeout=60)
        self.assertEqual(res.returncode, 1, res.stdout + res.stderr)
        self.assertIn("error: UNAVAILABLE", res.stderr)


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--server", required=True)
    parser.add_argument("--stubs", required=True)
    parser.add_argument("--example", required=True)
    parser.add_argument("--requests", required=True)
    ARGS, rest = parser.parse_known_args()
    unittest.main(argv=[sys.argv[0]] + rest, verbosity=2)
