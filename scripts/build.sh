#!/usr/bin/env bash
# Configures and builds geotraj with CMake: the one build that `make build`, CI and the
# container image (deploy/Dockerfile) share. Run scripts/install-deps.sh first.
#   usage: scripts/build.sh [BUILD_DIR [CMAKE_ARG...]]
#     BUILD_DIR   default: build
#     CMAKE_ARG   passed to the configure step, e.g. -DGEOTRAJ_BUILD_BENCH=OFF
#   environment: BUILD_TYPE (default Release), JOBS (default: nproc),
#                TARGETS (space-separated; default: all)
set -euo pipefail
cd "$(dirname "$0")/.."
build="${1:-build}"
[ $# -gt 0 ] && shift
jobs="${JOBS:-$(nproc)}"

cmake -S . -B "$build" -DCMAKE_BUILD_TYPE="${BUILD_TYPE:-Release}" "$@"
if [ -n "${TARGETS:-}" ]; then
  # shellcheck disable=SC2086  # TARGETS is a list of names
  cmake --build "$build" -j "$jobs" --target ${TARGETS}
else
  cmake --build "$build" -j "$jobs"
fi
