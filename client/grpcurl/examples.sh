#!/usr/bin/env bash
# Calls a running geotrajd with grpcurl, through server reflection (no .proto files needed).
#
#   geotrajd --address 127.0.0.1:50051 &
#   client/grpcurl/examples.sh [HOST:PORT]        (default: $GEOTRAJ_ADDRESS or 127.0.0.1:50051)
#
# grpcurl is not a Debian package: put it on PATH yourself. The request files beside this
# script are in the proto JSON mapping and work with the `geotraj` CLI as well:
#   convert_table_5_10.json   ConvertRequest: thesis Table 5.10 (with its erratum), per parameter
#   plan_demo_path_{a,b,c}.json  PlanRequest: the thesis demonstration (Tables 7.8, 7.18), paths A, B, C
#   analyze_demo_path_a.json  PlanRequest with analysisPoints, for AnalyzePath
#   bad_request.json          a PlanRequest with four mistakes: INVALID_ARGUMENT with a BadRequest
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

# The bad request fails on purpose: grpcurl prints the code, the message and the
# google.rpc.BadRequest field violations.
if call PlanTrajectory "$here/bad_request.json"; then
  echo "examples.sh: bad_request.json was accepted, but it should fail with InvalidArgument" >&2
  exit 1
fi
echo "== bad_request.json failed as expected"
