#!/usr/bin/env python3
"""Every move kind from a Python client, checked by finite differences of what is streamed.

Against a real geotrajd: joint moves to joints and to a pose, straight lines to a pose and
to joints, a time-optimal path, a jerk-limited path, a sequence and a blended sequence,
each as fast as the robot allows (durationS 0) and streamed at 100 Hz, 1 kHz and 10 kHz.
Every joint's velocity (first differences of the positions), acceleration (second
differences) and, where the model gives one, jerk (first differences of the streamed
accelerations) within the limits ListRobots states; some limit reached. The durations of
the fastest joint move and of the fastest straight line compared with references computed
here: the closed-form trapezoid of the joint move's normalised limits, and a time-optimal
timing of the streamed line's joints (forward and backward passes in b = s_dot^2 over
q(s) from the 10 kHz samples, Bobrow's method written here without geotraj).
Run: test_python_moves.py --server build/server/geotrajd --stubs build/tests/interop/pystubs
     --requests client/grpcurl
"""
import argparse
import math
import os
import sys
import unittest

from test_python_client import start_geotrajd, stop_geotrajd

ARGS = None
RATES = (100.0, 1000.0, 10000.0)


def double_s_time(h, v, a, j):
    """The minimum time of a rest-to-rest double S over distance h within v, a, j
    (Biagiotti and Melchiorri 2008, 3.4, with zero velocities at both ends)."""
    tj = a / j if v * j >= a * a else math.sqrt(v / j)  # the jerk phases reaching v
    ta = tj + v / a if v * j >= a * a else 2.0 * tj
    if h / v >= ta:  # v is reached: cruise for h / v - ta
        return h / v + ta
    if h >= 2.0 * a ** 3 / j ** 2:  # a is reached, v is not
        ta = (a * a / j + math.sqrt((a * a / j) ** 2 + 4.0 * a * h)) / (2.0 * a)
        return 2.0 * ta
    return 4.0 * (h / (2.0 * j)) ** (1.0 / 3.0)  # neither


class Moves(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        sys.path.insert(0, ARGS.stubs)
        global grpc, pb, rpc, json_format
        import grpc
        from geotraj.v1 import geotraj_pb2 as pb
        from geotraj.v1 import geotraj_pb2_grpc as rpc
        from google.protobuf import json_format
        cls.proc, cls.channel = start_geotrajd(ARGS.server)
        cls.stub = rpc.TrajectoryServiceStub(cls.channel)
        cls.models = {m.name: m for m in cls.stub.ListRobots(pb.ListRobotsRequest()).robots}

    @classmethod
    def tearDownClass(cls):
        stop_geotrajd(cls.proc, cls.channel)

    def example(self, name):
        with open(os.path.join(ARGS.requests, name)) as f:
            return json_format.Parse(f.read(), pb.PlanRequest())

    def stream(self, request):
        return [s for batch in self.stub.StreamSamples(request, timeout=120) for s in batch.samples]

    def check_limits(self, what, samples, limits, rate):
        """Largest usage of any limit by finite differences; fails past a limit."""
        dt = 1.0 / rate
        usage = 0.0
        n = len(samples)
        for k in range(1, n):
            h = samples[k].t - samples[k - 1].t
            self.assertGreater(h, 0.0, what)
            uniform_here = abs(h - dt) < 1e-9
            uniform_next = k + 1 < n and abs(samples[k + 1].t - samples[k].t - dt) < 1e-9
            for j, lim in enumerate(limits):
                v = (samples[k].joints[j] - samples[k - 1].joints[j]) / h
                # A first difference is the mean velocity over the period: the plan holds the
                # limit at its samples and at its check rate (2 kHz or more), and between
                # those points the velocity may pass it by parts per million.
                self.assertLessEqual(abs(v), lim.max_velocity * (1 + 1e-4), f"{what}: joint {j} velocity at t {samples[k].t}")
                usage = max(usage, abs(v) / lim.max_velocity)
                if uniform_here and uniform_next:
                    a = (samples[k + 1].joints[j] - 2 * samples[k].joints[j] + samples[k - 1].joints[j]) / (dt * dt)
                    self.assertLessEqual(abs(a), lim.max_acceleration * 1.02,
                                         f"{what}: joint {j} acceleration at t {samples[k].t}")
                    usage = max(usage, abs(a) / lim.max_acceleration)
                if uniform_here and lim.HasField("max_jerk"):
                    jerk = (samples[k].joint_accelerations[j] - samples[k - 1].joint_accelerations[j]) / dt
                    self.assertLessEqual(abs(jerk), lim.max_jerk * (1 + 1e-6), f"{what}: joint {j} jerk at t {samples[k].t}")
                    usage = max(usage, abs(jerk) / lim.max_jerk)
        return usage

    def run_kind(self, what, request, model, min_usage=0.95):
        durations = []
        for rate in RATES:
            request.motion.cycle_rate_hz = rate
            for step in request.sequence:  # a sequence streams at one rate
                if step.HasField("motion"):
                    step.motion.cycle_rate_hz = rate
            plan = self.stub.PlanTrajectory(request, timeout=120)
            samples = self.stream(request)
            self.assertEqual(len(samples), plan.motion.sample_count, what)
            usage = self.check_limits(f"{what} at {rate:g} Hz", samples, model.limits, rate)
            self.assertGreater(usage, min_usage, f"{what} at {rate:g} Hz: no limit is reached")
            durations.append(plan.motion.duration_s)
            print(f"[ measured ] {what} at {rate:g} Hz: {plan.motion.duration_s:.4f} s, {len(samples)} samples, "
                  f"largest limit usage {usage:.4f}")
        return durations

    def test_joint_move_to_joints_against_the_closed_form(self):
        request = self.example("joint_move_pa10.json")
        model = self.models["pa10"]
        durations = self.run_kind("jointMove to joints (PA-10)", request, model)
        # The move's x in [0, 1] under the tightest normalised limits: a double S in closed
        # form (Biagiotti and Melchiorri 2008, 3.4), the PA-10 having no jerk limits: each
        # joint's jerk bound is the documented default, max_acceleration / 0.05 s.
        dq = [abs(g - h) for g, h in zip(request.joint_move.goal, model.home)]
        v = min(l.max_velocity / d for l, d in zip(model.limits, dq) if d > 0)
        a = min(l.max_acceleration / d for l, d in zip(model.limits, dq) if d > 0)
        j = min(l.max_acceleration / 0.05 / d for l, d in zip(model.limits, dq) if d > 0)
        t_ref = double_s_time(1.0, v, a, j)
        for t in durations:
            self.assertLess(abs(t - t_ref), 1e-9 + 1e-9 * t_ref, f"{t} against {t_ref}")

    def test_joint_move_to_a_pose(self):
        request = self.example("sequence_ur5.json")
        move = pb.PlanRequest(robot=request.robot, motion=pb.MotionSpec(duration_s=0))
        move.joint_move.goal_pose.CopyFrom(request.sequence[2].joint_move.goal_pose)
        self.run_kind("jointMove to a pose (UR5)", move, self.models["ur5"])

    def test_fastest_line_against_a_time_optimal_timing_computed_here(self):
        request = self.example("linear_move_ur5.json")
        request.motion.duration_s = 0
        model = self.models["ur5"]
        # The default timing bounds the jerk (the UR5 gives no jerk limits: the default,
        # max_acceleration / 0.05 s); the time-optimal sweep is asked for explicitly.
        default = self.stub.PlanTrajectory(request, timeout=120)
        self.assertTrue(default.robot.HasField("default_jerk"))
        request.optimize.timing.time_optimal = True
        durations = self.run_kind("linearMove to a pose (UR5)", request, model)
        self.assertGreater(default.motion.duration_s, max(durations))
        # The reference: q(s) from the 10 kHz samples (s = distance along the line), q'(s) and
        # q''(s) by differences on a grid of 2,000 intervals, then the largest b = s_dot^2 at
        # each point under |q' s_dot| <= v_max and |q' s_ddot + q'' s_dot^2| <= a_max by
        # forward and backward passes (Bobrow, Dubowsky and Gibson 1985), the time by
        # integrating ds / s_dot.
        request.motion.cycle_rate_hz = 10000
        samples = self.stream(request)
        s_all = [x.s for x in samples]
        q_all = [list(x.joints) for x in samples]
        length = s_all[-1]
        m = 2000
        grid = [length * i / m for i in range(m + 1)]
        q = []
        k = 0
        for s in grid:  # linear interpolation in s of the dense samples
            while k + 2 < len(s_all) and s_all[k + 1] < s:
                k += 1
            s0, s1 = s_all[k], s_all[k + 1]
            w = 0.0 if s1 == s0 else min(max((s - s0) / (s1 - s0), 0.0), 1.0)
            q.append([a + w * (b - a) for a, b in zip(q_all[k], q_all[k + 1])])
        ds = length / m
        n = len(model.limits)
        d1 = [[(q[min(i + 1, m)][j] - q[max(i - 1, 0)][j]) / ((min(i + 1, m) - max(i - 1, 0)) * ds) for j in range(n)]
              for i in range(m + 1)]
        d2 = [[(q[min(i + 1, m)][j] - 2 * q[i][j] + q[max(i - 1, 0)][j]) / (ds * ds) if 0 < i < m else 0.0
               for j in range(n)] for i in range(m + 1)]

        def b_max(i):  # velocity limits and the acceleration limits' own bound on b
            cap = float("inf")
            for j, lim in enumerate(model.limits):
                if abs(d1[i][j]) > 1e-12:
                    cap = min(cap, (lim.max_velocity / abs(d1[i][j])) ** 2)
            return cap

        def accel_range(i, b):  # the s_ddot interval allowed at b
            lo, hi = -float("inf"), float("inf")
            for j, lim in enumerate(model.limits):
                a1, a2 = d1[i][j], d2[i][j] * b
                if abs(a1) < 1e-12:
                    continue
                r1, r2 = (-lim.max_acceleration - a2) / a1, (lim.max_acceleration - a2) / a1
                lo, hi = max(lo, min(r1, r2)), min(hi, max(r1, r2))
            return lo, hi

        caps = [b_max(i) for i in range(m + 1)]
        fwd = [0.0] * (m + 1)
        for i in range(m):
            lo, hi = accel_range(i, fwd[i])
            fwd[i + 1] = min(caps[i + 1], max(0.0, fwd[i] + 2 * ds * max(hi, 0.0)))
        bwd = [0.0] * (m + 1)
        for i in range(m, 0, -1):
            lo, hi = accel_range(i, bwd[i])
            bwd[i - 1] = min(caps[i - 1], max(0.0, bwd[i] - 2 * ds * min(lo, 0.0)))
        b = [min(f, g) for f, g in zip(fwd, bwd)]
        t_ref = sum(2 * ds / (math.sqrt(b[i]) + math.sqrt(b[i + 1])) for i in range(m) if b[i] + b[i + 1] > 0)
        print(f"[ measured ] fastest UR5 line: geotraj {durations[-1]:.4f} s, reference here {t_ref:.4f} s")
        for t in durations:
            self.assertGreater(t, t_ref * 0.99, "faster than the time-optimal reference")
            self.assertLess(t, t_ref * 1.03, "slower than the time-optimal reference by more than 3 %")

    def test_line_to_joints(self):
        request = self.example("linear_move_ur5.json")
        request.motion.duration_s = 0
        request.linear_move.ClearField("goal")
        request.linear_move.goal_joints.extend([0.3, -1.45, 1.4, -1.5, -1.5708, 0.2])  # near the home, on its branch
        self.run_kind("linearMove to joints (UR5)", request, self.models["ur5"])

    def test_time_optimal_path(self):
        request = self.example("plan_pa10_path_c.json")
        request.motion.duration_s = 0
        request.robot.report_only = False
        request.optimize.timing.time_optimal = True
        self.run_kind("path C, time-optimal (PA-10)", request, self.models["pa10"])

    def test_default_timing_bounds_the_jerk(self):
        # durationS 0 alone: the PA-10 gives no jerk limits, so its joints are bounded by the
        # documented default, max_acceleration / 0.05 s, which the plan names and the
        # streamed joints keep by differences of their accelerations.
        request = self.example("plan_pa10_path_c.json")
        request.motion.duration_s = 0
        request.robot.report_only = False
        plan = self.stub.PlanTrajectory(request, timeout=120)
        self.assertEqual(plan.robot.default_jerk.ramp_s, 0.05)
        model = pb.RobotModel()
        model.CopyFrom(self.models["pa10"])
        for j, lim in enumerate(model.limits):
            lim.max_jerk = lim.max_acceleration / 0.05
            self.assertAlmostEqual(plan.robot.default_jerk.max_jerk[j], lim.max_jerk, delta=1e-9 * lim.max_jerk)
        self.run_kind("path C, durationS 0 (PA-10, default jerk a_max / 0.05 s)", request, model, min_usage=0.9)

    def test_jerk_limited_path(self):
        request = self.example("plan_pa10_path_c.json")
        request.motion.duration_s = 0
        request.robot.report_only = False
        request.optimize.timing.jerk_limited = True
        model = pb.RobotModel()
        model.CopyFrom(self.models["pa10"])
        for lim in model.limits:
            lim.max_jerk = 4 * lim.max_acceleration
        request.robot.ClearField("name")
        request.robot.model.CopyFrom(model)
        self.run_kind("path C, jerk-limited (PA-10, max jerk 4 a_max)", request, model, min_usage=0.9)

    def test_path_c_on_a_urdf_arm(self):
        # The Franka Panda, read from URDF (its jerk limits published): path C jerk-limited,
        # after a joint approach from the home; every joint's velocity, acceleration and jerk
        # by differences within the limits ListRobots states.
        request = self.example("plan_panda_path_c.json")
        request.optimize.timing.jerk_limited = True
        self.run_kind("path C, jerk-limited (Panda, URDF)", request, self.models["panda"], min_usage=0.9)

    def test_sequences(self):
        self.run_kind("sequence (UR5)", self.example("sequence_ur5.json"), self.models["ur5"], min_usage=0.5)
        self.run_kind("blended sequence (UR5)", self.example("sequence_blended_ur5.json"), self.models["ur5"],
                      min_usage=0.5)


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--server", required=True)
    parser.add_argument("--stubs", required=True)
    parser.add_argument("--requests", required=True)
    ARGS, rest = parser.parse_known_args()
    unittest.main(argv=[sys.argv[0]] + rest, verbosity=2)
