#!/usr/bin/env python3
"""An example geotraj client in Python, on the geotraj package (client/python/geotraj).

Plans a trajectory with PlanTrajectory, prints its summary, then streams its samples with
StreamSamples into a CSV file. When the server refuses the request, prints the status code,
the message and the error details from the grpc-status-details-bin trailer: the field
violations of a google.rpc.BadRequest, the violations of a google.rpc.PreconditionFailure.

It imports the installed package (pip install ./client/python), else the one beside this
file, whose generated stubs then come from --stubs (README.md beside this file). Then:
    geotraj_example.py --server 127.0.0.1:50051 --request client/grpcurl/plan_demo_path_a.json --csv path_a.csv
    geotraj_example.py --request client/grpcurl/bad_request.json      # exit 1, field violations
    geotraj_example.py --request client/grpcurl/plan_joint_path_panda.json --payload 3 \
        --max-torque panda_joint2=50 --csv -                          # timed within a torque
Options: --token TOKEN (or $GEOTRAJ_TOKEN) sends `authorization: Bearer TOKEN`;
--tls-ca FILE calls over TLS trusting the CA certificates in FILE (PEM).
Exit status: 0 done, 1 the server refused the request (or the call failed), 2 bad usage.
"""
import argparse
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
DEFAULT_REQUEST = os.path.join(HERE, "..", "grpcurl", "plan_demo_path_a.json")


def parse_args(argv):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--server", default=os.environ.get("GEOTRAJ_ADDRESS", "127.0.0.1:50051"),
                   help="HOST:PORT of geotrajd (default: $GEOTRAJ_ADDRESS or 127.0.0.1:50051)")
    p.add_argument("--token", default=os.environ.get("GEOTRAJ_TOKEN"),
                   help="bearer token, sent as `authorization: Bearer TOKEN` (default: $GEOTRAJ_TOKEN)")
    p.add_argument("--tls-ca", metavar="FILE",
                   help="use TLS and trust the CA certificates in FILE (PEM); default: plaintext")
    p.add_argument("--tls-server-name", metavar="NAME",
                   help="with --tls-ca: the name the server's certificate must carry, if not HOST")
    p.add_argument("--request", default=DEFAULT_REQUEST,
                   help="a PlanRequest in the proto JSON mapping (default: client/grpcurl/plan_demo_path_a.json)")
    p.add_argument("--csv", default="samples.csv",
                   help="where StreamSamples' samples go, one row each; '-' for stdout (default: samples.csv)")
    p.add_argument("--payload", metavar="MASS[,X,Y,Z]",
                   help="what the tool carries (robot.payload): kg, and its centre of mass [m] in the tool frame")
    p.add_argument("--max-torque", metavar="JOINT=NM,...",
                   help="joint torque limits by joint name (robot.jointLimits[].maxTorque) [N m]")
    p.add_argument("--no-stream", action="store_true", help="plan only")
    p.add_argument("--timeout", type=float, default=60.0, help="deadline of the plan [s] (default: 60)")
    p.add_argument("--stream-timeout", type=float, default=None,
                   help="deadline of the stream [s] (default: none, so that a motion of any length streams whole)")
    p.add_argument("--stubs", default=os.environ.get("GEOTRAJ_PY_STUBS", os.path.join(HERE, "gen")),
                   help="without an installed geotraj package: the directory of the generated stubs "
                        "(default: $GEOTRAJ_PY_STUBS or gen/ beside this file)")
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


def print_plan(plan, out=sys.stdout):
    if plan.steps:  # a sequence: one line per motion, the robot at rest between them
        print(f"plan: a sequence of {len(plan.steps)} motions", file=out)
        for st in plan.steps:
            steps = f"steps {st.index}-{st.last_index}" if st.last_index > st.index else f"step {st.index}"
            print(f"  {steps} ({st.kind}): from t = {st.start_time_s:.6g} s for {st.duration_s:.6g} s, "
                  f"{st.arc_length:.6f} m", file=out)
            for c in st.corners:
                print(f"    corner after step {c.after_step}: blend within {c.deviation:.4g} m "
                      f"(tolerance {c.tolerance:.4g} m)", file=out)
    elif not plan.segments:
        print("plan: no path segments (a joint move or a joint path)", file=out)
    else:
        print(f"plan: {len(plan.segments)} segments, arc length {plan.arc_length:.6f} m, "
              f"closed-loop error {plan.closed_loop.max_error:.3g}"
              + (f" ({plan.closed_loop.worst_field})" if plan.closed_loop.worst_field else ""), file=out)
    for i, seg in enumerate(plan.segments):
        # A path of pieces: which segments are its exact pieces and which the transitions.
        kind_name = seg.DESCRIPTOR.fields_by_name["kind"].enum_type.values_by_number[seg.kind].name
        kind = {"SEGMENT_KIND_PIECE": f" (piece {seg.piece})",
                "SEGMENT_KIND_TRANSITION": f" (transition into piece {seg.piece})"}.get(kind_name, "")
        print(f"  segment {i}: {seg.arc_length:.6f} m{kind}", file=out)
    if plan.HasField("motion"):
        m = plan.motion
        print(f"motion: {m.duration_s:.6g} s, peak speed {m.peak_speed:.6g} m/s, "
              f"peak acceleration {m.peak_acceleration:.6g} m/s^2, {m.sample_count} samples", file=out)
    if plan.HasField("robot"):
        print(f"robot: feasible {plan.robot.feasible}, {len(plan.robot.violations)} violations", file=out)
        # A model with mass properties: each joint's largest torque and its share of the limit.
        for j in plan.robot.joints:
            if j.HasField("peak_torque"):
                usage = f", {100.0 * j.torque_usage:.1f} % of its limit" if j.HasField("torque_usage") else ""
                print(f"  joint {j.joint}: peak torque {j.peak_torque:.4g} N m{usage}", file=out)
    # The optimisers that ran (optimize: tangentScales, breakpoints, timing, redundancy).
    for field, report in plan.optimization.ListFields():
        status = report.DESCRIPTOR.fields_by_name["status"].enum_type.values_by_number[report.status].name
        print(f"optimizer {field.name}: objective {report.objective_before:.6g} -> {report.objective_after:.6g}, "
              f"{report.iterations} iterations, {report.seconds:.3g} s, {status.replace('OPTIMIZER_STATUS_', '').lower()}",
              file=out)


def main(argv=None):
    args = parse_args(sys.argv[1:] if argv is None else argv)
    geotraj = import_geotraj(args.stubs, "geotraj_example.py")
    pb = geotraj.pb

    try:
        request = pb.PlanRequest()
        request.CopyFrom(geotraj.as_message(args.request, pb.PlanRequest))
        if args.payload:
            values = [float(x) for x in args.payload.split(",")]
            if len(values) not in (1, 4):
                raise ValueError("--payload takes MASS or MASS,X,Y,Z")
            request.robot.payload.mass = values[0]
            if len(values) == 4:
                c = request.robot.payload.center_of_mass
                c.x, c.y, c.z = values[1:]
        for item in filter(None, (args.max_torque or "").split(",")):
            joint, _, value = item.partition("=")
            if not joint or not value:
                raise ValueError(f"--max-torque takes JOINT=NM,...: {item!r} is not one")
            request.robot.joint_limits.add(joint=joint, max_torque=float(value))
    except (OSError, ValueError) as e:
        print(f"geotraj_example.py: {e}", file=sys.stderr)
        return 2

    with geotraj.Client(args.server, token=args.token, tls_ca=args.tls_ca, timeout=args.timeout,
                        tls_server_name=args.tls_server_name) as client:
        try:
            plan = client.plan(request)
            info = sys.stderr if args.csv == "-" else sys.stdout  # stdout: only CSV with '-'
            print_plan(plan, info)
            if args.no_stream:
                return 0
            if not request.HasField("motion"):
                print("no motion in the request: nothing to stream (give `motion` to get samples)", file=info)
                return 0
            if args.csv == "-":
                try:
                    client.stream_csv(request, sys.stdout, timeout=args.stream_timeout)
                    sys.stdout.flush()
                except BrokenPipeError:  # `| head`: the reader has had enough (the stream is cancelled)
                    os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            else:
                with open(args.csv, "w", newline="", encoding="utf-8") as out:
                    count = client.stream_csv(request, out, timeout=args.stream_timeout)
                print(f"stream: {count} samples written to {args.csv}")
        except geotraj.GeotrajError as err:
            print(err.describe(), file=sys.stderr)
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
