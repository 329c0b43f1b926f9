"""``deploy/compose.yaml`` rendered from the specification (docs/deploy.md).

The file runs the fleet in containers: the one-shot ``certs`` service, the Zenoh router, the
traffic recorder, one service per agent of the specification, the ``world`` (the simulated
kitchen, when an agent drives it) and a Rerun web viewer, from the images of deploy/Dockerfile
(:data:`IMAGES`: the runtime image for most, the robot image for the agent that plays the
robot, ag_ex, the viewer image for the viewer and the recorder). The services
that are not agents, the shared settings (the ``x-roco`` and ``x-env`` anchors) and the
file's comments are this module's text; the agents' services follow from the specification:

- one service per agent, in the specification's start order (``SystemSpec.launch_order``),
  running ``python -m services.runtime.main NAME`` after the certificates, the router and the
  recorder, healthy once the agent is ready (its roles set up and the agents it asks seen:
  it writes :data:`READY_FILE`, which the check reads);
- the agent the specification's ``start_order`` names last (a_hi: a person's command is taken
  once the others are there) waits until every other agent is healthy;
- what an agent's container needs beyond that is stated here, once, in :data:`AGENT_EXTRAS`
  and :data:`ROBOT_EXTRAS` (:func:`agent_extras`): its image when not the runtime one (the
  robot's, ag_ex: the robot image, with Mesa for the head camera), a named volume for what it
  keeps across restarts (a_km's knowledge, a_co's accepted commands), Linux capabilities (none
  has one now: the services are not root) and the robot's hardware it drives (the robot's:
  the ``world`` service, the simulated kitchen of velma/world/, whose shared memory and
  processes its container shares, so that the robot link between them works and neither
  takes the other's link for an orphan). A system without a robot has no world and no robot
  image.

Where the file finds the system and the host's folders is its :class:`~services.deploy.layout.
Layout`: the kitchen's file (:data:`~services.deploy.layout.KITCHEN`) builds the images from
roco's checkout; another system's runs them as they are, mounts the system's folder
read-only in every roco service, sets ``ROCO_SPEC`` to its specification there (in ``x-env``
and in ``certs``, which so issues that system's identities) and opens with
:data:`SYSTEM_COMMENT` (services/deploy/layout.py). ``--check`` names the difference it can:
an agent's service, an identity's mount, the system's folder, ``ROCO_SPEC``
(:func:`named_difference`).

Least privilege for the credentials (:func:`credentials`): only ``certs`` mounts the whole
folder (it issues; the CA's key is there); an agent or the recorder mounts the CA's certificate
and its own identity (:func:`identity_mounts`), the router :data:`ROUTER_MOUNTS`, the world and
the viewer nothing; all read-only.

Every service runs as the image's user (uid :data:`UID`; ``ROCO_UID``/``ROCO_GID`` name another,
e.g. the owner of the host's run and credentials folders) within its own memory, CPU and
process limits (:data:`LIMITS`, measured: docs/deploy.md).

Every service logs to standard output, rotated by Docker's json-file driver (:data:`LOG_SIZE`,
:data:`LOG_FILES`); the router's Zenoh log is at :data:`ROUTER_LOG`. No health check starts an
interpreter or opens a connection to the router.

The file is in the Compose Specification format (no ``version:``), valid for ``docker
compose`` v2 and Debian's ``docker-compose`` 1.29. ``roco deploy compose`` writes it,
``roco deploy compose --check`` compares it, and ``roco spec new-agent`` brings it up to date.
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from services.deploy.layout import KITCHEN, SPEC_VARIABLE, SYSTEM_IN, Layout, project_name
from services.security.folder import ACL_FILE, CA_CERT, PASSWORDS, ROUTER
from services.spec.generated import GeneratedFile
from services.spec.model import SystemSpec, asked
from services.spec_check.acl import RECORDER, identities
from shared.settings import Settings, deployment_name
from velma.world.mode import WORLD_SERVICE

PROJECT = Path(__file__).resolve().parents[2]
"""The project's root folder (where ``services/`` and ``deploy/`` are)."""

IN_CHECKOUT = Path("deploy", "compose.yaml")
COMPOSE_FILE = PROJECT / IN_CHECKOUT
"""The project's compose file."""

MAX_COMPOSE_BYTES = 1 << 20
"""Largest compose file :func:`check` reads (1 MiB; the rendered file is ≈ 10 kB)."""

MOUNTS = tuple(KITCHEN.mounts())
"""What every roco service of the kitchen mounts: the run folders and the fleet's run name
(another system's: its folder too, services/deploy/layout.py)."""

CERTS_HOST = KITCHEN.certs_host
"""The kitchen's credentials folder on the host (services/security/certs.py lays it out)."""
CERTS_IN = "/certs"
"""Where a service finds its credentials (``ROCO_SECURITY``): the folder's layout, with only
the files the service needs."""
MESH_IDENTITY = Settings.env_name("router_identity")
"""The variable naming a meshed router's identity (``router_<host>``, docs/deploy.md)."""


def credentials(*entries: str, host: str = CERTS_HOST) -> list[str]:
    """Read-only mounts of ``entries`` (files or identity folders) of the credentials folder
    ``host`` (as the file names it), each at its own place below :data:`CERTS_IN`."""
    return [f"{host}/{e}:{CERTS_IN}/{e}:ro" for e in entries]


def identity_mounts(name: str, host: str = CERTS_HOST) -> list[str]:
    """What identity ``name``'s service mounts of the credentials folder ``host``: the CA's
    certificate and ``name``'s own folder (certificate, key, password); no other key, no
    password table."""
    return credentials(CA_CERT, name, host=host)


def router_mounts(host: str = CERTS_HOST) -> list[str]:
    """What the router mounts of the credentials folder ``host``: the CA's certificate, its own
    certificate and key, the password table it checks, its ACL and, on a host of a mesh, its
    identity."""
    return [
        *credentials(CA_CERT, f"{ROUTER}.pem", f"{ROUTER}.key", PASSWORDS, ACL_FILE, host=host),
        # a meshed router's own identity folder; unset, the CA's certificate (public) at a path
        # nothing reads: compose 1.29 has no conditional mount
        f"{host}/${{{MESH_IDENTITY}:-{CA_CERT}}}:{CERTS_IN}/${{{MESH_IDENTITY}:-unused-{CA_CERT}}}:ro",
    ]


ROUTER_MOUNTS = router_mounts()
"""The kitchen's router's mounts of the credentials folder (:func:`router_mounts`)."""

READY_FILE = "/tmp/roco.ready"
"""Where a roco service writes that it is ready (``ROCO_READY_FILE``, shared/ready_file.py): in
the container's own layer; the process removes it when it starts and stops."""
READY_TEST = json.dumps(["CMD", "cat", READY_FILE])
"""The health check of every roco service: the ready file is there (``cat`` prints what it says
into ``docker inspect``'s health log); no interpreter, no connection."""
LOG_SIZE = "10m"
LOG_FILES = 3
"""Docker's json-file log of a container: rotated at :data:`LOG_SIZE`, :data:`LOG_FILES` files
kept, per container."""
ROUTER_LOG = "info"
"""Zenoh's log level in the router (``RUST_LOG``; ``ROCO_ROUTER_LOG`` overrides it at ``up``):
INFO, as services/runtime/zenoh_log.py's default."""

RUN_VARIABLES = tuple(Settings.env_name(f) for f in ("run_dir", "km_store", "state_dir"))
"""The variables in which deploy/entrypoint.sh replaces ``{run}`` by the run's name."""


UID = 10001
"""The uid and gid of the image's user ``roco`` (deploy/Dockerfile), the services' default."""


@dataclass(frozen=True)
class Image:
    """One of roco's images: a ``target`` of deploy/Dockerfile, tagged ``${variable:-default}``
    in the compose file, whose services take the YAML anchor ``anchor`` (its image and build)."""

    target: str
    variable: str
    default: str
    anchor: str


IMAGES: dict[str, Image] = {
    "runtime": Image("runtime", deployment_name("image"), "roco:latest", "roco"),
    "robot": Image("robot", deployment_name("robot_image"), "roco-robot:latest", "roco-robot"),
    "viewer": Image("viewer", deployment_name("viewer_image"), "roco-viewer:latest", "roco-viewer"),
}
"""roco's images (deploy/Dockerfile; docs/deploy.md gives their sizes): ``runtime`` for every
service but these: ``robot`` (runtime + Mesa's software OpenGL) for ag_ex, whose camera process
renders the head camera; ``viewer`` (runtime + the Rerun CLI) for the web viewer and the
recorder, which merges the run's Rerun parts with ``rerun rrd merge``."""


@dataclass(frozen=True)
class Limits:
    """A container's resource limits: ``memory_mb`` MiB of memory (``mem_limit``; the kernel's
    OOM killer ends the service past it, and ``restart: unless-stopped`` starts it again),
    ``cpus`` CPUs of time (``cpus``, a CFS quota) and ``pids`` processes and threads
    (``pids_limit``)."""

    memory_mb: int
    cpus: float
    pids: int

    def lines(self) -> list[str]:
        """The service's keys, as compose file format 2.x and the Compose Specification name
        them (docker-compose 1.29 and docker compose v2 read both)."""
        return [
            f"    mem_limit: {self.memory_mb}m",
            f"    cpus: {self.cpus:g}",
            f"    pids_limit: {self.pids}",
        ]


LIMITS: dict[str, Limits] = {
    "certs": Limits(memory_mb=256, cpus=1, pids=128),
    "router": Limits(memory_mb=256, cpus=1, pids=128),
    "recorder": Limits(memory_mb=640, cpus=1, pids=128),
    "world": Limits(memory_mb=256, cpus=1, pids=128),
    "a_km": Limits(memory_mb=256, cpus=1, pids=128),
    "a_pl": Limits(memory_mb=256, cpus=1, pids=128),
    "a_co": Limits(memory_mb=256, cpus=1, pids=128),
    "ag_ex": Limits(memory_mb=1152, cpus=2, pids=256),
    "a_ta": Limits(memory_mb=256, cpus=1, pids=128),
    "a_hi": Limits(memory_mb=512, cpus=1, pids=128),
    "viewer": Limits(memory_mb=1280, cpus=1, pids=128),
}
"""Each service's limits, from its peaks in the compose smoke test (scripts/compose_smoke.sh
sampled by scripts/container_peaks.sh; docs/deploy.md gives the peaks and the machine):

- memory: twice the peak, rounded up to 64 MiB, at least 256 MiB (a long-lived fleet's
  knowledge and queues grow past one pour's); the viewer's also holds the Rerun server's
  buffer (1 GiB, ``rerun --server-memory-limit``'s default);
- CPUs: 1 (twice each peak is less), but ag_ex 2: its 1 kHz loop must not meet the quota,
  which throttles in 100 ms periods (the loop would count them as overruns);
- PIDs (processes and threads): 128, over twice each peak, as Zenoh's and Mesa's thread pools
  grow with the host's CPUs; ag_ex 256 (its camera renders with Mesa's llvmpipe, up to 32
  threads of its own).

a_hi's memory is twice its peak with its language models loaded, measured in-process (242 MiB;
docs/deploy.md). An agent not named here has :data:`AGENT_LIMITS`."""
AGENT_LIMITS = Limits(memory_mb=256, cpus=1, pids=128)
"""The limits of an agent :data:`LIMITS` does not name (a new agent of the specification): an
agent's but ag_ex's."""


def limits(service: str) -> Limits:
    """``service``'s limits (:data:`LIMITS`, else :data:`AGENT_LIMITS`)."""
    return LIMITS.get(service, AGENT_LIMITS)


class ComposeError(ValueError):
    """The specification cannot be rendered as a compose file, or the file cannot be read."""


@dataclass(frozen=True)
class StateVolume:
    """A named ``volume`` mounted at ``path`` in an agent's container, and the ``variables`` (of
    :data:`RUN_VARIABLES`) that point the agent at ``<path>/{run}``: what it keeps survives a
    restart of its container within a run, and a new run starts empty."""

    volume: str
    path: str
    variables: tuple[str, ...]


@dataclass(frozen=True)
class AgentExtras:
    """What an agent's container needs beyond every agent's: a ``state`` volume, Linux
    ``capabilities`` (``cap_add``) and the comment lines that say why."""

    state: StateVolume | None = None
    capabilities: tuple[str, ...] = ()
    why: tuple[str, ...] = ()
    hardware: str | None = None
    """The service of the hardware the agent drives (its IPC and PID namespaces are shared,
    and the agent starts after it), or None."""
    image: str = "runtime"
    """Which of :data:`IMAGES` the agent runs in."""


AGENT_EXTRAS: dict[str, AgentExtras] = {
    "a_km": AgentExtras(state=StateVolume("km_store", "/var/lib/roco/km", (Settings.env_name("km_store"),))),
    "a_co": AgentExtras(state=StateVolume("co_state", "/var/lib/roco/co", (Settings.env_name("state_dir"),))),
}
"""Per agent of the kitchen, what its container needs beyond every agent's (an agent not named
needs nothing more: its kept state, services/runtime/state_store.py, goes to the run folder)."""

ROBOT_EXTRAS = AgentExtras(
    hardware=WORLD_SERVICE,
    image="robot",
    why=(
        "the 1 kHz loop asks for SCHED_FIFO, which its user (not root) is refused here: it runs",
        "on with normal scheduling and says so in its log and report (velma/executor/timing.py;",
        "docs/deploy.md: an override that grants it)",
    ),
)
"""What the agent that plays the robot (``role = "robot"``: ag_ex) needs: the robot image and
the ``world`` it drives. A system without a robot has neither."""


def agent_extras(spec: SystemSpec, name: str) -> AgentExtras:
    """What agent ``name`` of ``spec`` needs beyond every agent's: :data:`ROBOT_EXTRAS` when it
    plays the robot, else :data:`AGENT_EXTRAS`' (none when it names no such agent)."""
    if name == spec.playing("robot"):
        return ROBOT_EXTRAS
    return AGENT_EXTRAS.get(name, AgentExtras())


_SERVICE = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]*")
"""A compose service name (the Compose Specification's ``[a-zA-Z0-9._-]``)."""
_PLAIN = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_YAML_WORDS = frozenset({"y", "n", "yes", "no", "on", "off", "true", "false", "null"})
"""Plain YAML 1.1 scalars that are not strings (docker-compose 1.29 reads YAML 1.1)."""

COMMENT = """\
# The roco fleet in containers: the Zenoh router, the traffic recorder, the agents of the
# specification, the simulated world ag_ex drives and a Rerun web viewer, from three images, the
# targets of deploy/Dockerfile: runtime (ROCO_IMAGE) for most, robot (ROCO_ROBOT_IMAGE: with Mesa,
# the head camera's) for ag_ex, viewer (ROCO_VIEWER_IMAGE: with the Rerun CLI) for the viewer and
# the recorder. docs/deploy.md tells the whole story.
#
# Rendered by `roco deploy compose` from the specification (services/spec/robot_companion.toml:
# one service per agent) and services/deploy/compose.py (the other services, the settings below,
# each agent's volumes and capabilities): change those, not this file; `roco deploy compose
# --check` says whether this file is what they give, and `roco spec new-agent` renders it again.
#
#   scripts/build_image.sh                                     (the three images, :latest and
#                                                               :VERSION, without a registry)
#   docker compose -f deploy/compose.yaml -p roco up -d        (or docker-compose 1.29: same flags;
#                    add -f deploy/compose.netfault.yaml for `roco fault net --delay/--loss`)
#   roco status --router tls/127.0.0.1:7447 --credentials deploy/certs
#   roco send --router tls/127.0.0.1:7447 --credentials deploy/certs "pour the jar into the bowl"
#   roco down --compose                                        (compose down, then the run's report)
#
# Configured by environment (shell or deploy/.env):
#   ROCO_IMAGE            image to run/build (target runtime)      roco:latest
#                         (roco:VERSION, e.g. roco:0.1.0: that version, as build_image.sh tags it)
#   ROCO_ROBOT_IMAGE      ag_ex's (target robot)                   roco-robot:latest
#   ROCO_VIEWER_IMAGE     the viewer's and recorder's (viewer)     roco-viewer:latest
#                         (`compose build` or `up` without them builds each service's target)
#   ROCO_BASE             base image of the runtime stage          python:3.11-slim
#   ROCO_BUILD_BASE       base image of the build stage            python:3.11-slim
#   ROCO_UID, ROCO_GID    user and group the services run as       10001 (the image's roco)
#                         (the owner of ROCO_RUNS and ROCO_CERTS: `id -u`, `id -g`)
#   ROCO_ROUTER_PUBLISH   host address:port of the router          127.0.0.1:7447
#                         (0.0.0.0:7447 to let another host's router mesh with this one)
#   ROCO_PEER             other routers to mesh with, comma-separated (tcp/HOST:7447)
#   ROCO_RUNS             host folder of the run folders           ../runs (the repository's runs/)
#   ROCO_RUN              run folder name                          the router's creation time (UTC)
#   ROCO_REALTIME         1: pace the simulation to wall time      1
#   ROCO_SEED, ROCO_POSE_SEED, ROCO_LOG_LEVEL                      as for `roco run`
#   ROCO_ROUTER_LOG       Zenoh's log level in the router          info
#                         (RUST_LOG: trace, debug, info, warn, error)
#   ROCO_PERCEPTION       camera (head Kinect) or truth (physics)  camera
#   ROCO_CAMERA_IDLE_S    s without an Observe before ag_ex's      60
#                         camera process ends ("never": kept)
#   ROCO_RECEIVE_POLL_US  µs an agent polls for a quick answer     500
#                         before it sleeps (0: never; docs/agents.md)
#   ROCO_RERUN            1: record robot and traffic with Rerun   1
#   ROCO_RERUN_CONNECT    the viewer to stream to                  rerun+http://viewer:9876/proxy
#   ROCO_VIEWER_BIND, ROCO_VIEWER_WEB_PORT, ROCO_VIEWER_GRPC_PORT  127.0.0.1, 9090, 9876
#   ROCO_CERTS            host folder of the credentials           ./certs (deploy/certs)
#   ROCO_SECURITY         credentials folder in the containers     /certs ("" = access control off)
#   ROCO_ROUTER_IDENTITY  a meshed router's identity               none (router_HOST: docs/deploy.md)
#   ROCO_PROTO            tls (mutual TLS) or tcp                  tls (tcp with ROCO_SECURITY="")
#
# Access control is on (docs/security.md): the one-shot service `certs` issues a private CA, the
# router's certificate and one identity per agent/recorder/operator into ROCO_CERTS unless it
# holds them already (`roco deploy certs --keep`); the router requires mutual TLS and a password
# and applies the ACL generated from the specification. Least privilege: only `certs` sees the
# CA's key; every other service mounts, read-only, the CA's certificate and its own identity
# (certificate, key, password), the router its own key, the password table and the ACL; the
# world and the viewer no credentials. Off, for experiments:
#   ROCO_SECURITY= ROCO_PROTO=tcp docker compose -f deploy/compose.yaml -p roco up -d
#
# Logs: every service writes its log lines to standard output (`docker compose logs a_km`),
# the agents and the recorder to the run folder's logs/NAME.log as well; Docker's json-file
# driver keeps at most @LOG_FILES files of @LOG_SIZE per container. Health: a service is
# healthy once it is ready (an agent: its roles set up and the agents it asks seen; the
# recorder: it records; the router: it listens; the world: it serves the robot link), which it
# says by writing @READY_FILE (ROCO_READY_FILE); the check reads that file with `cat`.
# The viewer's check opens its two ports from bash.
#
# Limits: each service has a memory limit, a CPU quota and a process/thread limit, about twice
# the peaks measured in the compose smoke test (docs/deploy.md: how, and on what machine).
#
# Compose Specification format (no `version:`): valid for `docker compose` v2 and for
# Debian's `docker-compose` 1.29 (depends_on conditions, healthchecks, init, cap_add, mem_limit,
# cpus, pids_limit).

"""
"""The file's opening comment for roco's kitchen (:data:`KITCHEN`; another system's:
:data:`SYSTEM_COMMENT`)."""

BUILD = """\
  build: &build
    context: ..
    dockerfile: deploy/Dockerfile
    target: runtime
    args:
      BASE: ${ROCO_BASE:-python:3.11-slim}
      BUILD_BASE: ${ROCO_BUILD_BASE:-python:3.11-slim}
"""
"""How the kitchen's file builds the runtime image: roco's checkout is the context (the other
images' anchors build their targets from it too). Another system's file builds nothing."""

BODY = """\
x-roco: &roco
  image: ${ROCO_IMAGE:-roco:latest}
@BUILD
  # the image's user roco, or the owner of the host's folders (ROCO_RUNS, ROCO_CERTS)
  user: "${ROCO_UID:-@UID}:${ROCO_GID:-@UID}"
  init: true  # tini as PID 1: signals reach the service, zombies are reaped
  restart: unless-stopped
  logging:  # docker compose logs; rotated
    driver: json-file
    options:
      max-size: "@LOG_SIZE"
      max-file: "@LOG_FILES"
  volumes:
@MOUNTS
  healthcheck: &health
    interval: 5s
    timeout: 5s
    retries: 5
    start_period: 120s

@IMAGES
x-env: &env
  ROCO_ROUTER: ${ROCO_PROTO:-tls}/router:7447
  ROCO_SECURITY: ${ROCO_SECURITY-/certs}
  ROCO_RUN: ${ROCO_RUN:-}
  ROCO_RUN_DIR: /runs/{run}
  ROCO_REALTIME: ${ROCO_REALTIME:-1}
  ROCO_SEED: ${ROCO_SEED:-0}
  ROCO_POSE_SEED: ${ROCO_POSE_SEED:-}
  ROCO_PERCEPTION: ${ROCO_PERCEPTION:-}
  ROCO_CAMERA_IDLE_S: ${ROCO_CAMERA_IDLE_S:-}
  ROCO_RECEIVE_POLL_US: ${ROCO_RECEIVE_POLL_US:-}
  ROCO_LOG_LEVEL: ${ROCO_LOG_LEVEL:-INFO}
  ROCO_LOG_STDOUT: "1"
  ROCO_READY_FILE: @READY_FILE
  ROCO_RERUN: ${ROCO_RERUN:-1}
  ROCO_RERUN_CONNECT: ${ROCO_RERUN_CONNECT-rerun+http://viewer:9876/proxy}
@SPEC_ENV

x-after-router: &after-router
  certs:
    condition: service_completed_successfully
  router:
    condition: service_healthy
  recorder:
    condition: service_healthy

services:
  certs:  # one shot: the deployment's credentials, unless ROCO_CERTS has them (docs/security.md)
    <<: *roco
    restart: "no"
    command: ["python", "-m", "services.cli", "deploy", "certs", "/certs", "--keep"]
@CERTS_SERVICE
@LIMITS certs
    healthcheck:
      disable: true

  router:
    <<: *roco
    command: ["sh", "-c", "exec python -m services.runtime.router --listen $${ROCO_PROTO:-tls}/0.0.0.0:7447"]
    environment:
      <<: *env
      ROCO_NEW_RUN: "1"
      ROCO_CONNECT: ${ROCO_PEER:-}
      ROCO_PROTO: ${ROCO_PROTO:-tls}
      ROCO_ROUTER_IDENTITY: ${ROCO_ROUTER_IDENTITY:-}  # a meshed router's identity (roco deploy router)
      RUST_LOG: ${ROCO_ROUTER_LOG:-@ROUTER_LOG}
    volumes:
@ROUTER_MOUNTS
    depends_on:
      certs:
        condition: service_completed_successfully
    ports:
      - ${ROCO_ROUTER_PUBLISH:-127.0.0.1:7447}:7447
@LIMITS router
    healthcheck:
      <<: *health
      test: @READY_TEST

  recorder:  # the viewer image: it merges the run's Rerun parts with the Rerun CLI
    <<: *roco-viewer
    command: ["python", "-m", "services.recorder.recorder"]
    environment: *env
    volumes:
@RECORDER_MOUNTS
    depends_on:
      certs:
        condition: service_completed_successfully
      router:
        condition: service_healthy
    stop_grace_period: 60s  # it merges the Rerun parts into recording.rrd when it stops
@LIMITS recorder
    healthcheck:
      <<: *health
      test: @READY_TEST

"""
"""The file from its anchors to the recorder's service, with marks (``@MOUNTS``, …) that
:func:`_head` fills for the layout."""
HEAD = COMMENT + BODY
"""The kitchen's opening comment and the body."""

AGENTS_COMMENT = "  # The agents of the specification, in its start order (services/deploy/compose.py).\n"

VIEWER = """\
  viewer:
    <<: *roco-viewer
    command:
      - python
      - -m
      - rerun_cli
      - --serve-web
      - --bind
      - 0.0.0.0
      - --port
      - "9876"
      - --web-viewer-port
      - "9090"
    environment:
      RUST_LOG: warn
    volumes:
      - @RUNS_HOST:/runs:ro
    ports:
      - ${ROCO_VIEWER_BIND:-127.0.0.1}:${ROCO_VIEWER_WEB_PORT:-9090}:9090
      - ${ROCO_VIEWER_BIND:-127.0.0.1}:${ROCO_VIEWER_GRPC_PORT:-9876}:9876
@LIMITS viewer
    healthcheck:  # both ports accept a connection (bash's /dev/tcp: no Python started)
      <<: *health
      test: ["CMD", "bash", "-c", "exec 3<>/dev/tcp/127.0.0.1/9876 4<>/dev/tcp/127.0.0.1/9090"]
"""

WORLD = """\
  world:  # Velma's hardware side: the simulated kitchen (velma/world/); restarted, a power cycle of the robot
    <<: *roco
    command: ["python", "-m", "velma.world"]
    environment: *env
    ipc: shareable  # the robot link is shared memory: ag_ex joins this IPC namespace
    depends_on:  # the run's name (its folder) comes from the router
      router:
        condition: service_healthy
@LIMITS world
    healthcheck:  # ready once it serves the robot link (it names it in the run folder)
      <<: *health
      test: @READY_TEST
"""

NOT_AGENTS = ("certs", "router", "recorder", "viewer", WORLD_SERVICE)
"""The services of the file that are not agents (an agent may have none of these names)."""


def last_started(spec: SystemSpec) -> str:
    """The agent that waits until every other agent is healthy: the last one the
    specification's ``start_order`` names (else the last in its start order)."""
    return (spec.start_order or spec.launch_order)[-1]


def _key(name: str) -> str:
    """``name`` as a YAML mapping key: plain where YAML 1.1 reads it as that string."""
    if _PLAIN.fullmatch(name) and name.lower() not in _YAML_WORDS:
        return name
    return json.dumps(name)


def _environment(name: str, state: StateVolume | None, layout: Layout) -> list[str]:
    """Agent ``name``'s environment and volumes: every service's, its credentials and its kept
    state."""
    env = ["    environment: *env"]
    if state is not None:
        env = [
            "    environment:",
            "      <<: *env",
            *(f"      {var}: {state.path}/{{run}}" for var in state.variables),
        ]
    kept = [f"{state.volume}:{state.path}"] if state is not None else []
    mounts = [*layout.mounts(), *identity_mounts(name, layout.certs_host), *kept]
    return [*env, "    volumes:", *_list(mounts)]


def _list(items: list[str]) -> list[str]:
    """A service's list items (6 spaces deep)."""
    return [f"      - {i}" for i in items]


def _depends_on(spec: SystemSpec, name: str, extras: AgentExtras) -> list[str]:
    """What agent ``name``'s service waits for: the router, its hardware, and every other agent
    when it is the last started."""
    needs = [f"      {extras.hardware}:", "        condition: service_healthy"] if extras.hardware else []
    if name == last_started(spec):
        return [
            "    depends_on:  # last in the specification's start_order: once every other agent is healthy",
            "      <<: *after-router",
            *needs,
            *(
                line
                for other in spec.launch_order
                if other != name
                for line in (f"      {_key(other)}:", "        condition: service_healthy")
            ),
        ]
    if needs:
        return ["    depends_on:", "      <<: *after-router", *needs]
    return ["    depends_on: *after-router"]


def _shared_with_hardware(hardware: str | None) -> list[str]:
    """The IPC and PID namespaces an agent shares with the ``hardware`` it drives (none
    without)."""
    if hardware is None:
        return []
    return [
        f"    # the robot link to {hardware} is shared memory with a futex; one PID namespace,",
        "    # so that each side tells a live peer's blocks from a killed one's (velma/shm.py)",
        f'    ipc: "service:{hardware}"',
        f'    pid: "service:{hardware}"',
    ]


def _agent(spec: SystemSpec, name: str, layout: Layout) -> list[str]:
    """The lines of agent ``name``'s service."""
    extras = agent_extras(spec, name)
    key = json.dumps(name)
    lines = [
        f"  {_key(name)}:",
        f"    <<: *{IMAGES[extras.image].anchor}",
        f'    command: ["python", "-m", "services.runtime.main", {key}]',
    ]
    lines += _environment(name, extras.state, layout)
    lines += _depends_on(spec, name, extras)
    lines += _shared_with_hardware(extras.hardware)
    lines += [f"    # {why}" for why in extras.why]
    if extras.capabilities:
        lines.append(f"    cap_add: [{', '.join(extras.capabilities)}]")
    lines += limits(name).lines()
    lines += [
        "    healthcheck:",
        "      <<: *health",
        f"      test: {READY_TEST}",
    ]
    return lines


def hardware(spec: SystemSpec) -> list[str]:
    """The hardware services the agents of ``spec`` drive (:attr:`AgentExtras.hardware`)."""
    named = (agent_extras(spec, n).hardware for n in spec.launch_order)
    return sorted({h for h in named if h is not None})


def images(spec: SystemSpec) -> list[str]:
    """The keys of :data:`IMAGES` the file of ``spec`` runs, in that order: the runtime and the
    viewer image, and the robot image when an agent plays the robot."""
    used = {"runtime", "viewer", *(agent_extras(spec, n).image for n in spec.launch_order)}
    return [key for key in IMAGES if key in used]


_LIMITS_MARK = re.compile(r"^@LIMITS (\S+)\n", re.M)


def _fill(text: str, layout: Layout = KITCHEN) -> str:
    """``text`` with the settings of this module in place of their marks (``@READY_TEST``, …;
    a line ``@LIMITS SERVICE``: that service's :data:`LIMITS`; ``@RUNS_HOST``: the run folders
    on the host in ``layout``)."""
    text = _LIMITS_MARK.sub(lambda m: "\n".join(limits(m.group(1)).lines()) + "\n", text)
    values = {
        "@UID": str(UID),
        "@READY_TEST": READY_TEST,
        "@READY_FILE": READY_FILE,
        "@LOG_SIZE": LOG_SIZE,
        "@LOG_FILES": str(LOG_FILES),
        "@ROUTER_LOG": ROUTER_LOG,
        "@RUNS_HOST": layout.runs_host,
    }
    for mark, value in values.items():
        text = text.replace(mark, value)
    return text


def _image_anchors(spec: SystemSpec, layout: Layout) -> str:
    """The anchors of the images but the runtime one (``x-roco``'s) that ``spec``'s file runs:
    each is ``x-roco`` with its own image and, when ``layout`` builds, its build target."""
    text = ""
    for image in (IMAGES[key] for key in images(spec)):
        if image.target == "runtime":
            continue
        build = f"  build:\n    <<: *build\n    target: {image.target}\n" if layout.builds else ""
        text += (
            f"x-{image.anchor}: &{image.anchor}\n"
            "  <<: *roco\n"
            f"  image: ${{{image.variable}:-{image.default}}}\n"
            f"{build}\n"
        )
    return text


def _certs_service(layout: Layout) -> list[str]:
    """The ``certs`` service's environment and volumes: the whole credentials folder and, for
    another system, its folder and ``ROCO_SPEC``, whose identities it issues."""
    if layout.system_mount is None:
        return ["    volumes:", f"      - {layout.certs_host}:{CERTS_IN}"]
    return [
        "    environment:  # the specification whose identities it issues",
        f"      {SPEC_VARIABLE}: {layout.spec_in}",
        "    volumes:",
        *_list([f"{layout.certs_host}:{CERTS_IN}", layout.system_mount]),
    ]


def _head(spec: SystemSpec, layout: Layout) -> str:
    """:data:`COMMENT` (another system's: :func:`system_comment`) and :data:`BODY` with its
    mounts (every service's, the router's and the recorder's), images and settings for
    ``layout``."""
    host = layout.certs_host
    spec_env = [] if layout.system is None else [f"  {SPEC_VARIABLE}: {layout.spec_in}"]
    lines = {
        "@BUILD": BUILD.splitlines() if layout.builds else [],
        "@MOUNTS": [f"    - {m}" for m in layout.mounts()],
        "@ROUTER_MOUNTS": _list([*layout.mounts(), *router_mounts(host)]),
        "@RECORDER_MOUNTS": _list([*layout.mounts(), *identity_mounts(RECORDER, host)]),
        "@SPEC_ENV": spec_env,
        "@CERTS_SERVICE": _certs_service(layout),
    }
    body = BODY.replace("@IMAGES\n", _image_anchors(spec, layout))
    for mark, mounts in lines.items():
        body = body.replace(mark + "\n", "".join(f"{line}\n" for line in mounts))
    comment = COMMENT if layout.system is None else system_comment(spec, layout)
    return _fill(comment + body, layout)


SYSTEM_COMMENT = """\
# The fleet of @TITLE in containers: the Zenoh router, the traffic recorder, the agents of the
# specification and a Rerun web viewer, in roco's images, which this file does not build
# (scripts/build_image.sh builds them in roco's checkout): ROCO_IMAGE (roco:latest) for most,
# ROCO_VIEWER_IMAGE (roco-viewer:latest) for the viewer and the recorder.@ROBOT
#   agents:      @AGENTS
#   identities:  @IDENTITIES
#
# The system's folder, @SYSTEM (a path here is relative to this file's folder), is mounted
# read-only at @SYSTEM_IN in every roco service, and ROCO_SPEC names the specification there
# (@SPEC_IN): the agents import the system's package from it, and the one-shot service
# `certs` issues the identities into ROCO_CERTS, @CERTS unless set: outside the system's
# folder, which every service sees.
#
# Rendered by `roco deploy compose --spec @SPEC_FILE --file THIS_FILE` (in this file's folder)
# from the specification and roco's services/deploy/compose.py: change those, not this file;
# `roco deploy compose --check` with the same options says whether this file is what they give.
#
#   docker compose -f THIS_FILE -p @PROJECT up -d      (or docker-compose 1.29: same flags)
#   roco status --spec @SPEC_FILE --router tls/127.0.0.1:7447 --credentials @CERTS
#
# Configured by environment (shell or .env) as roco's own deploy/compose.yaml is (docs/deploy.md);
# ROCO_RUNS, the host folder of the run folders, is @RUNS unless set.

"""
"""Another system's opening comment (:func:`system_comment` fills its ``@MARKS``)."""

_COMMENT_MARK = re.compile(r"@([A-Z_]+)")


def system_comment(spec: SystemSpec, layout: Layout) -> str:
    """:data:`SYSTEM_COMMENT` for ``spec`` in ``layout`` (another system's)."""
    robot = spec.playing("robot")
    image = IMAGES["robot"]
    values = {
        "TITLE": " ".join(spec.system.split()) or "the system",
        "AGENTS": ", ".join(spec.launch_order),
        "ROBOT": f"\n# {image.variable} ({image.default}) runs {robot}, the robot, beside its world."
        if robot
        else "",
        "SYSTEM": str(layout.system),
        "SYSTEM_IN": SYSTEM_IN,
        "SPEC_IN": layout.spec_in,
        "SPEC_FILE": f"{layout.system}/{layout.spec}",
        "IDENTITIES": ", ".join(issued(spec)),
        "CERTS": layout.certs,
        "RUNS": layout.runs,
        "PROJECT": project_name(Path(layout.spec)),
    }
    return _COMMENT_MARK.sub(lambda m: values[m.group(1)], SYSTEM_COMMENT)


def issued(spec: SystemSpec) -> list[str]:
    """The identities the ``certs`` service issues for ``spec`` (services/spec_check/acl.py
    ``identities``: its agents', the recorder's, the operator's, …) and the router's."""
    return [*identities(spec), ROUTER]


def _check_readiness(spec: SystemSpec) -> None:
    """Raise ComposeError when an agent asks the one started last: that one waits until every
    other agent is healthy, and an agent is healthy once it has seen the agents it asks
    (services/spec/model.py ``asked``), so neither would ever be."""
    last = last_started(spec)
    for name in spec.launch_order:
        if name != last and last in asked(spec, name):
            raise ComposeError(
                f"agent {name} asks {last}, which starts once every other agent is healthy: {name} "
                f"would never be ready (an agent is ready once it has seen the agents it asks); "
                f"name another agent last in the specification's start_order"
            )


def _volumes(spec: SystemSpec) -> list[str]:
    """The file's named volumes: the fleet's and each agent's kept state's. Raises ComposeError
    for an agent whose name cannot be a compose service's, or is one of :data:`NOT_AGENTS`."""
    volumes = ["fleet"]
    for name in spec.launch_order:
        if not _SERVICE.fullmatch(name) or name in NOT_AGENTS:
            raise ComposeError(
                f"agent {name!r} cannot be a compose service: a service's name is letters, digits, "
                f"'.', '_' and '-', not {', '.join(NOT_AGENTS)}"
            )
        state = agent_extras(spec, name).state
        if state is not None and state.volume not in volumes:
            volumes.append(state.volume)
    return volumes


def render(spec: SystemSpec, layout: Layout = KITCHEN) -> str:
    """The compose file ``spec`` gives in ``layout`` (see the module docstring; the kitchen's:
    deploy/compose.yaml). Raises ComposeError for an agent whose name cannot be a compose
    service's, or is one of :data:`NOT_AGENTS`, and when an agent asks the last started one
    (:func:`last_started`, which waits for it to be healthy: neither would ever be)."""
    volumes = _volumes(spec)
    _check_readiness(spec)
    head = _head(spec, layout)
    agents = "\n".join("\n".join(_agent(spec, name, layout)) + "\n" for name in spec.launch_order)
    agents = AGENTS_COMMENT + agents
    if WORLD_SERVICE in hardware(spec):
        agents = _fill(WORLD, layout) + "\n" + agents
    tail = "volumes:\n" + "".join(f"  {v}: {{}}\n" for v in volumes)
    return f"{head}{agents}\n{_fill(VIEWER, layout)}\n{tail}"


_SERVICE_LINE = re.compile(r'^  "?([A-Za-z0-9][A-Za-z0-9_.-]*)"?:.*\n', re.M)
_CREDENTIAL = re.compile(rf"^      - \S+:{CERTS_IN}/(\S+):ro$", re.M)


def services(text: str) -> dict[str, str]:
    """The services of compose file ``text``, each with the text of its block (its lines below
    its name), as rendered here (two spaces deep, between ``services:`` and ``volumes:``)."""
    body = text.split("\nservices:\n", 1)[-1].split("\nvolumes:\n", 1)[0]
    parts = _SERVICE_LINE.split(body)
    return dict(zip(parts[1::2], parts[2::2], strict=True))


def _agents_differ(found: dict[str, str], spec: SystemSpec) -> str | None:
    """The agents with no service, or services of no agent, among ``found``."""
    names = set(found) - set(NOT_AGENTS)
    agents = set(spec.launch_order)
    if missing := sorted(agents - names):
        return f"no service for agent {', '.join(missing)}"
    if extra := sorted(names - agents):
        return f"a service for {', '.join(extra)}, which the specification has no agent of"
    return None


def _identities_differ(found: dict[str, str], spec: SystemSpec) -> str | None:
    """An agent's or the recorder's service among ``found`` that does not mount its own
    identity, or mounts another's credentials."""
    for name in (*spec.launch_order, RECORDER):
        mounted = set(_CREDENTIAL.findall(found.get(name, "")))
        if name not in mounted:
            return f"service {name} does not mount its identity {name}"
        if others := sorted(mounted - {CA_CERT, name}):
            return f"service {name} mounts credentials not its own ({', '.join(others)})"
    return None


def _system_differs(text: str, found: dict[str, str], spec: SystemSpec, layout: Layout) -> str | None:
    """For another system: a roco service among ``found`` (or the ``x-roco`` anchor) without the
    system's folder, or ``ROCO_SPEC`` not naming its specification in ``x-env`` or ``certs``."""
    if layout.system_mount is None:
        return None
    mount = f"- {layout.system_mount}\n"
    anchor = text.split("\nx-roco: &roco\n", 1)[-1].split("\nx-", 1)[0]
    if mount not in anchor:
        return f"x-roco does not mount the system's folder ({layout.system_mount})"
    for name in ("certs", "router", "recorder", *spec.launch_order):
        if mount not in found.get(name, mount):
            return f"service {name} does not mount the system's folder ({layout.system_mount})"
    setting = f"{SPEC_VARIABLE}: {layout.spec_in}\n"
    env = text.split("\nx-env: &env\n", 1)[-1].split("\n\n", 1)[0]
    if f"\n  {setting}" not in f"\n{env}\n":
        return f"x-env does not set {SPEC_VARIABLE} to {layout.spec_in}"
    if f"\n      {setting}" not in found.get("certs", ""):
        return (
            f"service certs does not set {SPEC_VARIABLE} to {layout.spec_in}: "
            f"it would issue another system's identities"
        )
    return None


def named_difference(text: str, spec: SystemSpec, layout: Layout = KITCHEN) -> str | None:
    """What compose file ``text`` lacks, or has beyond what ``spec`` gives in ``layout``, that
    can be named: an agent's service, an identity's mount, the system's folder or its
    ``ROCO_SPEC``; None when none of these differs."""
    found = services(text)
    return (
        _agents_differ(found, spec)
        or _identities_differ(found, spec)
        or _system_differs(text, found, spec, layout)
    )


def compose_generated(
    what: str,
    relative: Path,
    render: Callable[[SystemSpec], str],
    named_difference: Callable[[str, SystemSpec], str | None],
    wrote: Callable[[SystemSpec], str],
    command: str = "roco deploy compose",
) -> GeneratedFile:
    """A file of the compose deployment at ``relative`` in a checkout, written by ``command``
    (``GeneratedFile``'s other arguments), bounded and failing as the compose file."""
    return GeneratedFile(
        what=what,
        relative=relative,
        command=command,
        max_bytes=MAX_COMPOSE_BYTES,
        error=ComposeError,
        render=render,
        named_difference=named_difference,
        wrote=wrote,
    )


def _wrote(spec: SystemSpec) -> str:
    return f"one service per agent ({', '.join(spec.launch_order)})"


COMPOSE = compose_generated("compose file", IN_CHECKOUT, render, named_difference, _wrote)
"""``deploy/compose.yaml`` (services/spec/generated.py): ``read``, ``difference``, ``check``,
``write``, ``bring_up_to_date``."""
read = COMPOSE.read
difference = COMPOSE.difference
check = COMPOSE.check
write = COMPOSE.write
bring_up_to_date = COMPOSE.bring_up_to_date


def compose_for(layout: Layout, command: str = "roco deploy compose") -> GeneratedFile:
    """The compose file in ``layout`` (services/deploy/layout.py ``layout_for``): :data:`COMPOSE`
    for the kitchen's, else one that renders, checks and writes another system's, brought up
    to date by ``command`` (e.g. with its ``--spec`` and ``--file``)."""
    if layout == KITCHEN:
        return COMPOSE
    return compose_generated(
        "compose file",
        IN_CHECKOUT,
        lambda spec: render(spec, layout),
        lambda text, spec: named_difference(text, spec, layout),
        _wrote,
        command,
    )


def described(spec: SystemSpec, layout: Layout) -> str:
    """What a compose file of ``spec`` in ``layout`` issues and mounts, for ``--check``'s line:
    the identities and, for another system, its folder and ``ROCO_SPEC``."""
    said = f"identities: {', '.join(issued(spec))}"
    if layout.system_mount is not None:
        said += f"; the system's folder ({layout.system}) read-only at {SYSTEM_IN}"
        said += f", {SPEC_VARIABLE}={layout.spec_in}"
    return said
