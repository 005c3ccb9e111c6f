#!/usr/bin/env python3
"""A user's acceptance test of the three ways to get a motion out of geotrajd: what
PlanTrajectory reports within every limit, Execute runs at 100 % override, sample for
sample the same positions as StreamSamples.

Cases: every request file under --requests (client/grpcurl/*.json) that parses as a
PlanRequest and has a motion, in two modes: "fixed" (a durationS: the file's own, or
FIXED_DURATION_S's where the file has durationS 0) and "fastest" (durationS 0, as fast as
the limits allow; only where a robot is given). Beside the files, the move kinds they do
not hold, built as test_python_moves.py builds them. Today's list (35 cases):
  analyze_demo_path_a.json, plan_demo_path_a/b/c.json   path, no robot    fixed 10 s
  plan_pa10_path_c.json (reportOnly)                     path, PA-10       fixed 10 s, fastest
  plan_pa10_path_c.json, durationS 20                    path, PA-10       fixed 20 s (the file's
                                                         10 s is beyond the arm's accelerations)
  plan_pa10_path_b_redundancy.json                       path, PA-10, optimize.redundancy
                                                                           fixed 10 s, fastest
  plan_helix.json                                        path of pieces, no robot   fixed 8 s
  plan_seam_ur5e.json                                    path of pieces with transitions, UR5e
                                                                           fixed 3 s, fastest
  plan_seam_roll_ur5e.json                               path, UR5e, robot.toolAxisFree
                                                                           fixed 1.5 s, fastest
  plan_panda_path_c.json                                 path + robot.approach joint, Panda
                                                                           fixed 8 s, fastest
  plan_panda_path_c.json, robot.approach linear          path + approach linear     fixed 8 s, fastest
  joint_move_pa10.json                                   jointMove to joints        fixed 3 s, fastest
  plan_joint_path_panda.json                             jointPath, nine Panda waypoints
                                                                           fixed 4 s, fastest
  jointMove to a pose (UR5)      sequence_ur5.json's third step's pose              fixed 2 s, fastest
  linear_move_ur5.json                                   linearMove to a pose       fixed 2 s, fastest
  linearMove to joints (UR5)     linear_move_ur5.json with goalJoints               fixed 2 s, fastest
  sequence_ur5.json                                      sequence (a step of 1.5 s) fixed 2 s, fastest
  sequence_blended_ur5.json                              blended sequence           fixed 4 s, fastest
  plan_pa10_path_c.json, jerk-limited (inline PA-10 model, max jerk 4 a_max)        fastest
  plan_panda_path_c.json, optimize.timing.jerkLimited                               fastest
  joint_move_pa10.json with ExecuteOptions.accelerationReserve 0.3                  fastest
(optimize.timing times a motion by the limits whatever its durationS: the jerk-limited
kinds have no fixed mode.) The test prints one line for each case.

Skipped request files (each recognised by parsing and by content; the test fails when the
files and this list disagree):
  appendix_b_b11.json, appendix_b_b13.json, appendix_b_optimized.json,
  appendix_b_uniform.json  AnalyzePath requests (the thesis's Appendix B curve): a path and
                           analysisPoints, no motion; nothing to stream or execute
  bad_request.json         the error-details example: no motion, and an invalid path (a
                           tangent of length 2, a torsion on a straight frame)
  convert_table_5_10.json  a ConvertRequest: a path only (it parses as a PlanRequest
                           without a motion)
  execute_panda.json       an ExecuteRequest, not a PlanRequest; its plan is
                           plan_panda_path_c.json's (checked here: were it another, it
                           would be a case of its own)
  fk_pa10.json             a ForwardKinematicsRequest (does not parse as a PlanRequest)
  ik_ur5_all.json          an InverseKinematicsRequest (does not parse as a PlanRequest)
  jog_panda.json           two JogRequests (a JogStart and a joint command), not one message

For each case:
  1. PlanTrajectory of the request must succeed: its motion.durationS, sampleCount and,
     with a robot, whether its report is feasible are recorded.
  2. StreamSamples of the same request: as many samples as the Plan's sampleCount, the
     last at the Plan's durationS.
  3. Execute (a bidirectional stream: the first message `plan` = the request, options
     default; a Heartbeat whenever nothing else was sent for 0.2 s, so that the 1 s
     deadman does not act; every SampleBatch read until the end) at 100 % override must
     end OK ("completed") and give the samples of its reference:
       - a request timed by the limits (durationS 0, optimize.timing): Execute keeps its
         acceleration reserve (ExecuteOptions.accelerationReserve, default 0.1), which is
         the plan of motion.accelerationScale = 1 - reserve (docs/live.md, "Why a
         reserve"; proto MotionSpec.acceleration_scale), so the reference is StreamSamples
         of the request with accelerationScale 0.9. A sequence with a step of its own
         durationS refuses that field on the request (INVALID_ARGUMENT: not with a
         durationS); it is then given on every step timed by the limits instead, as
         planner::reserve_room scales them, and a NOTE on the case's line says so;
       - a request with a durationS: the plain request, or, for a path with robot.approach
         (timed by the limits), the request with accelerationScale 1 - reserve (which then
         scales the approach);
       - accelerationReserve 0.3: the request with accelerationScale 0.7.
     Compared sample by sample: the same count; Execute's planTime (where on the plan a
     live sample stands; its `t` is the cycle clock, equal to planTime at 100 % except at
     the final sample, which comes at the next cycle) equal to the reference's t; the tool
     position and the joints equal; the speed factor 1 up to the final sample; Execute's
     LiveStatus.planDurationS equal to the reference's duration.
     Equal means within 1e-9 (s, m) and, for the joints, 1e-8 rad. Both calls evaluate one planned trajectory with
     the same sampler at the same plan times (Execute's a sum of cycle periods, an ulp or
     so from k / rate: 1e-16 s measured), so planTime and the tool position agree to
     round-off (1e-15 measured), and 1e-9 is six orders above that and far below what
     another timing or path gives (a timing 0.1 % apart moves points by ~1e-4 m). 1e-9 is
     also the IK's own convergence tolerance (core/robot/ik.hpp, IkOptions: 1e-9 m and
     1e-9 rad of residual), where the joints come from: the tracker's Newton iterations
     start from a predictor over the previous samples, so an ulp of plan time there can
     stop them at another point within the residual, 1e-9 rad or so away (measured: up to
     2.3e-9 rad on the UR5's lines, with plan time and tool position bit for bit equal).
     The joints are therefore compared within 1e-8 rad, ten times the IK's residual and
     still five orders below what another timing or branch gives.
  Where the Plan reports the robot outside its limits (a reportOnly file), StreamSamples
  and Execute without reportOnly must both refuse it instead. Execute refuses reportOnly
  by design (INVALID_ARGUMENT; test_python_live.py checks it), so Execute and the
  references take the request with reportOnly cleared, as test_python_moves.py does.
  Every mismatch names the request, the mode, the sample index (and sequence step) and the
  differing quantities with both values; a refusal gives the status and its text.

Execute runs in real time: the calls run 8 at once (a thread pool, the longest first), so
that the wall time is about the longest plan (20 s) plus the rest divided by 8. A plan
longer than MAX_PLAN_S (40 s) is shortened first (a fixed durationS scaled down, a fastest
motion's maxSpeed raised) and its line says so; none of the files needs it today. When
geotrajd dies under an Execute call, it is started again, and the calls that were running
run again one at a time: the one that brings it down alone fails with its exit status.

Run: test_plan_stream_execute.py --server build/server/geotrajd --stubs build/tests/interop/pystubs
         --requests client/grpcurl
"""
import argparse
import concurrent.futures
import json
import math
import os
import queue
import signal
import subprocess
import sys
import threading
import time
import unittest

from test_python_client import start_geotrajd, stop_geotrajd

ARGS = None
TOLERANCE = 1e-9           # [s, m] see the module docstring
JOINT_TOLERANCE = 1e-8     # [rad] ten times the IK's residual tolerance: see the module docstring
DEFAULT_RESERVE = 0.1      # ExecuteOptions.accelerationReserve when absent
HEARTBEAT_S = 0.2          # a fifth of the default 1 s deadman
CONCURRENT_EXECUTES = 8
MAX_PLAN_S = 40.0

# The fixed durationS [s] of the cases whose file gives none (durationS 0). A sequence's
# applies to each of its motions (a step with its own durationS keeps it; a blended chain is
# one motion); a path with robot.approach: to the path, after the approach. Chosen so that
# the robot can follow the plan (path C on the Panda in 7 s breaks joint 1's acceleration).
# A file not listed gets 1.5 times its fastest duration, rounded up to a whole second.
FIXED_DURATION_S = {
    "joint_move_pa10.json": 3.0,
    "plan_panda_path_c.json": 8.0,
    "sequence_ur5.json": 2.0,
    "sequence_blended_ur5.json": 4.0,
    "jointMove to a pose (UR5)": 2.0,
    "linearMove to joints (UR5)": 2.0,
    "plan_panda_path_c.json, robot.approach linear": 8.0,
}

# The request files that are not cases, and why (kept equal to the module docstring).
EXPECTED_SKIPS = {
    "appendix_b_b11.json": "no motion",
    "appendix_b_b13.json": "no motion",
    "appendix_b_optimized.json": "no motion",
    "appendix_b_uniform.json": "no motion",
    "bad_request.json": "no motion",
    "convert_table_5_10.json": "no motion",
    "execute_panda.json": "ExecuteRequest",
    "fk_pa10.json": "ForwardKinematicsRequest",
    "ik_ur5_all.json": "InverseKinematicsRequest",
    "jog_panda.json": "JogRequest",
}


class Case:
    """One (request, mode): the request PlanTrajectory and StreamSamples take as it is, the
    reserve Execute is given (None: the default), and what the run found."""

    def __init__(self, name, mode, request, reserve=None):
        self.name, self.mode, self.request, self.reserve = name, mode, request, reserve
        self.problems = []   # what fails the case
        self.notes = []      # what the line says besides
        self.plan = None
        self.reference = None        # (samples, what it is)
        self.infeasible = False      # the Plan reports the robot outside its limits
        self.execute = None          # ExecuteResult
        self.execute_request = None  # the request Execute and the reference take (reportOnly cleared)

    @property
    def label(self):
        return f"{self.name} [{self.mode}]"


class ExecuteResult:
    def __init__(self):
        self.samples = []   # (t, plan_time, speed_factor, step, x, y, z, joints)
        self.code = self.details = self.reason = None
        self.live = None    # the last batch's LiveStatus
        self.wall_s = 0.0
        self.crash = None   # geotrajd's exit status when it died under the call


def exit_status(code):
    return f"signal {-code} ({signal.Signals(-code).name})" if code < 0 else f"exit status {code}"


class Server:
    """geotrajd, started again when it dies under an Execute call, so that one crash does
    not take every other case with it (the calls it interrupts run again, one at a time)."""

    def __init__(self, path):
        self.path = path
        self.lock = threading.Lock()
        self.generation = 0
        self.deaths = []  # (generation, exit status)
        self.proc, self.channel = start_geotrajd(path)
        self.stub = rpc.TrajectoryServiceStub(self.channel)

    def current(self):
        with self.lock:
            return self.generation, self.proc, self.stub

    def died(self, generation, proc):
        """The exit status of the server a call ran on if it has exited (then a new one
        serves the next calls), else None."""
        try:
            proc.wait(timeout=2)
        except subprocess.TimeoutExpired:
            return None
        with self.lock:
            if self.generation == generation:
                self.deaths.append((generation, proc.returncode))
                self.channel.close()
                self.proc, self.channel = start_geotrajd(self.path)
                self.stub = rpc.TrajectoryServiceStub(self.channel)
                self.generation += 1
        return proc.returncode

    def stop(self):
        stop_geotrajd(self.proc, self.channel)


def execute_requests(first, outbox):
    """The request stream of one Execute call: `first`, then whatever `outbox` hands over,
    and a heartbeat whenever it hands nothing over for HEARTBEAT_S; None ends it (after the
    response stream has ended: a half-close would leave the call to the deadman)."""
    yield first
    while True:
        try:
            message = outbox.get(timeout=HEARTBEAT_S)
        except queue.Empty:
            yield pb.ExecuteRequest(heartbeat=pb.Heartbeat())
            continue
        if message is None:
            return
        yield message


def stream_row(s):
    return (s.t, s.step, s.position.x, s.position.y, s.position.z, tuple(s.joints))


def live_row(s):
    return (s.t, s.plan_time, s.speed_factor, s.step, s.position.x, s.position.y, s.position.z, tuple(s.joints))


def timed_by_limits(request):
    """planner::time_optimally_timed for the request's own motion: optimize.timing, or
    durationS 0 with a robot or the trapezoidal profile."""
    timing = request.optimize.timing
    minimum_time = request.motion.duration_s == 0.0 and (
        request.HasField("robot") or request.motion.profile in (pb.MOTION_PROFILE_UNSPECIFIED,
                                                                  pb.MOTION_PROFILE_TRAPEZOIDAL))
    return timing.time_optimal or timing.jerk_limited or minimum_time


def copy(request):
    out = pb.PlanRequest()
    out.CopyFrom(request)
    return out


def error_text(e):
    return f"{e.code().name}: {e.details()}"


class PlanStreamExecute(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        sys.path.insert(0, ARGS.stubs)
        global grpc, pb, rpc, json_format
        import grpc
        from geotraj.v1 import geotraj_pb2 as pb
        from geotraj.v1 import geotraj_pb2_grpc as rpc
        from google.protobuf import json_format
        cls.server = Server(ARGS.server)
        cls.models = {m.name: m for m in cls.server.stub.ListRobots(pb.ListRobotsRequest()).robots}

    @classmethod
    def tearDownClass(cls):
        cls.server.stop()

    @property
    def stub(self):
        return self.server.stub

    # --- the request files ---------------------------------------------------------------------

    @staticmethod
    def classify(directory):
        """({file: PlanRequest} of the files that are cases, {file: (kind, reason)} of the
        others), by parsing each file and looking at what it holds."""
        plans, skipped, executes = {}, {}, {}
        for name in sorted(f for f in os.listdir(directory) if f.endswith(".json")):
            with open(os.path.join(directory, name)) as f:
                text = f.read()
            try:
                request = json_format.Parse(text, pb.PlanRequest())
            except json_format.ParseError as e:
                # Which message it is instead: the first JSON document of the file.
                try:
                    first, end = json.JSONDecoder().raw_decode(text)
                except ValueError:
                    skipped[name] = ("not JSON", str(e))
                    continue
                kind = None
                for message in (pb.ExecuteRequest, pb.JogRequest, pb.ForwardKinematicsRequest,
                                pb.InverseKinematicsRequest, pb.ConvertRequest):
                    try:
                        parsed = json_format.ParseDict(first, message())
                    except json_format.ParseError:
                        continue
                    kind = message.DESCRIPTOR.name
                    break
                more = " (one of several messages in the file)" if text[end:].strip() else ""
                if kind == "ExecuteRequest" and parsed.HasField("plan"):
                    executes[name] = parsed.plan
                what = kind or "message of another type"
                article = "an" if what[0] in "AEIOUaeiou" else "a"
                skipped[name] = (kind or "unknown", f"{article} {what}{more}, not a PlanRequest: "
                                                     f"{str(e).splitlines()[0]}")
                continue
            if not request.HasField("motion"):
                skipped[name] = ("no motion", "a PlanRequest without a motion (geometry only: ConvertConstraints, "
                                              "AnalyzePath or an error example): nothing to stream or execute")
                continue
            plans[name] = request
        # An ExecuteRequest's plan is a case unless a PlanRequest file holds the same plan.
        for name, plan in executes.items():
            twin = next((n for n, r in plans.items() if r == plan), None)
            if twin is None:
                plans[name] = plan
                del skipped[name]
            else:
                skipped[name] = ("ExecuteRequest", f"an ExecuteRequest whose plan is {twin}'s (a case there)")
        return plans, skipped

    def test_request_files_are_classified_as_documented(self):
        _, skipped = self.classify(ARGS.requests)
        for name, (kind, reason) in sorted(skipped.items()):
            print(f"[ skipped  ] {name}: {reason}")
        self.assertEqual({n: k for n, (k, _) in skipped.items()}, EXPECTED_SKIPS,
                         "the skipped request files differ from the list in the docstring: update both")

    # --- the cases -----------------------------------------------------------------------------

    def fixed_duration(self, name, request):
        if name in FIXED_DURATION_S:
            return FIXED_DURATION_S[name]
        fastest = copy(request)
        fastest.motion.duration_s = 0.0
        fastest.robot.report_only = True
        return float(math.ceil(1.5 * self.stub.PlanTrajectory(fastest, timeout=120).motion.duration_s))

    def cases(self):
        plans, _ = self.classify(ARGS.requests)
        kinds = dict(plans)  # name -> request, in the file's own mode
        # The kinds the files do not hold (test_python_moves.py's shapes).
        sequence = plans["sequence_ur5.json"]
        move = pb.PlanRequest(robot=sequence.robot, motion=pb.MotionSpec(duration_s=0, cycle_rate_hz=500))
        move.joint_move.goal_pose.CopyFrom(sequence.sequence[2].joint_move.goal_pose)
        kinds["jointMove to a pose (UR5)"] = move
        line = copy(plans["linear_move_ur5.json"])
        line.motion.duration_s = 0
        line.linear_move.ClearField("goal")
        line.linear_move.goal_joints.extend([0.3, -1.45, 1.4, -1.5, -1.5708, 0.2])  # near the home, on its branch
        kinds["linearMove to joints (UR5)"] = line
        approach = copy(plans["plan_panda_path_c.json"])
        approach.robot.approach = pb.APPROACH_MOVE_LINEAR
        kinds["plan_panda_path_c.json, robot.approach linear"] = approach
        fastest_only = {}
        jerk = copy(plans["plan_pa10_path_c.json"])
        jerk.motion.duration_s = 0
        jerk.robot.report_only = False
        jerk.optimize.timing.jerk_limited = True
        model = pb.RobotModel()
        model.CopyFrom(self.models["pa10"])
        for lim in model.limits:
            lim.max_jerk = 4 * lim.max_acceleration
        jerk.robot.ClearField("name")
        jerk.robot.model.CopyFrom(model)
        fastest_only["plan_pa10_path_c.json, jerk-limited (inline PA-10, max jerk 4 a_max)"] = jerk
        panda = copy(plans["plan_panda_path_c.json"])
        panda.optimize.timing.jerk_limited = True
        fastest_only["plan_panda_path_c.json, optimize.timing.jerkLimited"] = panda
        # The file's own 10 s is beyond the PA-10's accelerations (its report says so): a fixed
        # duration it can follow, so that one fixed-duration path with a robot is executed.
        slow = copy(plans["plan_pa10_path_c.json"])
        slow.motion.duration_s = 20.0
        fixed_only = {"plan_pa10_path_c.json, durationS 20": slow}

        out = []
        for name, request in kinds.items():
            fixed = copy(request)
            if fixed.motion.duration_s == 0.0:
                fixed.motion.duration_s = self.fixed_duration(name, request)
            if self.has_jerk_limits(fixed):
                # The trapezoid's acceleration steps break the Panda's jerk limits at 1 kHz
                # (PlanTrajectory says so): a fixed duration on such an arm is an S-curve.
                fixed.motion.profile = pb.MOTION_PROFILE_S_CURVE
            out.append(Case(name, f"fixed {fixed.motion.duration_s:g} s", fixed))
            if request.HasField("robot"):
                fastest = copy(request)
                fastest.motion.duration_s = 0.0
                out.append(Case(name, "fastest", fastest))
        for name, request in fixed_only.items():
            out.append(Case(name, f"fixed {request.motion.duration_s:g} s", request))
        for name, request in fastest_only.items():
            out.append(Case(name, "fastest", request))
        larger = copy(plans["joint_move_pa10.json"])
        larger.motion.duration_s = 0.0
        out.append(Case("joint_move_pa10.json", "fastest, accelerationReserve 0.3", larger, reserve=0.3))
        return out

    def has_jerk_limits(self, request):
        if request.robot.HasField("model"):
            limits = request.robot.model.limits
        elif request.robot.name in self.models:
            limits = self.models[request.robot.name].limits
        else:
            return False
        return any(lim.HasField("max_jerk") for lim in limits)

    # --- the calls -----------------------------------------------------------------------------

    def stream(self, request):
        return [stream_row(s) for batch in self.stub.StreamSamples(request, timeout=300) for s in batch.samples]

    def shorten(self, case):
        """A plan longer than MAX_PLAN_S made shorter (the docstring)."""
        duration = case.plan.motion.duration_s
        request = case.request
        if request.motion.duration_s > 0.0:
            factor = MAX_PLAN_S / duration
            request.motion.duration_s = math.floor(request.motion.duration_s * factor * 10) / 10
            for step in request.sequence:
                if step.HasField("motion") and step.motion.duration_s > 0.0:
                    step.motion.duration_s = math.floor(step.motion.duration_s * factor * 10) / 10
            what = f"durationS {request.motion.duration_s:g} s"
        elif request.motion.HasField("max_speed"):
            request.motion.max_speed *= 1.1 * duration / MAX_PLAN_S
            what = f"maxSpeed {request.motion.max_speed:g} m/s"
        else:
            case.notes.append(f"the plan takes {duration:.1f} s; nothing in its request shortens it")
            return
        case.plan = self.stub.PlanTrajectory(request, timeout=120)
        case.notes.append(f"shortened from {duration:.1f} s to {case.plan.motion.duration_s:.1f} s ({what})")

    def plan_and_stream(self, case):
        """Steps 1 and 2, and the reference of step 3."""
        try:
            case.plan = self.stub.PlanTrajectory(case.request, timeout=120)
        except grpc.RpcError as e:
            case.problems.append(f"PlanTrajectory refused the request: {error_text(e)}")
            return
        if case.plan.motion.duration_s > MAX_PLAN_S:
            self.shorten(case)
        plan = case.plan
        if case.request.HasField("robot"):
            case.infeasible = not plan.robot.feasible
        try:
            samples = self.stream(case.request)
        except grpc.RpcError as e:
            case.problems.append(f"StreamSamples refused what PlanTrajectory planned: {error_text(e)}")
            return
        if len(samples) != plan.motion.sample_count:
            case.problems.append(f"StreamSamples sent {len(samples)} samples, PlanTrajectory's sampleCount is "
                                 f"{plan.motion.sample_count}")
        if not samples or abs(samples[-1][0] - plan.motion.duration_s) > TOLERANCE:
            case.problems.append(f"StreamSamples' last sample is at t {samples[-1][0] if samples else None!r}, "
                                 f"PlanTrajectory's durationS is {plan.motion.duration_s!r}")

        plain = copy(case.request)
        if plain.HasField("robot"):
            plain.robot.report_only = False  # Execute refuses reportOnly (the docstring)
        case.execute_request = plain
        if case.infeasible:
            # Outside the limits: StreamSamples without reportOnly must refuse it, as Execute must.
            try:
                self.stream(plain)
                case.problems.append("PlanTrajectory reports the robot outside its limits, yet StreamSamples "
                                     "without reportOnly streamed it")
            except grpc.RpcError as e:
                case.notes.append(f"StreamSamples without reportOnly refuses it ({e.code().name})")
            return
        reserve = DEFAULT_RESERVE if case.reserve is None else case.reserve
        approach = plain.HasField("path") and plain.robot.approach != pb.APPROACH_MOVE_UNSPECIFIED
        if not ((timed_by_limits(plain) or approach) and reserve > 0.0):
            case.reference = (samples if not case.request.robot.report_only else self.stream(plain),
                              "the plain request" + (" (reportOnly cleared)" if case.request.robot.report_only else ""))
            return
        scaled = copy(plain)
        scaled.motion.acceleration_scale = 1.0 - reserve
        what = f"motion.accelerationScale {1.0 - reserve:g}"
        try:
            case.reference = (self.stream(scaled), f"the request with {what}")
            return
        except grpc.RpcError as e:
            if e.code() != grpc.StatusCode.INVALID_ARGUMENT or not scaled.sequence:
                case.problems.append(f"StreamSamples of the request with {what} (Execute's plan, docs/live.md) "
                                     f"refused: {error_text(e)}")
                return
            case.notes.append(f"NOTE: the request with {what} is refused ({error_text(e)}); given on every step "
                              f"timed by the limits instead")
        per_step = copy(plain)
        for step in per_step.sequence:
            if not step.HasField("motion") or step.motion.duration_s == 0.0:
                step.motion.acceleration_scale = 1.0 - reserve
        try:
            case.reference = (self.stream(per_step), f"the request with accelerationScale {1.0 - reserve:g} "
                                                     f"on its steps timed by the limits")
        except grpc.RpcError as e:
            case.problems.append(f"StreamSamples of the request with accelerationScale {1.0 - reserve:g} on its "
                                 f"steps timed by the limits refused: {error_text(e)}")

    def execute(self, case):
        """One Execute call to its end, at 100 % override."""
        first = pb.ExecuteRequest(plan=case.execute_request)
        if case.reserve is not None:
            first.options.acceleration_reserve = case.reserve
        outbox = queue.Queue()
        result = ExecuteResult()
        started = time.monotonic()
        duration = case.plan.motion.duration_s if case.plan else 0.0
        generation, proc, stub = self.server.current()
        call = stub.Execute(execute_requests(first, outbox), timeout=2 * duration + 120)
        try:
            for batch in call:
                result.samples.extend(live_row(s) for s in batch.samples)
                result.live = batch.live
        except grpc.RpcError:
            pass  # the status says why
        finally:
            outbox.put(None)
        result.code, result.details = call.code(), call.details()
        result.reason = dict(call.trailing_metadata() or ()).get("geotraj-stop-reason")
        result.wall_s = time.monotonic() - started
        if result.code == grpc.StatusCode.UNAVAILABLE:
            result.crash = self.server.died(generation, proc)
        return result

    # --- the comparison ------------------------------------------------------------------------

    @staticmethod
    def compare(case):
        """The first mismatch between Execute's samples and the reference's, with every
        quantity that differs there; None when they agree. Also the largest differences."""
        live, (reference, _) = case.execute.samples, case.reference
        worst = {"planTime": 0.0, "position": 0.0, "joints": 0.0}
        first = None
        for k, (a, b) in enumerate(zip(live, reference)):
            t, tau, r, step, x, y, z, q = a
            t_ref, step_ref, x_ref, y_ref, z_ref, q_ref = b
            diffs = []
            if abs(tau - t_ref) > TOLERANCE:
                diffs.append(f"planTime {tau!r} vs t {t_ref!r} ({tau - t_ref:+.3e} s)")
            worst["planTime"] = max(worst["planTime"], abs(tau - t_ref))
            for axis, u, v in (("x", x, x_ref), ("y", y, y_ref), ("z", z, z_ref)):
                worst["position"] = max(worst["position"], abs(u - v))
                if abs(u - v) > TOLERANCE:
                    diffs.append(f"position.{axis} {u!r} vs {v!r} ({u - v:+.3e} m)")
            if len(q) != len(q_ref):
                diffs.append(f"{len(q)} joints vs {len(q_ref)}")
            for j, (u, v) in enumerate(zip(q, q_ref)):
                worst["joints"] = max(worst["joints"], abs(u - v))
                if abs(u - v) > JOINT_TOLERANCE:
                    diffs.append(f"joints[{j}] {u!r} vs {v!r} ({u - v:+.3e})")
            if k + 1 < len(live) and abs(r - 1.0) > 1e-12:
                diffs.append(f"speedFactor {r!r} (not 1 at 100 % override)")
            if diffs and first is None:
                first = (f"first mismatch at sample {k} (step {step}, Execute t {t:.6f} s): "
                         + "; ".join(diffs) + (f" [{len(diffs)} quantities]" if len(diffs) > 1 else ""))
        count = None
        if len(live) != len(reference):
            count = (f"Execute sent {len(live)} samples (plan {case.execute.live.plan_duration_s!r} s), "
                     f"the reference {len(reference)} (last t {reference[-1][0]!r} s)")
        mismatch = "; ".join(m for m in (count, first) if m) or None
        return mismatch, worst

    def check_execute(self, case):
        result = case.execute
        if result.crash is not None:
            case.problems.append(f"geotrajd died ({exit_status(result.crash)}) under this Execute call, run alone "
                                 f"(the call ended {result.code.name}: {result.details})")
            return
        if case.infeasible:
            if result.code == grpc.StatusCode.OK or result.samples:
                case.problems.append(f"PlanTrajectory reports the robot outside its limits, yet Execute ran it "
                                     f"({result.code.name}, {len(result.samples)} samples)")
            else:
                case.notes.append(f"Execute refuses it: {result.code.name}: {result.details}")
            return
        if result.code != grpc.StatusCode.OK or result.reason != "completed":
            case.problems.append(f"Execute did not run the plan PlanTrajectory accepted: {result.code.name} "
                                 f"(reason {result.reason}, {len(result.samples)} samples): {result.details}")
            return
        if case.reference is None:
            return
        mismatch, worst = self.compare(case)
        reference_duration = case.reference[0][-1][0]
        if abs(result.live.plan_duration_s - reference_duration) > TOLERANCE:
            case.problems.append(f"Execute's plan takes {result.live.plan_duration_s!r} s, the reference "
                                 f"{reference_duration!r} s ({result.live.plan_duration_s - reference_duration:+.6f} s)")
        if mismatch:
            case.problems.append(f"against {case.reference[1]}: {mismatch}")
        case.notes.append(f"Execute {len(result.samples)} samples in {result.wall_s:.1f} s, against {case.reference[1]}: "
                          f"largest differences planTime {worst['planTime']:.1e} s, position {worst['position']:.1e} m, "
                          f"joints {worst['joints']:.1e}")

    # --- the test ------------------------------------------------------------------------------

    def test_plan_stream_and_execute_agree(self):
        started = time.monotonic()
        cases = self.cases()
        for case in cases:
            self.plan_and_stream(case)
        planned = time.monotonic()
        # Execute in real time, CONCURRENT_EXECUTES at once, the longest first.
        runnable = [c for c in cases if c.plan is not None and c.execute_request is not None]
        runnable.sort(key=lambda c: -c.plan.motion.duration_s)
        with concurrent.futures.ThreadPoolExecutor(CONCURRENT_EXECUTES) as pool:
            futures = {pool.submit(self.execute, c): c for c in runnable}
            for future in concurrent.futures.as_completed(futures):
                futures[future].execute = future.result()
        # The calls a crash of the server ended, again one at a time: which one brings it down.
        for case in [c for c in runnable if c.execute.crash is not None]:
            case.execute = self.execute(case)
            if case.execute.crash is None:
                case.notes.append("run again alone: geotrajd died under another call while this one ran")
        executed = time.monotonic()
        for case in runnable:
            self.check_execute(case)

        for case in cases:
            plan = case.plan
            summary = "no plan"
            if plan is not None:
                summary = f"Plan {plan.motion.duration_s:.4f} s, {plan.motion.sample_count} samples"
                if plan.HasField("robot"):
                    summary += ", feasible" if plan.robot.feasible else ", NOT feasible (reportOnly)"
            print(f"[ {'FAIL' if case.problems else 'PASS'} ] {case.label}: {summary}")
            for line in case.problems:
                print(f"             FAIL: {line}")
            for line in case.notes:
                print(f"             {line}")
        failed = [c for c in cases if c.problems]
        for generation, code in self.server.deaths:
            print(f"[ crashed  ] geotrajd (server {generation + 1}) died with {exit_status(code)}; started again")
        print(f"[ measured ] {len(cases)} cases, {len(cases) - len(failed)} pass, {len(failed)} fail; wall time "
              f"{executed - started:.1f} s (plans and streams {planned - started:.1f} s, Executes "
              f"{executed - planned:.1f} s for {sum(c.plan.motion.duration_s for c in runnable):.1f} s of plans)")
        for case in cases:
            with self.subTest(case.label):
                if case.problems:
                    self.fail(f"{case.label}: " + " | ".join(case.problems))


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--server", required=True)
    parser.add_argument("--stubs", required=True)
    parser.add_argument("--requests", required=True)
    ARGS, rest = parser.parse_known_args()
    unittest.main(argv=[sys.argv[0]] + rest, verbosity=2)
