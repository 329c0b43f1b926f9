#!/usr/bin/env bash
# Build roco's images (deploy/Dockerfile's targets runtime, viewer and robot) where the build can
# reach no registry (robots, CI):
#
#   1. wheelhouse: the wheels of roco's dependencies for Linux x86_64 / CPython 3.11, made on
#      this host with pip (PyPI must be reachable from the host once; the build needs nothing)
#      into deploy/wheelhouse/ (git-ignored); skipped while it matches pyproject.toml;
#   2. base images: python:3.11-slim if it is here or can be pulled (both stages); else two made
#      once each with debootstrap (Debian bookworm) and `docker import`: the runtime base
#      roco-base:bookworm-<hash of its package list> (python3, libgomp1, iproute2) and the build
#      base (the same with python3-venv, Python's headers, g++ and the software EGL MuJoCo
#      renders the head camera with, which the robot target copies from it);
#   3. docker build --network host --build-arg BASE=<runtime base> --build-arg
#      BUILD_BASE=<build base> -f deploy/Dockerfile, with the wheelhouse served on 127.0.0.1 for
#      the build's `pip install --no-index --find-links`, three times, one target after the
#      other (the legacy builder reuses the stages built before): --target runtime tagged TAG,
#      viewer (runtime + the Rerun CLI) tagged VIEWER_TAG, robot (runtime + Mesa) tagged
#      ROBOT_TAG; each also with its repository and the version in pyproject.toml (roco:latest
#      and roco:0.1.0, roco-viewer:latest and roco-viewer:0.1.0, ...). Prints each one's size
#      (docker's Size, as `docker images` shows it, 1 MB = 10^6 bytes).
#
# Usage: scripts/build_image.sh [--tag IMAGE] [--base IMAGE] [--mirror URI] [--refresh-wheelhouse]
#                               [--no-cache]
# Environment: ROCO_IMAGE (TAG, default roco:latest); ROCO_VIEWER_IMAGE, ROCO_ROBOT_IMAGE
#   (VIEWER_TAG, ROBOT_TAG; default TAG's repository with -viewer, -robot: roco-viewer:latest,
#   roco-robot:latest, as deploy/compose.yaml runs them); ROCO_BASE (runtime base image, default as
#   in 2); ROCO_BUILD_BASE (build base, default: ROCO_BASE if set, else as in 2);
#   ROCO_LOCAL_BASE, ROCO_LOCAL_BUILD_BASE (default roco-base:bookworm-<hash>);
#   DEBIAN_MIRROR (the Debian mirror for debootstrap, as --mirror; default: the one this host's
#   apt uses, scripts/apt_mirror.py); ROCO_BASE_PACKAGES, ROCO_BUILD_BASE_PACKAGES (Debian
#   packages of the local bases); ROCO_WHEEL_PORT (loopback port the wheelhouse is served on,
#   default 7449); PYTHON (host Python with pip, default python3); DOCKER (default docker).
# Before phase 1 it checks that an engine answers and that the bases are here, can be pulled, or
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
BUILD_BASE=${ROCO_BUILD_BASE:-}  # none: the runtime base, or the local build base (phase 2)
MIRROR=${DEBIAN_MIRROR:-}  # none: this host's apt configuration names it (phase 2)
# the runtime stage's base: what roco runs with, no compiler, no headers
BASE_PACKAGES=${ROCO_BASE_PACKAGES:-python3,libgomp1,iproute2}
# the build stage's base: the same with the venv module, Python's headers, g++ and Mesa's EGL
# (the robot target takes Mesa's files from it: deploy/mesa_files.py)
BUILD_BASE_PACKAGES=${ROCO_BUILD_BASE_PACKAGES:-python3,python3-venv,python3-dev,g++,libgomp1,iproute2,libegl1,libegl-mesa0,libgl1-mesa-dri,libgl1,libopengl0}
# a local base's tag names its package list: another list makes another base
base_tag() { printf 'roco-base:bookworm-%s' "$(printf '%s' "$1" | sha256sum | cut -c1-8)"; }
LOCAL_BASE=${ROCO_LOCAL_BASE:-$(base_tag "$BASE_PACKAGES")}
LOCAL_BUILD_BASE=${ROCO_LOCAL_BUILD_BASE:-$(base_tag "$BUILD_BASE_PACKAGES")}
# the image's version tag, beside TAG: the version in pyproject.toml
VERSION=""
while IFS= read -r line; do
    case "$line" in 'version = "'*'"') VERSION=${line#version = \"}; VERSION=${VERSION%\"}; break ;; esac
done < pyproject.toml
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
        -h|--help) sed -n '2,41p' "$0"; exit 0 ;;
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

[ -n "$VERSION" ] || { echo "build_image.sh: no version = \"...\" line in pyproject.toml" >&2; exit 1; }
repository_of() {  # repository_of IMAGE: IMAGE without its :tag (a registry's host:port/ kept)
    case "${1##*/}" in *:*) printf '%s' "${1%:*}" ;; *) printf '%s' "$1" ;; esac
}
tag_of() {  # tag_of IMAGE: IMAGE's tag (latest when it has none)
    case "${1##*/}" in *:*) printf '%s' "${1##*:}" ;; *) printf latest ;; esac
}
repository=$(repository_of "$TAG")
VIEWER_TAG=${ROCO_VIEWER_IMAGE:-$repository-viewer:$(tag_of "$TAG")}
ROBOT_TAG=${ROCO_ROBOT_IMAGE:-$repository-robot:$(tag_of "$TAG")}
# each image also gets its repository with the version: roco:0.1.0, roco-viewer:0.1.0, ...
VERSION_TAG=$repository:$VERSION

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
        echo "build_image.sh: no python:3.11-slim here, and none can be pulled: the bases are $LOCAL_BASE and $LOCAL_BUILD_BASE"
        BASE=$LOCAL_BASE
    fi
fi
if [ -z "$BUILD_BASE" ]; then
    if [ "$BASE" = "$LOCAL_BASE" ]; then BUILD_BASE=$LOCAL_BUILD_BASE; else BUILD_BASE=$BASE; fi
fi
to_make=()  # "TAG PACKAGES" of each local base still to make
for image in "$BASE" "$BUILD_BASE"; do
    have_image "$image" && continue
    case "$image" in
        "$LOCAL_BASE") to_make+=("$LOCAL_BASE $BASE_PACKAGES") ;;
        "$LOCAL_BUILD_BASE") to_make+=("$LOCAL_BUILD_BASE $BUILD_BASE_PACKAGES") ;;
        *) echo "build_image.sh: base image $image is not here and cannot be pulled" >&2; exit 1 ;;
    esac
done
if [ ${#to_make[@]} -gt 0 ]; then
    command -v debootstrap >/dev/null || {
        echo "build_image.sh: making ${to_make[0]%% *} needs debootstrap (apt-get install debootstrap)" >&2
        exit 1
    }
    [ "$(id -u)" = 0 ] || {
        echo "build_image.sh: making ${to_make[0]%% *} with debootstrap needs root" >&2
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

# 2. the base images (chosen, and their tools checked, before phase 1) ----------------------
make_base() {  # make_base TAG PACKAGES: debootstrap --variant=minbase, then docker import
    local tag=$1 packages=$2
    if [ -z "$MIRROR" ]; then
        # the mirror this host's apt uses (sources.list, sources.list.d/*.list and *.sources)
        MIRROR=$("$PYTHON" scripts/apt_mirror.py --suite bookworm) || exit 1
        echo "build_image.sh: Debian mirror from this host's apt configuration: $MIRROR"
    fi
    echo "build_image.sh: making the base $tag with debootstrap ($MIRROR)"
    rootfs="$work/rootfs"
    mkdir -p "$rootfs"
    # dpkg on a tmpfs: ≈ 3× faster than on this kind of VM's disk
    mount -t tmpfs -o size=4g,mode=0755 roco-rootfs "$rootfs" 2>/dev/null || true
    live_status "build_image.sh: phase base" "$work/debootstrap.log" \
        debootstrap --variant=minbase --include="$packages" bookworm "$rootfs" "$MIRROR" || {
        tail -20 "$work/debootstrap.log" >&2
        echo "build_image.sh: debootstrap failed" >&2
        exit 1
    }
    # a smaller base: no package lists, caches, docs, man pages, translations or logs
    rm -rf "$rootfs"/var/lib/apt/lists/* "$rootfs"/var/cache/apt/*.bin "$rootfs"/var/cache/apt/archives/*.deb \
        "$rootfs"/usr/share/doc/* "$rootfs"/usr/share/man/* "$rootfs"/usr/share/info/* \
        "$rootfs"/usr/share/locale/* "$rootfs"/var/log/*.log
    tar -C "$rootfs" --numeric-owner -c . | "$DOCKER" import \
        --change 'ENV PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin' \
        --change 'ENV LANG=C.UTF-8' \
        --change 'CMD ["/bin/bash"]' \
        -m "debootstrap --variant=minbase --include=$packages bookworm" \
        - "$tag" >/dev/null
    if mountpoint -q "$rootfs"; then umount "$rootfs"; fi
    rm -rf "$rootfs"
    rootfs=""
    echo "build_image.sh: made $tag ($("$DOCKER" image inspect -f '{{.Size}}' "$tag" | awk '{printf "%.0f MB", $1/1e6}'))"
}
for entry in "${to_make[@]}"; do make_base "${entry%% *}" "${entry#* }"; done
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
build_target() {  # build_target TARGET IMAGE: deploy/Dockerfile's TARGET, tagged IMAGE and its version
    local target=$1 image=$2
    local version_tag
    version_tag=$(repository_of "$image"):$VERSION
    echo "build_image.sh: building $image ($version_tag, target $target) on $BASE, compiled on $BUILD_BASE (log: $work/build-$target.log)"
    live_status "build_image.sh: phase build $target" "$work/build-$target.log" \
        "$DOCKER" build "${NO_CACHE[@]}" --network host --target "$target" \
        --build-arg BASE="$BASE" \
        --build-arg BUILD_BASE="$BUILD_BASE" \
        --build-arg WHEELS="http://127.0.0.1:$PORT/" \
        --build-arg WHEELHOUSE_ID="$wheelhouse_id" \
        -f deploy/Dockerfile -t "$image" -t "$version_tag" . || {
        tail -40 "$work/build-$target.log" >&2
        cp "$work/build-$target.log" /tmp/roco-build-image.log
        echo "build_image.sh: docker build --target $target failed (whole log: /tmp/roco-build-image.log)" >&2
        exit 1
    }
}
build_target runtime "$TAG"
NO_CACHE=()  # the next targets reuse the stages just built
build_target viewer "$VIEWER_TAG"
build_target robot "$ROBOT_TAG"
kill "$server_pid"; wait "$server_pid" 2>/dev/null || true; server_pid=""
phase build
megabytes() { "$DOCKER" image inspect -f '{{.Size}}' "$1" | awk '{printf "%.0f", $1 / 1e6}'; }
runtime_mb=$(megabytes "$TAG")
user=$("$DOCKER" image inspect -f '{{.Config.User}}' "$TAG")
echo "build_image.sh: built on $BASE in $(($(date +%s) - t_start)) s, each runs as user $user:"
echo "build_image.sh:   $TAG ($VERSION_TAG): $runtime_mb MB"
for image in "$VIEWER_TAG" "$ROBOT_TAG"; do
    mb=$(megabytes "$image")
    echo "build_image.sh:   $image ($(repository_of "$image"):$VERSION): $mb MB, $TAG + $((mb - runtime_mb)) MB"
done
