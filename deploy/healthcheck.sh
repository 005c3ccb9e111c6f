#!/bin/sh
# The container's HEALTHCHECK: grpc.health.v1.Health/Check through the geotraj CLI, on
# loopback. It asks the health-only port (GEOTRAJ_HEALTH_ADDRESS, plaintext, no tokens)
# when there is one, else the main port (GEOTRAJ_ADDRESS; plaintext only).
#   environment: GEOTRAJ_HEALTHCHECK_SERVICE: "" (liveness, the default) or geotraj.readiness
#                GEOTRAJ_HEALTHCHECK_CLI: the geotraj CLI (default /usr/local/bin/geotraj)
# Exit 0 when SERVING, 1 otherwise: what Docker expects.
set -eu
addr="${GEOTRAJ_HEALTH_ADDRESS:-${GEOTRAJ_ADDRESS:-127.0.0.1:50051}}"
port="${addr##*:}"
exec "${GEOTRAJ_HEALTHCHECK_CLI:-/usr/local/bin/geotraj}" --server "127.0.0.1:${port}" --timeout 3 \
  health --service "${GEOTRAJ_HEALTHCHECK_SERVICE:-}"
