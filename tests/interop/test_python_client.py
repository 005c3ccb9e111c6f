#!/usr/bin/env python3
"""geotraj from a client in another language: Python's grpcio against a real geotrajd.

Checks the thesis's numbers, the closed loop, the analysis profile recomputed here from its
own positions, the robots (the streamed joints through a forward kinematics written here
from the ListRobots answer), and the error details (google.rpc.BadRequest,
google.rpc.PreconditionFailure) that clients depend on.
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


def start_geotrajd(server):
    """geotrajd on a free loopback port and a ready channel to it: (process, channel).
    Its log (one line per call) goes nowhere: an unread pipe would fill and block it."""
    import grpc
    port = free_port()
    proc = subprocess.Popen([server, "--address", f"127.0.0.1:{port}"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    channel = grpc.insecure_channel(f"127.0.0.1:{port}")
    grpc.channel_ready_future(channel).result(timeout=30)
    return proc, channel


def stop_geotrajd(proc, channel):
    channel.close()
    proc.terminate()
    proc.wait(timeout=30)


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
        cls.proc, cls.channel = start_geotrajd(ARGS.server)
        cls.stub = rpc.TrajectoryServiceStub(cls.channel)

    @classmethod
    def tearDownClass(cls):
        stop_geotrajd(cls.proc, cls.channel)

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
        for f in (path.frames[1], path.frames[2]):  # 7.2.8: "kappa' and tau' are also set to zero"
            f.curvature_derivative, f.torsion_derivative = 0, 0
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

    # --- Random frame sets under the three readings (PathSpec.unspecified) ---------------------

    def random_path(self, rng, reading):
        def unit():
            v = [rng.gauss(0, 1) for _ in range(3)]
            n = math.sqrt(sum(c * c for c in v))
            return [c / n for c in v]

        def cross(a, b):
            return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]

        count = rng.randint(2, 6)
        closed = rng.random() < 0.3
        path = pb.PathSpec(closed=closed, unspecified=reading)
        p = [rng.uniform(-1, 1) for _ in range(3)]
        for i in range(count):
            both_sides = closed or 0 < i < count - 1
            f = path.frames.add()
            v3(f.position, *p)
            t = unit()
            n = cross(t, unit())
            norm = math.sqrt(sum(c * c for c in n))
            n = [c / norm for c in n]
            v3(f.tangent, *t)
            if rng.random() < 0.3:
                f.tangent_scale = rng.uniform(0.3, 2.5)
            if both_sides and rng.random() < 0.3:
                f.leave_tangent_scale = rng.uniform(0.3, 2.5)  # the two sides' scales differ
            kappa = None
            if rng.random() < 0.75:
                kappa = 0.0 if rng.random() < 0.1 else math.exp(rng.uniform(math.log(0.2), math.log(5.0)))
                f.curvature = kappa
                if kappa > 0:
                    if rng.random() < 0.5:
                        f.torsion = rng.uniform(-5, 5)
                    if rng.random() < 0.4:
                        f.curvature_derivative = rng.uniform(-10, 10)
                    if f.HasField("torsion") and rng.random() < 0.5:
                        f.torsion_derivative = rng.uniform(-20, 20)
            # A lowest-degree segment bends only where a curvature is given.
            if (kappa and kappa > 0) or (rng.random() < 0.3 and reading != pb.UNSPECIFIED_CONSTRAINTS_LOWEST_DEGREE):
                v3(f.normal, *n)
            if both_sides and rng.random() < 0.15:
                f.cusp = True
            if both_sides and kappa is not None and rng.random() < 0.15:
                f.inflection = True
            step = rng.uniform(0.4, 1.5)
            p = [a + step * b for a, b in zip(p, unit())]
        return path

    def jerk_energy(self, path, per_segment=1000):
        """The sum over segments of the integral of |d3p/du3|^2 du, by third differences of
        AnalyzePath's positions (stencils inside one segment only)."""
        segments = len(path.frames) if path.closed else len(path.frames) - 1
        profile = self.stub.AnalyzePath(pb.PlanRequest(path=path, analysis_points=per_segment * segments + 1))
        pts = [(q.u, (q.position.x, q.position.y, q.position.z)) for q in profile.points]
        h = 1.0 / per_segment
        energy = 0.0
        for k in range(len(pts) - 3):
            if math.floor(pts[k][0] + 1e-9) != math.floor(pts[k + 3][0] - 1e-9):
                continue  # the stencil straddles a frame, where d3p/du3 may jump
            d3 = [(pts[k + 3][1][c] - 3 * pts[k + 2][1][c] + 3 * pts[k + 1][1][c] - pts[k][1][c]) / h ** 3
                  for c in range(3)]
            energy += sum(c * c for c in d3) * h
        return energy

    def test_random_frame_sets_under_every_reading(self):
        import random
        rng = random.Random(2026)
        readings = [pb.UNSPECIFIED_CONSTRAINTS_SMOOTHEST, pb.UNSPECIFIED_CONSTRAINTS_THESIS_ZEROS,
                    pb.UNSPECIFIED_CONSTRAINTS_LOWEST_DEGREE]
        checked_g4 = 0
        for case in range(24):
            state = rng.getstate()
            paths = []
            for reading in readings:
                rng.setstate(state)  # the same frames under each reading
                paths.append(self.random_path(rng, reading))
            for reading, path in zip(readings, paths):
                with self.subTest(case=case, reading=pb.UnspecifiedConstraints.Name(reading)):
                    resp = self.stub.PlanTrajectory(pb.PlanRequest(path=path))
                    self.assertLess(resp.closed_loop.max_error, 1e-9, resp.closed_loop.worst_field)
                    for seg in resp.segments:
                        for v in (seg.arc_length, seg.peak_curvature.value, seg.min_speed.value, seg.turning):
                            self.assertTrue(math.isfinite(v))
                    if reading != pb.UNSPECIFIED_CONSTRAINTS_SMOOTHEST:
                        continue
                    # G4 where nothing breaks it: the same curvature, torsion and derivatives
                    # measured on the curve on both sides of every frame with two sides.
                    n = len(path.frames)
                    for i, f in enumerate(path.frames):
                        if f.cusp or f.inflection or f.stop or not (path.closed or 0 < i < n - 1):
                            continue
                        a, b = resp.frames[i].approach, resp.frames[i].leave
                        for field in ("curvature", "torsion", "curvature_derivative", "torsion_derivative"):
                            self.assertEqual(a.HasField(field), b.HasField(field), f"frame {i} {field}")
                            if a.HasField(field):
                                x, y = getattr(a, field), getattr(b, field)
                                self.assertLess(abs(x - y), 1e-6 * max(1.0, abs(x)), f"frame {i} {field}: {x} vs {y}")
                        checked_g4 += 1
            # The smoothest curve's energy is never above the thesis's zeros (a candidate of its).
            e_smooth, e_thesis = self.jerk_energy(paths[0]), self.jerk_energy(paths[1])
            self.assertLessEqual(e_smooth, e_thesis * (1 + 1e-4) + 1e-9, f"case {case}")
        self.assertGreater(checked_g4, 10)

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

    def motion_request(self, which, duration, method=None):
        req = pb.PlanRequest(path=self.demo_path(which))
        req.motion.duration_s = duration
        if method is not None:
            req.motion.time_parameterization = method
        return req

    def test_stream_thesis_speed_measured_as_the_thesis_does(self):
        # 100 Hz, 10 s: 1001 samples; the speed measured between consecutive samples
        # (distance / period, as Tables 7.21 and 7.22 measure it) follows the profile.
        req = self.motion_request("C", 10.0)
        samples = [s for batch in self.stub.StreamSamples(req, timeout=60) for s in batch.samples]
        self.assertEqual(len(samples), 1001)
        self.assertAlmostEqual(samples[-1].t, 10.0, places=12)
        plan = self.stub.PlanTrajectory(req)
        self.assertEqual(plan.motion.sample_count, 1001)
        peak = plan.motion.peak_speed
        # The trapezoid of Eqs. 6.11-6.13 (with the erratum), recomputed here: two portions
        # (the cusp at frame 3 is a rest), durations in proportion to their lengths, ramp
        # fraction 0.15. Every sample's s must sit where this profile puts it.
        lengths = [plan.segments[0].arc_length + plan.segments[1].arc_length, plan.segments[2].arc_length]
        total = sum(lengths)
        starts = [0.0, lengths[0]]
        t_starts = [0.0, 10.0 * lengths[0] / total]
        def profile_s(t):
            i = 0 if t < t_starts[1] else 1
            T = 10.0 * lengths[i] / total
            tb = 0.15 * T
            v = lengths[i] / (T - tb)   # (6.11)
            a = v / tb                  # (6.12)
            tau = min(max(t - t_starts[i], 0.0), T)
            if tau < tb:
                return starts[i] + 0.5 * a * tau * tau
            if tau <= T - tb:
                return starts[i] + 0.5 * a * tb * tb + v * (tau - tb)
            return starts[i] + lengths[i] - 0.5 * a * (T - tau) ** 2
        for smp in samples:
            self.assertAlmostEqual(smp.s, profile_s(smp.t), delta=1e-9)
        self.assertAlmostEqual(peak, total / (10.0 * 0.85), places=12)
        # The thesis's measure: distance between consecutive samples over the period. It
        # equals the profile's mean speed up to the chord's shortfall on the arc, about
        # kappa^2 ds^2 / 24: below 0.01 % where kappa < 25 1/m at 100 Hz, but 0.4 % on the
        # tight turn (kappa ~ 150 1/m) of this path's first segment.
        worst = 0.0
        for a, b in zip(samples, samples[1:]):
            if a.u < 2.0 < b.u:
                continue  # the path reverses at the cusp inside this period: a chord is no speed
            dt = b.t - a.t
            measured = math.dist((a.position.x, a.position.y, a.position.z), (b.position.x, b.position.y, b.position.z)) / dt
            worst = max(worst, abs(measured - (b.s - a.s) / dt))
        self.assertLess(worst / peak, 5e-3)
        # The motion rests at the cusp (frame 3, u = 2) and at both ends.
        self.assertEqual(samples[0].speed, 0.0)
        self.assertAlmostEqual(samples[-1].speed, 0.0, places=12)
        # The rest at the cusp falls between two samples: their speeds are the deceleration
        # and acceleration ramps' a |t - t_cusp|, and both lie on the path's frame 3 side.
        t_cusp = t_starts[1]
        for smp in samples:
            if abs(smp.t - t_cusp) < 0.01:
                i = 0 if smp.t < t_cusp else 1
                T = 10.0 * lengths[i] / total
                a_max = lengths[i] / (T - 0.15 * T) / (0.15 * T)
                self.assertLess(smp.speed, a_max * abs(smp.t - t_cusp) * (1 + 1e-6) + 1e-12)
        for s in samples:
            q = (s.orientation.w, s.orientation.x, s.orientation.y, s.orientation.z)
            self.assertAlmostEqual(math.hypot(*q), 1.0, places=12)

    def test_stream_cancelled_by_the_client(self):
        req = self.motion_request("A", 3600.0)  # an hour at 100 Hz: 360,001 samples
        req.samples_per_batch = 100
        call = self.stub.StreamSamples(req)
        received = 0
        for batch in call:
            received += len(batch.samples)
            if received >= 1000:
                call.cancel()
                break
        self.assertLess(received, 360001)
        self.assertEqual(call.code(), grpc.StatusCode.CANCELLED)
        # The server is still serving.
        self.assertLess(self.stub.PlanTrajectory(pb.PlanRequest(path=self.demo_path("A"))).closed_loop.max_error, 1e-9)

    def test_stream_without_motion_is_an_error(self):
        with self.assertRaises(grpc.RpcError) as ctx:
            list(self.stub.StreamSamples(pb.PlanRequest(path=self.demo_path("A"))))
        self.assertEqual(ctx.exception.code(), grpc.StatusCode.INVALID_ARGUMENT)
        req = self.motion_request("A", -1.0)
        with self.assertRaises(grpc.RpcError) as ctx:
            list(self.stub.StreamSamples(req))
        self.assertEqual(ctx.exception.code(), grpc.StatusCode.INVALID_ARGUMENT)
        self.assertIn("motion.durationS", ctx.exception.details() + str(ctx.exception.trailing_metadata()))

    def test_stream_real_time_sends_no_sample_before_it_is_due(self):
        req = self.motion_request("A", 0.5)  # 51 samples over half a second
        req.pacing = pb.STREAM_PACING_REAL_TIME
        start = time.monotonic()  # before the server's start: a strict lower bound
        count = 0
        for batch in self.stub.StreamSamples(req, timeout=60):
            arrived = time.monotonic() - start
            for smp in batch.samples:
                self.assertGreaterEqual(arrived, smp.t)
                count += 1
        self.assertEqual(count, 51)

    def test_stream_real_time_cancelled_while_waiting(self):
        req = self.motion_request("A", 3600.0)
        req.pacing = pb.STREAM_PACING_REAL_TIME
        call = self.stub.StreamSamples(req)
        first = next(call)
        self.assertGreater(len(first.samples), 0)
        call.cancel()
        self.assertEqual(call.code(), grpc.StatusCode.CANCELLED)
        self.assertLess(self.stub.PlanTrajectory(pb.PlanRequest(path=self.demo_path("A"))).closed_loop.max_error, 1e-9)

    # --- robots --------------------------------------------------------------------------

    def robot_models(self):
        return {m.name: m for m in self.stub.ListRobots(pb.ListRobotsRequest()).robots}

    def test_list_robots(self):
        models = self.robot_models()
        self.assertEqual(set(models), {"pa10", "ur5", "panda", "iiwa14", "ur5e"})
        for name, dof, convention in (("pa10", 7, pb.DH_CONVENTION_MODIFIED), ("ur5", 6, pb.DH_CONVENTION_STANDARD),
                                      ("panda", 7, None), ("iiwa14", 7, None), ("ur5e", 6, None)):
            m = models[name]
            if convention is None:  # read from URDF: a general chain, joints by name and kind
                self.assertEqual((len(m.links), len(m.joints)), (0, dof))
                self.assertTrue(all(j.name and j.joint_type == pb.JOINT_TYPE_REVOLUTE for j in m.joints))
            else:
                self.assertEqual(m.dh_convention, convention)
                self.assertEqual(len(m.links), dof)
            self.assertEqual((len(m.limits), len(m.home)), (dof, dof))
            self.assertTrue(m.description)
            for lim, q in zip(m.limits, m.home):
                self.assertLess(lim.min_position, lim.max_position)
                self.assertGreater(lim.max_velocity, 0.0)
                self.assertGreater(lim.max_acceleration, 0.0)
                self.assertTrue(lim.min_position <= q <= lim.max_position)
        # The PA-10's home holds the tool at the demonstration's first key frame.
        self.assertLess(math.dist(translation(forward_kinematics(models["pa10"], models["pa10"].home)),
                                  (0.106, 0.0, 0.975)), 1e-6)

    def test_stream_joints_reproduce_the_path(self):
        # Joint-space motions of the PA-10 within its limits: path C of the demonstration over
        # 60 s (IK at every sample) and a 3 s joint move. The streamed joints go through the
        # forward kinematics above, built from the ListRobots answer only.
        pa10 = self.robot_models()["pa10"]
        path_c = self.motion_request("C", 60.0)
        path_c.robot.name = "pa10"
        joint_move = pb.PlanRequest(joint_move=pb.JointMove(goal=[0.6, 0.9, -0.3, 1.5, 0.4, 0.6, -0.8]))
        joint_move.robot.name = "pa10"
        joint_move.motion.duration_s = 3.0
        joint_move.motion.cycle_rate_hz = 500.0
        for name, req, count in (("path C", path_c, 6001), ("joint move", joint_move, 1501)):
            with self.subTest(name):
                plan = self.stub.PlanTrajectory(req)
                self.assertTrue(plan.robot.feasible)
                samples = [s for batch in self.stub.StreamSamples(req, timeout=60) for s in batch.samples]
                self.assertEqual(len(samples), count)
                self.assertEqual(plan.motion.sample_count, count)
                fk = []
                for s in samples:
                    self.assertEqual((len(s.joints), len(s.joint_velocities), len(s.joint_accelerations)), (7, 7, 7))
                    p = translation(forward_kinematics(pa10, s.joints))
                    # The IK's residual is at most 1e-9 m.
                    self.assertLess(math.dist(p, (s.position.x, s.position.y, s.position.z)), 1e-8, f"t = {s.t}")
                    fk.append(p)
                # The speed measured on the recomputed path (chord over period) against the
                # streamed speed, averaged over the period: they differ by the chord's
                # shortfall on the arc and the change of speed within the period, both
                # second order in the period; loosely, 1 % of the peak speed.
                peak = max(s.speed for s in samples)
                self.assertAlmostEqual(peak, plan.motion.peak_speed, delta=1e-3 * peak)
                worst = 0.0
                for a, b, p_a, p_b in zip(samples, samples[1:], fk, fk[1:]):
                    if name == "path C" and a.u < 2.0 < b.u:
                        continue  # the path reverses at the cusp inside this period
                    measured = math.dist(p_a, p_b) / (b.t - a.t)
                    worst = max(worst, abs(measured - 0.5 * (a.speed + b.speed)))
                self.assertLess(worst, 1e-2 * peak)

    def test_kinematics_calls(self):
        # ComputeForwardKinematics against the forward kinematics written here; the pose it
        # gives back through ComputeInverseKinematics (cold, from the home), whose joints
        # reproduce it here; every branch of a UR5 pose; the closest pose out of reach.
        import random
        rng = random.Random(20261203)
        models = self.robot_models()
        for name in ("pa10", "ur5", "panda", "iiwa14", "ur5e"):
            m = models[name]
            for _ in range(20):
                q = [rng.uniform(lim.min_position, lim.max_position) for lim in m.limits]
                fk = self.stub.ComputeForwardKinematics(pb.ForwardKinematicsRequest(robot=pb.RobotSpec(name=name), joints=q))
                x = forward_kinematics(m, q)
                mine = pose_matrix(fk.pose)
                for i in range(3):
                    for j in range(4):
                        self.assertAlmostEqual(mine[i][j], x[i][j], delta=1e-12)
                self.assertEqual(len(fk.jacobian), 6 * len(q))
                self.assertTrue(fk.within_limits)
                ik = self.stub.ComputeInverseKinematics(
                    pb.InverseKinematicsRequest(robot=pb.RobotSpec(name=name), target=fk.pose))
                self.assertTrue(ik.reachable, name)
                y = forward_kinematics(m, ik.solutions[0].joints)
                self.assertLess(math.dist(translation(y), translation(x)), 1e-8)
                for i in range(3):
                    for j in range(3):
                        self.assertAlmostEqual(y[i][j], x[i][j], delta=1e-8)
                for lim, qi in zip(m.limits, ik.solutions[0].joints):
                    self.assertTrue(lim.min_position <= qi <= lim.max_position)
        ur5 = models["ur5"]
        q = [0.3, -1.2, 1.4, -0.8, 1.1, 0.5]
        fk = self.stub.ComputeForwardKinematics(pb.ForwardKinematicsRequest(robot=pb.RobotSpec(name="ur5"), joints=q))
        every = self.stub.ComputeInverseKinematics(pb.InverseKinematicsRequest(
            robot=pb.RobotSpec(name="ur5"), target=fk.pose, all_solutions=True, restarts=1999))
        self.assertEqual(len(every.solutions), 8)
        for s in every.solutions:
            self.assertLess(math.dist(translation(forward_kinematics(ur5, s.joints)), translation(pose_matrix(fk.pose))), 1e-8)
        far = pb.InverseKinematicsRequest(robot=pb.RobotSpec(name="ur5"))
        v3(far.target.position, 2.0, 0.0, 0.5)
        out = self.stub.ComputeInverseKinematics(far)
        self.assertFalse(out.reachable)
        self.assertEqual(len(out.solutions), 0)
        reached = translation(forward_kinematics(ur5, out.closest.joints))
        self.assertAlmostEqual(out.closest.position_error, math.dist(reached, (2.0, 0.0, 0.5)), delta=1e-9)

    def test_robot_cannot_follow_details(self):
        # Path A in the thesis's 10 s is too fast for the PA-10: FAILED_PRECONDITION with a
        # google.rpc.PreconditionFailure listing the report's violations.
        req = self.motion_request("A", 10.0)
        req.robot.name = "pa10"
        with self.assertRaises(grpc.RpcError) as ctx:
            self.stub.PlanTrajectory(req)
        err = ctx.exception
        self.assertEqual(err.code(), grpc.StatusCode.FAILED_PRECONDITION)
        for words in ("pa10", "joint", "t =", "sample"):
            self.assertIn(words, err.details())
        details = dict(err.trailing_metadata()).get("grpc-status-details-bin")
        self.assertIsNotNone(details, "no google.rpc.Status in the trailers")
        status = status_pb2.Status.FromString(details)
        self.assertEqual(status.code, grpc.StatusCode.FAILED_PRECONDITION.value[0])
        violations = []
        for any_detail in status.details:
            failure = error_details_pb2.PreconditionFailure()
            if any_detail.Unpack(failure):
                violations.extend(failure.violations)
        req.robot.report_only = True
        report = self.stub.PlanTrajectory(req).robot
        self.assertFalse(report.feasible)
        self.assertEqual([(v.type, v.subject) for v in violations],
                         [(pb.LimitKind.Name(e.kind), f"joint {e.joint}") for e in report.violations])
        for v, e in zip(violations, report.violations):
            self.assertIn(f"sample {e.sample}", v.description)

    def test_optimized_path_and_time_optimal_timing(self):
        # Tangent scales for the shortest path A: the report's objective is the plan's length.
        req = pb.PlanRequest(path=self.demo_path("A"))
        req.path.unspecified = pb.UNSPECIFIED_CONSTRAINTS_LOWEST_DEGREE  # the optimiser's model
        plain = self.stub.PlanTrajectory(req)
        req.optimize.tangent_scales.objective = pb.TANGENT_SCALE_OBJECTIVE_ARC_LENGTH
        resp = self.stub.PlanTrajectory(req)
        report = resp.optimization.tangent_scales
        self.assertIn(report.status, (pb.OPTIMIZER_STATUS_CONVERGED, pb.OPTIMIZER_STATUS_ITERATION_LIMIT))
        self.assertEqual(len(report.tangent_scales), 5)  # 4 frames, the cusp's leaving side apart
        self.assertLess(abs(resp.arc_length - report.objective_after), 1e-6 * resp.arc_length)
        self.assertLess(resp.arc_length, plain.arc_length)
        self.assertLess(resp.closed_loop.max_error, 1e-9)
        # The PA-10 on path C as fast as its joints allow: every streamed joint velocity and
        # acceleration within the ListRobots limits, one of them reached.
        req = self.motion_request("C", 0.0)
        req.robot.name = "pa10"
        req.optimize.timing.time_optimal = True
        resp = self.stub.PlanTrajectory(req)
        self.assertTrue(resp.robot.feasible)
        self.assertEqual(resp.optimization.timing.objective_after, resp.motion.duration_s)
        self.assertLess(resp.motion.duration_s, 10.0)
        limits = self.robot_models()["pa10"].limits
        samples = [s for batch in self.stub.StreamSamples(req) for s in batch.samples]
        self.assertEqual(len(samples), resp.motion.sample_count)
        top = 0.0
        for s in samples:
            for v, a, lim in zip(s.joint_velocities, s.joint_accelerations, limits):
                self.assertLessEqual(abs(v), lim.max_velocity * (1 + 1e-9))
                self.assertLessEqual(abs(a), lim.max_acceleration * (1 + 1e-9))
                top = max(top, abs(v) / lim.max_velocity, abs(a) / lim.max_acceleration)
        self.assertGreater(top, 0.98)


# Forward kinematics of a geotraj.v1.RobotModel, from the conventions the proto states, with
# 4x4 homogeneous matrices as lists (no numpy): X_WT = base A_1(q_1) ... A_n(q_n) tool,
# modified DH A_i = RotX(alpha) TransX(a) RotZ(theta) TransZ(d), standard DH
# A_i = RotZ(theta) TransZ(d) TransX(a) RotX(alpha); theta = theta_i + offset_i + q_i
# (revolute) or d = d_i + offset_i + q_i (prismatic). Units: m, rad.
def matmul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(4)) for j in range(4)] for i in range(4)]


def rot_x(angle):
    c, s = math.cos(angle), math.sin(angle)
    return [[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1]]


def rot_z(angle):
    c, s = math.cos(angle), math.sin(angle)
    return [[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]


def trans(x, y, z):
    return [[1, 0, 0, x], [0, 1, 0, y], [0, 0, 1, z], [0, 0, 0, 1]]


def pose_matrix(pose):
    m = trans(pose.position.x, pose.position.y, pose.position.z)
    if pose.HasField("orientation"):
        q = pose.orientation  # (w, x, y, z) by name
        n = math.sqrt(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z)
        w, x, y, z = q.w / n, q.x / n, q.y / n, q.z / n
        r = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
             [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
             [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
        for i in range(3):
            m[i][:3] = r[i]
    return m


def rot_axis(axis, angle):
    # Rodrigues: R = I + sin(a) K + (1 - cos(a)) K^2, K the cross-product matrix of the unit axis.
    n = math.sqrt(sum(c * c for c in axis))
    x, y, z = (c / n for c in axis)
    c, s, v = math.cos(angle), math.sin(angle), 1.0 - math.cos(angle)
    return [[c + x * x * v, x * y * v - z * s, x * z * v + y * s, 0.0],
            [y * x * v + z * s, c + y * y * v, y * z * v - x * s, 0.0],
            [z * x * v - y * s, z * y * v + x * s, c + z * z * v, 0.0],
            [0.0, 0.0, 0.0, 1.0]]


def forward_kinematics(model, q):
    x = pose_matrix(model.base)
    if model.joints:  # a general chain: base * origin_1 M_1(q_1) ... origin_n M_n(q_n) * flange * tool
        for joint, qi in zip(model.joints, q):
            axis = (joint.axis.x, joint.axis.y, joint.axis.z) if joint.HasField("axis") else (0.0, 0.0, 1.0)
            x = matmul(x, pose_matrix(joint.origin))
            if joint.joint_type == pb.JOINT_TYPE_PRISMATIC:
                n = math.sqrt(sum(c * c for c in axis))
                x = matmul(x, trans(*(qi * c / n for c in axis)))
            else:
                x = matmul(x, rot_axis(axis, qi))
        return matmul(matmul(x, pose_matrix(model.flange)), pose_matrix(model.tool))
    for link, qi in zip(model.links, q):
        prismatic = link.joint_type == pb.JOINT_TYPE_PRISMATIC
        theta = link.theta + (0.0 if prismatic else link.offset + qi)
        d = link.d + (link.offset + qi if prismatic else 0.0)
        if model.dh_convention == pb.DH_CONVENTION_MODIFIED:
            a = matmul(matmul(rot_x(link.alpha), trans(link.a, 0, 0)), matmul(rot_z(theta), trans(0, 0, d)))
        else:
            a = matmul(matmul(rot_z(theta), trans(0, 0, d)), matmul(trans(link.a, 0, 0), rot_x(link.alpha)))
        x = matmul(x, a)
    return matmul(x, pose_matrix(model.tool))


def translation(x):
    return (x[0][3], x[1][3], x[2][3])


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--server", required=True)
    parser.add_argument("--stubs", required=True)
    ARGS, rest = parser.parse_known_args()
    unittest.main(argv=[sys.argv[0]] + rest, verbosity=2)
