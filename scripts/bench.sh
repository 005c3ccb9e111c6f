#!/usr/bin/env bash
# Runs the benchmarks as docs/performance.md reports them (median of 5 repetitions).
#   usage: scripts/bench.sh [BUILD_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
build="${1:-build}"
args=(--benchmark_repetitions=5 --benchmark_report_aggregates_only=true)
echo "== $(nproc) cores, $(uname -m), $(g++ --version | head -1)"
"$build/bench/bench_core" "${args[@]}"
if [ -x "$build/bench/bench_server" ]; then
  "$build/bench/bench_server" "${args[@]}"
fi
