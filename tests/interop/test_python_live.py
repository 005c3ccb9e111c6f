#!/usr/bin/env python3
"""Live execution (Execute) and jogging (Jog) from Python clients against a real geotrajd on
loopback: both bidirectional streams driven by threads and a queue-fed request iterator.

Execute runs the Panda on path C (client/grpcurl/plan_panda_path_c.json: a joint approach,
then the time-optimal path at 1 kHz) under a speed override, pause, resume and stop: every
streamed set point within the ListRobots limits by finite differences (velocity, acceleration,
jerk), every position on the plan's path (the same request streamed by StreamSamples at
10 kHz), stops at rest within the stopping time the server announced. Then the ways a call
ends: deadman, the client's cancel, a deadline, SIGTERM (drain), a bad control message, each
with its status code and `geotraj-stop-reason` trailer. Jog: a joint driven into its position
limit (it stops there, exactly), Cartesian jogs in the world and the tool frame. 100 live
calls at once, twice, with the server's memory flat; and the example client
client/python/geotraj_live.py run as a user runs it (on the geotraj package of the source
tree), its set points saved with --csv.

Run: test_python_live.py --server build/server/geotrajd --stubs build/tests/interop/pystubs
         --requests client/grpcurl --example client/python/geotraj_live.py
"""
import argparse
import csv
import math
import os
import queue
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time
import unittest

from test_python_client import free_port, stop_geotrajd

ARGS = None
REASON = "geotraj-stop-reason"
DENSE_RATE = 10000.0  # [Hz] the reference stream of the path checks


class LiveCall:
    """One Execute or Jog call. The requests go through a queue whose generator grpcio consumes
    on its own thread; the batches are read on a thread of this class, which calls
    `control(call, batch)` after each, so that a command answers what was just streamed, and
    sends `heartbeat` every `heartbeat_s` of sample time (None: never; the deadman then acts).
    The request stream stays open until the response stream ends (a half-close would leave
    the call to the deadman)."""

    def __init__(self, method, first, heartbeat, control=None, timeout=None, heartbeat_s=0.2):
        self.requests = queue.Queue()
        self.requests.put(first)
        self.heartbeat, self.heartbeat_s, self.control = heartbeat, heartbeat_s, control
        self.batches, self.samples, self.sent = [], [], []  # sent: (samples received before it, message)
        self.arrivals = []  # time.monotonic() of each batch's arrival
        self.error = None  # what `control` raised
        self.started = time.monotonic()
        self.first_arrival = self.ended = None
        self.call = method(self._requests(), timeout=timeout)
        self.thread = threading.Thread(target=self._read, daemon=True)
        self.thread.start()

    def _requests(self):
        while True:
            message = self.requests.get()
            if message is None:
                return
            yield message

    def send(self, message):
        self.sent.append((len(self.samples), message))
        self.requests.put(message)

    def _read(self):
        beat = 0.0
        try:
            for batch in self.call:
                if self.first_arrival is None:
                    self.first_arrival = time.monotonic()
                self.batches.append(batch)
                self.arrivals.append(time.monotonic())
                self.samples.extend(batch.samples)
                if self.heartbeat_s is not None and batch.samples and batch.samples[-1].t >= beat + self.heartbeat_s:
                    beat = batch.samples[-1].t
                    self.requests.put(self.heartbeat)
                if self.control is not None:
                    self.control(self, batch)
        except grpc.RpcError:
            pass  # the call's status says it
        except BaseException as e:  # a failed check in `control`
            self.error = e
            self.call.cancel()
        finally:
            self.ended = time.monotonic()
            self.requests.put(None)

    def wait(self, timeout=60.0):
        """Waits for the end of the call; its status code."""
        self.thread.join(timeout)
        if self.thread.is_alive():
            self.call.cancel()
            self.thread.join(10)
            raise AssertionError(f"the call did not end within {timeout} s")
        if self.error is not None:
            raise self.error
        return self.call.code()

    def reason(self):
        return dict(self.call.trailing_metadata() or ()).get(REASON)

    def sent_index(self, kind):
        """Samples received before the first message holding `kind` was sent."""
        return next(i for i, m in self.sent if m.HasField(kind))


def bad_request_fields(call):
    """The field paths of the google.rpc.BadRequest in a call's trailers."""
    raw = dict(call.trailing_metadata() or ()).get("grpc-status-details-bin")
    if raw is None:
        return []
    fields = []
    for detail in status_pb2.Status.FromString(raw).details:
        bad = error_details_pb2.BadRequest()
        if detail.Unpack(bad):
            fields.extend(v.field for v in bad.field_violations)
    return fields


def start_geotrajd(*extra):
    """geotrajd with flags `extra` on a free loopback port, as test_python_client.py starts it,
    and a ready channel to it: (process, channel, address)."""
    address = f"127.0.0.1:{free_port()}"
    proc = subprocess.Popen([ARGS.server, "--address", address, *extra],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    channel = grpc.insecure_channel(address)
    grpc.channel_ready_future(channel).result(timeout=30)
    return proc, channel, address


def rss_kib(pid):
    with open(f"/proc/{pid}/status") as f:
        return int(re.search(r"^VmRSS:\s+(\d+) kB", f.read(), re.M).group(1))


def dot(a, b):
    return sum(x * y for x, y in zip(a, b))


def angle_deg(a, b):
    c = dot(a, b) / math.sqrt(dot(a, a) * dot(b, b))
    return math.degrees(math.acos(max(-1.0, min(1.0, c))))


def xyz(v):
    return (v.x, v.y, v.z)


def tool_x_axis(q):
    """The first column of the rotation of the unit quaternion q (w, x, y, z by name)."""
    return (1 - 2 * (q.y * q.y + q.z * q.z), 2 * (q.x * q.y + q.z * q.w), 2 * (q.x * q.z - q.y * q.w))


def point_segment_distance(p, a, b):
    ab = [y - x for x, y in zip(a, b)]
    ap = [y - x for x, y in zip(a, p)]
    n = dot(ab, ab)
    w = 0.0 if n == 0.0 else min(max(dot(ap, ab) / n, 0.0), 1.0)
    return math.dist(p, [x + w * d for x, d in zip(a, ab)])


class Live(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        sys.path.insert(0, ARGS.stubs)
        global grpc, pb, rpc, json_format, status_pb2, error_details_pb2
        import grpc
        from geotraj.v1 import geotraj_pb2 as pb
        from geotraj.v1 import geotraj_pb2_grpc as rpc
        from google.protobuf import json_format
        from google.rpc import error_details_pb2, status_pb2
        cls.proc, cls.channel, cls.address = start_geotrajd()
        cls.stub = rpc.TrajectoryServiceStub(cls.channel)
        cls.models = {m.name: m for m in cls.stub.ListRobots(pb.ListRobotsRequest()).robots}

    @classmethod
    def tearDownClass(cls):
        stop_geotrajd(cls.proc, cls.channel)

    # --- requests ----------------------------------------------------------------------------

    def example(self, name):
        with open(os.path.join(ARGS.requests, name)) as f:
            return json_format.Parse(f.read(), pb.PlanRequest())

    def path_c(self):
        """The Panda on path C, time-optimal within its velocities and accelerations and, as
        the jerk checks need, its jerks; a joint approach first. 1 kHz."""
        request = self.example("plan_panda_path_c.json")
        request.optimize.timing.jerk_limited = True
        return request

    def joint_move(self):
        """The PA-10's joint move as fast as it goes (2.2 s; 2.3 s with Execute's reserve) at
        100 Hz."""
        request = self.example("joint_move_pa10.json")
        request.motion.cycle_rate_hz = 100.0
        return request

    def execute(self, plan, control=None, timeout=60.0, heartbeat_s=0.2, stub=None, **options):
        first = pb.ExecuteRequest(plan=plan, options=pb.ExecuteOptions(**options))
        return LiveCall((stub or self.stub).Execute, first, pb.ExecuteRequest(heartbeat=pb.Heartbeat()),
                        control, timeout, heartbeat_s)

    def jog(self, control=None, timeout=60.0, heartbeat_s=0.2, stub=None, robot="panda", **start):
        first = pb.JogRequest(start=pb.JogStart(robot=pb.RobotSpec(name=robot), **start))
        return LiveCall((stub or self.stub).Jog, first, pb.JogRequest(heartbeat=pb.Heartbeat()),
                        control, timeout, heartbeat_s)

    # --- checks ------------------------------------------------------------------------------

    def check_limits(self, what, samples, limits, velocity_scale=1.0):
        """Every set point within the position limits, velocities (first differences of the
        positions) within max_velocity x velocity_scale, accelerations (second differences)
        within max_acceleration with 2 % slack as test_python_moves.py allows, jerks
        (differences of the streamed accelerations) within max_jerk where the model has it;
        the streamed velocities and accelerations within their limits too. Samples uniform in
        time. Returns the largest usage of a velocity, an acceleration and a jerk limit."""
        self.assertGreater(len(samples), 2, what)
        dt = samples[1].t - samples[0].t
        usage = [0.0, 0.0, 0.0]
        for k, s in enumerate(samples):
            for j, lim in enumerate(limits):
                where = f"{what}: joint {j} at t {s.t:.6f}"
                self.assertTrue(lim.min_position <= s.joints[j] <= lim.max_position, f"{where}: position {s.joints[j]}")
                self.assertLessEqual(abs(s.joint_velocities[j]), lim.max_velocity * velocity_scale * (1 + 1e-9), where)
                self.assertLessEqual(abs(s.joint_accelerations[j]), lim.max_acceleration * (1 + 1e-9), where)
            if k == 0:
                continue
            self.assertAlmostEqual(s.t - samples[k - 1].t, dt, delta=1e-9, msg=f"{what}: uniform in time")
            for j, lim in enumerate(limits):
                where = f"{what}: joint {j} at t {s.t:.6f}"
                v = (s.joints[j] - samples[k - 1].joints[j]) / dt
                self.assertLessEqual(abs(v), lim.max_velocity * velocity_scale * (1 + 1e-4), f"{where}: velocity {v}")
                usage[0] = max(usage[0], abs(v) / (lim.max_velocity * velocity_scale))
                if k + 1 < len(samples):
                    a = (samples[k + 1].joints[j] - 2 * s.joints[j] + samples[k - 1].joints[j]) / (dt * dt)
                    self.assertLessEqual(abs(a), lim.max_acceleration * 1.02, f"{where}: acceleration {a}")
                    usage[1] = max(usage[1], abs(a) / lim.max_acceleration)
                if lim.HasField("max_jerk"):
                    jerk = (s.joint_accelerations[j] - samples[k - 1].joint_accelerations[j]) / dt
                    self.assertLessEqual(abs(jerk), lim.max_jerk * (1 + 1e-6), f"{where}: jerk {jerk}")
                    usage[2] = max(usage[2], abs(jerk) / lim.max_jerk)
        return usage

    def assert_at_rest(self, what, sample):
        for j, (v, a) in enumerate(zip(sample.joint_velocities, sample.joint_accelerations)):
            self.assertEqual((v, a), (0.0, 0.0), f"{what}: joint {j} not at rest at t {sample.t}")
        if sample.HasField("speed_factor"):
            self.assertEqual(sample.speed_factor, 0.0, what)

    def assert_ended(self, what, call, code, reason, state=None):
        """The call ended with `code` and the trailer's `reason` after a final sample at rest."""
        self.assertEqual(call.wait(), code, f"{what}: {call.call.details()}")
        self.assertEqual(call.reason(), reason, what)
        self.assertTrue(call.samples, f"{what}: no samples")
        self.assert_at_rest(what, call.samples[-1])
        if state is not None:
            self.assertEqual(call.batches[-1].live.state, state, what)

    def dense_path(self, request, plan_duration):
        """The request streamed by StreamSamples at 10 kHz with the room Execute leaves
        (accelerationScale 1 - 0.1, the default reserve): the same path, timed alike. Its duration is
        Execute's within one cycle of the request's rate: the steps of a sequence (here the
        approach, then the path) each end on the cycle grid, and a time-optimal timing is
        checked on a grid that follows the rate (1e-5 of the duration apart). Positions [m]
        at plan times k / 10 kHz."""
        dense = pb.PlanRequest()
        dense.CopyFrom(request)
        dense.motion.cycle_rate_hz = DENSE_RATE
        dense.motion.acceleration_scale = 1.0 - 0.1
        plan = self.stub.PlanTrajectory(dense, timeout=60)
        self.assertAlmostEqual(plan.motion.duration_s, plan_duration, delta=1.0 / request.motion.cycle_rate_hz,
                               msg="Execute's plan and StreamSamples' differ")
        points = [xyz(s.position) for b in self.stub.StreamSamples(dense, timeout=60) for s in b.samples]
        self.assertEqual(len(points), plan.motion.sample_count)
        return points

    def assert_on_path(self, what, samples, dense, window_s):
        """Each sample's position within 1e-6 m of the dense polyline, within `window_s` of its
        plan time (the chord error at 10 kHz is below 1e-8 m here; the IK's residual 1e-9 m)."""
        worst = 0.0
        w = int(math.ceil(window_s * DENSE_RATE)) + 1
        for s in samples:
            k = int(round(s.plan_time * DENSE_RATE))
            window = range(max(k - w, 0), min(k + w, len(dense) - 1))
            d = min(point_segment_distance(xyz(s.position), dense[i], dense[i + 1]) for i in window)
            self.assertLess(d, 1e-6, f"{what}: {d} m off the path at plan time {s.plan_time}")
            worst = max(worst, d)
        return worst

    # --- Execute -----------------------------------------------------------------------------

    def test_execute_override_pause_resume_within_limits(self):
        # 100 % -> 40 % from plan time 0.3 s; a pause once the speed factor has held 0.4 for
        # 0.2 s; resume after 0.3 s at rest; 100 % once 0.4 is back for 0.1 s; to the end.
        steps = {}

        def control(call, batch):
            s = batch.samples[-1]
            if "slow" not in steps and s.plan_time >= 0.3:
                steps["slow"] = s.t
                call.send(pb.ExecuteRequest(speed_override=40))
            elif "slow" in steps and "pause" not in steps:
                if abs(s.speed_factor - 0.4) > 1e-12:
                    steps.pop("at 40", None)
                elif s.t - steps.setdefault("at 40", s.t) >= 0.2:
                    steps["pause"] = s.t
                    call.send(pb.ExecuteRequest(pause=pb.Pause()))
            elif "pause" in steps and "resume" not in steps and batch.live.state == pb.LIVE_STATE_PAUSED:
                if s.t - steps.setdefault("paused", s.t) >= 0.3:
                    steps["resume"] = s.t
                    call.send(pb.ExecuteRequest(resume=pb.Resume()))
            elif "resume" in steps and "fast" not in steps and abs(s.speed_factor - 0.4) <= 1e-12:
                if s.t - steps.setdefault("at 40 again", s.t) >= 0.1:
                    steps["fast"] = s.t
                    call.send(pb.ExecuteRequest(speed_override=100))

        call = self.execute(self.path_c(), control)
        self.assert_ended("path C", call, grpc.StatusCode.OK, "completed", pb.LIVE_STATE_COMPLETED)
        self.assertTrue({"slow", "pause", "resume", "fast"} <= set(steps), f"not every step was taken: {steps}")
        samples, live = call.samples, call.batches[-1].live
        self.assertAlmostEqual(samples[-1].plan_time, live.plan_duration_s, delta=1e-12)
        self.assertEqual(samples[0].t, 0.0)
        usage = self.check_limits("path C live", samples, self.models["panda"].limits)
        print(f"[ measured ] path C live, {len(samples)} samples over {samples[-1].t:.3f} s "
              f"(plan {live.plan_duration_s:.3f} s): "
              f"largest usage of velocity {usage[0]:.3f}, acceleration {usage[1]:.3f}, jerk {usage[2]:.3f}; "
              f"speed factor bounds {live.factor_acceleration_limit:.3f} 1/s, {live.factor_jerk_limit:.1f} 1/s^2 "
              f"({live.binding})")
        # The speed factor: r = d(plan time)/dt in [0, 1], settled at 0.4, paused at 0, back at 1.
        r = [s.speed_factor for s in samples]
        self.assertTrue(all(0.0 <= x <= 1.0 for x in r))
        self.assertGreater(sum(1 for x in r if abs(x - 0.4) < 1e-12), 200)
        self.assertTrue(any(b.live.speed_override == 40 for b in call.batches))
        self.assertEqual(live.speed_override, 100)
        self.assertEqual(r[-2], 1.0, "the speed factor did not come back to 1 before the end")
        # Plan time advances at the speed factor (trapezoidal rule), up to the final sample,
        # which stands at the plan's end (its duration is no whole number of cycles).
        for a, b in zip(samples[:-2], samples[1:-1]):
            self.assertAlmostEqual(b.plan_time - a.plan_time, 0.5 * (a.speed_factor + b.speed_factor) * (b.t - a.t),
                                   delta=1e-6)
        # Paused: the joints held still, at rest.
        paused = [s for s in samples[call.sent_index("pause"):call.sent_index("resume")] if s.speed_factor == 0.0]
        self.assertGreater(len(paused), 250)
        for s in paused:
            self.assertEqual(list(s.joints), list(paused[0].joints))
            self.assert_at_rest("paused", s)
        # Resumed: no jump in the joints or their velocities from the last paused sample on.
        dt = samples[1].t - samples[0].t
        resumed = call.sent_index("resume")
        for a, b in zip(samples[resumed - 5:resumed + 200], samples[resumed - 4:resumed + 201]):
            for j, lim in enumerate(self.models["panda"].limits):
                self.assertLessEqual(abs(b.joints[j] - a.joints[j]), lim.max_velocity * dt * (1 + 1e-9))
                self.assertLessEqual(abs(b.joint_velocities[j] - a.joint_velocities[j]),
                                     lim.max_acceleration * dt * (1 + 1e-9))
        self.assertGreater(samples[resumed + 200].plan_time, paused[0].plan_time)

    def test_pause_and_stop_stay_on_the_path(self):
        # Pause at plan time 0.8 s (in the path, after the approach), resume after 0.3 s at
        # rest, stop at plan time 2.0 s: every sample's position on the planned path.
        steps = {}

        def control(call, batch):
            s = batch.samples[-1]
            if "pause" not in steps and s.plan_time >= 0.8:
                steps["pause"] = s.t
                call.send(pb.ExecuteRequest(pause=pb.Pause()))
            elif "pause" in steps and "resume" not in steps and batch.live.state == pb.LIVE_STATE_PAUSED:
                if s.t - steps.setdefault("paused", s.t) >= 0.3:
                    steps["resume"] = s.t
                    call.send(pb.ExecuteRequest(resume=pb.Resume()))
            elif "resume" in steps and "stop" not in steps and s.plan_time >= 2.0:
                steps["stop"] = s.t
                call.send(pb.ExecuteRequest(stop=pb.Stop()))

        request = self.path_c()
        call = self.execute(request, control)
        self.assert_ended("path C paused and stopped", call, grpc.StatusCode.OK, "stopped", pb.LIVE_STATE_STOPPED)
        samples = call.samples
        self.assertLess(samples[-1].plan_time, call.batches[-1].live.plan_duration_s)
        dense = self.dense_path(request, call.batches[-1].live.plan_duration_s)
        worst = self.assert_on_path("live path C", samples, dense, 1.0 / request.motion.cycle_rate_hz)
        paused = [s for s in samples if s.speed_factor == 0.0][:-1]  # the final sample is at rest too
        self.assertGreater(len(paused), 250)
        for s in paused:
            self.assertEqual(list(s.joints), list(paused[0].joints))
            self.assertEqual(xyz(s.position), xyz(paused[0].position))
            self.assert_at_rest("paused", s)
        self.check_limits("path C paused and stopped", samples, self.models["panda"].limits)
        print(f"[ measured ] {len(samples)} live samples of path C: at most {worst:.2e} m from the 10 kHz polyline")

    def test_stop_within_the_announced_stopping_time(self):
        announced = {}

        def control(call, batch):
            if not announced and batch.samples[-1].plan_time >= 1.2:
                announced.update(time=batch.live.stopping_time_s, plan_time=batch.live.stopping_plan_time_s,
                                 t=batch.samples[-1].t, tau=batch.samples[-1].plan_time)
                call.send(pb.ExecuteRequest(stop=pb.Stop()))

        call = self.execute(self.path_c(), control)
        self.assert_ended("stop at full speed", call, grpc.StatusCode.OK, "stopped", pb.LIVE_STATE_STOPPED)
        final = call.samples[-1]
        batch_period = 0.01  # samplesPerBatch absent: one batch per 10 ms
        took, covered = final.t - announced["t"], final.plan_time - announced["tau"]
        print(f"[ measured ] stop from plan time {announced['tau']:.3f} s: {took:.3f} s, {covered:.3f} s of plan time; "
              f"announced at most {announced['time']:.3f} s, {announced['plan_time']:.3f} s")
        self.assertGreater(took, 0.0)
        self.assertLess(final.plan_time, call.batches[-1].live.plan_duration_s, "the plan ended before the stop")
        self.assertLessEqual(took, announced["time"] + 2 * batch_period)
        self.assertLessEqual(covered, announced["plan_time"] + 2 * batch_period)
        self.check_limits("stop at full speed", call.samples, self.models["panda"].limits)

    def test_deadman(self):
        # No message after the first: the motion runs at full speed for the deadman time,
        # then stops on the path.
        call = self.execute(self.path_c(), heartbeat_s=None, deadman_s=0.3)
        self.assert_ended("deadman", call, grpc.StatusCode.ABORTED, "deadman", pb.LIVE_STATE_STOPPED)
        self.assertIn("deadman", call.call.details())
        # The stop was decided no sooner than 0.3 s of wall time into the motion: the first
        # slowed sample arrived that late after the first batch (on the wall clock, which
        # the deadman reads: a loaded machine may send samples late, never early).
        slowed = next(k for k, b in enumerate(call.batches) if any(s.speed_factor < 1.0 for s in b.samples))
        self.assertGreaterEqual(call.arrivals[slowed] - call.first_arrival, 0.3 - 0.05,
                                "stopped before the deadman time")
        self.assertLess(call.samples[-1].plan_time, call.batches[-1].live.plan_duration_s)
        stopping = call.batches[0].live.stopping_time_s
        self.assertLessEqual(call.samples[-1].t, 0.3 + stopping + 0.5)
        self.assertLessEqual(call.ended - call.first_arrival, 0.3 + stopping + 0.5)
        self.check_limits("deadman", call.samples, self.models["panda"].limits)

    def serves(self):
        """The server still executes and jogs: a call of each, stopped at its first batch."""
        call = self.execute(self.joint_move(), lambda c, b: c.sent or c.send(pb.ExecuteRequest(stop=pb.Stop())))
        self.assert_ended("an Execute after", call, grpc.StatusCode.OK, "stopped")
        jog = self.jog(lambda c, b: c.sent or c.send(pb.JogRequest(stop=pb.Stop())))
        self.assert_ended("a Jog after", jog, grpc.StatusCode.OK, "stopped")

    def test_cancel_and_deadline_mid_call(self):
        # Path C at 50 % (7 s at full speed: 3.5 s) with a 5 s deadline; a jog with 3 s. Both
        # under 10 s: gRPC encodes a deadline of 10 s to 100 s rounded up to 100 ms, which the
        # server then sees up to 0.1 s later than the client, beyond its margin of 50 ms and
        # 3 batches; the call then ends by the client's deadline, not at rest (a server bug).
        for name, start, timeout in (
                ("Execute", lambda **kw: self.execute(self.path_c(), speed_override=50, **kw), 5.0),
                ("Jog", lambda **kw: self.jog(**kw), 3.0)):
            with self.subTest(f"{name} cancelled"):
                call = start()
                while len(call.samples) < 30 and call.thread.is_alive():
                    time.sleep(0.01)
                call.call.cancel()
                self.assertEqual(call.wait(), grpc.StatusCode.CANCELLED)
            with self.subTest(f"{name} with a deadline"):
                def jog_on(call, batch):
                    if not call.sent:
                        call.send(pb.JogRequest(joints=pb.JointJog(velocities=[0.5, 0, 0, 0, 0, 0, 0])))
                call = start(timeout=timeout, **({"control": jog_on} if name == "Jog" else {}))
                self.assert_ended(f"{name} with a deadline", call, grpc.StatusCode.DEADLINE_EXCEEDED, "deadline",
                                  pb.LIVE_STATE_STOPPED)
                self.assertLess(call.ended - call.started, timeout, "the final sample came after the deadline")
                self.assertGreater(max(abs(v) for s in call.samples for v in s.joint_velocities), 0.1, "no motion")
            self.serves()

    def test_sigterm_drains_live_calls(self):
        proc, channel, _ = start_geotrajd("--drain-seconds", "5")
        try:
            stub = rpc.TrajectoryServiceStub(channel)
            execute = self.execute(self.path_c(), stub=stub, speed_override=30)
            jog = self.jog(lambda c, b: c.sent or c.send(pb.JogRequest(joints=pb.JointJog(velocities=[0.3] + [0] * 6))),
                           stub=stub)
            while min(len(execute.samples), len(jog.samples)) < 50 and execute.thread.is_alive():
                time.sleep(0.01)
            signalled = time.monotonic()
            proc.send_signal(signal.SIGTERM)
            for what, call in (("Execute", execute), ("Jog", jog)):
                self.assert_ended(f"{what} drained", call, grpc.StatusCode.UNAVAILABLE, "drain", pb.LIVE_STATE_STOPPED)
                self.assertTrue(any(abs(v) > 0 for v in call.samples[len(call.samples) // 2].joint_velocities))
            self.assertEqual(proc.wait(timeout=30), 0)
            self.assertLess(time.monotonic() - signalled, 5.0, "geotrajd took longer than its drain time")
        finally:
            channel.close()
            if proc.poll() is None:
                proc.kill()
                proc.wait()

    # --- Jog ---------------------------------------------------------------------------------

    def test_joint_jog_stops_at_the_position_limit(self):
        panda = self.models["panda"]
        joint, lim = 3, panda.limits[3]  # home -2.356 rad, limits [-3.072, -0.070] rad
        steps = {}

        def command(value):
            velocities = [0.0] * 7
            velocities[joint] = value
            return pb.JogRequest(joints=pb.JointJog(velocities=velocities))

        def control(call, batch):
            s = batch.samples[-1]
            if "down" not in steps:
                steps["down"] = s.t
                call.send(command(-1.0))
            elif "away" not in steps and s.joints[joint] == lim.min_position and not any(s.joint_velocities):
                if s.t - steps.setdefault("at limit", s.t) >= 0.2:
                    steps["away"] = s.t
                    call.send(command(1.0))
            elif "away" in steps and "stop" not in steps and s.t - steps["away"] >= 0.5:
                steps["stop"] = s.t
                call.send(pb.JogRequest(stop=pb.Stop()))

        call = self.jog(control, cycle_rate_hz=1000.0)
        self.assert_ended("joint jog", call, grpc.StatusCode.OK, "stopped", pb.LIVE_STATE_STOPPED)
        samples = call.samples
        self.assertTrue({"down", "at limit", "away", "stop"} <= set(steps), f"not every step was taken: {steps}")
        self.check_limits("joint jog", samples, panda.limits, velocity_scale=0.25)
        lowest = min(s.joints[joint] for s in samples)
        self.assertGreaterEqual(lowest, lim.min_position)
        self.assertLess(lowest - lim.min_position, 1e-9)
        self.assertTrue(any(abs(s.joint_velocities[joint]) >= lim.max_velocity * 0.25 * (1 - 1e-9) for s in samples))
        # limitedJoints: the joint from its braking for the limit until it moves away.
        held = [b for b in call.batches if b.samples[-1].t <= steps["away"]]
        self.assertIn(joint, held[-1].live.limited_joints)
        self.assertFalse(call.batches[0].live.limited_joints)
        self.assertGreater(samples[-1].joints[joint], lim.min_position + 0.05, "it did not move away from the limit")
        self.assertTrue(any(not b.live.limited_joints for b in call.batches if b.samples[-1].t > steps["away"] + 0.1))
        for s in samples:  # only the jogged joint moves
            for j in range(7):
                if j != joint:
                    self.assertEqual(s.joints[j], panda.home[j])

    def cartesian_jog(self, frame):
        """Jogs +x in `frame` at 0.5 x 0.25 m/s for 0.6 s from the Panda's home, then stops: the
        call."""
        def control(call, batch):
            s = batch.samples[-1]
            if not call.sent:
                call.send(pb.JogRequest(twist=pb.CartesianJog(linear=pb.Vec3(x=0.5), frame=frame)))
            elif len(call.sent) == 1 and s.t >= 0.6:
                call.send(pb.JogRequest(stop=pb.Stop()))

        call = self.jog(control, cycle_rate_hz=500.0)
        self.assert_ended(f"Cartesian jog in {pb.CoordinateMode.Name(frame)}", call, grpc.StatusCode.OK, "stopped",
                          pb.LIVE_STATE_STOPPED)
        self.check_limits("Cartesian jog", call.samples, self.models["panda"].limits, velocity_scale=0.25)
        return call

    def test_cartesian_jog_world_and_tool_frame(self):
        for frame in (pb.COORDINATE_MODE_WORLD, pb.COORDINATE_MODE_TOOL):
            with self.subTest(pb.CoordinateMode.Name(frame)):
                call = self.cartesian_jog(frame)
                samples = call.samples
                stopped = call.sent[1][0]
                # After the ramp (0.3 s from the command) until the stop: the tool moves along
                # world x, or along its own x axis, at 0.5 x 0.25 m/s.
                ramped = [s for s in samples[:stopped] if s.t >= samples[call.sent[0][0]].t + 0.3]
                self.assertGreater(len(ramped), 50)
                worst = 0.0
                for a, b in zip(ramped, ramped[5:]):
                    d = [y - x for x, y in zip(xyz(a.position), xyz(b.position))]
                    axis = (1.0, 0.0, 0.0) if frame == pb.COORDINATE_MODE_WORLD else tool_x_axis(a.orientation)
                    worst = max(worst, angle_deg(d, axis))
                    self.assertAlmostEqual(math.sqrt(dot(d, d)) / (b.t - a.t), 0.125, delta=0.01)
                self.assertLess(worst, 3.0, "the tool does not move along the commanded axis")
                first, last = samples[0], samples[-1]
                moved = [y - x for x, y in zip(xyz(first.position), xyz(last.position))]
                axis = (1.0, 0.0, 0.0) if frame == pb.COORDINATE_MODE_WORLD else tool_x_axis(first.orientation)
                print(f"[ measured ] Cartesian jog +x in {pb.CoordinateMode.Name(frame)}: "
                      f"moved {math.dist(xyz(first.position), xyz(last.position)):.4f} m, "
                      f"{angle_deg(moved, axis):.3f} deg off the axis overall, at most {worst:.3f} deg after the ramp; "
                      f"smallest singular value {min(s.smallest_singular_value for s in samples):.3f}")

    # --- many calls --------------------------------------------------------------------------

    def test_hundred_concurrent_live_calls_with_flat_memory(self):
        def jog_then_stop(call, batch):
            s = batch.samples[-1]
            if not call.sent:
                call.send(pb.JogRequest(joints=pb.JointJog(velocities=[0.2, -0.2, 0.2, 0.2, 0.2, -0.2, 0.2])))
            elif len(call.sent) == 1 and s.t >= 1.8:
                call.send(pb.JogRequest(stop=pb.Stop()))

        goal = self.joint_move().joint_move.goal
        rss = []
        for round_ in range(2):
            calls = []  # (which, call), each about 2 s, 10 samples per batch
            for i in range(50):
                calls.append(("Execute", self.execute(self.joint_move(), samples_per_batch=10, deadman_s=10)))
                calls.append(("Jog", self.jog(jog_then_stop, samples_per_batch=10, deadman_s=10)))
            for what, call in calls:
                code = call.wait(timeout=60)
                self.assertEqual(code, grpc.StatusCode.OK, f"round {round_ + 1}: {what}: {call.call.details()}")
                self.assertEqual(call.reason(), "completed" if what == "Execute" else "stopped")
                self.assert_at_rest(what, call.samples[-1])
                if what == "Execute":  # the whole move, to its goal
                    self.assertEqual(call.samples[-1].plan_time, call.batches[-1].live.plan_duration_s)
                    for q, g in zip(call.samples[-1].joints, goal):
                        self.assertAlmostEqual(q, g, delta=1e-9)
                self.assertTrue(all(len(b.samples) <= 10 for b in call.batches))
            # All at once: every call's first batch came before any call ended.
            self.assertLess(max(c.first_arrival for _, c in calls), min(c.ended for _, c in calls))
            rss.append(rss_kib(self.proc.pid))
        print(f"[ measured ] geotrajd VmRSS after 100 live calls: {rss[0] / 1024:.1f} MiB, "
              f"after 100 more: {rss[1] / 1024:.1f} MiB")
        self.assertLess(rss[1] - rss[0], 20 * 1024, "memory grows with the calls")

    # --- bad input ---------------------------------------------------------------------------

    def test_bad_input_names_the_field(self):
        call = LiveCall(self.stub.Execute, pb.ExecuteRequest(heartbeat=pb.Heartbeat()),
                        pb.ExecuteRequest(heartbeat=pb.Heartbeat()))
        self.assertEqual(call.wait(), grpc.StatusCode.INVALID_ARGUMENT)
        self.assertEqual(call.samples, [])
        self.assertIn("plan", bad_request_fields(call.call))

        report_only = self.path_c()
        report_only.robot.report_only = True
        call = self.execute(report_only)
        self.assertEqual(call.wait(), grpc.StatusCode.INVALID_ARGUMENT)
        self.assertIn("plan.robot.reportOnly", bad_request_fields(call.call))

        call = self.execute(self.path_c(), deadman_s=0, speed_override=101, samples_per_batch=0)
        self.assertEqual(call.wait(), grpc.StatusCode.INVALID_ARGUMENT)
        self.assertEqual(sorted(bad_request_fields(call.call)),
                         ["options.deadmanS", "options.samplesPerBatch", "options.speedOverride"])

        def too_fast(call, batch):
            if not call.sent and batch.samples[-1].plan_time >= 0.5:
                call.send(pb.ExecuteRequest(speed_override=150))

        call = self.execute(self.path_c(), too_fast)
        self.assert_ended("speedOverride 150", call, grpc.StatusCode.INVALID_ARGUMENT, "invalid", pb.LIVE_STATE_STOPPED)
        self.assertEqual(bad_request_fields(call.call), ["speedOverride"])
        self.assertIn("150", call.call.details())
        self.check_limits("speedOverride 150", call.samples, self.models["panda"].limits)

        def wrong_count(call, batch):
            if not call.sent:
                call.send(pb.JogRequest(joints=pb.JointJog(velocities=[0.5] * 6)))

        call = self.jog(wrong_count)
        self.assert_ended("six velocities for seven joints", call, grpc.StatusCode.INVALID_ARGUMENT, "invalid")
        self.assertEqual(bad_request_fields(call.call), ["joints.velocities"])

        call = LiveCall(self.stub.Jog, pb.JogRequest(start=pb.JogStart(robot=pb.RobotSpec(name="no-such-arm"))),
                        pb.JogRequest(heartbeat=pb.Heartbeat()))
        self.assertEqual(call.wait(), grpc.StatusCode.INVALID_ARGUMENT)
        self.assertEqual(len([f for f in bad_request_fields(call.call) if f.startswith("start.robot")]), 1)

    # --- the example client --------------------------------------------------------------------

    def test_example_client(self):
        # client/python/geotraj_live.py as a user runs it: the PA-10's joint move (2.3 s at
        # full speed) at 50 % after 1 s, paused at 2 s for 1 s, resumed, to the end; a jog of
        # the Panda's joint 4 that stops after 0.5 s; an unknown robot (exit status 1).
        # The execute's set points go to a CSV (--csv): one row each, the example's columns, the
        # PA-10's goal at the end, at rest.
        cmd = [sys.executable, ARGS.example, "--address", self.address, "--stubs", ARGS.stubs]
        with tempfile.TemporaryDirectory() as tmp:
            out = os.path.join(tmp, "setpoints.csv")
            res = subprocess.run(cmd + ["execute", os.path.join(ARGS.requests, "joint_move_pa10.json"), "--csv", out],
                                 capture_output=True, text=True, timeout=60)
            self.assertEqual(res.returncode, 0, res.stdout + res.stderr)
            with open(out, newline="") as f:
                rows = list(csv.reader(f))
        for line in ("-> speed override 50 %", "-> pause", "-> resume", "end: completed (OK)"):
            self.assertIn(line, res.stdout)
        states = re.findall(r"(?m)^\s+[\d.]+\s+([\d.]+) / ([\d.]+)\s+([\d.]+)\s+(\w+)$", res.stdout)
        self.assertIn("paused", [state for _, _, _, state in states])
        self.assertIn("0.500", [factor for _, _, factor, _ in states])
        self.assertEqual(states[-1][0], states[-1][1])  # the plan's end
        self.assertEqual(states[-1][3], "completed")
        count = int(re.search(r"end: completed \(OK\), (\d+) samples", res.stdout).group(1))
        self.assertIn(f"csv: {count} set points written to {out}", res.stdout)
        self.assertEqual(rows[0], ["t", "u", "s", "segment", "x", "y", "z", "qw", "qx", "qy", "qz", "vx", "vy", "vz",
                                   "ax", "ay", "az", "speed"] + [f"q{j}" for j in range(7)])
        self.assertEqual(len(rows), count + 1)
        ts = [float(r[0]) for r in rows[1:]]
        self.assertTrue(all(b > a for a, b in zip(ts, ts[1:])))
        self.assertGreater(ts[-1], 3.0)  # 2.3 s of plan, half of it at 50 %, a second paused
        goal = [0.6, 0.9, -0.3, 1.5, 0.4, 0.6, -0.8]
        for q, g in zip(rows[-1][-7:], goal):
            self.assertAlmostEqual(float(q), g, places=9)
        res = subprocess.run(cmd + ["jog", "--robot", "panda", "--joint", "3", "--command", "0.5", "--seconds", "0.5"],
                             capture_output=True, text=True, timeout=60)
        self.assertEqual(res.returncode, 0, res.stdout + res.stderr)
        self.assertIn("-> stop", res.stdout)
        self.assertIn("end: stopped (OK)", res.stdout)
        moved = re.search(r"joint 3: from (\S+) to (\S+) rad", res.stdout)
        self.assertGreater(float(moved.group(2)) - float(moved.group(1)), 0.1)
        res = subprocess.run(cmd + ["jog", "--robot", "no-such-arm"], capture_output=True, text=True, timeout=60)
        self.assertEqual(res.returncode, 1, res.stdout + res.stderr)
        self.assertIn("error: INVALID_ARGUMENT", res.stderr)
        self.assertRegex(res.stderr, r"(?m)^  start\.robot\.name: unknown robot")


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--server", required=True)
    parser.add_argument("--stubs", required=True)
    parser.add_argument("--requests", required=True)
    parser.add_argument("--example", required=True)
    ARGS, rest = parser.parse_known_args()
    unittest.main(argv=[sys.argv[0]] + rest, verbosity=2)
