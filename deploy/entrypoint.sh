#!/bin/sh
# roco's container entrypoint: settle which run this container belongs to, then exec the
# service's command (so that it gets the signals Docker sends).
#
# A run is one life of the fleet: it starts when the router's container is created. The router
# (ROCO_NEW_RUN=1) names it ROCO_RUN if that is set, else by the UTC time
# (YYYYmmdd-HHMMSS, as `roco run` names run folders), and writes the name to
# $ROCO_FLEET_DIR/run (a volume every roco service mounts); a restart of the same router
# container keeps the name. Every other service reads it there (ROCO_RUN overrides).
# Then "{run}" in ROCO_RUN_DIR, ROCO_KM_STORE and ROCO_STATE_DIR is replaced by
# the name, so a restarted agent continues in the same run folder with the same store, and a
# new fleet (docker compose down && up) starts with a fresh one, as the simulated kitchen does.
#
# The services run as the image's user roco (uid 10001) or ROCO_UID: a run folder it cannot
# write (the host's ROCO_RUNS belongs to another uid) stops the service with one line saying so.
set -eu

cannot_write() {  # cannot_write PATH: the line that says whose folder it must be, then exit 2
    echo "roco-entrypoint: cannot write $1 as uid $(id -u): make the host folder mounted there" \
        "(ROCO_RUNS) writable by uid $(id -u), or run as its owner (ROCO_UID, ROCO_GID; docs/deploy.md)" >&2
    exit 2
}

fleet_dir=${ROCO_FLEET_DIR:-/var/lib/roco/fleet}
run=${ROCO_RUN:-}
case "$run" in
    *[!A-Za-z0-9._-]*) echo "roco-entrypoint: ROCO_RUN=$run: use letters, digits, '.', '_', '-'" >&2; exit 2 ;;
esac

uses_run() {
    for value in "${ROCO_RUN_DIR:-}" "${ROCO_KM_STORE:-}" "${ROCO_STATE_DIR:-}"; do
        case "$value" in *"{run}"*) return 0 ;; esac
    done
    return 1
}

if [ "${ROCO_NEW_RUN:-0}" = 1 ]; then
    mkdir -p "$fleet_dir"
    marker=/var/tmp/roco-run  # in the container's own layer: survives a restart, not a re-creation
    if [ -s "$marker" ]; then
        run=$(cat "$marker")
    elif [ -z "$run" ]; then
        stamp=$(date -u +%Y%m%d-%H%M%S)
        run=$stamp
        n=1
        while [ -e "/runs/$run" ]; do run="$stamp-$n"; n=$((n + 1)); done
    fi
    printf '%s\n' "$run" > "$marker"
    printf '%s\n' "$run" > "$fleet_dir/run.tmp" && mv "$fleet_dir/run.tmp" "$fleet_dir/run"
    echo "roco-entrypoint: run $run" >&2
elif [ -z "$run" ] && uses_run; then
    waited=0
    while [ ! -s "$fleet_dir/run" ]; do  # the router writes it before it is healthy
        if [ "$waited" -ge 120 ]; then
            echo "roco-entrypoint: no run name in $fleet_dir/run after 120 s (is the router up?)" >&2
            exit 2
        fi
        sleep 1
        waited=$((waited + 1))
    done
    run=$(cat "$fleet_dir/run")
fi

if [ -n "$run" ]; then
    for var in ROCO_RUN_DIR ROCO_KM_STORE ROCO_STATE_DIR; do
        eval "value=\${$var:-}"
        case "$value" in
            *"{run}"*) export "$var=$(printf '%s' "$value" | sed "s|{run}|$run|g")" ;;
        esac
    done
    export ROCO_RUN="$run"
fi
if [ -n "${ROCO_RUN_DIR:-}" ]; then
    mkdir -p "$ROCO_RUN_DIR/logs" 2>/dev/null && [ -w "$ROCO_RUN_DIR/logs" ] || cannot_write "$ROCO_RUN_DIR"
    if [ "${ROCO_NEW_RUN:-0}" = 1 ] && [ ! -e "$ROCO_RUN_DIR/run.json" ]; then
        # run.json as `roco up` writes it (the run's start, for `roco report`); never fatal
        python -c '
import os, sys, time
from pathlib import Path
from services.runtime.run_folder import RunInfo, write_run_info
env, pose = os.environ, os.environ.get("ROCO_POSE_SEED", "")
write_run_info(Path(sys.argv[1]), RunInfo(
    started=time.time(), router=env.get("ROCO_ROUTER", ""), realtime=env.get("ROCO_REALTIME") == "1",
    seed=int(env.get("ROCO_SEED") or 0), pose_seed=int(pose) if pose else None))
' "$ROCO_RUN_DIR" || echo "roco-entrypoint: run.json not written" >&2
    fi
fi

# not ready until the service says so (ROCO_READY_FILE, read by the health check): a file left
# in the container's layer by the service's last life does not speak for this one
if [ -n "${ROCO_READY_FILE:-}" ]; then rm -f "$ROCO_READY_FILE"; fi

exec "$@"
