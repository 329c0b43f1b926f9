#!/usr/bin/env bash
# Build roco's image (deploy/Dockerfile) where the build can reach no registry (robots, CI):
#
#   1. wheelhouse: the wheels of roco's dependencies for Linux x86_64 / CPython 3.11, made on
#      this host with pip (PyPI must be reachable from the host once; the build needs nothing)
#      into deploy/wheelhouse/ (git-ignored); skipped while it matches pyproject.toml;
#   2. base image: python:3.11-slim if it is here or can be pulled; else roco-base:bookworm-<hash
#      of its package list>, made once with debootstrap (Debian bookworm: its python3.11,
#      libgomp1, iproute2 and the software EGL MuJoCo renders the head camera with) and
#      `docker import`;
#   3. docker build --network host --build-arg BASE=<base> -f deploy/Dockerfile, with the
#      wheelhouse served on 127.0.0.1 for the build's `pip install --no-index --find-links`.
#
# Usage: scripts/build_image.sh [--tag IMAGE] [--base IMAGE] [--mirror URI] [--refresh-wheelhouse]
#                               [--no-cache]
# Environment: ROCO_IMAGE (tag, default roco:latest); ROCO_BASE (base image, default as in 2);
#   ROCO_LOCAL_BASE (default roco-base:bookworm-<hash>); DEBIAN_MIRROR (the Debian mirror for
#   debootstrap, as --mirror; default: the one this host's apt uses, scripts/apt_mirror.py);
#   ROCO_BASE_PACKAGES (Debian packages of the local base); ROCO_WHEEL_PORT (loopback port the
#   wheelhouse is served on, default 7449); PYTHON (host Python with pip, default python3);
#   DOCKER (default docker).
# Before phase 1 it checks that an engine answers and that the base is here, can be pulled, or
# can be made (debootstrap, as root); each missing one is named at once (`roco doctor --compose`
# lists them all). Prints the time of each phase; on a terminal,
# a status line shows the running phase, its seconds and its log's last line
# (scripts/live_status.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
# shellcheck source=scripts/live_status.sh
. scripts/live_status.sh

TAG=${ROCO_IMAGE:-roco:latest}
BASE=${ROCO_BASE:-}
MIRROR=${DEBIAN_MIRROR:-}  # none: this host's apt configuration names it (phase 2)
BASE_PACKAGES=${ROCO_BASE_PACKAGES:-python3,python3-venv,python3-dev,g++,libgomp1,iproute2,libegl1,libegl-mesa0,libgl1-mesa-dri,libgl1,libopengl0}
# the local base's tag names its package list: another list makes another base
LOCAL_BASE=${ROCO_LOCAL_BASE:-roco-base:bookworm-$(printf '%s' "$BASE_PACKAGES" | sha256sum | cut -c1-8)}
PORT=${ROCO_WHEEL_PORT:-7449}
PYTHON=${PYTHON:-python3}
DOCKER=${DOCKER:-docker}
WHEELHOUSE=deploy/wheelhouse
REFRESH=0
NO_CACHE=()
while [ $# -gt 0 ]; do
    case "$1" in
        --tag) TAG=$2; shift 2 ;;
        --base) BASE=$2; shift 2 ;;
        --mirror) MIRROR=$2; shift 2 ;;
        --refresh-wheelhouse) REFRESH=1; shift ;;
        --no-cache) NO_CACHE=(--no-cache); shift ;;
        -h|--help) sed -n '2,26p' "$0"; exit 0 ;;
        *) echo "build_image.sh: unknown argument $1" >&2; exit 2 ;;
    esac
done

# the wheelhouse's target: deploy/Dockerfile's Python (3.11) on Debian bookworm (glibc 2.36);
# pip does not widen --platform to older manylinux tags by itself: every one is listed
PIP_TARGET=(--only-binary=:all: --python-version 3.11 --implementation cp --abi cp311 --abi abi3 --abi none)
for glibc in $(seq 36 -1 17); do PIP_TARGET+=(--platform "manylinux_2_${glibc}_x86_64"); done
PIP_TARGET+=(--platform manylinux2014_x86_64 --platform manylinux2010_x86_64 --platform manylinux1_x86_64)

work=$(mktemp -d /var/tmp/roco-build.XXXXXX)
server_pid=""
rootfs=""
cleanup() {
    if [ -n "$server_pid" ]; then kill "$server_pid" 2>/dev/null || true; wait "$server_pid" 2>/dev/null || true; fi
    if [ -n "$rootfs" ] && mountpoint -q "$rootfs"; then umount "$rootfs" || true; fi
    rm -rf "$work"
}
trap cleanup EXIT

t_start=$(date +%s)
phase_start=$t_start
phase() {  # phase NAME: print how long the phase that just ended took
    local now
    now=$(date +%s)
    printf 'build_image.sh: phase %-10s %4d s\n' "$1" "$((now - phase_start))"
    phase_start=$now
}

# before anything takes time: an engine that answers, and the base image or what makes it
"$DOCKER" version >/dev/null 2>&1 || {
    echo "build_image.sh: no Docker engine answers '$DOCKER version' (apt-get install docker.io; start it:" \
        "systemctl start docker, or without systemd: service docker start, or dockerd &)" >&2
    exit 1
}
have_image() { "$DOCKER" image inspect "$1" >/dev/null 2>&1; }
if [ -z "$BASE" ]; then
    if have_image python:3.11-slim || timeout 120 "$DOCKER" pull -q python:3.11-slim >/dev/null 2>&1; then
        BASE=python:3.11-slim
    else
        echo "build_image.sh: no python:3.11-slim here, and none can be pulled: the base is $LOCAL_BASE"
        BASE=$LOCAL_BASE
    fi
fi
if ! have_image "$BASE"; then
    if [ "$BASE" != "$LOCAL_BASE" ]; then
        echo "build_image.sh: base image $BASE is not here and cannot be pulled" >&2
        exit 1
    fi
    command -v debootstrap >/dev/null || {
        echo "build_image.sh: making $LOCAL_BASE needs debootstrap (apt-get install debootstrap)" >&2
        exit 1
    }
    [ "$(id -u)" = 0 ] || {
        echo "build_image.sh: making $LOCAL_BASE with debootstrap needs root" >&2
        exit 1
    }
fi

# 1. the wheelhouse -----------------------------------------------------------------------
mkdir -p "$WHEELHOUSE"
stamp="$WHEELHOUSE/.pyproject.sha256"
want=$(sha256sum pyproject.toml | cut -d' ' -f1)
if [ "$REFRESH" = 0 ] && [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ]; then
    echo "build_image.sh: the wheelhouse matches pyproject.toml ($(find "$WHEELHOUSE" -name '*.whl' | wc -l) wheels)"
else
    # pip reuses a file of the same name already in the target folder: an old roco wheel would
    # bring roco's old dependencies (a new one, e.g. cryptography, went missing)
    rm -f "$stamp" "$WHEELHOUSE"/roco-*.whl
    # roco's own wheel, to resolve its dependencies (the image installs roco from the source)
    make_wheelhouse() {
        # (ROCO_BUILD_NATIVE=0: this wheel only names the dependencies, nothing is compiled)
        ROCO_BUILD_NATIVE=0 "$PYTHON" -m pip wheel --no-deps --disable-pip-version-check -w "$work/roco" . &&
            "$PYTHON" -m pip download --disable-pip-version-check -d "$WHEELHOUSE" "${PIP_TARGET[@]}" \
                "$work"/roco/roco-*.whl wheel $("$PYTHON" -c 'import tomllib; print(" ".join(tomllib.load(open("pyproject.toml", "rb"))["build-system"]["requires"]))')
    }
    live_status "build_image.sh: phase wheelhouse" "$work/pip.log" make_wheelhouse || {
        grep -v '^WARNING: Location' "$work/pip.log" | tail -20 >&2
        echo "build_image.sh: making the wheelhouse failed" >&2
        exit 1
    }
    echo "$want" > "$stamp"
    echo "build_image.sh: wheelhouse $WHEELHOUSE: $(find "$WHEELHOUSE" -name '*.whl' | wc -l) wheels, $(du -sh "$WHEELHOUSE" | cut -f1)"
fi
phase wheelhouse

# 2. the base image (chosen, and its tools checked, before phase 1) --------------------------
if ! have_image "$BASE"; then
    if [ -z "$MIRROR" ]; then
        # the mirror this host's apt uses (sources.list, sources.list.d/*.list and *.sources)
        MIRROR=$("$PYTHON" scripts/apt_mirror.py --suite bookworm) || exit 1
        echo "build_image.sh: Debian mirror from this host's apt configuration: $MIRROR"
    fi
    echo "build_image.sh: making the base $LOCAL_BASE with debootstrap ($MIRROR)"
    rootfs="$work/rootfs"
    mkdir -p "$rootfs"
    # dpkg on a tmpfs: ≈ 3× faster than on this kind of VM's disk
    mount -t tmpfs -o size=4g,mode=0755 roco-rootfs "$rootfs" 2>/dev/null || true
    live_status "build_image.sh: phase base" "$work/debootstrap.log" \
        debootstrap --variant=minbase --include="$BASE_PACKAGES" bookworm "$rootfs" "$MIRROR" || {
        tail -20 "$work/debootstrap.log" >&2
        echo "build_image.sh: debootstrap failed" >&2
        exit 1
    }
    # a smaller base: no package lists, caches, docs, man pages or logs
    rm -rf "$rootfs"/var/lib/apt/lists/* "$rootfs"/var/cache/apt/*.bin "$rootfs"/var/cache/apt/archives/*.deb \
        "$rootfs"/usr/share/doc/* "$rootfs"/usr/share/man/* "$rootfs"/usr/share/info/* "$rootfs"/var/log/*.log
    tar -C "$rootfs" --numeric-owner -c . | "$DOCKER" import \
        --change 'ENV PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin' \
        --change 'ENV LANG=C.UTF-8' \
        --change 'CMD ["/bin/bash"]' \
        -m "debootstrap --variant=minbase --include=$BASE_PACKAGES bookworm" \
        - "$LOCAL_BASE" >/dev/null
    if mountpoint -q "$rootfs"; then umount "$rootfs"; fi
    rootfs=""
    echo "build_image.sh: made $LOCAL_BASE ($("$DOCKER" image inspect -f '{{.Size}}' "$LOCAL_BASE" | awk '{printf "%.0f MB", $1/1e6}'))"
fi
phase base

# 3. the image ----------------------------------------------------------------------------
if (exec 3<>"/dev/tcp/127.0.0.1/$PORT") 2>/dev/null; then
    echo "build_image.sh: port $PORT on 127.0.0.1 is taken; set ROCO_WHEEL_PORT" >&2
    exit 1
fi
"$PYTHON" -m http.server --bind 127.0.0.1 --directory "$WHEELHOUSE" "$PORT" > "$work/http.log" 2>&1 &
server_pid=$!
for _ in $(seq 50); do (exec 3<>"/dev/tcp/127.0.0.1/$PORT") 2>/dev/null && break; sleep 0.1; done
wheelhouse_id=$(find "$WHEELHOUSE" -name '*.whl' -printf '%f %s\n' | sort | sha256sum | cut -c1-16)
echo "build_image.sh: building $TAG on $BASE (log: $work/build.log)"
live_status "build_image.sh: phase build" "$work/build.log" \
    "$DOCKER" build "${NO_CACHE[@]}" --network host \
    --build-arg BASE="$BASE" \
    --build-arg WHEELS="http://127.0.0.1:$PORT/" \
    --build-arg WHEELHOUSE_ID="$wheelhouse_id" \
    -f deploy/Dockerfile -t "$TAG" . || {
    tail -40 "$work/build.log" >&2
    cp "$work/build.log" /tmp/roco-build-image.log
    echo "build_image.sh: docker build failed (whole log: /tmp/roco-build-image.log)" >&2
    exit 1
}
kill "$server_pid"; wait "$server_pid" 2>/dev/null || true; server_pid=""
phase build
size=$("$DOCKER" image inspect -f '{{.Size}}' "$TAG" | awk '{printf "%.0f MB", $1/1e6}')
echo "build_image.sh: $TAG built on $BASE ($size) in $(($(date +%s) - t_start)) s"
