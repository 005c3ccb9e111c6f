#!/usr/bin/env bash
# deploy/healthcheck.sh (the image's HEALTHCHECK) against a real geotrajd, configured as
# the image configures it: exit 0 while it serves, non-zero once it has stopped; through
# the health-only port (--health-address), with a token required on the main port.
#   usage: healthcheck_test.sh SOURCE_DIR GEOTRAJD GEOTRAJ_CLI
set -euo pipefail
src="$1" server="$2" cli="$3"
check="$src/deploy/healthcheck.sh"
free_port() { /usr/bin/python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'; }
port="$(free_port)" health_port="$(free_port)"
export GEOTRAJ_ADDRESS="127.0.0.1:$port" GEOTRAJ_PLAINTEXT=true GEOTRAJ_HEALTHCHECK_CLI="$cli"
export GEOTRAJ_HEALTH_ADDRESS="127.0.0.1:$health_port"
# Tokens guard the main port; the health-only port must answer without one.
export GEOTRAJ_AUTH_TOKEN="healthcheck-test-token"
log="$(mktemp)"
"$server" > "$log" 2>&1 &
pid=$!
trap 'kill -9 $pid 2> /dev/null || true; rm -f "$log"' EXIT
ok=""
for _ in $(seq 1 100); do
  if sh "$check"; then ok=1; break; fi
  kill -0 "$pid" 2> /dev/null || { cat "$log"; echo "FAIL: geotrajd exited"; exit 1; }
  sleep 0.2
done
[ -n "$ok" ] || { cat "$log"; echo "FAIL: healthcheck.sh never reported SERVING"; exit 1; }
echo "healthcheck.sh: SERVING (exit 0)"
kill -TERM "$pid"
wait "$pid" || true
if sh "$check"; then
  echo "FAIL: healthcheck.sh reports SERVING after geotrajd stopped"
  exit 1
fi
echo "healthcheck.sh: non-zero after geotrajd stopped"
echo "healthcheck_test: OK"
