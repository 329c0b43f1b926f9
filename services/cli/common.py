"""What the command modules of services/cli/ share: ``fail``, the exit status of an
interrupted command, the options several commands take, and the checks and look-ups they make
the same way.

Every command module beside it imports from here; services/cli/__init__.py only assembles
their Typer apps. This module imports nothing above the runtime and services/fleet_state.py;
no tool imports services/cli/, the top layer (README.md, "How it is built").
"""

from __future__ import annotations

import os
import signal
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal

import typer

from services.fleet_state import FLEET_FILE, FleetState, FleetStateError, read_state
from services.runtime.run_folder import RunFolderError, check_run_folder, is_bag_folder, new_run_dir
from services.runtime.session import SessionRefused, listening, open_operator, port_in_use
from services.security.context import register
from shared.settings import ROUTER_PORT, Settings

if TYPE_CHECKING:
    import zenoh

    from services.spec.model import SystemSpec

MARKUP: Literal["markdown"] = "markdown"
"""Help texts are Markdown (typer's ``rich_markup_mode``): `code`, lists, indented examples."""
INTERRUPTED = 130
"""The exit status of a command ended by Ctrl-C (SIGINT), SIGTERM or SIGHUP: 128 + SIGINT."""


def fail(message: str, code: int = 1) -> typer.Exit:
    """Print ``roco: message`` on stderr; the exit (status ``code``) to raise."""
    typer.echo(f"roco: {message}", err=True)
    return typer.Exit(code)


# ---------------------------------------------------------------------------------- options
AclOption = Annotated[
    bool | None,
    typer.Option(
        "--acl/--no-acl",
        help="authenticate every process and enforce the access control generated from the "
        "specification (docs/security.md); --no-acl for experiments [default: on, unless ROCO_ACL=0]",
        show_default=False,
    ),
]
TlsOption = Annotated[
    bool | None,
    typer.Option(
        "--tls/--no-tls",
        help="with access control, mutual TLS and direct links between agents; --no-tls: passwords "
        "over TCP, every communicate through the router [default: on, unless ROCO_TLS=0]",
        show_default=False,
    ),
]
CredentialsOption = Annotated[
    Path | None,
    typer.Option(
        "--credentials",
        help="the deployment's credentials folder (`roco deploy certs`) for a router with access "
        "control; the tool authenticates as `operator` (ROCO_IDENTITY) [default: ROCO_SECURITY, "
        "else the fleet of 'roco up']",
        show_default=False,
    ),
]
RunsDirMade = Annotated[
    Path,
    typer.Option("--runs-dir", help="where this run's folder is made (named by the date and time it starts)"),
]
RouterOption = Annotated[
    str | None,
    typer.Option(
        help=f"the router to reach, e.g. tcp/HOST:{ROUTER_PORT} [default: the fleet of 'roco up', "
        "else ROCO_ROUTER]",
        show_default=False,
    ),
]
FleetRunsDir = Annotated[
    Path,
    typer.Option(
        "--runs-dir", help="where 'roco up' keeps its fleet state: the fleet's router, unless --router"
    ),
]
RecordOption = Annotated[
    bool,
    typer.Option(
        "--record/--no-record",
        envvar=Settings.env_name("rerun"),
        help="record robot, scene and traffic in RUN/recording.rrd (Rerun)",
    ),
]
ViewOption = Annotated[
    bool, typer.Option("--view/--no-view", help="also show the recording live in a Rerun viewer")
]
GatewayOption = Annotated[
    int | None,
    typer.Option(
        "--gateway",
        min=1,
        max=65535,
        metavar="PORT",
        help="also run the ACL gateway (`roco gateway --port PORT`, docs/gateway.md) as a process of "
        "the fleet: agents of other FIPA platforms post to 127.0.0.1:PORT [default: no gateway]",
        show_default=False,
    ),
]
Ros2Option = Annotated[
    bool,
    typer.Option(
        "--ros2",
        help="also run `roco ros2 --all` (docs/ros2.md) as a process of the fleet: ROS 2 node /roco "
        "on --ros2-domain publishes joint_states, tf, roco/task_state, the head camera (while subscribed) "
        "and serves roco/say",
    ),
]
Ros2DomainOption = Annotated[
    int, typer.Option("--ros2-domain", min=0, max=232, help="with --ros2: the face's ROS_DOMAIN_ID")
]
Ros2NamespaceOption = Annotated[
    str, typer.Option("--ros2-namespace", help="with --ros2: the face's namespace (its topics below it)")
]


LiveOption = Annotated[
    bool | None,
    typer.Option(
        "--live/--no-live",
        help="a live view under the event lines: plan, step, agents, time, loop overruns "
        "[default: on a terminal, unless --quiet]",
        show_default=False,
    ),
]
SpecFile = Annotated[
    Path | None,
    typer.Option(
        "--spec",
        envvar=Settings.env_name("spec"),
        help="the system's specification file [default: $ROCO_SPEC, else the run's, else roco's kitchen]",
        show_default=False,
    ),
]
"""``--spec FILE`` (or ``ROCO_SPEC``) of the commands that read the specification; resolve it
with :func:`chosen_spec`."""


def chosen_spec(given: Path | None, run_dir: Path | None = None) -> Path:
    """The specification a command works with: ``given`` (``--spec`` or ``ROCO_SPEC``), else
    the one run ``run_dir`` used (services/runtime/run_folder.py ``spec_of_run``), else the
    shipped Robot Companion's. Raises :class:`typer.Exit` (one line, exit 1) when the file
    cannot be loaded: what follows needs it."""
    from services.runtime.run_folder import spec_of_run
    from services.spec.model import DEFAULT_SPEC, SpecError, load

    path = given or (spec_of_run(run_dir) if run_dir is not None else None) or DEFAULT_SPEC
    try:
        load(path)
    except SpecError as exc:
        raise fail(str(exc)) from None
    return path


def fleet_spec(given: Path | None, runs_dir: Path, router: str | None) -> Path:
    """The specification file ``given`` (``--spec``), else that of the fleet ``roco up`` keeps
    in ``runs_dir`` (unless a ``router`` is named: then not that fleet's), else the shipped
    one. Raises :class:`typer.Exit` as :func:`chosen_spec` does."""
    state = fleet_state(runs_dir) if router is None else None
    return chosen_spec(given, Path(state.run_dir) if state is not None else None)


def fleet_system(given: Path | None, runs_dir: Path, router: str | None) -> SystemSpec:
    """:func:`fleet_spec`, loaded."""
    from services.spec.model import load

    return load(fleet_spec(given, runs_dir, router))


CheckOnly = Annotated[
    bool, typer.Option("--check", help="only say whether the file is what the specification gives")
]
"""``--check`` of the commands that write a file rendered from the specification."""


def file_option(what: str, default: str) -> Any:
    """``--file F`` of a command that writes ``what`` (default: ``default`` in this checkout)."""
    return typer.Option(help=f"the {what} [default: {default} of this checkout]", show_default=False)


def shown(path: Path) -> str:
    """``path`` relative to the working folder where it is below it."""
    try:
        return str(path.resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(path)


# ------------------------------------------------------------------ checks made before a run
def run_folder(path: Path) -> Path:
    """``path`` when it is a run folder (``run.json`` or ``traffic.jsonl`` in it) or a rosbag2
    folder of ``roco export`` (services/ros2/bag.py); one line and exit 2 otherwise, before
    anything is read or written."""
    if is_bag_folder(path):
        return path
    try:
        check_run_folder(path)
    except RunFolderError as exc:
        raise fail(str(exc), code=2) from None
    return path


def new_run_folder(runs_dir: Path) -> Path:
    """A new run folder under ``runs_dir`` (services/runtime/run_folder.py ``new_run_dir``);
    one line and exit 2 when none can be made there."""
    try:
        return new_run_dir(runs_dir)
    except RunFolderError as exc:
        raise fail(str(exc), code=2) from None


def port_free(port: int, option: str, host: str = "127.0.0.1") -> None:
    """One line and exit 2 when something listens on ``host:port`` already, naming ``option``
    to choose another."""
    if listening(f"tcp/{host}:{port}"):
        raise fail(port_in_use(host, port, option), code=2)


def interrupt(signum: int, frame: object) -> None:
    """A signal handler that ends the command as Ctrl-C does (raises KeyboardInterrupt)."""
    raise KeyboardInterrupt


def stop_on_signals() -> None:
    """SIGTERM and SIGHUP (the terminal closed) end a command as Ctrl-C does: the fleet it
    started is stopped, none of its processes is left behind."""
    signal.signal(signal.SIGTERM, interrupt)
    signal.signal(signal.SIGHUP, interrupt)


def security_switches(acl: bool | None, tls: bool | None) -> None:
    """Set the switches the launcher reads (``ROCO_ACL``, ``ROCO_TLS``;
    services/security/context.py) for this process and the processes it starts; None leaves
    the environment's choice."""
    if tls is not None:
        os.environ[Settings.env_name("tls")] = "1" if tls else "0"
    if acl is not None:
        os.environ[Settings.env_name("acl")] = "1" if acl else "0"
    if tls:
        os.environ[Settings.env_name("acl")] = "1"


# ------------------------------------------------------------- reaching a running fleet
def fleet_state(runs_dir: Path) -> FleetState | None:
    """The fleet ``roco up`` left in ``runs_dir`` (services/fleet_state.py), None when none is
    up; one line and exit 2 for a state file that cannot be read."""
    try:
        return read_state(runs_dir)
    except FleetStateError as exc:
        raise fail(str(exc), code=2) from None


def fleet_endpoint(state: FleetState) -> str:
    """The router endpoint of the fleet `roco up` left ``state`` of, its credentials registered
    for it when the fleet runs with access control (its run folder's ``security``)."""
    security = Path(state.run_dir) / "security"
    if security.is_dir():  # the fleet of `roco up --runs-dir …` runs with access control
        register(state.endpoint, security)
    return state.endpoint


def endpoint_of(router: str | None, runs_dir: Path) -> str:
    """The router to reach: ``router`` (``--router``), else the fleet of ``roco up`` in
    ``runs_dir``, else ``ROCO_ROUTER``."""
    if router:
        return router
    state = fleet_state(runs_dir)
    if state is None:
        return ",".join(Settings.from_env(only=("router",)).router)
    return fleet_endpoint(state)


def operator_session(
    endpoint: str, credentials: Path | None = None, runs_dir: Path | None = None
) -> zenoh.Session:
    """The operator's session with the router at ``endpoint`` (its credentials from
    ``credentials``, ``ROCO_SECURITY`` or the fleet of ``roco up``); one line and exit 1 when
    it cannot be opened (services/runtime/session.py ``open_operator``). ``runs_dir``: where
    the endpoint was found (``roco up``'s state), named when that fleet is gone."""
    try:
        return open_operator(endpoint, credentials=credentials)
    except SessionRefused as exc:
        state = fleet_state(runs_dir) if runs_dir is not None else None
        gone = state is not None and state.endpoint == endpoint and not listening(endpoint)
        if runs_dir is not None and gone:
            where = runs_dir / FLEET_FILE
            raise fail(
                f"no router answers at {endpoint}: the fleet {where} names is gone; "
                "'roco down' clears its state, then 'roco up' starts one"
            ) from None
        raise fail(str(exc)) from None
