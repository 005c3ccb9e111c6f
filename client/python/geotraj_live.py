#!/usr/bin/env python3
"""An example of geotraj's live calls in Python, on the geotraj package: Execute and Jog.

    geotraj_live.py --address 127.0.0.1:50051 execute client/grpcurl/plan_panda_path_c.json
    geotraj_live.py --address 127.0.0.1:50051 execute client/grpcurl/plan_panda_path_c.json --csv setpoints.csv
    geotraj_live.py --address 127.0.0.1:50051 jog --robot panda --joint 3 --command 0.5 --seconds 1

execute  streams the plan's set points in real time (Execute), sets the speed override to
         50 % after 1 s, pauses at 2 s for 1 s, resumes, and prints the progress (time, plan
         time, speed factor, state) every 0.25 s until the plan is done.
jog      jogs one joint (Jog) at a fraction of its maximum velocity for some seconds, then
         stops it and waits for the final set point, at rest.
--csv FILE writes every set point received, one row each, in the columns of
geotraj_example.py's CSV ('-': to stdout, the progress then to stderr).

Both calls are bidirectional streams (geotraj.Execution, geotraj.Jogging): the requests go
through a queue, which grpcio reads from its own thread through a generator; a heartbeat every
0.2 s tells the server that the client is still there (after 1 s without a message the
server's deadman stops the motion). It imports the installed geotraj package, else the one
beside this file, whose generated stubs then come from --stubs (README.md beside this file).
Exit status: 0 done (the plan completed, or the jog stopped when asked), 1 the call ended
otherwise (the code, the message, the stop reason and any field violations are printed),
2 bad usage.
"""
import argparse
import contextlib
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
PROGRESS_S = 0.25  # [s] of sample time between progress lines


def parse_args(argv):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--address", "--server", default=os.environ.get("GEOTRAJ_ADDRESS", "127.0.0.1:50051"),
                   help="HOST:PORT of geotrajd (default: $GEOTRAJ_ADDRESS or 127.0.0.1:50051)")
    p.add_argument("--token", default=os.environ.get("GEOTRAJ_TOKEN"),
                   help="bearer token, sent as `authorization: Bearer TOKEN` (default: $GEOTRAJ_TOKEN)")
    p.add_argument("--tls-ca", metavar="FILE",
                   help="use TLS and trust the CA certificates in FILE (PEM); default: plaintext")
    p.add_argument("--stubs", default=os.environ.get("GEOTRAJ_PY_STUBS", os.path.join(HERE, "gen")),
                   help="without an installed geotraj package: the directory of the generated stubs "
                        "(default: $GEOTRAJ_PY_STUBS or gen/ beside this file)")
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--csv", metavar="FILE",
                        help="write the set points received to FILE as CSV, one row each ('-': stdout)")
    calls = p.add_subparsers(dest="call", required=True)
    e = calls.add_parser("execute", parents=[common],
                         help="execute a plan with a speed override, a pause and a resume")
    e.add_argument("request", help="a PlanRequest in the proto JSON mapping (a file of client/grpcurl/)")
    e.add_argument("--override", type=float, default=50.0, help="the speed override to set [%%] (default: 50)")
    e.add_argument("--override-at", type=float, default=1.0, help="when to set it [s] (default: 1)")
    e.add_argument("--pause-at", type=float, default=2.0, help="when to pause [s] (default: 2)")
    e.add_argument("--pause-for", type=float, default=1.0, help="how long to stay paused [s] (default: 1)")
    j = calls.add_parser("jog", parents=[common], help="jog one joint, then stop")
    j.add_argument("--robot", default="panda", help="a built-in robot (ListRobots; default: panda)")
    j.add_argument("--joint", type=int, default=0, help="the joint, zero-based (default: 0)")
    j.add_argument("--command", type=float, default=0.5,
                   help="the joint's velocity as a fraction of its maximum (x the jog's velocity scale, 0.25), "
                        "in [-1, 1] (default: 0.5)")
    j.add_argument("--seconds", type=float, default=1.0, help="how long to jog before stopping [s] (default: 1)")
    return p.parse_args(argv)


def import_geotraj(stubs, prog):
    """The geotraj package: the installed one, else the one beside this file (the source
    tree), whose generated stubs come from `stubs`. Exit status 2 when neither imports."""
    os.environ["GEOTRAJ_PY_STUBS"] = stubs  # read by the source tree's package only
    saved = sys.path[:]
    sys.path[:] = [p for p in sys.path if os.path.abspath(p or os.curdir) != HERE]
    try:
        try:
            import geotraj
        except ModuleNotFoundError as e:
            if e.name != "geotraj":
                raise
            sys.path[:] = [HERE] + saved
            import geotraj
    except ImportError as e:
        print(f"{prog}: {e}", file=sys.stderr)
        sys.exit(2)
    return geotraj


def print_end(call, error, out):
    """How the call ended: its stop reason and status, then any error's details (stderr);
    returns the exit status."""
    code = error.code_name if error is not None else "OK"
    reason = (error.stop_reason if error is not None else call.stop_reason) or "no stop reason"
    print(f"end: {reason} ({code}), {call.sample_count} samples", file=out)
    if error is None:
        return 0
    print(error.describe(), file=sys.stderr)
    return 1


def execute(geotraj, client, args, writer, out):
    try:
        request = geotraj.as_message(args.request, geotraj.pb.PlanRequest)
    except (OSError, ValueError) as e:
        print(f"geotraj_live.py: {e}", file=sys.stderr)
        return 2
    if writer is not None:
        writer.steps = geotraj.has_steps(request)
    call = client.execute(request, record=False)
    script = [  # (time [s], what to print, the control), in time order
        (args.override_at, f"speed override {args.override:g} %", lambda: call.set_override(args.override)),
        (args.pause_at, "pause", call.pause),
        (args.pause_at + args.pause_for, "resume", call.resume),
    ]
    print("   t [s]   plan time [s]   speed factor   state", file=out)
    next_line, error = 0.0, None
    with call:
        try:
            for batch in call:
                if writer is not None:
                    writer.write_batch(batch)
                s, live = batch.samples[-1], batch.live
                if live.acceleration_reserve > 0:  # the first batch: how the reserve changed the timing
                    print(f"acceleration reserve {live.acceleration_reserve:g}: {live.reserve_note}", file=out)
                if s.t >= next_line or call.state in ("completed", "stopped"):
                    print(f"{s.t:8.3f}   {s.plan_time:6.3f} / {live.plan_duration_s:.3f}   {s.speed_factor:12.3f}   "
                          f"{call.state}", file=out)
                    next_line += PROGRESS_S
                while script and s.t >= script[0][0]:
                    when, what, control = script.pop(0)
                    print(f"{s.t:8.3f}   -> {what}", file=out)
                    control()
        except geotraj.GeotrajError as e:
            error = e
    return print_end(call, error, out)


def jog(geotraj, client, args, writer, out):
    call = client.jog(args.robot)
    stopping = False
    next_line, first, s, error = 0.0, None, None, None
    print(f"   t [s]   joint {args.joint} [rad]   velocity [rad/s]   state   limited joints", file=out)
    with call:
        try:
            for batch in call:
                if writer is not None:
                    writer.write_batch(batch)
                s = batch.samples[-1]
                if first is None:
                    if not 0 <= args.joint < len(s.joints):
                        print(f"geotraj_live.py: --joint {args.joint}: {args.robot} has joints 0 to "
                              f"{len(s.joints) - 1}", file=sys.stderr)
                        call.stop()
                        for _ in call:
                            pass
                        return 2
                    first = batch.samples[0].joints[args.joint]
                    velocities = [0.0] * len(s.joints)  # every other joint held
                    velocities[args.joint] = args.command
                    call.joints(velocities)
                if s.t >= next_line or call.state == "stopped":
                    print(f"{s.t:8.3f}   {s.joints[args.joint]:14.6f}   {s.joint_velocities[args.joint]:16.6f}   "
                          f"{call.state}   {list(batch.live.limited_joints)}", file=out)
                    next_line += PROGRESS_S
                if not stopping and s.t >= args.seconds:
                    print(f"{s.t:8.3f}   -> stop", file=out)
                    call.stop()
                    stopping = True
        except geotraj.GeotrajError as e:
            error = e
    if first is not None:
        print(f"joint {args.joint}: from {first:.6f} to {s.joints[args.joint]:.6f} rad", file=out)
    return print_end(call, error, out)


def main(argv=None):
    args = parse_args(sys.argv[1:] if argv is None else argv)
    geotraj = import_geotraj(args.stubs, "geotraj_live.py")
    out = sys.stderr if args.csv == "-" else sys.stdout  # stdout: only CSV with '-'
    with contextlib.ExitStack() as stack:
        writer = None
        if args.csv == "-":
            writer = geotraj.CsvWriter(sys.stdout)
        elif args.csv:
            try:
                writer = geotraj.CsvWriter(stack.enter_context(open(args.csv, "w", newline="", encoding="utf-8")))
            except OSError as e:
                print(f"geotraj_live.py: --csv: {e}", file=sys.stderr)
                return 2
        client = stack.enter_context(geotraj.Client(args.address, token=args.token, tls_ca=args.tls_ca))
        status = (execute if args.call == "execute" else jog)(geotraj, client, args, writer, out)
        if writer is not None and args.csv != "-":
            print(f"csv: {writer.count} set points written to {args.csv}", file=out)
        return status


if __name__ == "__main__":
    sys.exit(main())
