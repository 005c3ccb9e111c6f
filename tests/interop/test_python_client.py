#!/usr/bin/env python3
"""geotraj from a client in another language: Python's grpcio against a real geotrajd.

Checks the thesis's numbers, the closed loop, the analysis profile recomputed here from its
own positions, and the error details (google.rpc.BadRequest) that clients depend on.
Run: test_python_client.py --server build/server/geotrajd --stubs build/tests/interop/pystubs
"""
import argparse
import math
import socket
import subprocess
import sys
import time
import unittest

ARGS = None


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def v3(pb, x, y, z):
    pb.x, pb.y, pb.z = x, y, z


class PythonClient(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        sys.path.insert(0, ARGS.stubs)
        global grpc, pb, rpc, status_pb2, error_details_pb2
        import grpc
        from geotraj.v1 import geotraj_pb2 as pb
        from geotraj.v1 import geotraj_pb2_grpc as rpc
        from google.rpc import error_details_pb2, status_pb2
        cls.port = free_port()
        cls.proc = subprocess.Popen([ARGS.server, "--address", f"127.0.0.1:{cls.port}"],
                                    stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        cls.channel = grpc.insecure_channel(f"127.0.0.1:{cls.port}")
        grpc.channel_ready_future(cls.channel).result(timeout=30)
        cls.stub = rpc.TrajectoryServiceStub(cls.channel)

    @classmethod
    def tearDownClass(cls):
        cls.channel.close()
        cls.proc.terminate()
        cls.proc.wait(timeout=30)

    # The thesis's demonstration (Tables 7.8 with its erratum, 7.18): path A, B or C.
    def demo_path(self, which):
        k2, t2, k3, t3 = {"A": (5, -50, 1, 0), "B": (10, -50, 10, 100), "C": (20, -50, 10, -100)}[which]
        path = pb.PathSpec(derivative_convention=pb.DERIVATIVE_CONVENTION_PER_PARAMETER)
        rows = [((0.106, 0, 0.975), (1, 0, 0), (0, -1, 0)), ((0.4, 0.15, 0.5), (0, -1, 0), (0, 0, -1)),
                ((0.5, -0.3, 0.525), (1, 0, 0), (0, 1, 0)), ((0.2, -0.5, 0.6), (0, -1, 0), (0, 0, -1))]
        for i, (p, t, n) in enumerate(rows):
            f = path.frames.add()
            v3(f.position, *p)
            v3(f.tangent, *t)
            v3(f.normal, *n)
            f.tangent_scale = 0.25
        path.frames[1].curvature, path.frames[1].torsion = k2, t2
        path.frames[2].curvature, path.frames[2].torsion = k3, t3
        path.frames[2].cusp = True
        return path

    def test_table_7_19_and_7_20(self):
        expected2 = {"A": (-0.3125, -3.9063), "B": (-0.625, -7.8125), "C": (-1.25, -15.625)}
        expected3 = {"A": (0.0625, 0.0), "B": (0.625, 15.625), "C": (0.625, -15.625)}
        for which in "ABC":
            resp = self.stub.ConvertConstraints(pb.ConvertRequest(path=self.demo_path(which)))
            d2 = resp.frames[1].approach.derivatives
            self.assertAlmostEqual(d2[1].z, expected2[which][0], places=4)  # Table 7.19 (erratum A)
            self.assertAlmostEqual(d2[2].x, expected2[which][1], places=4)
            d3 = resp.frames[2].approach.derivatives
            self.assertAlmostEqual(d3[0].x, 0.25, places=12)                 # Table 7.20
            self.assertAlmostEqual(d3[1].y, expected3[which][0], places=4)
            self.assertAlmostEqual(d3[2].z, expected3[which][1], places=4)
            self.assertAlmostEqual(resp.frames[2].leave.derivatives[0].x, -0.25, places=12)  # cusp
            self.assertEqual(len(resp.frames[0].leave.derivatives), 1)  # only the tangent is given

    def test_plan_closed_loop(self):
        for which in "ABC":
            resp = self.stub.PlanTrajectory(pb.PlanRequest(path=self.demo_path(which)))
            self.assertLess(resp.closed_loop.max_error, 1e-9)
            self.assertEqual(len(resp.segments), 3)
            self.assertAlmostEqual(sum(s.arc_length for s in resp.segments), resp.arc_length, places=12)
            frame2 = resp.frames[1]
            self.assertAlmostEqual(frame2.leave.curvature, {"A": 5, "B": 10, "C": 20}[which], places=9)
            self.assertAlmostEqual(frame2.leave.torsion, -50, places=7)

    def test_analysis_recomputed_here(self):
        req = pb.PlanRequest(path=self.demo_path("C"), analysis_points=3001)
        prof = self.stub.AnalyzePath(req)
        pts = prof.points
        self.assertEqual(len(pts), 3001)
        self.assertAlmostEqual(pts[-1].u, 3.0, places=12)
        # Arc length: the polyline through the points approaches s from below.
        chord = 0.0
        for a, b in zip(pts, pts[1:]):
            chord += math.dist((a.position.x, a.position.y, a.position.z), (b.position.x, b.position.y, b.position.z))
            self.assertGreaterEqual(b.s, a.s)
        self.assertLess(abs(chord - prof.arc_length) / prof.arc_length, 1e-4)
        self.assertLessEqual(chord, prof.arc_length * (1 + 1e-12))
        # At u = 1 (frame 2, leaving side) the profile says curvature 20.
        self.assertAlmostEqual(pts[1000].u, 1.0, places=12)
        self.assertAlmostEqual(pts[1000].curvature, 20.0, places=7)
        for p in pts:
            t = (p.tangent.x, p.tangent.y, p.tangent.z)
            self.assertAlmostEqual(math.hypot(*t), 1.0, places=12)
            if p.HasField("curvature") and p.curvature > 0:
                n = (p.normal.x, p.normal.y, p.normal.z)
                self.assertAlmostEqual(sum(a * b for a, b in zip(t, n)), 0.0, places=9)

    def test_bad_request_names_fields(self):
        path = self.demo_path("A")
        path.frames[1].curvature = 0.0  # torsion -50 stays: torsion needs curvature > 0
        v3(path.frames[3].tangent, 0, -0.5, 0)  # not a unit vector
        with self.assertRaises(grpc.RpcError) as ctx:
            self.stub.PlanTrajectory(pb.PlanRequest(path=path))
        err = ctx.exception
        self.assertEqual(err.code(), grpc.StatusCode.INVALID_ARGUMENT)
        details = dict(err.trailing_metadata()).get("grpc-status-details-bin")
        self.assertIsNotNone(details, "no google.rpc.Status in the trailers")
        status = status_pb2.Status.FromString(details)
        self.assertEqual(status.code, grpc.StatusCode.INVALID_ARGUMENT.value[0])
        fields = {}
        for any_detail in status.details:
            bad = error_details_pb2.BadRequest()
            if any_detail.Unpack(bad):
                fields.update({v.field: v.description for v in bad.field_violations})
        self.assertIn("path.frames[1].torsion", fields)
        self.assertIn("path.frames[3].tangent", fields)
        self.assertIn("curvature", fields["path.frames[1].torsion"])


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--server", required=True)
    parser.add_argument("--stubs", required=True)
    ARGS, rest = parser.parse_known_args()
    unittest.main(argv=[sys.argv[0]] + rest, verbosity=2)
