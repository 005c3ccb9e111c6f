#!/usr/bin/env python3
"""Joint paths through waypoints (PlanRequest.jointPath) from a Python client, checked on what
StreamSamples and Execute send.

Against a real geotrajd, on every arm ListRobots lists, waypoints drawn (seeded, the same every
run) within the middle of each joint's range: a random set of 5 to 10 waypoints with one stop,
6 waypoints on one joint-space line, back and forth (A, B, A, B), a random walk of 40 steps of
0.05 rad, and 2 waypoints; on the Panda also the pick and place of
client/grpcurl/plan_joint_path_panda.json and a random walk of 200 waypoints. Each as fast as
the limits allow (durationS 0), in the default timing (jerk-limited) and in the time-optimal
sweep alone (optimize.timing.timeOptimal), each streamed at 1 kHz and at 4 kHz:
  - the first and last samples at the first and last waypoints (1e-9), at rest; every interior
    waypoint within blendTolerance of the polyline of the samples (plus the chord bound, below);
    waypoints on one line passed on it, every sample on that line; a rest (a sample there with
    a velocity of at most maxAcceleration dt / 2) at every stop and reversal;
  - every joint's velocity, acceleration and jerk by finite differences of the positions within
    the model's limits (the jerk for the jerk-limited timing: within maxJerk, or the documented
    default bound maxAcceleration / 0.05 s on the arms without one);
  - nothing that grows with the rate. The server plans each rate on its own (the jerk-limited
    durations differ by up to 1 % between 1 and 4 kHz), so the 4 kHz stream is compared with
    its own every fourth sample (1 kHz): the largest acceleration by differences the same (1 %),
    the largest jerk of the jerk-limited timing below 1.5 times (an acceleration step would
    show as a jerk 4 times larger, as the sweep's steps do);
  - the duration against a time-optimal reference computed here without geotraj: Kunz and
    Stilman's path (lines, each corner a circular arc whose largest deviation from the waypoint
    is the tolerance unless half a line is shorter) timed within the same joint velocity and
    acceleration limits by a phase-plane sweep in b = s_dot^2. The sweep within 3 % of it or
    faster, the jerk-limited timing within 10 % on an arm with its own jerk limits and 30 % under
    the default jerk (JERK_LIMITED_DEFAULT_RAMP_OVER_REFERENCE); on the small-step walks, whose blends are all
    bounded by the lines (the shapes then differ), printed only.
Execute runs the pick and place with a pause and a resume: it completes at the last waypoint,
the pause holds the arm at rest on the planned path, every set point on that path and within
the limits. Bad waypoints and tolerances are INVALID_ARGUMENT with a google.rpc.BadRequest
naming the field. One line per set gives the durations, the reference, the largest usage of
each limit at 1 and 4 kHz, and the largest distance to a waypoint.
Run: test_python_joint_paths.py --server build/server/geotrajd --stubs build/tests/interop/pystubs
     --requests client/grpcurl
"""
import argparse
import concurrent.futures
import math
import os
import queue
import sys
import time
import unittest
import zlib

import numpy as np

from test_python_client import start_geotrajd, stop_geotrajd

ARGS = None
RATES = (1000.0, 4000.0)
SEED = 20261206
DEFAULT_JERK_RAMP_S = 0.05  # docs/moves.md: a joint without maxJerk is bounded by maxAcceleration / 0.05 s
# Finite differences. k! times a divided difference of order k of the positions is a mean of
# the k-th derivative over its k + 1 samples (Peano's kernel, a B-spline, is positive with unit
# integral), so the scheme adds nothing: a difference passes a limit only where the motion
# does between the points the server checks (every sample at the cycle rate and at
# CHECK_RATE_HZ or more, TimingReport.checkRateHz). Between two of them a velocity passes the
# larger checked value by at most maxAcceleration h / 2, h = 1 / CHECK_RATE_HZ (the proto's
# bound): the velocity's allowance, per joint (5e-4 of maxVelocity on the PA-10, the UR arms
# and the iiwa, up to 1.9e-3 on the Panda). Accelerations and jerks get 1 % (an acceleration passes its
# checked values by at most maxJerk h / 2 between them, 0.5 % of maxAcceleration under the
# default jerk bound; test_python_moves.py and test_python_live.py allow 2 %).
CHECK_RATE_HZ = 2000.0
ACCELERATION_SLACK = 0.01
JERK_SLACK = 0.01
# The rate test: at 4 times the rate a step in an acceleration shows as a jerk by differences
# 4 times larger, a bounded jerk as the same one.
ACCELERATION_GROWTH = 1.01
JERK_GROWTH = 1.5
# The 200-waypoint set's optimiser budget [s] (optimize.timeBudgetS), and the sets run at once.
PLAN_BUDGET_S = 2.0
WORKERS = 2
# Durations against the reference (the sweep is time-optimal on its own path).
SWEEP_OVER_REFERENCE = 1.03
# The jerk-limited timing against the time-optimal reference: within 10 % on an arm whose model
# gives its joints' jerk limits (the Panda's), within 30 % on an arm bounded by the default
# jerk a_max / 0.05 s: every swing of a joint acceleration between -a_max and +a_max, which the
# time-optimal timing makes in no time, then takes 0.1 s, and the UR arms' random sets have
# dozens of them (measured 1.10-1.25 there, 1.00-1.01 on the Panda).
JERK_LIMITED_OVER_REFERENCE = 1.10
JERK_LIMITED_DEFAULT_RAMP_OVER_REFERENCE = 1.30


# --- waypoints ---------------------------------------------------------------------------------

def middle_box(model):
    """The middle of each joint's range: its middle half, at most 1 rad either side of the
    middle (the UR arms turn +-2 pi: their lines stay a few seconds long)."""
    lo = np.array([l.min_position for l in model.limits])
    hi = np.array([l.max_position for l in model.limits])
    mid, half = 0.5 * (lo + hi), np.minimum(0.25 * (hi - lo), 1.0)
    return mid - half, mid + half


def random_point(rng, box):
    return rng.uniform(box[0], box[1])


def random_walk(rng, box, count, step):
    """`count` waypoints, `step` apart in random directions (a dense planner's output: every
    corner turns by about 90 degrees in 6 or 7 joints), within `box`."""
    points = [random_point(rng, box)]
    while len(points) < count:
        d = rng.normal(size=len(box[0]))
        q = points[-1] + step * d / np.linalg.norm(d)
        if np.all(q >= box[0]) and np.all(q <= box[1]):
            points.append(q)
    return points


def far_pair(rng, box, least):
    """Two random points at least `least` apart."""
    while True:
        a, b = random_point(rng, box), random_point(rng, box)
        if np.linalg.norm(b - a) >= least:
            return a, b


def arm_cases(model):
    """The sets of one arm: (name, waypoints, stops, tolerance, compare with the reference)."""
    rng = np.random.default_rng(SEED + zlib.crc32(model.name.encode()))
    box = middle_box(model)
    cases = []
    n = int(rng.integers(5, 11))
    points = [random_point(rng, box) for _ in range(n)]
    stops = [False] * n
    stops[int(rng.integers(1, n - 1))] = True
    cases.append((f"random, {n} waypoints, 1 stop", points, stops, 0.1, True))
    a, b = far_pair(rng, box, 1.0)
    fractions = [0.0] + sorted(rng.uniform(0.1, 0.9, size=4)) + [1.0]
    cases.append(("collinear, 6 waypoints", [a + f * (b - a) for f in fractions], [False] * 6, 0.05, True))
    a, b = far_pair(rng, box, 0.8)
    cases.append(("back and forth A B A B", [a, b, a, b], [False] * 4, 0.05, True))
    cases.append(("random walk, 40 steps of 0.05 rad", random_walk(rng, box, 41, 0.05), [False] * 41, 0.05, False))
    a, b = far_pair(rng, box, 1.0)
    cases.append(("2 waypoints", [a, b], [False, False], 0.05, True))
    return cases


# --- the reference: Kunz and Stilman's path, timed by a phase-plane sweep ---------------------

def rest_pieces(points, stops):
    """The waypoints cut where the motion rests: at stops and at reversals (a corner of 180
    degrees). Repeated waypoints merged, waypoints in line with their neighbours dropped."""
    pts, flags = [points[0]], [stops[0]]
    for p, s in zip(points[1:], stops[1:]):
        if np.linalg.norm(p - pts[-1]) > 1e-9:
            pts.append(p)
            flags.append(s)
        else:
            flags[-1] = flags[-1] or s
    pieces, current = [], [pts[0]]
    for i in range(1, len(pts)):
        current.append(pts[i])
        if i == len(pts) - 1:
            break
        u = (pts[i] - pts[i - 1]) / np.linalg.norm(pts[i] - pts[i - 1])
        w = (pts[i + 1] - pts[i]) / np.linalg.norm(pts[i + 1] - pts[i])
        cos = float(np.dot(u, w))
        if flags[i] or cos <= -1.0 + 1e-12:
            pieces.append(current)
            current = [pts[i]]
        elif cos >= 1.0 - 1e-12:
            current.pop()  # on the line: passed without a blend
    pieces.append(current)
    return pieces


def kunz_stilman_grid(points, tolerance, arc_intervals=160, line_step=0.01):
    """Kunz and Stilman's path through `points` (one piece, at rest at both ends): lines, each
    corner replaced by a circular arc tangent to both lines at l = min(|d_prev| / 2,
    |d_next| / 2, tolerance sin(a / 2) / (1 - cos(a / 2))) from the corner (a: the angle
    between the line directions), radius r = l / tan(a / 2): its largest deviation from the
    waypoint is the tolerance unless a line's half is shorter. Returns the grid (interval
    lengths ds, q'(s) and q''(s) at each point, a junction given twice, once with each side's
    derivatives), the number of blends and of those bounded by half a line."""
    P = [np.asarray(p, float) for p in points]
    seg = [b - a for a, b in zip(P, P[1:])]
    L = [float(np.linalg.norm(d)) for d in seg]
    U = [d / n for d, n in zip(seg, L)]
    blends, bounded = [], 0
    for i in range(1, len(P) - 1):
        a = math.acos(max(-1.0, min(1.0, float(np.dot(U[i - 1], U[i])))))
        l_tol = tolerance * math.sin(a / 2) / (1 - math.cos(a / 2))
        l = min(L[i - 1] / 2, L[i] / 2, l_tol)
        bounded += l_tol > min(L[i - 1], L[i]) / 2
        blends.append((l, a))
    ds, D, C = [], [], []

    def add(step, d, c):
        if D:
            ds.append(step)
        D.append(d)
        C.append(c)

    zero = np.zeros(len(P[0]))
    for i, (u, length) in enumerate(zip(U, L)):
        start = blends[i - 1][0] if i > 0 else 0.0
        end = blends[i][0] if i < len(blends) else 0.0
        part = max(length - start - end, 0.0)
        m = max(16, int(math.ceil(part / line_step)))
        add(0.0, u, zero)
        for _ in range(m):
            add(part / m, u, zero)
        if i < len(blends):
            l, a = blends[i]
            r = l / math.tan(a / 2)
            w = U[i + 1] - u
            center = P[i + 1] + w / np.linalg.norm(w) * (r / math.cos(a / 2))
            x = (P[i + 1] - l * u - center) / r
            for k in range(arc_intervals + 1):
                phi = a * k / arc_intervals
                add(0.0 if k == 0 else r * a / arc_intervals,
                    -x * math.sin(phi) + u * math.cos(phi), -(x * math.cos(phi) + u * math.sin(phi)) / r)
    return np.array(ds), np.array(D), np.array(C), len(blends), bounded


def phase_plane_time(ds, D, C, vmax, amax):
    """The least time over the grid, from rest to rest, within |q_j' s_dot| <= vmax_j and
    |q_j' s_ddot + q_j'' s_dot^2| <= amax_j: the largest b = s_dot^2 at each point (the
    velocity limits, and the largest b at which some s_ddot keeps every acceleration),
    a forward pass with the largest s_ddot and a backward pass with the smallest (b' = 2
    s_ddot, each interval under its first point's bounds), their minimum, and the time as
    the sum of 2 ds / (sqrt(b_i) + sqrt(b_i+1)) (exact where s_ddot is constant)."""
    eps = 1e-12
    moving = np.abs(D) > eps
    absd = np.where(moving, np.abs(D), 1.0)
    alpha = np.where(moving, amax / absd, np.inf)           # s_ddot in [-alpha - beta b, alpha - beta b]
    beta = np.where(moving, C / np.where(moving, D, 1.0), 0.0)
    cap = np.min(np.where(moving, (vmax / absd) ** 2, np.inf), axis=1)
    still = ~moving & (np.abs(C) > eps)                      # a joint that only curves: |c| b <= a
    cap = np.minimum(cap, np.min(np.where(still, amax / np.where(still, np.abs(C), 1.0), np.inf), axis=1))
    # lo_j(b) <= hi_k(b) for every pair: (beta_k - beta_j) b <= alpha_j + alpha_k
    num = alpha[:, :, None] + alpha[:, None, :]
    den = beta[:, None, :] - beta[:, :, None]
    with np.errstate(invalid="ignore", divide="ignore"):
        pair = np.where(den > eps, num / np.where(den > eps, den, 1.0), np.inf)
    cap = np.minimum(cap, np.nan_to_num(pair, nan=np.inf, posinf=np.inf).min(axis=(1, 2)))
    n = len(cap)
    alpha_l, beta_l, cap_l, ds_l = alpha.tolist(), beta.tolist(), cap.tolist(), ds.tolist()

    def hi(i, b):
        return min(x - y * b for x, y in zip(alpha_l[i], beta_l[i]))

    def lo(i, b):
        return max(-x - y * b for x, y in zip(alpha_l[i], beta_l[i]))

    fwd = [0.0] * n
    for i in range(n - 1):
        fwd[i + 1] = min(cap_l[i + 1], max(0.0, fwd[i] + 2 * ds_l[i] * hi(i, fwd[i])))
    bwd = [0.0] * n
    for i in range(n - 1, 0, -1):
        bwd[i - 1] = min(cap_l[i - 1], max(0.0, bwd[i] - 2 * ds_l[i - 1] * lo(i, bwd[i])))
    root = np.sqrt(np.minimum(fwd, bwd))
    pairs = root[:-1] + root[1:]
    return float(np.sum(np.where(ds > 0, 2 * ds / np.where(pairs > 0, pairs, 1.0), 0.0)))


def reference_duration(points, stops, tolerance, model):
    """Kunz and Stilman's path at `tolerance`, timed within the model's joint velocities and
    accelerations, resting where geotraj rests. (duration, blends, blends bounded by half a
    line instead of the tolerance)."""
    vmax = np.array([l.max_velocity for l in model.limits])
    amax = np.array([l.max_acceleration for l in model.limits])
    total, blends, bounded = 0.0, 0, 0
    for piece in rest_pieces(points, stops):
        ds, D, C, n, b = kunz_stilman_grid(piece, tolerance)
        total += phase_plane_time(ds, D, C, vmax, amax)
        blends, bounded = blends + n, bounded + b
    return total, blends, bounded


# --- the streamed motion -------------------------------------------------------------------

def rest_waypoints(points, stops):
    """Indices of the interior waypoints where the motion must rest: stops and reversals."""
    out = []
    for i in range(1, len(points) - 1):
        u, w = points[i] - points[i - 1], points[i + 1] - points[i]
        if stops[i] or float(np.dot(u, w)) <= -(1.0 - 1e-12) * np.linalg.norm(u) * np.linalg.norm(w):
            out.append(i)
    return out


def polyline_distance(q, w, reach, d=None):
    """The distance from w to the polyline of the samples q, on the segments whose samples lie
    within `reach` of the nearest sample's distance (no other segment comes closer when samples
    are at most `reach` apart). `d`: the samples' distances to w, when known roughly."""
    if d is None:
        d = np.linalg.norm(q - w, axis=1)
    near = np.nonzero(d <= d.min() + reach)[0]
    k = np.unique(np.clip(np.concatenate([near - 1, near]), 0, len(q) - 2))
    a, ab = q[k], q[k + 1] - q[k]
    nn = np.einsum("ij,ij->i", ab, ab)
    f = np.clip(np.einsum("ij,ij->i", w - a, ab) / np.where(nn > 0, nn, 1.0), 0.0, 1.0)
    return float(np.linalg.norm(a + f[:, None] * ab - w, axis=1).min())


def rough_distances(q, points):
    """Each sample's distance to each point, (samples, points), through one matrix product
    (|q|^2 - 2 q.w + |w|^2: within 1e-6 or so, enough to choose the segments to measure)."""
    w = np.array(points)
    d2 = np.einsum("ij,ij->i", q, q)[:, None] - 2 * q @ w.T + np.einsum("ij,ij->i", w, w)[None, :]
    return np.sqrt(np.maximum(d2, 0.0))


def limits_of(model):
    """Each joint's maxVelocity, maxAcceleration and maxJerk (the model's, else the default
    bound maxAcceleration / 0.05 s that a motion timed by the limits keeps)."""
    vmax = np.array([l.max_velocity for l in model.limits])
    amax = np.array([l.max_acceleration for l in model.limits])
    jmax = np.array([l.max_jerk if l.HasField("max_jerk") else l.max_acceleration / DEFAULT_JERK_RAMP_S
                     for l in model.limits])
    return vmax, amax, jmax


def on_segment(a, b, p):
    ab = b - a
    if float(np.dot(ab, ab)) == 0.0:
        return False
    f = float(np.dot(p - a, ab) / np.dot(ab, ab))
    return 0.0 <= f <= 1.0 and float(np.linalg.norm(a + f * ab - p)) <= 1e-9


class Failures:
    """Checks of a case run on a worker thread, reported by the test afterwards."""

    def __init__(self):
        self.messages = []

    def check(self, ok, message):
        if not ok:
            self.messages.append(message)
        return ok


class JointPaths(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        sys.path.insert(0, ARGS.stubs)
        global grpc, pb, rpc, json_format, status_pb2, error_details_pb2
        import grpc
        from geotraj.v1 import geotraj_pb2 as pb
        from geotraj.v1 import geotraj_pb2_grpc as rpc
        from google.protobuf import json_format
        from google.rpc import error_details_pb2, status_pb2
        cls.proc, cls.channel = start_geotrajd(ARGS.server)
        cls.stub = rpc.TrajectoryServiceStub(cls.channel)
        cls.models = {m.name: m for m in cls.stub.ListRobots(pb.ListRobotsRequest()).robots}

    @classmethod
    def tearDownClass(cls):
        stop_geotrajd(cls.proc, cls.channel)

    def example(self, name):
        with open(os.path.join(ARGS.requests, name)) as f:
            return json_format.Parse(f.read(), pb.PlanRequest())

    def request(self, model, points, stops, tolerance, rate, time_optimal):
        request = pb.PlanRequest(robot=pb.RobotSpec(name=model.name),
                                 motion=pb.MotionSpec(duration_s=0, cycle_rate_hz=rate))
        request.joint_path.blend_tolerance = tolerance
        for p, s in zip(points, stops):
            request.joint_path.waypoints.add(positions=[float(x) for x in p], stop=s)
        if time_optimal:
            request.optimize.timing.time_optimal = True
            # The sweep steps its accelerations, which a model with jerk limits (the Panda)
            # refuses; reportOnly streams it all the same (its velocities and accelerations
            # are checked here).
            request.robot.report_only = any(l.HasField("max_jerk") for l in model.limits)
        return request

    def stream(self, request):
        """(t, joints, joint velocities) of StreamSamples."""
        t, q, v = [], [], []
        for batch in self.stub.StreamSamples(request, timeout=120):
            for s in batch.samples:
                t.append(s.t)
                q.extend(s.joints)
                v.extend(s.joint_velocities)
        n = len(t)
        return np.array(t), np.array(q).reshape(n, -1), np.array(v).reshape(n, -1)

    # --- one case --------------------------------------------------------------------------

    def run_timing(self, fails, label, model, points, stops, tolerance, rate, time_optimal, budget):
        """One timing at one rate: the waypoint and limit checks; its figures."""
        what = f"{label}, {'time-optimal' if time_optimal else 'jerk-limited'} at {rate:g} Hz"
        request = self.request(model, points, stops, tolerance, rate, time_optimal)
        if budget is not None and not time_optimal:
            request.optimize.time_budget_s = budget
        t, q, v = self.stream(request)
        dt = 1.0 / rate
        vmax, amax, jmax = limits_of(model)
        out = {"duration": float(t[-1])}
        gaps = np.diff(t)
        fails.check(len(t) > 3 and t[0] == 0.0, f"{what}: {len(t)} samples from t {t[0] if len(t) else None}")
        fails.check(np.all(np.abs(gaps[:-1] - dt) < 1e-9) and 0.0 < gaps[-1] < dt + 1e-9,
                    f"{what}: samples not {dt} s apart (the last one at the end, at most {dt} s after)")
        # The ends: the first and last waypoints, at rest.
        for where, k, w in (("first", 0, points[0]), ("last", -1, points[-1])):
            off = float(np.max(np.abs(q[k] - w)))
            fails.check(off <= 1e-9, f"{what}: the {where} sample is {off:.3g} from the {where} waypoint")
            fails.check(np.all(np.abs(v[k]) <= 1e-9), f"{what}: the {where} sample moves: {v[k]}")
        # Between two samples the motion leaves their chord by at most |q_j''| dt^2 / 8 in each
        # joint, so the distance from a waypoint to the polyline of the samples is the motion's
        # own within chord = ||maxAcceleration|| dt^2 / 8 (5e-6 rad at 1 kHz, 3e-7 rad at 4 kHz
        # on the Panda; the accelerations are checked below).
        chord = float(np.linalg.norm(amax * (1 + ACCELERATION_SLACK))) * dt * dt / 8 + 1e-9
        reach = float(np.linalg.norm(vmax)) * dt
        rests = rest_waypoints(points, stops)
        collinear = all(on_segment(points[0], points[-1], p) for p in points[1:-1])
        if collinear:
            a, ab = points[0], points[-1] - points[0]
            f = np.clip((q - a) @ ab / (ab @ ab), 0.0, 1.0)
            off = float(np.max(np.linalg.norm(a + f[:, None] * ab - q, axis=1)))
            fails.check(off <= 1e-9, f"{what}: a sample {off:.3g} off the line of the waypoints")
        worst = 0.0
        for first in range(1, len(points) - 1, 50):
            interior = list(range(first, min(first + 50, len(points) - 1)))
            rough = rough_distances(q, [points[i] for i in interior])
            for c, i in enumerate(interior):
                d = polyline_distance(q, points[i], reach + 1e-5, rough[:, c])
                worst = max(worst, d)
                bound = chord if (collinear or i in rests) else tolerance + chord
                fails.check(d <= bound, f"{what}: waypoint {i} passed at {d:.9f}, more than {bound:.9f}"
                                        f"{' (on the line)' if collinear else ' (a rest)' if i in rests else ''}")
        for i in rests:
            # A rest at the waypoint at some t*: the sample nearest t* in time is within dt / 2
            # of it, so within the chord bound of the waypoint, each joint's velocity within
            # maxAcceleration dt / 2 of 0. It is the sample nearest the waypoint or one beside
            # it (nearest in space may be the other side of t*, where the arm accelerates less).
            d = np.linalg.norm(q - points[i], axis=1)
            k = int(np.argmin(d))
            fails.check(d[k] <= chord, f"{what}: no sample at the rest at waypoint {i}: the nearest {d[k]:.3g} away")
            still = [m for m in range(max(k - 1, 0), min(k + 2, len(t)))
                     if np.all(np.abs(v[m]) <= amax * (1 + ACCELERATION_SLACK) * dt / 2 + 1e-9)]
            fails.check(bool(still), f"{what}: not at rest at waypoint {i} (t {t[k]:.4f}): velocities "
                                     f"{v[max(k - 1, 0):k + 2]}")
        out["distance"] = worst
        # Limits by differences of the positions at the stream's rate; and, of this motion, at
        # a quarter of it (every fourth sample) for the rate checks.
        out["usage"] = self.check_differences(fails, what, t, q, (vmax, amax, jmax), not time_optimal)
        if rate == RATES[1]:
            ratio = int(round(RATES[1] / RATES[0]))
            keep = list(range(0, len(t), ratio))
            if keep[-1] != len(t) - 1:
                keep.append(len(t) - 1)
            out["usage_quarter"] = self.check_differences(fails, f"{what}, every {ratio}th sample", t[keep], q[keep],
                                                          (vmax, amax, jmax), not time_optimal)
        return out

    def check_differences(self, fails, what, t, q, limits, jerk):
        """The largest usage of each limit (velocity, acceleration, jerk) by divided differences
        of the positions (k! q[t_i, ..., t_i+k]: the usual differences where the samples are
        uniform, and the last sample, at the motion's end, less than a period after the one
        before it); fails past a limit (the jerk only when `jerk`)."""
        if len(t) > 4 and t[-1] - t[-2] < 1e-6 * (t[1] - t[0]):
            t, q = np.delete(t, -2), np.delete(q, -2, axis=0)  # the end on the sample before: rounding would rule
        vmax, amax, _ = limits
        slacks = (amax / (2 * CHECK_RATE_HZ * vmax), np.full(len(amax), ACCELERATION_SLACK),
                  np.full(len(amax), JERK_SLACK))
        d = q
        usage = {}
        for order, (name, lim, slack) in enumerate(zip(("velocity", "acceleration", "jerk"), limits, slacks), 1):
            d = order * np.diff(d, axis=0) / (t[order:] - t[:-order])[:, None]
            rel = np.abs(d) / lim
            k, j = np.unravel_index(int(np.argmax(rel)), rel.shape)
            usage[name[0]] = float(rel[k, j])
            over = np.max(rel - slack, axis=0)  # per joint, past 1 where a limit is broken
            if order < 3 or jerk:
                jj = int(np.argmax(over))
                kk = int(np.argmax(rel[:, jj]))
                fails.check(over[jj] <= 1.0, f"{what}: joint {jj} {name} by differences at {rel[kk, jj]:.5f} of its "
                                             f"limit at t {t[kk]:.4f} (allowed 1 + {slack[jj]:.2g})")
        return usage

    def run_case(self, model, what, points, stops, tolerance, compare, budget=None):
        """Both timings at both rates, the rate checks and the reference. (line, failures, the
        largest usage of each limit)."""
        fails = Failures()
        started = time.monotonic()
        label = f"{model.name} {what} (tolerance {tolerance:g})"
        res = {}
        for time_optimal in (True, False):
            for rate in RATES:
                try:
                    res[time_optimal, rate] = self.run_timing(fails, label, model, points, stops, tolerance, rate,
                                                              time_optimal, budget)
                except grpc.RpcError as e:
                    kind = "time-optimal" if time_optimal else "jerk-limited"
                    fails.check(False, f"{label}, {kind} at {rate:g} Hz: StreamSamples ended {e.code()}: {e.details()}")
                    return f"{label}: {fails.messages[-1]}", fails.messages, {"v": 0.0, "a": 0.0, "j": 0.0}
            # The 4 kHz stream at 4 kHz against itself at 1 kHz: an acceleration step leaves the
            # acceleration by differences as it is and multiplies the jerk by the rate's ratio.
            kind = "time-optimal" if time_optimal else "jerk-limited"
            high, low = res[time_optimal, RATES[1]]["usage"], res[time_optimal, RATES[1]]["usage_quarter"]
            fails.check(high["a"] <= low["a"] * ACCELERATION_GROWTH + 1e-9,
                        f"{label}, {kind}: acceleration by differences {high['a']:.4f} of its limit at 4 kHz "
                        f"against {low['a']:.4f} on every fourth sample (1 kHz)")
            if not time_optimal:
                fails.check(high["j"] < low["j"] * JERK_GROWTH,
                            f"{label}, {kind}: jerk by differences {high['j']:.4f} of its limit at 4 kHz "
                            f"against {low['j']:.4f} on every fourth sample (1 kHz): an acceleration step")
        reference, blends, bounded = reference_duration(points, stops, tolerance, model)
        sweep = [res[True, r]["duration"] for r in RATES]
        jerk = [res[False, r]["duration"] for r in RATES]
        if compare:
            for t in sweep:
                fails.check(t <= reference * SWEEP_OVER_REFERENCE,
                            f"{label}: the time-optimal sweep takes {t:.4f} s, {t / reference:.3f} times the "
                            f"reference's {reference:.4f} s")
            own_jerk = all(l.HasField("max_jerk") for l in model.limits)
            bound = JERK_LIMITED_OVER_REFERENCE if own_jerk else JERK_LIMITED_DEFAULT_RAMP_OVER_REFERENCE
            for t in jerk:
                fails.check(t <= reference * bound,
                            f"{label}: the jerk-limited timing takes {t:.4f} s, {t / reference:.3f} times the "
                            f"reference's {reference:.4f} s")

        def use(time_optimal, key):
            low, high = res[time_optimal, RATES[0]], res[time_optimal, RATES[1]]
            return f"{low['usage'][key]:.3f}/{high['usage'][key]:.3f}/{high['usage_quarter'][key]:.3f}"

        default_jerk = "" if any(l.HasField("max_jerk") for l in model.limits) else " (default bound)"
        line = (f"{label}: sweep {sweep[0]:.4f}/{sweep[1]:.4f} s, jerk-limited {jerk[0]:.4f}/{jerk[1]:.4f} s"
                f"{'' if budget is None else f' (optimiser budget {budget:g} s)'}; reference {reference:.4f} s "
                f"({bounded} of {blends} blends bounded by half a line{'' if compare else ', printed only'}): "
                f"{sweep[0] / reference:.3f}x, {jerk[0] / reference:.3f}x; usage: sweep v {use(True, 'v')} "
                f"a {use(True, 'a')} (its steps: j {use(True, 'j')}), jerk-limited v {use(False, 'v')} "
                f"a {use(False, 'a')} j{default_jerk} {use(False, 'j')}; waypoints passed within "
                f"{max(x['distance'] for x in res.values()):.6f}; {time.monotonic() - started:.1f} s")
        peaks = {key: max(x["usage"][key] for (to, _), x in res.items() if key != "j" or not to)
                 for key in ("v", "a", "j")}
        return line, fails.messages, peaks

    def test_sets_on_every_arm(self):
        cases = []
        panda = self.models.get("panda")
        self.assertIsNotNone(panda, "ListRobots lists no Panda")
        # 200 waypoints on one arm. The jerk-limited programme on 198 blends runs into the
        # server's default optimiser budget (10 s) more than once at each rate (20-30 s a
        # plan on a loaded 2-core machine): it gets PLAN_BUDGET_S (optimize.timeBudgetS),
        # and what it returns then must keep every limit all the same.
        walk = random_walk(np.random.default_rng(SEED), middle_box(panda), 200, 0.05)
        cases.append((panda, "random walk, 200 waypoints 0.05 rad apart", walk, [False] * 200, 0.05, False,
                      PLAN_BUDGET_S))
        example = self.example("plan_joint_path_panda.json")
        cases.append((panda, "pick and place (plan_joint_path_panda.json)",
                      [np.array(w.positions) for w in example.joint_path.waypoints],
                      [w.stop for w in example.joint_path.waypoints], example.joint_path.blend_tolerance, True))
        for name in sorted(self.models):
            for case in arm_cases(self.models[name]):
                cases.append((self.models[name],) + case)
        started = time.monotonic()
        with concurrent.futures.ThreadPoolExecutor(WORKERS) as pool:  # the most waypoints first
            futures = {i: pool.submit(self.run_case, *cases[i])
                       for i in sorted(range(len(cases)), key=lambda i: -len(cases[i][2]))}
            results = [futures[i].result() for i in range(len(cases))]
        print(f"[ measured ] {len(cases)} sets on {len(self.models)} arms in {time.monotonic() - started:.1f} s. "
              f"Per set: the durations of the time-optimal sweep and of the jerk-limited timing at 1/4 kHz; the "
              f"reference computed here and each duration over it (at 1 kHz); the largest usage of the velocity (v), "
              f"acceleration (a) and jerk (j) limits by differences at 1 kHz / 4 kHz / the 4 kHz stream's every "
              f"fourth sample; the largest distance from an interior waypoint to the samples; the wall time")
        for (model, what, *_), (line, messages, _) in zip(cases, results):
            print(f"[ measured ] {line}")
            with self.subTest(arm=model.name, set=what):
                self.assertFalse(messages, "\n".join(messages))
        summary = []
        for key, name in (("v", "velocity"), ("a", "acceleration"), ("j", "jerk (jerk-limited)")):
            (_, _, peaks), (model, what, *_) = max(zip(results, cases), key=lambda x: x[0][2][key])
            summary.append(f"{name} {peaks[key]:.6f} ({model.name} {what})")
        print("[ measured ] largest usage by differences over every set, timing and rate: " + ", ".join(summary))

    # --- Execute ---------------------------------------------------------------------------

    def execute(self, request, control):
        """Execute `request`: the commands go through a queue that grpcio's request iterator
        reads, with a heartbeat every 0.2 s of sample time (the deadman acts after 1 s);
        `control(send, batch)` after each batch. (call, batches, samples)."""
        commands = queue.Queue()
        commands.put(pb.ExecuteRequest(plan=request))

        def requests():
            while True:
                message = commands.get()
                if message is None:
                    return
                yield message

        call = self.stub.Execute(requests(), timeout=60)
        batches, samples, beat = [], [], 0.0
        try:
            for batch in call:
                batches.append(batch)
                samples.extend(batch.samples)
                if batch.samples and batch.samples[-1].t >= beat + 0.2:
                    beat = batch.samples[-1].t
                    commands.put(pb.ExecuteRequest(heartbeat=pb.Heartbeat()))
                control(commands.put, batch)
        finally:
            commands.put(None)
        return call, batches, samples

    def test_execute_pause_and_resume(self):
        # The pick and place at 1 kHz: a pause sent at plan time 0.8 s, a resume after 0.3 s at
        # rest, then to the end.
        request = self.example("plan_joint_path_panda.json")
        model = self.models[request.robot.name]
        points = [np.array(w.positions) for w in request.joint_path.waypoints]
        steps = {}

        def control(send, batch):
            s = batch.samples[-1]
            if "pause" not in steps and s.plan_time >= 0.8:
                steps["pause"] = s.t
                send(pb.ExecuteRequest(pause=pb.Pause()))
            elif "pause" in steps and "resume" not in steps and batch.live.state == pb.LIVE_STATE_PAUSED:
                if s.t - steps.setdefault("paused", s.t) >= 0.3:
                    steps["resume"] = s.t
                    send(pb.ExecuteRequest(resume=pb.Resume()))

        call, batches, samples = self.execute(request, control)
        self.assertEqual(call.code(), grpc.StatusCode.OK, call.details())
        self.assertEqual(dict(call.trailing_metadata() or ()).get("geotraj-stop-reason"), "completed")
        self.assertEqual(batches[-1].live.state, pb.LIVE_STATE_COMPLETED)
        self.assertEqual({"pause", "paused", "resume"}, set(steps), "the pause and the resume were not both sent")
        t = np.array([s.t for s in samples])
        q = np.array([list(s.joints) for s in samples])
        tau = np.array([s.plan_time for s in samples])
        factor = np.array([s.speed_factor for s in samples])
        v = np.array([list(s.joint_velocities) for s in samples])
        # Completed at the last waypoint, at rest, at the plan's end.
        self.assertLessEqual(float(np.max(np.abs(q[-1] - points[-1]))), 1e-9)
        self.assertTrue(np.all(v[-1] == 0.0))
        self.assertAlmostEqual(tau[-1], batches[-1].live.plan_duration_s, delta=1e-12)
        # Paused: held still, at rest.
        paused = np.nonzero(factor == 0.0)[0][:-1]  # the final sample is at rest too
        self.assertGreater(len(paused), 250, "paused for less than 0.25 s")
        self.assertTrue(np.all(q[paused] == q[paused[0]]), "the joints moved while paused")
        self.assertTrue(np.all(v[paused] == 0.0), "a joint velocity while paused")
        # On the planned path: the same request streamed at 4 kHz with the room Execute leaves
        # (accelerationScale 1 - 0.1, the default reserve). Each live sample within the chord
        # bound of that polyline near its plan time (10 ms either side: the plans at 1 and 4 kHz
        # differ by a few microseconds).
        dense = pb.PlanRequest()
        dense.CopyFrom(request)
        dense.motion.cycle_rate_hz = RATES[1]
        dense.motion.acceleration_scale = 1.0 - 0.1
        td, qd, _ = self.stream(dense)
        self.assertAlmostEqual(td[-1], batches[-1].live.plan_duration_s, delta=1e-3)
        vmax, amax, jmax = limits_of(model)
        chord = float(np.linalg.norm(amax)) / RATES[1] ** 2 / 8 + 1e-9
        off = np.zeros(len(q))
        window = int(0.01 * RATES[1])
        for k in range(len(q)):
            i = int(round(tau[k] * RATES[1]))
            lo, hi = max(i - window, 0), min(i + window, len(qd) - 1)
            off[k] = polyline_distance(qd[lo:hi + 1], q[k], np.inf)
        k = int(np.argmax(off))
        self.assertLessEqual(off[k], chord, f"sample {k} (plan time {tau[k]:.4f}) off the path")
        self.assertLessEqual(off[paused[0]], chord, "paused off the path")
        # Within the limits by differences, as StreamSamples' motions.
        fails = Failures()
        usage = self.check_differences(fails, "Execute", t, q, (vmax, amax, jmax), True)
        self.assertFalse(fails.messages, "\n".join(fails.messages))
        print(f"[ measured ] Execute of the pick and place, paused at plan time {tau[paused[0]]:.3f} s for "
              f"{len(paused)} samples: {len(samples)} samples over {t[-1]:.3f} s (plan {tau[-1]:.4f} s); "
              f"largest distance to the 4 kHz stream's path {off.max():.2e} (paused {off[paused[0]]:.2e}); "
              f"largest usage by differences v {usage['v']:.3f} a {usage['a']:.3f} j {usage['j']:.3f}; "
              f"ends {np.max(np.abs(q[-1] - points[-1])):.1e} from the last waypoint")

    # --- errors ----------------------------------------------------------------------------

    def test_bad_input_named_by_field(self):
        base = self.example("plan_joint_path_panda.json")
        panda = self.models[base.robot.name]

        def outside(r):
            r.joint_path.waypoints[2].positions[3] = panda.limits[3].max_position + 0.2

        def short(r):
            del r.joint_path.waypoints[1].positions[-1]

        def negative(r):
            r.joint_path.blend_tolerance = -0.01

        def single(r):
            del r.joint_path.waypoints[1:]

        for what, change, field in (("a waypoint outside the limits", outside, "jointPath.waypoints[2].positions[3]"),
                                    ("a waypoint of 6 joints on the Panda", short, "jointPath.waypoints[1].positions"),
                                    ("a negative blend tolerance", negative, "jointPath.blendTolerance"),
                                    ("one waypoint", single, "jointPath.waypoints")):
            request = pb.PlanRequest()
            request.CopyFrom(base)
            change(request)
            for method in ("PlanTrajectory", "StreamSamples"):
                with self.subTest(what=what, method=method):
                    with self.assertRaises(grpc.RpcError) as ctx:
                        answer = getattr(self.stub, method)(request, timeout=30)
                        if method == "StreamSamples":
                            list(answer)
                    err = ctx.exception
                    self.assertEqual(err.code(), grpc.StatusCode.INVALID_ARGUMENT, err.details())
                    fields = field_violations(err)
                    self.assertIn(field, fields, f"{what}: {err.details()}")
                    if method == "PlanTrajectory":
                        print(f"[ measured ] {what}: INVALID_ARGUMENT, {field}: {fields[field]}")


def field_violations(err):
    """The google.rpc.BadRequest field violations in an error's trailers: {field: description}."""
    raw = dict(err.trailing_metadata() or ()).get("grpc-status-details-bin")
    fields = {}
    if raw is not None:
        for detail in status_pb2.Status.FromString(raw).details:
            bad = error_details_pb2.BadRequest()
            if detail.Unpack(bad):
                fields.update({v.field: v.description for v in bad.field_violations})
    return fields


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--server", required=True)
    parser.add_argument("--stubs", required=True)
    parser.add_argument("--requests", required=True)
    ARGS, rest = parser.parse_known_args()
    unittest.main(argv=[sys.argv[0]] + rest, verbosity=2)
