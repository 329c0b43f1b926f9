"""roco's settings: every ``ROCO_*`` environment variable, declared once (docs/settings.md).

Each field of :class:`Settings` is one variable: its name in the environment, its type, its
default and one line saying what it sets and which part of roco reads it. This is the only
module of ``shared/``, ``services/``, ``velma/`` and ``scripts/`` that spells a ``ROCO_*`` name
(tests/architecture/test_settings_only.py); other code reads values with
:meth:`Settings.from_env` and names variables with :meth:`Settings.env_name`.

How a value is read, for every variable: spaces around it are dropped, and an empty value
counts as unset (the default). A flag (``bool``) is ``1`` (on) or ``0`` (off); any other value
leaves its default. An integer is ≥ 0. A choice (``Literal``) is one of its words. A list
(``tuple[str, ...]``) is comma-separated. A value that does not parse raises ``ValueError``
with one line naming the variable and what it expects.

Variables that roco's Python does not read, but the deployment files (deploy/compose.yaml,
deploy/entrypoint.sh) and setup.py do, are :data:`DEPLOYMENT`. Imports nothing of roco: the
robot side (velma/) and every layer of services/ may import it.
"""

from __future__ import annotations

import math
import os
import types
import typing
from collections.abc import Callable, Collection, Mapping
from functools import cache
from pathlib import Path
from typing import Annotated, Any, Literal

import msgspec

PREFIX = "ROCO_"
"""What every roco variable's name starts with (the launcher forwards all of them)."""

Parse = Callable[[str, str, Any], Any]
"""``(name, value, default) → parsed``: ``value`` is stripped and not empty; raises ValueError
with one line naming the variable ``name``."""


class About(msgspec.Struct, frozen=True):
    """What :class:`Settings` declares of one field beside its type and default: the
    variable's ``name``, a one-line ``doc``, and for a type whose reading is not the
    module's rule (module docstring) its own ``parse`` and ``kind`` (its values, in words)."""

    name: str
    doc: str
    parse: Parse | None = None
    kind: str = ""


class Variable(msgspec.Struct, frozen=True, kw_only=True):
    """One declared setting as the docs and ``roco doctor`` show it: ``field`` of
    :class:`Settings`, the variable's ``name``, its values in words (``kind``), its ``default``
    (the field's value when unset), ``doc`` and how a value is read (``parse``)."""

    field: str
    name: str
    kind: str
    default: Any
    doc: str
    parse: Parse


# ------------------------------------------------------------------------------ parsing
def _seconds_or_never(name: str, value: str, default: Any) -> float:
    """Seconds > 0, or ``never`` (infinity)."""
    if value == "never":
        return math.inf
    try:
        seconds = float(value)
    except ValueError:
        seconds = math.nan
    if not seconds > 0 or math.isinf(seconds):
        raise ValueError(f"{name}={value!r}: expected a number of seconds > 0 or 'never'")
    return seconds


def _positive_factor(name: str, value: str, default: Any) -> float:
    """A finite number > 0."""
    try:
        factor = float(value)
    except ValueError:
        factor = math.nan
    if not factor > 0 or math.isinf(factor):
        raise ValueError(f"{name}={value!r}: expected a number > 0")
    return factor


def _microseconds(name: str, value: str, default: Any) -> float:
    """Microseconds ≥ 0, finite."""
    try:
        us = float(value)
    except ValueError:
        us = -1.0
    if not us >= 0.0 or math.isinf(us):
        raise ValueError(f"{name}={value!r}: expected a number of microseconds ≥ 0 (0: never poll)")
    return us


LOG_LEVELS = ("DEBUG", "INFO", "WARNING", "ERROR", "CRITICAL")


def _log_level(name: str, value: str, default: Any) -> str:
    """A level name of Python's logging, any case (``WARN``, ``FATAL`` and ``NOTSET`` too)."""
    level = value.upper()
    if level not in (*LOG_LEVELS, "WARN", "FATAL", "NOTSET"):
        raise ValueError(f"{name}={value!r}: expected one of {', '.join(LOG_LEVELS)}")
    return level


def _flag(name: str, value: str, default: Any) -> bool:
    return True if value == "1" else False if value == "0" else bool(default)


def _integer(name: str, value: str, default: Any) -> int:
    try:
        number = int(value)
    except ValueError:
        raise ValueError(f"{name}={value!r} is not an integer") from None
    if number < 0:
        raise ValueError(f"{name}={number} is negative")
    return number


def _choice(words: tuple[str, ...]) -> Parse:
    def parse(name: str, value: str, default: Any) -> str:
        if value not in words:
            raise ValueError(f"{name}={value!r}: expected one of {', '.join(words)}")
        return value

    return parse


def _items(name: str, value: str, default: Any) -> tuple[str, ...]:
    return tuple(item.strip() for item in value.split(",") if item.strip()) or default


def _text(name: str, value: str, default: Any) -> str:
    return value


def _path(name: str, value: str, default: Any) -> Path:
    return Path(value)


def _reading(annotation: Any) -> tuple[str, Parse]:
    """The values in words and the parse of a field of type ``annotation`` (module docstring)."""
    args = typing.get_args(annotation)
    if typing.get_origin(annotation) in (typing.Union, types.UnionType):
        return _reading(next(a for a in args if a is not type(None)))
    if typing.get_origin(annotation) is Literal:
        return " / ".join(args), _choice(args)
    if annotation == tuple[str, ...]:
        return "comma-separated", _items
    readings: dict[Any, tuple[str, Parse]] = {
        bool: ("1 / 0", _flag),
        int: ("integer ≥ 0", _integer),
        str: ("text", _text),
        Path: ("path", _path),
    }
    if annotation not in readings:
        raise TypeError(f"no reading of a setting of type {annotation!r}")
    return readings[annotation]


def env_text(value: Any) -> str:
    """``value`` as the environment holds it: a flag ``1``/``0``, a list comma-separated,
    infinity ``never``, None and nothing ``""``."""
    if value is None:
        return ""
    if isinstance(value, bool):
        return "1" if value else "0"
    if isinstance(value, tuple):
        return ",".join(value)
    if isinstance(value, float):
        return "never" if math.isinf(value) else f"{value:g}"
    return str(value)


# ------------------------------------------------------------------------------ the settings
ROUTER_PORT = 7447
"""The TCP port a fleet's Zenoh router listens on: ``roco up``, compose, the two hosts."""
GATEWAY_PORT = 7778
"""The port of ``roco gateway``'s FIPA HTTP message transport (JADE's default, FIPA SC00084)."""
DEFAULT_ROUTER = f"tcp/127.0.0.1:{ROUTER_PORT}"
"""The router endpoint of a local fleet (``ROCO_ROUTER`` unset)."""


class Settings(msgspec.Struct, frozen=True, kw_only=True):
    """Every ``ROCO_*`` variable roco's Python reads, one field each (module docstring).

    Build it with :meth:`from_env`; ``Settings()`` holds the defaults."""

    # --- the fleet and its connections
    router: Annotated[
        tuple[str, ...],
        About(
            "ROCO_ROUTER",
            "Zenoh endpoints of the router (comma-separated): every agent, the recorder, the health probe, "
            "and the tools when no fleet of `roco up` is found; the launcher sets it",
        ),
    ] = (DEFAULT_ROUTER,)
    run_dir: Annotated[
        Path | None,
        About(
            "ROCO_RUN_DIR",
            "the run folder (logs, traffic, recording, kept state) of every process of a fleet; the launcher "
            "and compose set it; unset: logs go to stderr",
        ),
    ] = None
    spec: Annotated[
        Path | None,
        About(
            "ROCO_SPEC",
            "the specification file the agents, the launcher and the viewer load; unset: "
            "services/spec/robot_companion.toml",
        ),
    ] = None
    log_level: Annotated[
        str,
        About(
            "ROCO_LOG_LEVEL",
            "level of an agent's and the recorder's log, any case (services/runtime/main.py)",
            parse=_log_level,
            kind=" / ".join(LOG_LEVELS),
        ),
    ] = "INFO"
    log_stdout: Annotated[
        bool,
        About(
            "ROCO_LOG_STDOUT",
            "1: an agent's and the recorder's log lines go to standard output too, besides the run folder's "
            "logs/NAME.log (compose sets it: `docker compose logs`; services/runtime/main.py)",
        ),
    ] = False
    ready_file: Annotated[
        Path | None,
        About(
            "ROCO_READY_FILE",
            "a file the router, the recorder, an agent or the world writes once it is ready and removes when "
            "it stops (shared/ready_file.py); compose's health checks read it; unset: none",
        ),
    ] = None
    faults: Annotated[
        str,
        About(
            "ROCO_FAULTS",
            "fault settings an agent starts with (docs/faults.md; services/runtime/faults.py); unset: none",
            kind="JSON",
        ),
    ] = ""
    security: Annotated[
        Path | None,
        About(
            "ROCO_SECURITY",
            "credentials folder (docs/security.md): sessions authenticate from it, the router applies its "
            "ACL; unset: the fleet of `roco up`'s, else none",
        ),
    ] = None
    identity: Annotated[
        str,
        About(
            "ROCO_IDENTITY",
            "the identity a tool's session authenticates as (an agent or the recorder is itself)",
        ),
    ] = "operator"
    acl: Annotated[
        bool,
        About(
            "ROCO_ACL",
            "0: the launcher starts local fleets without authentication and access control (--no-acl)",
        ),
    ] = True
    tls: Annotated[
        bool,
        About(
            "ROCO_TLS",
            "a local fleet with access control authenticates its processes with mutual TLS as well as "
            "passwords, and its agents link directly (ROCO_LINKS); 0: passwords over TCP, every communicate "
            "through the router (the launcher; --no-tls)",
        ),
    ] = True
    links: Annotated[
        Literal["peer", "router"],
        About(
            "ROCO_LINKS",
            "peer: agents on one host exchange communicates over direct links, one hop (without access "
            "control, or on mutual TLS); router: every communicate through the router "
            "(services/runtime/transport.py)",
        ),
    ] = "peer"
    listen: Annotated[
        str,
        About(
            "ROCO_LISTEN",
            "the endpoint the router listens on without --listen (services/runtime/router.py)",
        ),
    ] = f"tcp/0.0.0.0:{ROUTER_PORT}"
    connect: Annotated[
        tuple[str, ...],
        About(
            "ROCO_CONNECT",
            "other routers the router meshes with (comma-separated) without --connect; compose sets it from "
            "ROCO_PEER",
        ),
    ] = ()
    router_identity: Annotated[
        str | None,
        About(
            "ROCO_ROUTER_IDENTITY",
            "a meshed router's identity in the credentials folder without --identity (`roco deploy router`)",
        ),
    ] = None
    compose_project: Annotated[
        str | None,
        About(
            "ROCO_COMPOSE_PROJECT",
            "the compose project `roco fault` and `roco down --compose` act on; set: `roco fault` "
            "acts on the compose fleet by default",
        ),
    ] = None
    # --- the agent runtime
    receive_poll_us: Annotated[
        float,
        About(
            "ROCO_RECEIVE_POLL_US",
            "longest time an agent's receiving thread polls for a quick answer before it sleeps; 0: it never "
            "polls (services/runtime/polling.py)",
            parse=_microseconds,
            kind="µs ≥ 0",
        ),
    ] = 500.0
    receive: Annotated[
        Literal["inline", "agent-thread"],
        About(
            "ROCO_RECEIVE",
            "where an idle agent takes a communicate in: on the receiving thread, or handed to its own "
            "thread (the slower path, to compare; services/runtime/engine.py)",
        ),
    ] = "inline"
    hooks: Annotated[
        str | None,
        About(
            "ROCO_HOOKS",
            "module:attribute of the viewer hooks a process loads (services/runtime/hooks.py); unset: "
            "Rerun's with ROCO_RERUN=1, else none",
        ),
    ] = None
    interpreted: Annotated[
        bool,
        About(
            "ROCO_INTERPRETED",
            "1: the runtime's compiled modules load from their sources (services/runtime/native.py)",
        ),
    ] = False
    state_dir: Annotated[
        Path | None,
        About(
            "ROCO_STATE_DIR",
            "where agents keep what survives their restart (services/runtime/state_store.py); unset: the run "
            "folder's state/, else nothing is kept",
        ),
    ] = None
    km_store: Annotated[
        Path | None,
        About(
            "ROCO_KM_STORE",
            "a_km's knowledge store; unset: the run folder's km_store/, else in memory",
        ),
    ] = None
    tap_dir: Annotated[
        Path | None,
        About(
            "ROCO_TAP_DIR",
            "a folder where every transport appends the communicates it puts and every agent its FSM "
            "transitions (services/runtime/tap.py; `roco spec coverage --tests`); unset: nothing is tapped",
        ),
    ] = None
    # --- the viewer
    rerun: Annotated[
        bool,
        About(
            "ROCO_RERUN",
            "1: every process records the run with Rerun, recording.rrd in the run folder (services/viewer); "
            "roco run, scenario and chaos take --record/--no-record's default from it",
        ),
    ] = False
    rerun_id: Annotated[
        str | None,
        About(
            "ROCO_RERUN_ID",
            "the Rerun recording id; unset: the run folder's name",
        ),
    ] = None
    rerun_connect: Annotated[
        str | None,
        About(
            "ROCO_RERUN_CONNECT",
            "gRPC URL of a Rerun viewer every process streams to as well (`roco run --view` sets it)",
        ),
    ] = None
    rerun_camera: Annotated[
        bool,
        About(
            "ROCO_RERUN_CAMERA",
            "0: ag_ex renders no head camera for Rerun",
        ),
    ] = True
    # --- the report
    report_figures: Annotated[
        bool,
        About(
            "ROCO_REPORT_FIGURES",
            "0: a run's report.md is written without its PNG figures, most of the report's CPU time "
            "(services/report/figures.py)",
        ),
    ] = True
    # --- the robot
    realtime: Annotated[
        bool,
        About(
            "ROCO_REALTIME",
            "1: ag_ex's loop and the world process step on the wall clock (`roco run --realtime`)",
        ),
    ] = False
    seed: Annotated[
        int,
        About(
            "ROCO_SEED",
            "jitter of the jar content's start positions: ag_ex, the world process, `roco chaos`'s judge",
        ),
    ] = 0
    pose_seed: Annotated[
        int | None,
        About(
            "ROCO_POSE_SEED",
            "randomises the jar and bowl poses (as ROCO_SEED's readers); unset: the fixed poses",
        ),
    ] = None
    content_removed: Annotated[
        int,
        About(
            "ROCO_CONTENT_REMOVED",
            "spheres taken out of the jar before the run: the world process lays that many of its 18 on "
            "the floor behind the robot, out of reach and view (velma/model/scene.py remove_content): a "
            "pour that cannot fill the bowl, for benchmarks",
        ),
    ] = 0
    perception: Annotated[
        Literal["camera", "truth"] | None,
        About(
            "ROCO_PERCEPTION",
            "how ag_ex observes: head camera or the physics' truth (velma/executor/capture.py); unset: "
            "camera where off-screen GL renders, else truth",
        ),
    ] = None
    camera_idle_s: Annotated[
        float,
        About(
            "ROCO_CAMERA_IDLE_S",
            "seconds without an Observe before ag_ex's camera process ends "
            "(velma/executor/camera_process.py)",
            parse=_seconds_or_never,
            kind="s > 0 / never",
        ),
    ] = 60.0
    camera_hz: Annotated[
        float,
        About(
            "ROCO_CAMERA_HZ",
            "head-camera images per wall second at most that ag_ex renders while roco ros2 --camera "
            "subscribes (velma/executor/camera_feed.py; at most 30)",
            parse=_positive_factor,
            kind="Hz > 0",
        ),
    ] = 5.0
    watch_pace: Annotated[
        float,
        About(
            "ROCO_WATCH_PACE",
            "robot s per wall s at most while ag_ex watches with the head camera, when the fleet runs as "
            "fast as possible (velma/executor/watch.py)",
            parse=_positive_factor,
            kind="factor > 0",
        ),
    ] = 1.0
    world: Annotated[
        Literal["process", "loop"],
        About(
            "ROCO_WORLD",
            "where the kitchen's physics runs: a world process beside ag_ex, or inside ag_ex's loop to "
            "measure the split (velma/world/mode.py)",
        ),
    ] = "process"
    plant: Annotated[
        Literal["python", "compiled"] | None,
        About(
            "ROCO_PLANT",
            "the world's cycle, compiled (then required) or Python (velma/control/mujoco_side.py); unset: "
            "compiled where it can run",
        ),
    ] = None
    control_law: Annotated[
        Literal["python", "compiled"] | None,
        About(
            "ROCO_CONTROL_LAW",
            "the impedance control law, compiled (then required) or Python (velma/control/compiled.py); "
            "unset: compiled when built",
        ),
    ] = None
    # --- roco bench
    jade_home: Annotated[
        Path | None,
        About(
            "ROCO_JADE_HOME",
            "a JADE source tree `roco bench`'s jade part compiles and measures without --jade-home "
            "(services/bench/jade.py); unset: that part is skipped",
        ),
    ] = None

    @classmethod
    def from_env(
        cls, environ: Mapping[str, str] | None = None, *, only: Collection[str] | None = None
    ) -> Settings:
        """The settings of ``environ`` (default ``os.environ``, read now). ``only``: the fields
        to read (the others keep their defaults), so that a malformed variable the caller does
        not use does not stop it; None: all. Raises ValueError (one line naming the variable)
        for a value that does not parse, KeyError for a field of ``only`` that is not one."""
        env = os.environ if environ is None else environ
        declared = variables()
        values: dict[str, Any] = {}
        for field in declared if only is None else only:
            v = declared[field]
            raw = env.get(v.name, "").strip()
            if raw:
                values[field] = v.parse(v.name, raw, v.default)
        return cls(**values)

    @classmethod
    def env_name(cls, field: str) -> str:
        """The variable of ``field`` (``run_dir`` → ``ROCO_RUN_DIR``); KeyError when there is no
        such field."""
        return variables()[field].name


@cache
def variables() -> dict[str, Variable]:
    """Every field of :class:`Settings` as a :class:`Variable`, in declaration order (field
    name → variable). Raises TypeError for a field without :class:`About` or of a type this
    module cannot read."""
    out: dict[str, Variable] = {}
    for f in msgspec.structs.fields(Settings):
        about = next((m for m in getattr(f.type, "__metadata__", ()) if isinstance(m, About)), None)
        if about is None:
            raise TypeError(f"setting {f.name} has no About")
        kind, parse = (about.kind, about.parse) if about.parse else _reading(typing.get_args(f.type)[0])
        kind = about.kind or kind
        out[f.name] = Variable(
            field=f.name, name=about.name, kind=kind, default=f.default, doc=about.doc, parse=parse
        )
    return out


@cache
def settings() -> Settings:
    """This process's settings, read from ``os.environ`` at the first call and kept: for code
    that reads its configuration once per process. Code whose environment may change between
    calls (tests, a launcher that sets variables) reads :meth:`Settings.from_env` instead.
    Raises ValueError as :meth:`Settings.from_env` does (and again at the next call)."""
    return Settings.from_env()


# ------------------------------------------------------------------------------ deployment
class DeploymentVariable(msgspec.Struct, frozen=True):
    """A ``ROCO_*`` variable that roco's Python does not read: ``name``, its ``default`` (as
    the file that reads it writes it) and ``doc`` (what it sets, who reads it)."""

    name: str
    default: str
    doc: str


DEPLOYMENT: tuple[DeploymentVariable, ...] = (
    DeploymentVariable(
        "ROCO_IMAGE", "roco:latest", "runtime image the compose fleet runs and builds (all but these:)"
    ),
    DeploymentVariable(
        "ROCO_ROBOT_IMAGE", "roco-robot:latest", "ag_ex's image in the compose fleet (runtime + Mesa)"
    ),
    DeploymentVariable(
        "ROCO_VIEWER_IMAGE",
        "roco-viewer:latest",
        "the compose viewer's and recorder's image (runtime + Rerun CLI)",
    ),
    DeploymentVariable("ROCO_BASE", "python:3.11-slim", "base of the compose build's runtime stage"),
    DeploymentVariable("ROCO_BUILD_BASE", "python:3.11-slim", "base of the compose build's build stage"),
    DeploymentVariable("ROCO_UID", "10001", "uid the compose services run as (the image's roco)"),
    DeploymentVariable("ROCO_GID", "10001", "gid the compose services run as (the image's roco)"),
    DeploymentVariable(
        "ROCO_ROUTER_PUBLISH",
        f"127.0.0.1:{ROUTER_PORT}",
        "host address:port of the compose router (0.0.0.0: meshable)",
    ),
    DeploymentVariable("ROCO_PEER", "", "other routers the compose router meshes with, comma-separated"),
    DeploymentVariable("ROCO_RUNS", "../runs", "host folder of the compose fleet's run folders"),
    DeploymentVariable(
        "ROCO_RUN", "", "the compose fleet's run folder name (entrypoint.sh); unset: the router's start (UTC)"
    ),
    DeploymentVariable("ROCO_CERTS", "./certs", "host folder of the compose fleet's credentials"),
    DeploymentVariable("ROCO_PROTO", "tls", "the compose router's protocol: tls (mutual TLS) or tcp"),
    DeploymentVariable("ROCO_ROUTER_LOG", "info", "Zenoh's log level in the compose router (its RUST_LOG)"),
    DeploymentVariable("ROCO_VIEWER_BIND", "127.0.0.1", "host address of the compose Rerun viewer's ports"),
    DeploymentVariable("ROCO_VIEWER_WEB_PORT", "9090", "host port of the compose viewer's web page"),
    DeploymentVariable("ROCO_VIEWER_GRPC_PORT", "9876", "host port of the compose viewer's gRPC stream"),
    DeploymentVariable(
        "ROCO_NEW_RUN", "0", "1 (the compose router): this container starts a run (entrypoint.sh)"
    ),
    DeploymentVariable(
        "ROCO_FLEET_DIR", "/var/lib/roco/fleet", "where entrypoint.sh keeps the compose fleet's run name"
    ),
    DeploymentVariable("ROCO_BUILD_NATIVE", "1", "0: setup.py compiles no extension module"),
)
"""Variables of the deployment files and the build (module docstring): docker compose
(deploy/compose.yaml), deploy/entrypoint.sh, setup.py."""


def deployment_name(key: str) -> str:
    """The :data:`DEPLOYMENT` variable of ``key`` (``uid`` → ``ROCO_UID``); KeyError when none
    is declared."""
    name = PREFIX + key.upper()
    if not any(d.name == name for d in DEPLOYMENT):
        raise KeyError(f"no deployment variable {name}")
    return name


def names() -> list[str]:
    """Every declared variable's name: the settings', then :data:`DEPLOYMENT`'s."""
    return [v.name for v in variables().values()] + [d.name for d in DEPLOYMENT]
