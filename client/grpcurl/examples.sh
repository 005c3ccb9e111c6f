#!/usr/bin/env bash
# Calls a running geotrajd with grpcurl, through server reflection (no .proto files needed).
#
#   geotrajd --address 127.0.0.1:50051 &
#   client/grpcurl/examples.sh [HOST:PORT]        (default: $GEOTRAJ_ADDRESS or 127.0.0.1:50051)
#
# grpcurl is not a Debian package: put it on PATH yourself, or run buf_curl_examples.sh
# beside this script, which makes the same calls with `buf curl` (the npm package
# @bufbuild/buf, which `npm ci` in tests/interop/node installs). The request files beside this
# script are in the proto JSON mapping and work with the `geotraj` CLI as well:
#   convert_table_5_10.json   ConvertRequest: thesis Table 5.10 (with its erratum), per parameter
#   plan_demo_path_{a,b,c}.json  PlanRequest: the thesis demonstration (Tables 7.8, 7.18), paths A, B, C
#   analyze_demo_path_a.json  PlanRequest with analysisPoints, for AnalyzePath
#   bad_request.json          a PlanRequest with four mistakes: INVALID_ARGUMENT with a BadRequest
# and with a robot (ListRobots describes the built-in models "pa10", "ur5", "panda", "iiwa14", "ur5e"):
#   plan_pa10_path_c.json     PlanRequest: path C followed by the PA-10 in the thesis's 10 s. Too
#                             fast for the arm's joint accelerations, so it sets robot.reportOnly
#                             to get the joint report with its violations; without it the plan
#                             fails with FAILED_PRECONDITION and a google.rpc.PreconditionFailure
#                             (shown below). Over 30 s or more the PA-10 can follow it.
#   plan_pa10_path_b_redundancy.json  PlanRequest: path B on the PA-10 in the thesis's 10 s, its
#                             self-motion chosen for the whole path (optimize.redundancy,
#                             accelerationWeight 1): within every joint limit, where the
#                             sample-by-sample choice breaks joint 1's acceleration limit
#   plan_seam_roll_ur5e.json  PlanRequest: a 0.2 m seam on the UR5e whose plan turns the torch
#                             2.6 rad about its own axis in 1.5 s (beyond wrist 3's speed); with
#                             robot.toolAxisFree the roll is chosen with the joints and the
#                             streamed torch keeps its planned position and axis
#   joint_move_pa10.json      PlanRequest with a jointMove (thesis 6.2.2.1): the PA-10 from its
#                             home (start absent) to a goal in minimum time (durationS 0: the
#                             slowest joint sets the time), every joint on one synchronised profile
#   linear_move_ur5.json      PlanRequest with a linearMove (thesis 6.2.2.2): the UR5's tool on a
#                             straight line from its home pose (start absent), turning 90 degrees
#                             about z, in 2 s
#   sequence_ur5.json         PlanRequest with a sequence: the UR5 down a line to a pick pose, up
#                             in 1.5 s, a joint move to above the place pose, down a line
#   sequence_blended_ur5.json PlanRequest with a sequence of three lines whose two corners are
#                             blended within 2 cm: one motion without a rest at the corners
#   plan_joint_path_panda.json PlanRequest with a jointPath: nine Panda waypoints of a pick and
#                             place (as a sampling planner returns them) passed within 0.05 rad
#                             without stopping, as fast as the joint limits allow (jerk-limited)
#   plan_panda_path_c.json    PlanRequest: the thesis's path C on the Franka Panda (a URDF model),
#                             the tool pointing down, as fast as the arm's limits allow at 1 kHz,
#                             from its home by a joint move to the path's start (robot.approach)
#   fk_pa10.json              ForwardKinematicsRequest: the PA-10's tool pose, Jacobian and axes
#   ik_ur5_all.json           InverseKinematicsRequest: every branch of a UR5 tool pose (eight)
# Each works with StreamSamples too (the joints in every sample): StreamSamples refuses a
# motion the robot cannot follow unless robot.reportOnly is set.
# For the live calls (bidirectional streams: grpcurl sends every message of the file, then
# closes its side, and sends no heartbeats, so the server's deadman ends a motion that lasts
# longer than the deadman time; see docs/clients.md):
#   execute_panda.json        ExecuteRequest: plan_panda_path_c.json executed live, with a 30 s
#                             deadman (options.deadmanS) so that the 3.4 s motion completes: OK
#   jog_panda.json            JogRequest `start` (the Panda at its home, a 2 s deadman), then a
#                             `joints` command (joint 0 at half the jog speed): the joint turns
#                             until the deadman stops it, and the call ends ABORTED
set -euo pipefail

address="${1:-${GEOTRAJ_ADDRESS:-127.0.0.1:50051}}"
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"

if ! command -v grpcurl >/dev/null 2>&1; then
  echo "examples.sh: grpcurl is not on PATH (it is not packaged by Debian; install it yourself)" >&2
  exit 2
fi

call() {  # call METHOD FILE
  echo "== $1 < $(basename "$2")"
  grpcurl -plaintext -d @ "$address" "geotraj.v1.TrajectoryService/$1" < "$2"
}

echo "== services (reflection)"
grpcurl -plaintext "$address" list
echo "== health"
grpcurl -plaintext -d '{"service": "geotraj.v1.TrajectoryService"}' "$address" grpc.health.v1.Health/Check

call ConvertConstraints "$here/convert_table_5_10.json"
for path in a b c; do
  call PlanTrajectory "$here/plan_demo_path_$path.json"
done
call AnalyzePath "$here/analyze_demo_path_a.json"

echo "== ListRobots"
grpcurl -plaintext -d '{}' "$address" geotraj.v1.TrajectoryService/ListRobots
for request in plan_pa10_path_c plan_pa10_path_b_redundancy plan_seam_roll_ur5e plan_panda_path_c joint_move_pa10 linear_move_ur5 sequence_ur5 sequence_blended_ur5 \
  plan_joint_path_panda; do
  call PlanTrajectory "$here/$request.json"
done

# Your own arm: the URDF text inline in robot.urdf (here the Panda's own file, which
# `geotraj robots --urdf panda` prints), with its base and tip links.
echo "== PlanTrajectory < plan_panda_path_c.json with the Panda as an inline URDF"
geotraj_cli="${GEOTRAJ_CLI:-geotraj}"
if command -v "$geotraj_cli" >/dev/null 2>&1; then
  python3 -c '
import json, sys
request = json.load(open(sys.argv[1]))
request["robot"].pop("name")
request["robot"].update(urdf=sys.stdin.read(), baseLink="panda_link0", tipLink="panda_link8")
print(json.dumps(request))' "$here/plan_panda_path_c.json" < <("$geotraj_cli" robots --urdf panda) |
    grpcurl -plaintext -d @ "$address" geotraj.v1.TrajectoryService/PlanTrajectory | head -20
fi
call ComputeForwardKinematics "$here/fk_pa10.json"
call ComputeInverseKinematics "$here/ik_ur5_all.json"

# Live execution: the samples in real time at 1 kHz (about 340 batches; the last shown), the
# final one COMPLETED.
echo "== Execute < execute_panda.json (the last batch)"
grpcurl -plaintext -d @ "$address" geotraj.v1.TrajectoryService/Execute < "$here/execute_panda.json" | tail -n 24

# Jogging: no heartbeat follows the command, so the deadman (2 s) stops the joint and ends the
# call with ABORTED, after a final sample at rest.
echo "== Jog < jog_panda.json (ends ABORTED by the deadman)"
if grpcurl -plaintext -d @ "$address" geotraj.v1.TrajectoryService/Jog < "$here/jog_panda.json" | tail -n 8; then
  echo "examples.sh: Jog < jog_panda.json ended OK, but the deadman should have ended it with Aborted" >&2
  exit 1
fi
echo "== jog_panda.json ended by the deadman as expected"

# The bad request fails on purpose: grpcurl prints the code, the message and the
# google.rpc.BadRequest field violations.
if call PlanTrajectory "$here/bad_request.json"; then
  echo "examples.sh: bad_request.json was accepted, but it should fail with InvalidArgument" >&2
  exit 1
fi
echo "== bad_request.json failed as expected"

# Without reportOnly the PA-10 plan fails on purpose: FAILED_PRECONDITION naming the first
# broken limit (joint, time, sample), every one in the google.rpc.PreconditionFailure.
echo "== PlanTrajectory < plan_pa10_path_c.json without reportOnly"
if sed 's/"reportOnly": true/"reportOnly": false/' "$here/plan_pa10_path_c.json" |
    grpcurl -plaintext -d @ "$address" geotraj.v1.TrajectoryService/PlanTrajectory; then
  echo "examples.sh: plan_pa10_path_c.json without reportOnly was accepted, but it should fail with FailedPrecondition" >&2
  exit 1
fi
echo "== plan_pa10_path_c.json without reportOnly failed as expected"
