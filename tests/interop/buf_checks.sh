#!/usr/bin/env bash
# The .proto files checked with buf (npm package @bufbuild/buf, pinned in
# tests/interop/node/package-lock.json), then geotrajd called with `buf curl`:
#   1. buf lint       proto/ against the rules of buf.yaml (STANDARD, with the exceptions
#                     that buf.yaml explains)
#   2. buf breaking   proto/ against the last release, the git tag v0.5.0
#                     (GEOTRAJ_BUF_AGAINST overrides the input; the step is skipped, with a
#                     message, where the tag is not in this clone)
#   3. buf curl       client/grpcurl/buf_curl_examples.sh: the calls of examples.sh, through
#                     server reflection, against a geotrajd started here on 127.0.0.1:0
#
#   tests/interop/buf_checks.sh --server build/server/geotrajd [--buf PATH/TO/buf]
#
# buf: --buf, else $BUF, else tests/interop/node/node_modules/.bin/buf (after `npm ci` there),
# else buf on PATH. Exit 77 (ctest: skipped) when there is none and npm is not installed
# (or the build says, with --no-npm REASON, why it has no npm packages).
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
repo="$(cd "$here/../.." && pwd)"
server=""
buf="${BUF:-}"
no_npm=""
while [ $# -gt 0 ]; do
  case "$1" in
    --server) server="$2"; shift 2 ;;
    --buf) buf="$2"; shift 2 ;;
    --no-npm) no_npm="$2"; shift 2 ;;  # why the build has no npm packages (skip without buf)
    *) echo "buf_checks.sh: unknown argument $1" >&2; exit 2 ;;
  esac
done

if [ -z "$buf" ] || [ ! -x "$buf" ]; then
  if [ -x "$here/node/node_modules/.bin/buf" ]; then
    buf="$here/node/node_modules/.bin/buf"
  elif command -v buf >/dev/null 2>&1; then
    buf="$(command -v buf)"
  elif ! command -v npm >/dev/null 2>&1; then
    echo "buf_checks.sh: SKIPPED: npm is not installed, so buf (npm package @bufbuild/buf) is not either"
    echo "buf_checks.sh: install Node.js and npm (Debian: apt-get install nodejs npm) and rebuild"
    exit 77
  elif [ -n "$no_npm" ]; then
    echo "buf_checks.sh: SKIPPED: $no_npm, so buf (npm package @bufbuild/buf) is not installed"
    exit 77
  else
    echo "buf_checks.sh: buf not found: run 'npm ci' in tests/interop/node or build the geotraj_node_modules target" >&2
    exit 1
  fi
fi
echo "== $("$buf" --version 2>&1 | head -n1 | sed 's/^/buf /') ($buf)"

cd "$repo"

echo "== buf lint"
"$buf" lint
echo "buf lint: passed"

echo "== buf breaking"
against="${GEOTRAJ_BUF_AGAINST:-}"
if [ -z "$against" ]; then
  # The tag's tree has no buf.yaml: its proto/ is the module root, as buf.yaml's module is.
  git_dir=""
  if git -C "$repo" rev-parse --git-common-dir >/dev/null 2>&1; then
    git_dir="$(cd "$repo" && cd "$(git rev-parse --git-common-dir)" && pwd)"
  fi
  if [ -n "$git_dir" ] && git -C "$repo" rev-parse -q --verify "refs/tags/v0.5.0^{commit}" >/dev/null; then
    against="${git_dir}#format=git,tag=v0.5.0,subdir=proto"
  fi
fi
if [ -n "$against" ]; then
  echo "against $against"
  "$buf" breaking --against "$against"
  echo "buf breaking: passed"
else
  echo "buf breaking: SKIPPED: the tag v0.5.0 is not in this clone (git fetch --tags), and GEOTRAJ_BUF_AGAINST is not set"
fi

echo "== buf curl"
if [ -z "$server" ]; then
  echo "buf_checks.sh: --server PATH/TO/geotrajd is required for buf curl" >&2
  exit 2
fi
log="$(mktemp)"
GEOTRAJ_PLAINTEXT=true "$server" --address 127.0.0.1:0 >"$log" 2>&1 &
pid=$!
cleanup() {
  kill "$pid" 2>/dev/null || true
  wait "$pid" 2>/dev/null || true
  rm -f "$log"
}
trap cleanup EXIT
address=""
for _ in $(seq 1 300); do
  address="$(sed -n 's/^geotrajd: serving .* on \([^ ]*:[0-9]*\).*/\1/p' "$log" | head -n1)"
  [ -n "$address" ] && break
  if ! kill -0 "$pid" 2>/dev/null; then
    echo "buf_checks.sh: geotrajd exited early:" >&2
    cat "$log" >&2
    exit 1
  fi
  sleep 0.1
done
if [ -z "$address" ]; then
  echo "buf_checks.sh: geotrajd did not report its address within 30 s:" >&2
  cat "$log" >&2
  exit 1
fi
echo "geotrajd on $address"
BUF="$buf" bash "$repo/client/grpcurl/buf_curl_examples.sh" "$address"
echo "buf curl: passed"
echo "buf_checks.sh: lint, breaking and curl passed"
