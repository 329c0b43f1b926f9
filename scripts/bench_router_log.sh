#!/usr/bin/env bash
# How fast the router's log grows while a compose fleet idles (docs/deploy.md, "Logs and health").
#
# The fleet of deploy/compose.yaml comes up under a project of its own on free host ports (the
# images built already: scripts/build_image.sh; an engine answering `docker info`), every service
# healthy; then the router's `compose logs` are counted in bytes at the start and at the end of an
# idle window of MINUTES (no command sent; the agents connected, their health checks running).
# Prints the growth and its rate per hour, and exits 1 when the rate is 1 MB an hour or more (the
# target), 2 when the fleet did not come up. The fleet is taken down at the end.
#
# Usage: scripts/bench_router_log.sh [MINUTES]        (default 5)
# Environment: COMPOSE (default `docker compose` if it works, else docker-compose),
#   ROCO_ROUTER_LOG (the router's Zenoh log level, as in compose.yaml; default info).
set -euo pipefail
cd "$(dirname "$0")/.."
minutes=${1:-5}
[[ "$minutes" =~ ^[1-9][0-9]*$ ]] || { echo "bench_router_log: MINUTES must be a whole number ≥ 1" >&2; exit 2; }
docker info >/dev/null 2>&1 || { echo "bench_router_log: no Docker engine answers (start dockerd)" >&2; exit 2; }
if [ -z "${COMPOSE:-}" ]; then
    if docker compose version >/dev/null 2>&1; then COMPOSE="docker compose"; else COMPOSE=docker-compose; fi
fi
COMPOSE="$COMPOSE -f deploy/compose.yaml -p rocorouterlog"
free_port() {
    python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1]); s.close()'
}
work=$(mktemp -d /var/tmp/roco-routerlog.XXXXXX)
export ROCO_RUNS="$work/runs" ROCO_CERTS="$work/certs" ROCO_RUN=routerlog
ROCO_ROUTER_PUBLISH="127.0.0.1:$(free_port)" ROCO_VIEWER_WEB_PORT=$(free_port) ROCO_VIEWER_GRPC_PORT=$(free_port)
export ROCO_ROUTER_PUBLISH ROCO_VIEWER_WEB_PORT ROCO_VIEWER_GRPC_PORT
mkdir -p "$ROCO_RUNS" "$ROCO_CERTS"
chown "${ROCO_UID:-10001}:${ROCO_GID:-10001}" "$ROCO_RUNS" "$ROCO_CERTS" 2>/dev/null || true
finish() { $COMPOSE down -v --timeout 20 >/dev/null 2>&1 || true; rm -rf "$work"; }
trap finish EXIT

$COMPOSE up -d >"$work/up.log" 2>&1 || { cat "$work/up.log"; exit 2; }
deadline=$(($(date +%s) + 300))
for s in router recorder world a_km a_pl a_co ag_ex a_ta a_hi; do
    id=$($COMPOSE ps -q "$s")
    until [ "$(docker inspect -f '{{.State.Health.Status}}' "$id" 2>/dev/null)" = healthy ]; do
        [ "$(date +%s)" -le "$deadline" ] || { echo "bench_router_log: $s not healthy in 300 s" >&2; exit 2; }
        sleep 1
    done
done
before=$($COMPOSE logs --no-color router 2>/dev/null | wc -c)
[ "$before" -gt 0 ] || { echo "bench_router_log: the router logged nothing (not its log?)" >&2; exit 2; }
echo "bench_router_log: fleet healthy; router log ${before} bytes; idle for ${minutes} min (level ${ROCO_ROUTER_LOG:-info})"
sleep $((minutes * 60))  # the idle window measured
after=$($COMPOSE logs --no-color router 2>/dev/null | wc -c)
grown=$((after - before))
per_hour=$((grown * 60 / minutes))
echo "bench_router_log: router log grew ${grown} bytes in ${minutes} min idle: ${per_hour} bytes an hour (target < 1000000)"
[ "$per_hour" -lt 1000000 ]
