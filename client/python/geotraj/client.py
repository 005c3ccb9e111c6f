"""Client: geotrajd's calls from Python, with typed results and GeotrajError for failures.

Frames and units as the API's (proto/geotraj/v1/geotraj.proto): every vector and pose in the
world frame W unless said otherwise; SI units (m, s, rad); joints in the model's order, joint 0
at the base; indices zero-based.
"""
import os
import queue
import threading
from dataclasses import dataclass
from typing import Dict, Iterator, List, Optional, Sequence, Tuple, Union

import grpc
import numpy as np

from ._proto import RequestLike, as_message, enum_name, pb, pb_grpc
from .errors import GeotrajError
from .samples import CsvWriter, Samples, has_steps

DEFAULT_ADDRESS = "127.0.0.1:50051"
#: [s] between the heartbeats a live call sends; the server's deadman stops the motion after
#: 1 s (ExecuteOptions.deadmanS) without a message.
HEARTBEAT_S = 0.2

RobotLike = Union[str, "pb.RobotSpec", dict]


def _robot_spec(robot: RobotLike) -> "pb.RobotSpec":
    """A RobotSpec from a built-in model's name, a RobotSpec, or its dict in the JSON mapping."""
    if isinstance(robot, str):
        return pb.RobotSpec(name=robot)
    return as_message(robot, pb.RobotSpec, "robot")


@dataclass
class ForwardKinematics:
    """The forward kinematics of one configuration (ComputeForwardKinematics).

    position: the tool's origin in W [m], (3,).
    orientation: the tool's orientation in W, unit quaternion (w, x, y, z), (4,).
    jacobian: the geometric Jacobian, (6, J): rows vx, vy, vz [m/s] and wx, wy, wz [rad/s]
        in W per unit joint velocity.
    manipulability: Yoshikawa's sqrt(det(J J^T)) (0 at a singularity).
    axes: every joint's axis in W, (J, 2, 3): a point on it [m] and its unit direction.
    within_limits: whether every joint value is within its position limits.
    response: the whole ForwardKinematicsResponse.
    """
    position: np.ndarray
    orientation: np.ndarray
    jacobian: np.ndarray
    manipulability: float
    axes: np.ndarray
    within_limits: bool
    response: "pb.ForwardKinematicsResponse"


@dataclass
class InverseKinematics:
    """The inverse kinematics of one pose (ComputeInverseKinematics).

    reachable: a solution within both tolerances and the position limits was found.
    solutions: joint values, (K, J), nearest the seed first; K = 0 when not reachable.
    closest: when not reachable, the joint values whose pose comes closest, (J,); else None.
    response: the whole InverseKinematicsResponse (each solution's pose and errors).
    """
    reachable: bool
    solutions: np.ndarray
    closest: Optional[np.ndarray]
    response: "pb.InverseKinematicsResponse"


@dataclass
class Profile:
    """A path's profile (AnalyzePath), one row per point, uniformly spread in u. Quantities
    undefined at a point (the normal where the curvature is 0, ...) are NaN.

    u (N,); s: arc length [m] (N,); segment (N,) int; position [m], tangent, normal, binormal
    (unit) in W, (N, 3); curvature, torsion [1/m], their arc-length derivatives [1/m^2], (N,);
    speed: |dp/du| [m per unit u] (N,); arc_length: the path's [m].
    """
    u: np.ndarray
    s: np.ndarray
    segment: np.ndarray
    position: np.ndarray
    tangent: np.ndarray
    normal: np.ndarray
    binormal: np.ndarray
    curvature: np.ndarray
    torsion: np.ndarray
    curvature_derivative: np.ndarray
    torsion_derivative: np.ndarray
    speed: np.ndarray
    arc_length: float
    response: "pb.PathProfile"

    @classmethod
    def from_message(cls, profile: "pb.PathProfile") -> "Profile":
        pts = profile.points

        def vec(name):
            return np.array([(getattr(p, name).x, getattr(p, name).y, getattr(p, name).z) if p.HasField(name)
                             else (np.nan,) * 3 for p in pts], dtype=float).reshape(-1, 3)

        def opt(name):
            return np.array([getattr(p, name) if p.HasField(name) else np.nan for p in pts], dtype=float)

        return cls(u=np.array([p.u for p in pts], dtype=float), s=np.array([p.s for p in pts], dtype=float),
                   segment=np.array([p.segment for p in pts], dtype=np.int64), position=vec("position"),
                   tangent=vec("tangent"), normal=vec("normal"), binormal=vec("binormal"),
                   curvature=opt("curvature"), torsion=opt("torsion"),
                   curvature_derivative=opt("curvature_derivative"), torsion_derivative=opt("torsion_derivative"),
                   speed=np.array([p.speed for p in pts], dtype=float), arc_length=profile.arc_length,
                   response=profile)


class LiveCall:
    """A live call (Execute or Jog): a bidirectional stream whose requests go through a queue
    that grpcio reads on its own thread, with a heartbeat every HEARTBEAT_S seconds from a
    thread of this object until the call ends. Iterate it for the SampleBatches as they come;
    at the end, a call that did not end OK raises GeotrajError (with its stop reason).

    A context manager: leaving the block cancels a call still running (the server then
    brings the motion to rest).
    """

    def __init__(self, method, first, heartbeat, timeout: Optional[float], metadata, record: bool):
        self._queue: "queue.Queue" = queue.Queue()
        self._queue.put(first)
        self._heartbeat = heartbeat
        self._ended = threading.Event()
        self._record = record
        self._batches: List["pb.SampleBatch"] = []
        self.last_status: Optional["pb.LiveStatus"] = None
        self.last_sample: Optional["pb.Sample"] = None
        self.sample_count = 0
        self.call = method(self._requests(), timeout=timeout, metadata=metadata)
        threading.Thread(target=self._beat, daemon=True).start()

    def _requests(self):
        while True:
            request = self._queue.get()
            if request is None:  # the call is over: end the request stream
                return
            yield request

    def _beat(self):
        while not self._ended.wait(HEARTBEAT_S):
            self._queue.put(self._heartbeat)

    def send(self, request) -> None:
        """Queues a request message (sent in order, after those queued before)."""
        if not self._ended.is_set():
            self._queue.put(request)

    def _finish(self):
        if not self._ended.is_set():
            self._ended.set()
            self._queue.put(None)

    def __iter__(self) -> Iterator["pb.SampleBatch"]:
        try:
            for batch in self.call:
                self.sample_count += len(batch.samples)
                if batch.samples:
                    self.last_sample = batch.samples[-1]
                self.last_status = batch.live
                if self._record:
                    self._batches.append(batch)
                yield batch
        except grpc.RpcError:
            pass  # the status, below
        finally:
            self._finish()
        if self.call.code() != grpc.StatusCode.OK:
            raise GeotrajError.from_call(self.call)

    def cancel(self) -> None:
        """Cancels the call (the server brings the motion to rest)."""
        self._finish()
        self.call.cancel()

    @property
    def stop_reason(self) -> str:
        """The trailer `geotraj-stop-reason` once the call has ended: completed, stopped,
        deadman, drain, deadline, invalid ("" before)."""
        if not self._ended.is_set():
            return ""
        return dict(self.call.trailing_metadata() or ()).get("geotraj-stop-reason", "")

    @property
    def state(self) -> str:
        """The call's state after the last batch: "running", "paused", "completed", ..."""
        if self.last_status is None:
            return "unspecified"
        return enum_name(self.last_status, "state").removeprefix("LIVE_STATE_").lower()

    def samples(self, steps: bool = False) -> Samples:
        """Runs the call to its end (unless it has ended) and returns every sample received
        (needs record=True; raises GeotrajError when the call did not end OK)."""
        if not self._record:
            raise ValueError("this call does not keep its samples (record=False)")
        for _ in self:
            pass
        return Samples.from_batches(self._batches, steps)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        if not self.call.done():
            self.cancel()
        self._finish()
        return False


class Execution(LiveCall):
    """An Execute call: the plan's set points in real time, under the control messages below.
    Each control acts on the next sample; the batches report it (SampleBatch.live)."""

    def __init__(self, stub, plan: "pb.PlanRequest", options: "pb.ExecuteOptions", timeout, metadata, record):
        self.steps = has_steps(plan)
        super().__init__(stub.Execute, pb.ExecuteRequest(plan=plan, options=options),
                         pb.ExecuteRequest(heartbeat=pb.Heartbeat()), timeout, metadata, record)

    def set_override(self, percent: float) -> None:
        """The speed override [%], in [0, 100]: the fraction of the planned speed to run at."""
        self.send(pb.ExecuteRequest(speed_override=percent))

    def pause(self) -> None:
        """Slow to rest on the path and hold there (samples keep coming, at rest)."""
        self.send(pb.ExecuteRequest(pause=pb.Pause()))

    def resume(self) -> None:
        """From a pause back to the speed override."""
        self.send(pb.ExecuteRequest(resume=pb.Resume()))

    def stop(self) -> None:
        """Slow to rest on the path; the call ends OK with a final sample at rest (stop reason
        `stopped`)."""
        self.send(pb.ExecuteRequest(stop=pb.Stop()))

    def samples(self, steps: Optional[bool] = None) -> Samples:
        return super().samples(self.steps if steps is None else steps)


class Jogging(LiveCall):
    """A Jog call: joint set points at the cycle rate, following the latest command."""

    def __init__(self, stub, start: "pb.JogStart", timeout, metadata, record):
        super().__init__(stub.Jog, pb.JogRequest(start=start), pb.JogRequest(heartbeat=pb.Heartbeat()),
                         timeout, metadata, record)

    def joints(self, velocities: Sequence[float]) -> None:
        """Joint jogging: one value per joint in [-1, 1], the fraction of the joint's maximum
        velocity (times JogStart.velocityScale, 0.25 by default)."""
        self.send(pb.JogRequest(joints=pb.JointJog(velocities=list(velocities))))

    def twist(self, linear: Sequence[float] = (0, 0, 0), angular: Sequence[float] = (0, 0, 0),
              frame: str = "world") -> None:
        """Cartesian jogging: the tool's velocity and angular velocity, each component in
        [-1, 1] of JogStart.maxLinearSpeed [m/s] and maxAngularSpeed [rad/s], written in the
        world frame W (frame="world") or the tool frame (frame="tool")."""
        modes = {"world": pb.COORDINATE_MODE_WORLD, "tool": pb.COORDINATE_MODE_TOOL}
        if frame not in modes:
            raise ValueError(f"frame: \"world\" or \"tool\", got {frame!r}")
        lx, ly, lz = linear
        ax, ay, az = angular
        self.send(pb.JogRequest(twist=pb.CartesianJog(linear=pb.Vec3(x=lx, y=ly, z=lz),
                                                      angular=pb.Vec3(x=ax, y=ay, z=az), frame=modes[frame])))

    def stop(self) -> None:
        """Slow every joint to rest; the call ends OK with a final sample at rest."""
        self.send(pb.JogRequest(stop=pb.Stop()))


class Client:
    """A connection to geotrajd.

    address: HOST:PORT (default 127.0.0.1:50051).
    token: a bearer token, sent as `authorization: Bearer TOKEN` on every call (in the call's
        metadata, so that it goes on a plaintext channel too).
    tls_ca: call over TLS, trusting the CA certificates in this PEM file; None: plaintext.
    tls_server_name: with tls_ca, the name the server's certificate carries, if not the host.
    timeout: the deadline of unary calls (plan, analyze, kinematics, list_robots) [s]. Streams
        and live calls have none unless given theirs: a motion of any length streams whole.

    Every method raises GeotrajError when the call fails. Requests are accepted as the proto
    message, a dict in the proto JSON mapping, or the path of a JSON file (client/grpcurl/).
    Use it as a context manager, or close() it.
    """

    def __init__(self, address: str = DEFAULT_ADDRESS, token: Optional[str] = None,
                 tls_ca: Optional[Union[str, "os.PathLike[str]"]] = None, timeout: Optional[float] = 60.0,
                 tls_server_name: Optional[str] = None,
                 options: Sequence[Tuple[str, Union[str, int]]] = ()):
        self.address = address
        self.timeout = timeout
        self._metadata: List[Tuple[str, str]] = [("authorization", f"Bearer {token}")] if token else []
        opts = [("grpc.max_receive_message_length", 64 * 1024 * 1024), *options]
        if tls_ca is not None:
            with open(tls_ca, "rb") as f:
                creds = grpc.ssl_channel_credentials(root_certificates=f.read())
            if tls_server_name:
                opts.append(("grpc.ssl_target_name_override", tls_server_name))
            self.channel = grpc.secure_channel(address, creds, options=opts)
        else:
            self.channel = grpc.insecure_channel(address, options=opts)
        #: The generated stub, for anything this class does not wrap.
        self.stub = pb_grpc.TrajectoryServiceStub(self.channel)

    def close(self) -> None:
        self.channel.close()

    def __enter__(self) -> "Client":
        return self

    def __exit__(self, *exc) -> bool:
        self.close()
        return False

    def wait_ready(self, timeout: float = 10.0) -> None:
        """Waits until the channel is connected; GeotrajError UNAVAILABLE after `timeout` [s]."""
        try:
            grpc.channel_ready_future(self.channel).result(timeout=timeout)
        except grpc.FutureTimeoutError:
            raise GeotrajError(grpc.StatusCode.UNAVAILABLE,
                               f"no connection to {self.address} within {timeout:g} s") from None

    def _unary(self, method, request, timeout):
        try:
            return method(request, timeout=self.timeout if timeout is None else timeout, metadata=self._metadata)
        except grpc.RpcError as e:
            raise GeotrajError.from_call(e) from None

    # --- plans -------------------------------------------------------------------------------

    def plan(self, request: RequestLike, timeout: Optional[float] = None) -> "pb.PlanResponse":
        """PlanTrajectory: the whole plan without samples (segments, arc length, achieved
        frames, motion summary, robot and optimiser reports)."""
        return self._unary(self.stub.PlanTrajectory, as_message(request, pb.PlanRequest), timeout)

    def stream_batches(self, request: RequestLike, timeout: Optional[float] = None) -> Iterator["pb.SampleBatch"]:
        """StreamSamples, batch by batch as they arrive (for a motion too long to hold).
        timeout: the stream's deadline [s]; None: none."""
        call = self.stub.StreamSamples(as_message(request, pb.PlanRequest), timeout=timeout,
                                       metadata=self._metadata)
        try:
            yield from call
        except grpc.RpcError as e:
            raise GeotrajError.from_call(e) from None
        finally:
            call.cancel()  # a no-op once the stream ended; else the reader stopped early

    def stream(self, request: RequestLike, timeout: Optional[float] = None) -> Samples:
        """StreamSamples: every sample of the plan, as NumPy arrays (Samples)."""
        message = as_message(request, pb.PlanRequest)
        return Samples.from_batches(self.stream_batches(message, timeout), has_steps(message))

    def stream_csv(self, request: RequestLike, out, timeout: Optional[float] = None) -> int:
        """StreamSamples straight into CSV rows on the open text file `out`, as they arrive
        (the columns of Samples.write_csv); returns the number of samples."""
        message = as_message(request, pb.PlanRequest)
        writer = CsvWriter(out, has_steps(message))
        batches = self.stream_batches(message, timeout)
        try:
            for batch in batches:
                writer.write_batch(batch)
        finally:
            batches.close()  # a write that failed (a closed pipe) cancels the stream
        return writer.count

    def analyze(self, request: RequestLike, points: Optional[int] = None,
                timeout: Optional[float] = None) -> Profile:
        """AnalyzePath: curvature, torsion, their derivatives, speed and the Frenet frame at
        `points` points spread uniformly in u (default: the request's analysisPoints, else 101)."""
        message = as_message(request, pb.PlanRequest)
        if points is not None:
            copy = pb.PlanRequest()
            copy.CopyFrom(message)
            copy.analysis_points = points
            message = copy
        return Profile.from_message(self._unary(self.stub.AnalyzePath, message, timeout))

    def convert(self, request: RequestLike, timeout: Optional[float] = None) -> "pb.ConvertResponse":
        """ConvertConstraints: each key frame's geometric constraints as parametric derivatives."""
        return self._unary(self.stub.ConvertConstraints, as_message(request, pb.ConvertRequest), timeout)

    # --- robots ------------------------------------------------------------------------------

    def list_robots(self, timeout: Optional[float] = None) -> List["pb.RobotModel"]:
        """ListRobots: the models the server serves (the built-in ones and its --robot-model
        files), in full (joints or links, limits with their sources, home)."""
        return list(self._unary(self.stub.ListRobots, pb.ListRobotsRequest(), timeout).robots)

    def robots(self, timeout: Optional[float] = None) -> Dict[str, "pb.RobotModel"]:
        """The models the server serves, by name."""
        return {m.name: m for m in self.list_robots(timeout)}

    def forward_kinematics(self, robot: RobotLike, joints: Sequence[float] = (),
                           timeout: Optional[float] = None) -> ForwardKinematics:
        """ComputeForwardKinematics of `joints` [rad or m] (one per joint) on `robot`: a built-in
        model's name, a RobotSpec or its dict. Also takes a whole ForwardKinematicsRequest (a
        message, dict or file) as `robot`, with `joints` left empty."""
        if isinstance(robot, pb.ForwardKinematicsRequest) or (
                not isinstance(robot, (str, pb.RobotSpec)) and not joints):
            request = as_message(robot, pb.ForwardKinematicsRequest)
        else:
            request = pb.ForwardKinematicsRequest(robot=_robot_spec(robot), joints=[float(q) for q in joints])
        r = self._unary(self.stub.ComputeForwardKinematics, request, timeout)
        n = len(r.jacobian) // 6
        o = r.pose.orientation
        return ForwardKinematics(
            position=np.array([r.pose.position.x, r.pose.position.y, r.pose.position.z]),
            orientation=np.array([o.w, o.x, o.y, o.z]) if r.pose.HasField("orientation") else np.array([1.0, 0, 0, 0]),
            jacobian=np.array(r.jacobian, dtype=float).reshape(6, n),
            manipulability=r.manipulability,
            axes=np.array([[(a.origin.x, a.origin.y, a.origin.z), (a.direction.x, a.direction.y, a.direction.z)]
                           for a in r.axes], dtype=float).reshape(-1, 2, 3),
            within_limits=r.within_limits, response=r)

    def inverse_kinematics(self, robot: RobotLike, position: Optional[Sequence[float]] = None,
                           orientation: Optional[Sequence[float]] = None, *,
                           seed: Optional[Sequence[float]] = None, all_solutions: bool = False,
                           restarts: Optional[int] = None, max_solutions: Optional[int] = None,
                           position_tolerance: Optional[float] = None,
                           orientation_tolerance: Optional[float] = None,
                           timeout: Optional[float] = None) -> InverseKinematics:
        """ComputeInverseKinematics: the joint values that put the tool at `position` [m] with
        `orientation` (a unit quaternion w, x, y, z; None: the identity), both in W.
        seed: where the search starts (default: the model's home); solutions are ordered by
        their distance from it. all_solutions: every distinct solution found (the arm's
        branches), up to max_solutions. Also takes a whole InverseKinematicsRequest (a message,
        dict or file) as `robot`, with `position` left None."""
        if position is None:
            request = as_message(robot, pb.InverseKinematicsRequest)
        else:
            spec = _robot_spec(robot)
            if seed is not None:
                copy = pb.RobotSpec()
                copy.CopyFrom(spec)
                copy.initial_joints[:] = [float(q) for q in seed]
                spec = copy
            x, y, z = (float(c) for c in position)
            target = pb.Pose(position=pb.Vec3(x=x, y=y, z=z))
            if orientation is not None:
                w, qx, qy, qz = (float(c) for c in orientation)
                target.orientation.CopyFrom(pb.Quaternion(w=w, x=qx, y=qy, z=qz))
            request = pb.InverseKinematicsRequest(robot=spec, target=target, all_solutions=all_solutions)
            for name, value in (("restarts", restarts), ("max_solutions", max_solutions),
                                ("position_tolerance", position_tolerance),
                                ("orientation_tolerance", orientation_tolerance)):
                if value is not None:
                    setattr(request, name, value)
        r = self._unary(self.stub.ComputeInverseKinematics, request, timeout)
        n = len(r.solutions[0].joints) if r.solutions else len(r.closest.joints)
        return InverseKinematics(
            reachable=r.reachable,
            solutions=np.array([list(s.joints) for s in r.solutions], dtype=float).reshape(-1, n),
            closest=np.array(r.closest.joints, dtype=float) if r.HasField("closest") else None,
            response=r)

    # --- live calls --------------------------------------------------------------------------

    def execute(self, request: RequestLike, *, speed_override: Optional[float] = None,
                deadman_s: Optional[float] = None, acceleration_reserve: Optional[float] = None,
                samples_per_batch: Optional[int] = None, timeout: Optional[float] = None,
                record: bool = True) -> Execution:
        """Execute: starts the plan of `request` (a PlanRequest, as for stream) in real time and
        returns the running call. Iterate it for the batches; control it with
        set_override(percent), pause(), resume(), stop(); a heartbeat goes every 0.2 s.

        speed_override: at the start [%] (default 100). deadman_s: how long the server waits
        for a message before stopping the motion (default 1 s). acceleration_reserve: the share
        of the acceleration and jerk limits a plan timed by the limits leaves for speed changes
        (default 0.1). record: keep every batch, for samples() at the end.
        """
        options = pb.ExecuteOptions()
        for name, value in (("speed_override", speed_override), ("deadman_s", deadman_s),
                            ("acceleration_reserve", acceleration_reserve),
                            ("samples_per_batch", samples_per_batch)):
            if value is not None:
                setattr(options, name, value)
        return Execution(self.stub, as_message(request, pb.PlanRequest), options, timeout, self._metadata, record)

    def jog(self, robot: RobotLike, *, cycle_rate_hz: Optional[float] = None,
            velocity_scale: Optional[float] = None, max_linear_speed: Optional[float] = None,
            max_angular_speed: Optional[float] = None, deadman_s: Optional[float] = None,
            timeout: Optional[float] = None, record: bool = False) -> Jogging:
        """Jog: starts jogging `robot` (a built-in model's name, a RobotSpec or its dict; its
        initialJoints are where it is, default its home) and returns the running call. Command
        it with joints(velocities) or twist(linear, angular, frame), end it with stop()."""
        start = pb.JogStart(robot=_robot_spec(robot))
        for name, value in (("cycle_rate_hz", cycle_rate_hz), ("velocity_scale", velocity_scale),
                            ("max_linear_speed", max_linear_speed), ("max_angular_speed", max_angular_speed),
                            ("deadman_s", deadman_s)):
            if value is not None:
                setattr(start, name, value)
        return Jogging(self.stub, start, timeout, self._metadata, record)
