#!/usr/bin/env bash
# Builds the libFuzzer targets (clang, ASan + UBSan, coverage on all geotraj code) and runs
# each for a while on a copy of its seed corpus; fails on any crash, timeout, leak or
# out-of-memory. docs/reliability.md, "Fuzzing".
#
#   scripts/fuzz.sh [BUILD_DIR] [SECONDS_PER_TARGET]     (defaults: build-fuzz, 45)
#
# Environment:
#   FUZZ_TARGETS     the targets to run (default: all ten)
#   FUZZ_JOBS        build parallelism, and how many targets fuzz at once (default: nproc)
#   FUZZ_CONFIG      the configure flags (default: clang, Debug -g1, ASan + UBSan, the fuzz
#                    targets, no tests)
#   FUZZ_FORK        >0: run each target with -fork=N (N processes; a long job on a big machine)
#   FUZZ_KEEP_CORPUS 1: keep growing BUILD_DIR/fuzz-corpus/<target> across runs instead of
#                    starting again from the seeds
#   FUZZ_NO_BUILD    1: use the binaries already in BUILD_DIR
#   FUZZ_TIMEOUT     libFuzzer's -timeout per input [s] (default 10)
#   FUZZ_SKIP_REGRESSIONS 1: do not replay tests/fuzz/regressions first
# The harness reads GEOTRAJ_FUZZ_TRACE and GEOTRAJ_FUZZ_SERVER_GRACE_S (tests/fuzz/harness.hpp).
#
# Artifacts (crash-*, timeout-*, leak-*, oom-*) go to BUILD_DIR/fuzz-artifacts/<target>/,
# logs to BUILD_DIR/fuzz-logs/<target>.log. Replay one: BUILD_DIR/tests/fuzz/<target> FILE.
set -euo pipefail
cd "$(dirname "$0")/.."

build_dir="${1:-build-fuzz}"
seconds="${2:-45}"
targets="${FUZZ_TARGETS:-fuzz_plan_request fuzz_plan_request_json fuzz_convert fuzz_robot_model_json fuzz_http_head fuzz_kinematics fuzz_live fuzz_web fuzz_urdf fuzz_joint_limits_yaml}"
jobs="${FUZZ_JOBS:-$(nproc)}"
fork="${FUZZ_FORK:-0}"
timeout="${FUZZ_TIMEOUT:-10}"

if [ "${FUZZ_NO_BUILD:-0}" != 1 ]; then
  # Debug: assertions (Eigen's bounds checks included) stay on; GEOTRAJ_SANITIZE builds at -O2.
  config="${FUZZ_CONFIG:--DCMAKE_BUILD_TYPE=Debug -DCMAKE_CXX_FLAGS_DEBUG=-g1 -DCMAKE_CXX_COMPILER=clang++ -DGEOTRAJ_BUILD_FUZZ=ON -DGEOTRAJ_SANITIZE=ON -DGEOTRAJ_BUILD_TESTS=OFF -DGEOTRAJ_BUILD_BENCH=OFF}"
  # shellcheck disable=SC2086  # a list of flags
  cmake -S . -B "$build_dir" $config >/dev/null
  cmake --build "$build_dir" -j "$jobs" --target $targets fuzz_seeds
fi

bin="$build_dir/tests/fuzz"
export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"

# One target: its regressions, then its run. Prints its summary; fails on any finding.
fuzz_one() {
  local target="$1"
  local corpus="$build_dir/fuzz-corpus/$target"
  local artifacts="$build_dir/fuzz-artifacts/$target"
  local log="$build_dir/fuzz-logs/$target.log"
  if [ "${FUZZ_KEEP_CORPUS:-0}" != 1 ]; then rm -rf "$corpus"; fi
  mkdir -p "$corpus" "$artifacts" "$(dirname "$log")"
  cp -n "$bin/seeds/$target/"* "$corpus/" 2>/dev/null || true  # a copy: fuzzing adds to it

  # Known findings first: each file of tests/fuzz/regressions/<target>/ must pass now.
  local regressions="tests/fuzz/regressions/$target"
  if [ "${FUZZ_SKIP_REGRESSIONS:-0}" != 1 ] && compgen -G "$regressions/*" >/dev/null; then
    if ! "$bin/$target" -timeout="$timeout" -rss_limit_mb=2048 "$regressions"/* >"$log.regressions" 2>&1; then
      echo "FAIL $target: a regression input fails again; see $log.regressions" >&2
      return 1
    fi
  fi

  local args=(-max_total_time="$seconds" -timeout="$timeout" -rss_limit_mb=2048 -max_len=65536 -print_final_stats=1
              -artifact_prefix="$artifacts/")
  if [ -f "$bin/$target.dict" ]; then args+=(-dict="$bin/$target.dict"); fi
  if [ "$fork" -gt 0 ]; then args+=(-fork="$fork" -ignore_crashes=0 -ignore_timeouts=0 -ignore_ooms=0); fi
  local inputs
  inputs=$(ls "$corpus" | wc -l)
  if "$bin/$target" "${args[@]}" "$corpus" >"$log" 2>&1; then
    echo "== $target: ${seconds} s from $inputs inputs:" \
      "$(grep -E "^stat::number_of_executed_units|^stat::average_exec_per_sec|^stat::peak_rss_mb" "$log" | tr '\n' ' ')" \
      "$(grep -oE "cov: [0-9]+ ft: [0-9]+ corp: [0-9]+/[^ ]+" "$log" | tail -1)"
  else
    echo "FAIL $target: see $log; artifacts in $artifacts" >&2
    grep -E "ERROR: |==== geotraj fuzz check failed|SUMMARY|Test unit written" "$log" | head -8 >&2 || true
    return 1
  fi
}

# As many targets at once as FUZZ_JOBS (each a single process); the stage fails if any does.
status=0
running=0
for target in $targets; do
  fuzz_one "$target" &
  running=$((running + 1))
  if [ "$running" -ge "$jobs" ]; then
    wait -n || status=1
    running=$((running - 1))
  fi
done
while [ "$running" -gt 0 ]; do
  wait -n || status=1
  running=$((running - 1))
done
exit $status
