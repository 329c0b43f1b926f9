#!/usr/bin/env bash
# The compose smoke test (CI, as root, on a Debian machine with no registry but Debian's and
# PyPI): a real Docker engine runs the fleet of deploy/compose.yaml and the pour is sent from the
# host through the router's published port, with a_km restarted mid-task.
#
#   engine   Debian's docker.io, docker-compose (1.29) and debootstrap, installed if missing;
#            dockerd started in the background if no engine answers (and stopped at the end)
#   build    scripts/build_image.sh: wheelhouse, local base, docker build with no network of the
#            three images; the runtime image (roco:latest) must be at most 1000 MB (docker's
#            Size, 1 MB = 10^6 bytes, rounded up): "runtime image N MB ≤ 1000 MB"
#   up       `compose up -d` (with the NET_ADMIN override) under a project of its own, on free
#            host ports; the host folders the services write (the run folder, the credentials)
#            belong to their user (ROCO_UID, default the image's roco, 10001)
#   healthy  every service healthy (each roco service's ready file; the viewer's ports) within its
#            limits (memory, CPU, PIDs) and not as root, each in its image (ag_ex the robot
#            image, the recorder and the viewer the viewer image, the others roco:latest); then
#            the operator's view: `compose logs a_km` shows the agent's log, the router's log has
#            no DEBUG/TRACE line and no "tls handshake eof", every container's log is rotated
#   pour     `roco send "pour the jar into the bowl"` from the host, in the background; once a_co
#            has sent a_ta plan #1 (the first request on C1 in the run folder's traffic.jsonl),
#            `compose restart a_km`; the pour must end "succeeded" and the restarted a_km must
#            have kept its knowledge (its store is a volume)
#   power    `roco fault restart world` (a power cycle of the robot: a fresh kitchen; it starts
#            ag_ex again after the world, which shares its namespaces), world and
#            ag_ex healthy again, then the same pour, which must end "succeeded"; a_ta must have
#            reported the power cycle
#   netfault under deploy/compose.netfault.yaml (the fleet is up with it): `roco fault net a_km
#            --delay 0.2` applies and clears netem, or, on a kernel without netem, says so
#   down     `roco down --compose --volumes`: compose down (the project's volumes too), then
#            run.json and the report, each command's duration apart; the run folder stays in runs/
#
# Prints the time of each phase and a closing line "compose_smoke: N passed, N failed".
# Environment: ROCO_BIN (the host's roco, default .venv/bin/roco, else roco on PATH),
#   COMPOSE (the compose command, default `docker compose` if it works, else docker-compose),
#   ROCO_SMOKE_KEEP=1 (leave the fleet up and dockerd running on failure, to look at it).
set -euo pipefail
cd "$(dirname "$0")/.."
repo=$(pwd)

SENTENCE="pour the jar into the bowl"
PROJECT=${ROCO_SMOKE_PROJECT:-rocosmoke}
RUN_NAME=smoke-$(date -u +%Y%m%d-%H%M%S)
work=$(mktemp -d /var/tmp/roco-smoke.XXXXXX)
dockerd_pid=""
compose_up=0
send_pid=""
failed=1

t0=$(date +%s)
phase_start=$t0
timings=()
phase() {  # phase NAME: the phase that just ended, with its time
    local now
    now=$(date +%s)
    timings+=("$(printf '%-8s %4d s' "$1" "$((now - phase_start))")")
    echo "compose_smoke: phase $1 done in $((now - phase_start)) s"
    phase_start=$now
}
say() { echo "compose_smoke: $*"; }

free_port() {
    python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1]); s.close()'
}

finish() {
    local rc=$?
    [ $rc -ne 0 ] && failed=1
    if [ -n "$send_pid" ] && kill -0 "$send_pid" 2>/dev/null; then kill "$send_pid" 2>/dev/null || true; fi
    if [ "$failed" = 1 ] && [ "$compose_up" = 1 ]; then
        say "FAILED: the fleet as it is now"
        $COMPOSE ps || true
        $COMPOSE logs --tail 20 2>&1 | tail -120 || true
        for f in "$repo/runs/$RUN_NAME"/logs/*.log; do
            [ -f "$f" ] && { echo "--- $f (tail)"; tail -5 "$f"; }
        done
    fi
    if [ "${ROCO_SMOKE_KEEP:-0}" = 1 ] && [ "$failed" = 1 ]; then
        say "ROCO_SMOKE_KEEP=1: the fleet (project $PROJECT) and dockerd (pid ${dockerd_pid:-not started here}) are left running"
    else
        if [ "$compose_up" = 1 ]; then $COMPOSE down -v --timeout 20 >/dev/null 2>&1 || true; fi
        if [ -n "$dockerd_pid" ]; then
            kill "$dockerd_pid" 2>/dev/null || true
            for _ in $(seq 60); do kill -0 "$dockerd_pid" 2>/dev/null || break; sleep 0.5; done
        fi
    fi
    rm -rf "$work"
    echo "compose_smoke: timings"
    for line in "${timings[@]}"; do echo "  $line"; done
    echo "  total    $(($(date +%s) - t0)) s"
    if [ "$failed" = 0 ]; then
        echo "compose_smoke: 1 passed, 0 failed"
        exit 0
    fi
    echo "compose_smoke: 0 passed, 1 failed"
    exit 1
}
trap finish EXIT

# --- engine --------------------------------------------------------------------------------
if [ "$(id -u)" != 0 ]; then say "must run as root (it installs and starts the Docker engine)"; exit 1; fi
need=()
command -v dockerd >/dev/null || [ -x /usr/sbin/dockerd ] || need+=(docker.io)
command -v docker-compose >/dev/null || need+=(docker-compose)
command -v debootstrap >/dev/null || need+=(debootstrap)
if [ ${#need[@]} -gt 0 ]; then
    say "installing ${need[*]} from Debian"
    apt-get update -q >/dev/null
    DEBIAN_FRONTEND=noninteractive apt-get install -y -q "${need[@]}" >"$work/apt.log" 2>&1 ||
        { tail -20 "$work/apt.log"; exit 1; }
fi
if ! docker info >/dev/null 2>&1; then
    say "starting dockerd (log /var/tmp/roco-smoke-dockerd.log)"
    /usr/sbin/dockerd >/var/tmp/roco-smoke-dockerd.log 2>&1 &
    dockerd_pid=$!
    for _ in $(seq 120); do docker info >/dev/null 2>&1 && break; sleep 0.5; done
    docker info >/dev/null 2>&1 || { tail -20 /var/tmp/roco-smoke-dockerd.log; say "dockerd did not start"; exit 1; }
fi
if [ -z "${COMPOSE:-}" ]; then
    if docker compose version >/dev/null 2>&1; then COMPOSE="docker compose"; else COMPOSE=docker-compose; fi
fi
COMPOSE="$COMPOSE -f deploy/compose.yaml -f deploy/compose.netfault.yaml -p $PROJECT"
say "engine $(docker version -f '{{.Server.Version}}'), compose: $COMPOSE"
ROCO_BIN=${ROCO_BIN:-}
if [ -z "$ROCO_BIN" ]; then
    if [ -x .venv/bin/roco ]; then ROCO_BIN=.venv/bin/roco; else ROCO_BIN=$(command -v roco || true); fi
fi
[ -n "$ROCO_BIN" ] || { say "no roco on the host (python3 -m venv .venv && .venv/bin/pip install -e .)"; exit 1; }
phase engine

# --- build ---------------------------------------------------------------------------------
PYTHON=${PYTHON:-$(dirname "$ROCO_BIN")/python}
[ -x "$PYTHON" ] || PYTHON=python3
PYTHON=$PYTHON bash scripts/build_image.sh
runtime_image=${ROCO_IMAGE:-roco:latest}
runtime_mb=$(docker image inspect -f '{{.Size}}' "$runtime_image" | awk '{printf "%d", ($1 + 999999) / 1e6}')
if [ "$runtime_mb" -le 1000 ]; then
    say "runtime image $runtime_image $runtime_mb MB ≤ 1000 MB"
else
    say "runtime image $runtime_image $runtime_mb MB > 1000 MB"; exit 1
fi
phase build

# --- up ------------------------------------------------------------------------------------
router_port=$(free_port)
export ROCO_RUN=$RUN_NAME ROCO_RUNS="$repo/runs" ROCO_ROUTER_PUBLISH="127.0.0.1:$router_port"
export ROCO_VIEWER_WEB_PORT ROCO_VIEWER_GRPC_PORT
ROCO_VIEWER_WEB_PORT=$(free_port)
ROCO_VIEWER_GRPC_PORT=$(free_port)
# access control on, as by default: the one-shot `certs` service issues the deployment's
# credentials into ROCO_CERTS; the host's roco talks to the router as `operator` over mutual TLS
export ROCO_CERTS="$work/certs"
endpoint="tls/127.0.0.1:$router_port"
roco_host() { ROCO_SECURITY="$ROCO_CERTS" "$ROCO_BIN" "$@"; }
run_dir="$repo/runs/$RUN_NAME"
# the services run as the image's user (not root): the host folders they write are its own
owner="${ROCO_UID:-10001}:${ROCO_GID:-10001}"
mkdir -p "$ROCO_CERTS" "$run_dir"
chown "$owner" "$ROCO_CERTS" "$run_dir"
$COMPOSE down -v --timeout 5 >/dev/null 2>&1 || true  # a project left over by an earlier run
compose_up=1
$COMPOSE up -d >"$work/up.log" 2>&1 || { cat "$work/up.log"; exit 1; }
phase up

# --- healthy -------------------------------------------------------------------------------
services=(router recorder world a_km a_pl a_co ag_ex a_ta a_hi viewer)
declare -A cid
for s in "${services[@]}"; do
    cid[$s]=$($COMPOSE ps -q "$s")
    [ -n "${cid[$s]}" ] || { say "no container for $s"; exit 1; }
done
health() { docker inspect -f '{{if .State.Health}}{{.State.Health.Status}}{{else}}{{.State.Status}}{{end}}' "${cid[$1]}" 2>/dev/null || echo missing; }
deadline=$(($(date +%s) + 300))
while :; do
    pending=()
    for s in "${services[@]}"; do [ "$(health "$s")" = healthy ] || pending+=("$s"); done
    [ ${#pending[@]} -eq 0 ] && break
    if [ "$(date +%s)" -gt "$deadline" ]; then say "not healthy after 300 s: ${pending[*]}"; exit 1; fi
    sleep 1
done
say "all healthy $(( $(date +%s) - phase_start )) s after up"
# each service limited, none root (its user: the image's or ROCO_UID's)
for s in "${services[@]}"; do
    read -r user mem cpus pids < <(docker inspect -f \
        '{{.Config.User}} {{.HostConfig.Memory}} {{.HostConfig.NanoCpus}} {{.HostConfig.PidsLimit}}' "${cid[$s]}")
    case "${user%%:*}" in ""|0|root) say "$s runs as root (user '$user')"; exit 1 ;; esac
    for limit in "$mem" "$cpus" "$pids"; do
        case "$limit" in ""|0|"<nil>"|"<no value>"|-1) say "$s has no limit (memory $mem, nano-CPUs $cpus, PIDs $pids)"; exit 1 ;; esac
    done
done
say "every service runs as $(docker inspect -f '{{.Config.User}}' "${cid[a_km]}"), within its memory, CPU and PIDs limits"
# each service in the image it needs (deploy/compose.yaml: the robot image has Mesa, the viewer
# image the Rerun CLI)
for s in "${services[@]}"; do
    case "$s" in
        ag_ex) want=${ROCO_ROBOT_IMAGE:-roco-robot:latest} ;;
        recorder|viewer) want=${ROCO_VIEWER_IMAGE:-roco-viewer:latest} ;;
        *) want=$runtime_image ;;
    esac
    image=$(docker inspect -f '{{.Config.Image}}' "${cid[$s]}")
    [ "$image" = "$want" ] || { say "$s runs $image, not $want"; exit 1; }
done
say "ag_ex runs ${ROCO_ROBOT_IMAGE:-roco-robot:latest}, the recorder and the viewer ${ROCO_VIEWER_IMAGE:-roco-viewer:latest}, the others $runtime_image"
roco_host status --router "$endpoint"
# what an operator reads: the agents' logs in `compose logs`, the router's at INFO, rotation
$COMPOSE logs --no-color a_km >"$work/a_km.out" 2>&1
grep -q 'a_km INFO ready: roles set up' "$work/a_km.out" ||
    { tail -20 "$work/a_km.out"; say "compose logs a_km does not show the agent's log"; exit 1; }
$COMPOSE logs --no-color router >"$work/router.out" 2>&1
if grep -E ' (DEBUG|TRACE) |tls handshake eof' "$work/router.out"; then
    say "the router's log has DEBUG/TRACE lines or health-probe warnings"; exit 1
fi
for s in "${services[@]}"; do
    rotation=$(docker inspect -f '{{.HostConfig.LogConfig.Type}} {{index .HostConfig.LogConfig.Config "max-size"}}' "${cid[$s]}")
    [ "$rotation" = "json-file 10m" ] || { say "$s: log not rotated ($rotation)"; exit 1; }
done
say "compose logs show the agents' lines; the router logs at INFO; every log is rotated"
phase healthy

# --- a network fault under the documented override (deploy/compose.netfault.yaml) --------------
# netem where the host's kernel has it (then cleared); else the error must name the kernel
rc=0
out=$(roco_host fault net a_km --delay 0.2 --compose --project "$PROJECT" --compose-file deploy/compose.yaml \
    --router "$endpoint" --credentials "$ROCO_CERTS" 2>&1) || rc=$?
if [ "$rc" = 0 ]; then
    roco_host fault net a_km --delay 0 --compose --project "$PROJECT" --compose-file deploy/compose.yaml \
        --router "$endpoint" --credentials "$ROCO_CERTS" >/dev/null 2>&1 || { say "roco fault net: the delay was not cleared"; exit 1; }
    say "roco fault net a_km --delay 0.2: applied and cleared"
elif grep -q "kernel has no netem" <<<"$out"; then
    say "roco fault net a_km --delay 0.2: this kernel has no netem, and the error says so"
else
    echo "$out"; say "roco fault net a_km --delay 0.2 failed without naming the kernel"; exit 1
fi
phase netfault

# --- pour, with a_km restarted mid-task ----------------------------------------------------
say "sending \"$SENTENCE\" to $endpoint; run folder $run_dir"
roco_host send --router "$endpoint" --timeout 900 "$SENTENCE" >"$work/send.log" 2>&1 &
send_pid=$!
deadline=$(($(date +%s) + 300))
# the task runs once a_co has sent a_ta plan #1 (the first request on C1)
until grep '"channel":"C1"' "$run_dir/traffic.jsonl" 2>/dev/null | grep -q '"performative":"request"'; do
    kill -0 "$send_pid" 2>/dev/null || { cat "$work/send.log"; say "roco send ended before the task started"; exit 1; }
    [ "$(date +%s)" -le "$deadline" ] || { cat "$work/send.log"; say "the task did not start in 300 s"; exit 1; }
    sleep 0.2
done
say "task started ($(grep -c '' "$run_dir/traffic.jsonl") communicates so far): restarting a_km"
r0=$(date +%s)
$COMPOSE restart a_km >/dev/null 2>&1
until [ "$(health a_km)" = healthy ]; do
    [ $(($(date +%s) - r0)) -le 120 ] || { say "a_km not healthy 120 s after its restart"; exit 1; }
    sleep 0.5
done
say "a_km restarted and healthy again in $(($(date +%s) - r0)) s"
send_rc=0
wait "$send_pid" || send_rc=$?
send_pid=""
tail -3 "$work/send.log"
if [ "$send_rc" != 0 ] || ! tail -1 "$work/send.log" | grep -q '^succeeded:'; then
    say "the pour did not succeed (roco send exit $send_rc)"
    exit 1
fi
kept=$(grep -c 'kept from before' "$run_dir/logs/a_km.log" || true)
[ "$kept" -ge 1 ] || { say "the restarted a_km did not find its store (no 'kept from before' in its log)"; exit 1; }
say "the pour succeeded; the restarted a_km kept its knowledge"
phase pour

# --- a power cycle of the robot: the world restarted, then the pour again -------------------
# (a fresh kitchen, its time from 0; ag_ex shares the world's PID namespace, so the restart
# ends it too: `roco fault restart world` starts it again once the world is back, which Docker's
# restart manager does not do reliably; a_ta must renew a_km's picture of the kitchen)
started_ag_ex=$(docker inspect -f '{{.State.StartedAt}}' "${cid[ag_ex]}")
say "restarting the world (a power cycle of the robot): roco fault restart world"
r0=$(date +%s)
roco_host fault restart world --compose --project "$PROJECT" --compose-file deploy/compose.yaml \
    --router "$endpoint" --credentials "$ROCO_CERTS" >"$work/power.log" 2>&1 ||
    { cat "$work/power.log"; say "roco fault restart world failed"; exit 1; }
grep -q "ag_ex started again after it" "$work/power.log" ||
    { cat "$work/power.log"; say "roco fault restart world did not start ag_ex again"; exit 1; }
until [ "$(health world)" = healthy ] && [ "$(health ag_ex)" = healthy ] &&
    [ "$(docker inspect -f '{{.State.StartedAt}}' "${cid[ag_ex]}")" != "$started_ag_ex" ]; do
    [ $(($(date +%s) - r0)) -le 180 ] || { say "world and ag_ex not back 180 s after the world's restart"; exit 1; }
    sleep 0.5
done
say "world and ag_ex healthy again in $(($(date +%s) - r0)) s; sending \"$SENTENCE\" again"
send_rc=0
roco_host send --router "$endpoint" --timeout 900 "$SENTENCE" >"$work/send2.log" 2>&1 || send_rc=$?
tail -3 "$work/send2.log"
if [ "$send_rc" != 0 ] || ! tail -1 "$work/send2.log" | grep -q '^succeeded:'; then
    say "the pour after the power cycle did not succeed (roco send exit $send_rc)"
    exit 1
fi
grep -q "ag_ex's robot was power-cycled" "$run_dir/logs/a_ta.log" ||
    { say "a_ta did not report the power cycle"; exit 1; }
say "the pour after the power cycle succeeded; a_ta reported the power cycle"
phase power

# --- down, as an operator ends a session: roco down --compose --------------------------------
roco_host down --compose --project "$PROJECT" --compose-file deploy/compose.yaml --volumes \
    --router "$endpoint" --credentials "$ROCO_CERTS" >"$work/down.log" 2>&1 || { cat "$work/down.log"; exit 1; }
compose_up=0
tail -3 "$work/down.log"
if [ -s "$run_dir/recording.rrd" ]; then
    say "Rerun recording $(du -h "$run_dir/recording.rrd" | cut -f1)"
else
    say "no merged Rerun recording in $run_dir (not a failure)"
fi
# the report of the session, each of its two commands' durations apart
grep -q '^| Task durations |' "$run_dir/report.md" ||
    { say "roco down --compose wrote no report with each command's duration"; exit 1; }
say "roco down --compose wrote $run_dir/report.md"
phase down
failed=0
