#!/usr/bin/env bash
# The calls of examples.sh made with `buf curl` instead of grpcurl, through server
# reflection (no .proto files needed), and checked: every call must succeed, and the two
# requests that are wrong on purpose must fail with the right code and error detail.
#
#   geotrajd --address 127.0.0.1:50051 &
#   client/grpcurl/buf_curl_examples.sh [HOST:PORT]   (default: $GEOTRAJ_ADDRESS or 127.0.0.1:50051)
#
# buf is the npm package @bufbuild/buf, pinned in tests/interop/node: $BUF, else the one the
# build installs (build/tests/interop/node/node_modules, or $GEOTRAJ_BUILD_DIR's), else one
# `npm ci` installed in tests/interop/node, else buf on PATH.
# GEOTRAJ_TOKEN=...     sends `authorization: Bearer ...` with every call (and reflection).
# GEOTRAJ_TLS_CA=FILE   calls https:// and trusts the CA certificates in FILE (PEM);
#                       without it the calls are plaintext HTTP/2 (http:// with prior knowledge).
# tests/interop/buf_checks.sh runs this against a geotrajd of its own (ctest interop.buf).
set -euo pipefail

address="${1:-${GEOTRAJ_ADDRESS:-127.0.0.1:50051}}"
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
buf="${BUF:-}"
if [ -z "$buf" ]; then
  for candidate in "${GEOTRAJ_BUILD_DIR:-$here/../../build}/tests/interop/node/node_modules/.bin/buf" \
                   "$here/../../tests/interop/node/node_modules/.bin/buf"; do
    if [ -x "$candidate" ]; then buf="$candidate"; break; fi
  done
  if [ -z "$buf" ] && command -v buf >/dev/null 2>&1; then buf=buf; fi
  if [ -z "$buf" ]; then
    echo "buf_curl_examples.sh: buf not found: build the project (make), run 'npm ci' in tests/interop/node, or set BUF" >&2
    exit 2
  fi
fi

opts=(--protocol grpc --timeout 120s)
if [ -n "${GEOTRAJ_TLS_CA:-}" ]; then
  base="https://$address"
  opts+=(--cacert "$GEOTRAJ_TLS_CA")
else
  base="http://$address"
  opts+=(--http2-prior-knowledge)
fi
if [ -n "${GEOTRAJ_TOKEN:-}" ]; then
  opts+=(-H "authorization: Bearer $GEOTRAJ_TOKEN" --reflect-header "authorization: Bearer $GEOTRAJ_TOKEN")
fi
service="$base/geotraj.v1.TrajectoryService"

call() {  # call METHOD FILE
  echo "== $1 < $(basename "$2")"
  "$buf" curl "${opts[@]}" -d "@$2" "$service/$1"
}

# expect_failure CODE DETAIL METHOD [buf curl args]: the call must fail with CODE (buf
# curl's lower-case names) and carry a DETAIL (google.rpc.*) in its status details.
expect_failure() {
  local code="$1" detail="$2" method="$3" err
  shift 3
  err="$(mktemp)"
  if "$buf" curl "${opts[@]}" "$@" "$service/$method" 2>"$err"; then
    rm -f "$err"
    echo "buf_curl_examples.sh: $method was accepted, but it should fail with $code" >&2
    exit 1
  fi
  cat "$err"
  if ! grep -q "\"code\": \"$code\"" "$err" || ! grep -q "\"type\": \"$detail\"" "$err"; then
    rm -f "$err"
    echo "buf_curl_examples.sh: $method failed, but not with $code and a $detail" >&2
    exit 1
  fi
  rm -f "$err"
}

echo "== services (reflection)"
"$buf" curl "${opts[@]}" --list-services "$base"
echo "== health"
"$buf" curl "${opts[@]}" -d '{"service": "geotraj.v1.TrajectoryService"}' "$base/grpc.health.v1.Health/Check"

call ConvertConstraints "$here/convert_table_5_10.json"
for path in a b c; do
  call PlanTrajectory "$here/plan_demo_path_$path.json"
done
call AnalyzePath "$here/analyze_demo_path_a.json"

echo "== ListRobots"
"$buf" curl "${opts[@]}" -d '{}' "$service/ListRobots"
for request in plan_pa10_path_c plan_pa10_path_b_redundancy plan_seam_roll_ur5e plan_panda_path_c joint_move_pa10 linear_move_ur5 sequence_ur5 sequence_blended_ur5; do
  call PlanTrajectory "$here/$request.json"
done
call ComputeForwardKinematics "$here/fk_pa10.json"
call ComputeInverseKinematics "$here/ik_ur5_all.json"

# StreamSamples of path A: 10 s at 100 Hz, so 1001 samples (with --emit-defaults every
# sample prints its "t", even t = 0). Only the count is shown.
echo "== StreamSamples < plan_demo_path_a.json (sample count)"
samples="$("$buf" curl "${opts[@]}" --emit-defaults -d "@$here/plan_demo_path_a.json" "$service/StreamSamples" |
  grep -c '^ *"t": ')"
echo "$samples samples"
if [ "$samples" -ne 1001 ]; then
  echo "buf_curl_examples.sh: StreamSamples sent $samples samples, expected 1001" >&2
  exit 1
fi

# Live execution (a bidirectional stream: buf curl sends the file's one message, then closes
# its side): path C on the Panda in real time at 1 kHz, with a 30 s deadman, so that the
# 3.4 s motion completes. Only the last batch's state is shown.
echo "== Execute < execute_panda.json (the last state)"
state="$("$buf" curl "${opts[@]}" -d "@$here/execute_panda.json" "$service/Execute" | grep '"state": ' | tail -n 1)"
echo "$state"
if [[ "$state" != *'"LIVE_STATE_COMPLETED"'* ]]; then
  echo "buf_curl_examples.sh: Execute did not end with a COMPLETED batch" >&2
  exit 1
fi

# Jogging: `start`, then a joint command, and no heartbeat: the 2 s deadman stops the joint
# and ends the call with ABORTED, after a final sample at rest (STOPPED).
echo "== Jog < jog_panda.json (ended by the deadman on purpose)"
out="$(mktemp)"
err="$(mktemp)"
if "$buf" curl "${opts[@]}" -d "@$here/jog_panda.json" "$service/Jog" >"$out" 2>"$err"; then
  rm -f "$out" "$err"
  echo "buf_curl_examples.sh: Jog ended OK, but the deadman should end it with aborted" >&2
  exit 1
fi
cat "$err"
grep '"state": ' "$out" | tail -n 1
if ! grep -q '"code": "aborted"' "$err" || [[ "$(grep '"state": ' "$out" | tail -n 1)" != *'"LIVE_STATE_STOPPED"'* ]]; then
  rm -f "$out" "$err"
  echo "buf_curl_examples.sh: Jog failed, but not with aborted after a STOPPED batch" >&2
  exit 1
fi
rm -f "$out" "$err"
echo "== jog_panda.json ended by the deadman as expected"

# The bad request fails on purpose: INVALID_ARGUMENT with a google.rpc.BadRequest, whose
# field violations buf curl prints base64-encoded (grpcurl decodes them).
echo "== PlanTrajectory < bad_request.json (fails on purpose)"
expect_failure invalid_argument google.rpc.BadRequest PlanTrajectory -d "@$here/bad_request.json"
echo "== bad_request.json failed as expected"

# Without reportOnly the PA-10 plan fails on purpose: FAILED_PRECONDITION with a
# google.rpc.PreconditionFailure.
echo "== PlanTrajectory < plan_pa10_path_c.json without reportOnly (fails on purpose)"
expect_failure failed_precondition google.rpc.PreconditionFailure PlanTrajectory \
  -d "$(sed 's/"reportOnly": true/"reportOnly": false/' "$here/plan_pa10_path_c.json")"
echo "== plan_pa10_path_c.json without reportOnly failed as expected"
