"""One agent process: ``python -m services.runtime.main AGENT``.

Configuration comes from the environment so that the same command serves the local launcher
and a container: ``ROCO_ROUTER`` (comma-separated Zenoh endpoints, default
``tcp/127.0.0.1:7447``), ``ROCO_RUN_DIR`` (run folder; logs go to stderr otherwise),
``ROCO_SPEC`` (specification file), ``ROCO_LOG_LEVEL``, ``ROCO_LOG_STDOUT`` (1: the log on
standard output too, :func:`setup_logging`), ``ROCO_READY_FILE`` (written once the agent is
ready, ``Engine.ready``; removed at its start and stop: shared/ready_file.py), ``ROCO_FAULTS``
(fault settings, JSON; docs/faults.md), ``ROCO_SECURITY`` (credentials folder: the agent
authenticates as itself; docs/security.md). The Zenoh transport is always wrapped in the fault
layer (:class:`~services.runtime.faults.FaultyTransport`) so that ``roco fault`` can reach
every agent at run time; with no fault active it costs one attribute test per publication.
SIGTERM and SIGINT stop the agent cleanly. Exit code 2 on a configuration error;
:data:`EXIT_LOST` when a receiving thread of the transport ended before the agent stopped
(the agent would go on alive, its liveliness token up, deaf on that subscription): the process
ends after the current step (at the latest :data:`LOST_GRACE_S` later), and whoever runs it
starts it again as any crashed agent (services/scenario/runner.py; compose's restart policy).
"""

from __future__ import annotations

import contextlib
import functools
import importlib
import logging
import os
import signal
import sys
import threading
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from services.runtime.agent import Agent
    from services.spec.model import SystemSpec

EXIT_LOST = 70
"""The exit code of an agent whose receiving thread ended (``EX_SOFTWARE`` of sysexits.h: an
internal error)."""
LOST_GRACE_S = 10.0
"""How long (s) an agent whose receiving thread ended has to stop by itself before its process
is ended anyway (a step that does not return: a_pl planning)."""

# The runtime, the transport and the specification are imported where they are used, not here:
# a process that an agent starts with multiprocessing's spawn (ag_ex's loop and camera) imports
# this module again as its ``__mp_main__``, and should not pay ≈ 6 MiB for what it never runs.


def router_endpoints() -> list[str]:
    """Endpoints from ``ROCO_ROUTER`` (read now)."""
    from shared.settings import Settings

    return list(Settings.from_env(only=("router",)).router)


def agent_class(spec: SystemSpec, name: str) -> type[Agent]:
    """Import the implementation the specification names for agent ``name``.
    Raises SpecError when the agent or its implementation is unknown."""
    from services.runtime.agent import Agent
    from services.spec.model import SpecError

    for a in spec.agents:
        if a.name == name:
            module, _, cls = a.implementation.partition(":")
            try:
                found = getattr(importlib.import_module(module), cls)
            except (ImportError, AttributeError) as exc:
                raise SpecError(f"agent {name}: cannot load {a.implementation}: {exc}") from None
            if not (isinstance(found, type) and issubclass(found, Agent)):
                raise SpecError(f"agent {name}: {a.implementation} is not an Agent")
            return found
    raise SpecError(f"no agent {name!r} in the specification")


def setup_logging(name: str) -> None:
    """Log at ``ROCO_LOG_LEVEL`` (default INFO) to the run folder's ``logs/NAME.log``, else to
    stderr, and with ``ROCO_LOG_STDOUT=1`` to standard output as well (instead of stderr without
    a run folder): what ``docker compose logs`` shows. One line per record, the same on each
    (services/runtime/log_format.py). Raises ValueError for a ``ROCO_LOG_LEVEL`` that is not a
    level."""
    from services.runtime.log_format import OneLineFormatter
    from shared.settings import Settings

    read = Settings.from_env(only=("log_level", "run_dir", "log_stdout"))
    handlers: list[logging.Handler] = []
    if read.run_dir is not None:
        (read.run_dir / "logs").mkdir(parents=True, exist_ok=True)
        handlers.append(logging.FileHandler(read.run_dir / "logs" / f"{name}.log"))
    if read.log_stdout:
        handlers.append(logging.StreamHandler(sys.stdout))
    elif not handlers:
        handlers.append(logging.StreamHandler(sys.stderr))
    for handler in handlers:
        handler.setFormatter(OneLineFormatter())
    logging.basicConfig(level=read.log_level, handlers=handlers, force=True)


def ready_file() -> Path | None:
    """``ROCO_READY_FILE`` (read now), emptied: a file a killed process left there does not
    speak for this one (shared/ready_file.py). Raises OSError when it cannot be removed."""
    from shared import ready_file as ready
    from shared.settings import Settings

    path = Settings.from_env(only=("ready_file",)).ready_file
    ready.clear(path)
    return path


def say_ready(path: Path | None, line: str) -> None:
    """Write ``line`` to the ready file ``path`` (shared/ready_file.py); a file that cannot be
    written is logged, never a reason to stop the process (its health check then says
    unhealthy)."""
    from shared import ready_file as ready

    why = ready.mark(path, line)
    if why is not None:
        logging.getLogger(__name__).error("%s", why)


def main(argv: list[str] | None = None) -> int:
    from services.runtime.faults import FaultyTransport, settings_from_env
    from services.runtime.transport import ZenohTransport
    from services.spec.model import SpecError, load, spec_path
    from shared.ready_file import clear as clear_ready
    from shared.settings import Settings

    args = sys.argv[1:] if argv is None else argv
    if len(args) != 1:
        print("usage: python -m services.runtime.main AGENT", file=sys.stderr)
        return 2
    name = args[0]
    try:
        setup_logging(name)
    except ValueError as exc:  # a bad ROCO_LOG_LEVEL
        print(f"roco: {exc}", file=sys.stderr)
        return 2
    try:
        spec = load(spec_path())
        cls = agent_class(spec, name)
    except SpecError as exc:
        print(f"roco: {exc}", file=sys.stderr)
        return 2
    try:
        faults = settings_from_env()
    except ValueError as exc:
        print(f"roco: {Settings.env_name('faults')}: {exc}", file=sys.stderr)
        return 2
    try:  # authenticates as the agent itself when the fleet has access control (docs/security.md)
        zenoh_transport = ZenohTransport(router_endpoints(), identity=name, links=None)
    except ValueError as exc:  # no credentials for this agent
        print(f"roco: agent {name}: {exc}", file=sys.stderr)
        return 2
    transport = FaultyTransport(zenoh_transport, name, faults)
    try:
        agent = cls(transport, spec)
    except (SpecError, ValueError) as exc:  # e.g. roles that differ from the spec, a malformed ROCO_SEED
        transport.close()
        text = str(exc) if str(exc).startswith(f"agent {name}") else f"agent {name}: {exc}"
        print(f"roco: {text}", file=sys.stderr)
        return 2

    engine = agent.engine

    def on_signal(signum: int, frame: FrameType | None) -> None:
        engine.stop()

    deadline = threading.Timer(LOST_GRACE_S, os._exit, (EXIT_LOST,))
    deadline.daemon = True

    def on_lost(why: str) -> None:  # a receiving thread, just before it ends
        engine.stop()
        with contextlib.suppress(RuntimeError):  # started by another receiving thread
            deadline.start()

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    zenoh_transport.on_lost = on_lost
    ready = ready_file()
    engine.on_ready = functools.partial(say_ready, ready)
    engine.bind()
    logging.getLogger(name).info("started (pid %d)", os.getpid())
    try:
        engine.run()
    except Exception:  # the log says why the agent stopped (the launcher names the log)
        logging.getLogger(name).exception("stopped by an error")
        raise
    finally:
        clear_ready(ready)
        logging.getLogger(name).info("stopping; counters %s", dict(agent.counters))
        close = getattr(agent, "close", None)
        if callable(close):
            close()
        transport.close()
    deadline.cancel()
    if zenoh_transport.lost is not None:
        logging.getLogger(name).error("ended: %s", zenoh_transport.lost)
        return EXIT_LOST
    return 0


if __name__ == "__main__":
    sys.exit(main())
