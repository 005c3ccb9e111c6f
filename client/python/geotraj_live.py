#!/usr/bin/env python3
"""An example of geotraj's live calls in Python (Debian's python3-grpcio): Execute and Jog.

    geotraj_live.py --address 127.0.0.1:50051 execute client/grpcurl/plan_panda_path_c.json
    geotraj_live.py --address 127.0.0.1:50051 jog --robot panda --joint 3 --command 0.5 --seconds 1

execute  streams the plan's set points in real time (Execute), sets the speed override to
         50 % after 1 s, pauses at 2 s for 1 s, resumes, and prints the progress (time, plan
         time, speed factor, state) every 0.25 s until the plan is done.
jog      jogs one joint (Jog) at a fraction of its maximum velocity for some seconds, then
         stops it and waits for the final set point, at rest.

Both calls are bidirectional streams. The requests go through a queue, which grpcio reads
from its own thread through a generator; a heartbeat every 0.2 s tells the server that the
client is still there (after 1 s without a message the server's deadman stops the motion).
The stubs come from protoc and grpc_python_plugin (README.md beside this file).
Exit status: 0 done (the plan completed, or the jog stopped when asked), 1 the call ended
otherwise (the code, the message, the stop reason and any field violations are printed),
2 bad usage.
"""
import argparse
import os
import queue
import sys
import threading

HERE = os.path.dirname(os.path.abspath(__file__))
HEARTBEAT_S = 0.2  # [s] between heartbeats; the server's deadman time is 1 s
PROGRESS_S = 0.25  # [s] of sample time between progress lines


def parse_args(argv):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--address", "--server", default=os.environ.get("GEOTRAJ_ADDRESS", "127.0.0.1:50051"),
                   help="HOST:PORT of geotrajd (default: $GEOTRAJ_ADDRESS or 127.0.0.1:50051)")
    p.add_argument("--stubs", default=os.environ.get("GEOTRAJ_PY_STUBS", os.path.join(HERE, "gen")),
                   help="directory of the generated stubs (default: $GEOTRAJ_PY_STUBS or gen/ beside this file)")
    calls = p.add_subparsers(dest="call", required=True)
    e = calls.add_parser("execute", help="execute a plan with a speed override, a pause and a resume")
    e.add_argument("request", help="a PlanRequest in the proto JSON mapping (a file of client/grpcurl/)")
    e.add_argument("--override", type=float, default=50.0, help="the speed override to set [%%] (default: 50)")
    e.add_argument("--override-at", type=float, default=1.0, help="when to set it [s] (default: 1)")
    e.add_argument("--pause-at", type=float, default=2.0, help="when to pause [s] (default: 2)")
    e.add_argument("--pause-for", type=float, default=1.0, help="how long to stay paused [s] (default: 1)")
    j = calls.add_parser("jog", help="jog one joint, then stop")
    j.add_argument("--robot", default="panda", help="a built-in robot (ListRobots; default: panda)")
    j.add_argument("--joint", type=int, default=0, help="the joint, zero-based (default: 0)")
    j.add_argument("--command", type=float, default=0.5,
                   help="the joint's velocity as a fraction of its maximum (x the jog's velocity scale, 0.25), "
                        "in [-1, 1] (default: 0.5)")
    j.add_argument("--seconds", type=float, default=1.0, help="how long to jog before stopping [s] (default: 1)")
    return p.parse_args(argv)


def import_stubs(stubs):
    sys.path.insert(0, stubs)
    try:
        from geotraj.v1 import geotraj_pb2, geotraj_pb2_grpc
        from google.rpc import error_details_pb2, status_pb2
    except ImportError as e:
        print(f"geotraj_live.py: no stubs in {stubs} ({e}); generate them as client/python/README.md says",
              file=sys.stderr)
        sys.exit(2)
    return geotraj_pb2, geotraj_pb2_grpc, status_pb2, error_details_pb2


class LiveCall:
    """One live call: `send` queues a request (grpcio takes it from `_requests` on its own
    thread), a thread of ours queues a heartbeat every HEARTBEAT_S, and iterating the call
    gives the SampleBatches as they come."""

    def __init__(self, method, first, heartbeat):
        self._requests_queue = queue.Queue()
        self._requests_queue.put(first)
        self._ended = threading.Event()
        self.call = method(self._requests())
        beats = threading.Thread(target=self._beat, args=(heartbeat,), daemon=True)
        beats.start()

    def _requests(self):
        while True:
            request = self._requests_queue.get()
            if request is None:  # the call is over: end the request stream
                return
            yield request

    def _beat(self, heartbeat):
        while not self._ended.wait(HEARTBEAT_S):
            self._requests_queue.put(heartbeat)

    def send(self, request):
        self._requests_queue.put(request)

    def batches(self):
        try:
            yield from self.call
        finally:
            self._ended.set()
            self._requests_queue.put(None)

    def stop_reason(self):
        """The trailer that says why the call ended: completed, stopped, deadman, drain,
        deadline or invalid."""
        return dict(self.call.trailing_metadata() or ()).get("geotraj-stop-reason", "")


def state_name(pb, state):
    return pb.LiveState.Name(state).removeprefix("LIVE_STATE_").lower()


def print_end(call, samples, pb, status_pb2, error_details_pb2):
    """The call's status, its stop reason and any field violations; the exit status."""
    code = call.call.code()
    print(f"end: {call.stop_reason() or 'no stop reason'} ({code.name}), {samples} samples")
    if code.name == "OK":
        return 0
    print(f"error: {code.name}: {call.call.details()}", file=sys.stderr)
    raw = dict(call.call.trailing_metadata() or ()).get("grpc-status-details-bin")
    if raw is not None:
        for detail in status_pb2.Status.FromString(raw).details:
            bad = error_details_pb2.BadRequest()
            if detail.Unpack(bad):
                print("bad request, field violations:", file=sys.stderr)
                for v in bad.field_violations:
                    print(f"  {v.field}: {v.description}", file=sys.stderr)
    return 1


def execute(args, grpc, pb, stub, status_pb2, error_details_pb2):
    from google.protobuf import json_format
    with open(args.request) as f:
        plan = json_format.Parse(f.read(), pb.PlanRequest())
    call = LiveCall(stub.Execute, pb.ExecuteRequest(plan=plan), pb.ExecuteRequest(heartbeat=pb.Heartbeat()))
    script = [  # (time [s], what to print, the control message), in time order
        (args.override_at, f"speed override {args.override:g} %", pb.ExecuteRequest(speed_override=args.override)),
        (args.pause_at, "pause", pb.ExecuteRequest(pause=pb.Pause())),
        (args.pause_at + args.pause_for, "resume", pb.ExecuteRequest(resume=pb.Resume())),
    ]
    print("   t [s]   plan time [s]   speed factor   state")
    samples, next_line = 0, 0.0
    try:
        for batch in call.batches():
            samples += len(batch.samples)
            s, live = batch.samples[-1], batch.live
            if live.acceleration_reserve > 0:  # the first batch: how the reserve changed the timing
                print(f"acceleration reserve {live.acceleration_reserve:g}: {live.reserve_note}")
            if s.t >= next_line or live.state in (pb.LIVE_STATE_COMPLETED, pb.LIVE_STATE_STOPPED):
                print(f"{s.t:8.3f}   {s.plan_time:6.3f} / {live.plan_duration_s:.3f}   {s.speed_factor:12.3f}   "
                      f"{state_name(pb, live.state)}")
                next_line += PROGRESS_S
            while script and s.t >= script[0][0]:
                when, what, message = script.pop(0)
                print(f"{s.t:8.3f}   -> {what}")
                call.send(message)
    except grpc.RpcError:
        pass  # the status, below
    return print_end(call, samples, pb, status_pb2, error_details_pb2)


def jog(args, grpc, pb, stub, status_pb2, error_details_pb2):
    start = pb.JogStart(robot=pb.RobotSpec(name=args.robot))
    call = LiveCall(stub.Jog, pb.JogRequest(start=start), pb.JogRequest(heartbeat=pb.Heartbeat()))
    commanded = stopping = False
    samples, next_line, first = 0, 0.0, None
    print(f"   t [s]   joint {args.joint} [rad]   velocity [rad/s]   state   limited joints")
    try:
        for batch in call.batches():
            samples += len(batch.samples)
            s = batch.samples[-1]
            if first is None:
                first = batch.samples[0].joints[args.joint]
                velocities = [0.0] * len(s.joints)  # every other joint held
                velocities[args.joint] = args.command
                call.send(pb.JogRequest(joints=pb.JointJog(velocities=velocities)))
                commanded = True
            if s.t >= next_line or batch.live.state == pb.LIVE_STATE_STOPPED:
                print(f"{s.t:8.3f}   {s.joints[args.joint]:14.6f}   {s.joint_velocities[args.joint]:16.6f}   "
                      f"{state_name(pb, batch.live.state)}   {list(batch.live.limited_joints)}")
                next_line += PROGRESS_S
            if commanded and not stopping and s.t >= args.seconds:
                print(f"{s.t:8.3f}   -> stop")
                call.send(pb.JogRequest(stop=pb.Stop()))
                stopping = True
    except grpc.RpcError:
        pass
    if first is not None:
        print(f"joint {args.joint}: from {first:.6f} to {s.joints[args.joint]:.6f} rad")
    return print_end(call, samples, pb, status_pb2, error_details_pb2)


def main(argv=None):
    args = parse_args(sys.argv[1:] if argv is None else argv)
    pb, rpc, status_pb2, error_details_pb2 = import_stubs(args.stubs)
    import grpc
    with grpc.insecure_channel(args.address) as channel:
        stub = rpc.TrajectoryServiceStub(channel)
        run = execute if args.call == "execute" else jog
        return run(args, grpc, pb, stub, status_pb2, error_details_pb2)


if __name__ == "__main__":
    sys.exit(main())
