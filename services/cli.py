"""``roco``: run the Robot Companion, talk to a running fleet, and read run folders.

    roco run "pour the jar into the bowl"   whole system headless, to the end of the task
    roco up / roco down                      start / stop a fleet that keeps running
    roco send "<command>"                    give a running fleet a command
    roco status                              which agents are alive (Zenoh liveliness)
    roco report RUN                          write RUN/report.md

Every failure prints one line starting with ``roco:`` and exits non-zero.
"""

from __future__ import annotations

import os
import queue
import signal
import sys
import threading
import time
import uuid
from pathlib import Path
from typing import Annotated

import msgspec
import typer
import zenoh

from services.human_interface.messages import FINAL_REPORTS, HumanInput, HumanReport, ReportKind
from services.runtime import keys
from services.runtime.launcher import AGENT_ORDER, Fleet, LaunchError, alive_agents, free_port, open_client
from services.runtime.run_folder import RunInfo, new_run_dir, write_run_info

app = typer.Typer(add_completion=False, no_args_is_help=True, help=__doc__)
FLEET_FILE = ".fleet.json"
DEFAULT_ROUTER = "tcp/127.0.0.1:7447"


class FleetState(msgspec.Struct):
    """What ``roco up`` leaves for ``roco down``/``send``/``status``: endpoint and PIDs."""

    endpoint: str
    run_dir: str
    pids: dict[str, int]


def fail(message: str, code: int = 1) -> typer.Exit:
    typer.echo(f"roco: {message}", err=True)
    return typer.Exit(code)


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def _clock(t0: float) -> str:
    return f"[{time.time() - t0:7.1f} s]"


def _send_command(session: object, text: str, request_id: str) -> None:
    session.put(keys.HUMAN_IN, msgspec.json.encode(HumanInput(text=text, request_id=request_id)))  # type: ignore[attr-defined]


@app.command()
def run(
    command: Annotated[str, typer.Argument(help="what the person says, e.g. 'pour the jar into the bowl'")],
    runs_dir: Annotated[Path, typer.Option(help="where run folders are made")] = Path("runs"),
    realtime: Annotated[bool, typer.Option(help="pace the simulation to wall time")] = False,
    timeout: Annotated[float, typer.Option(help="give up after this many seconds")] = 900.0,
    quiet: Annotated[bool, typer.Option(help="print only the outcome")] = False,
    seed: Annotated[int, typer.Option(min=0, help="jitter of the jar content's start positions")] = 0,
    pose_seed: Annotated[
        int | None, typer.Option(min=0, help="randomise the jar and bowl poses (±2 cm, ±10°) with this seed")
    ] = None,
) -> None:
    """Start router, recorder and one process per agent; give a_hi the command; wait for the
    outcome; stop everything; write the run folder's report. Exit 0 only on success."""
    from services.monitor import is_world_update, progress_line

    run_dir = new_run_dir(runs_dir)
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    info = RunInfo(
        command=command,
        started=time.time(),
        router=endpoint,
        realtime=realtime,
        seed=seed,
        pose_seed=pose_seed,
    )
    fleet = Fleet(run_dir, endpoint, env=_scene_env(realtime, seed, pose_seed))
    t0 = info.started
    lines: queue.SimpleQueue[str | HumanReport] = queue.SimpleQueue()
    request_id = uuid.uuid4().hex[:8]
    decoder = msgspec.json.Decoder(HumanReport)
    outcome: HumanReport | None = None
    session = None
    signal.signal(signal.SIGTERM, _interrupt)
    try:
        typer.echo(f"roco: run folder {run_dir}; router {endpoint}")
        fleet.start_router()
        session = open_client(endpoint)
        fleet.start_recorder()
        fleet.wait_alive(session, ["recorder"], timeout=60)
        if not quiet:

            def on_traffic(sample: zenoh.Sample) -> None:
                line = progress_line(str(sample.key_expr), sample.payload.to_bytes())
                if line is not None:
                    lines.put(line)

            session.declare_subscriber(keys.FIPA_ALL, on_traffic)
        session.declare_subscriber(keys.HUMAN_OUT, lambda s: lines.put(decoder.decode(s.payload.to_bytes())))
        knowledge = threading.Event()

        def on_knowledge(sample: zenoh.Sample) -> None:
            if is_world_update(sample.payload.to_bytes()):
                knowledge.set()

        session.declare_subscriber(keys.fipa_key("C6", "a_ta", "a_km"), on_knowledge)
        fleet.start_agents()
        waited = fleet.wait_alive(session, AGENT_ORDER, timeout=120)
        typer.echo(f"{_clock(t0)} all agents alive after {waited:.1f} s: {', '.join(AGENT_ORDER)}")
        # paper Table 7: a_km receives initial knowledge about the environment before the command
        if not knowledge.wait(timeout=60):
            raise LaunchError("a_km received no initial knowledge from a_ta within 60 s")
        typer.echo(f"{_clock(t0)} a_km has initial knowledge of the scene")
        info.processes = fleet.pids()
        info.command_sent = time.time()
        write_run_info(run_dir, info)
        _send_command(session, command, request_id)
        typer.echo(f"{_clock(t0)} person → a_hi: “{command}”")
        deadline = time.monotonic() + timeout
        while outcome is None:
            if time.monotonic() > deadline:
                raise LaunchError(f"no outcome within {timeout:.0f} s")
            dead = fleet.dead()
            if dead:
                raise LaunchError(f"process {dead[0]} exited during the run (see {run_dir}/logs)")
            try:
                item = lines.get(timeout=0.5)
            except queue.Empty:
                continue
            if isinstance(item, HumanReport):
                if item.request_id != request_id:
                    continue
                typer.echo(f"{_clock(t0)} a_hi → person: {item.kind.value}: {item.text}")
                if item.kind in FINAL_REPORTS:
                    outcome = item
            else:
                typer.echo(f"{_clock(t0)} {item}")
    except LaunchError as exc:
        info.detail = str(exc)
    except KeyboardInterrupt:
        info.detail = "interrupted"
    finally:
        if session is not None:
            session.close()
        fleet.stop()
    info.ended = time.time()
    info.succeeded = outcome is not None and outcome.kind is ReportKind.SUCCEEDED
    if outcome is not None:
        info.detail = outcome.text
    write_run_info(run_dir, info)
    _finish_report(run_dir, info)
    if not info.succeeded:
        raise fail(f"the task failed: {info.detail} (run folder {run_dir})")


def _scene_env(realtime: bool, seed: int, pose_seed: int | None) -> dict[str, str]:
    """The environment that tells ag_ex its pacing and scene (services/executor/agent.py)."""
    env = {"ROCO_REALTIME": "1" if realtime else "0", "ROCO_SEED": str(seed)}
    if pose_seed is not None:
        env["ROCO_POSE_SEED"] = str(pose_seed)
    return env


def _finish_report(run_dir: Path, info: RunInfo) -> None:
    from services.report import build_report, write_report

    try:
        path = write_report(run_dir)
        report = build_report(run_dir)
    except Exception as exc:  # the run's outcome stands even if its report cannot be made
        typer.echo(f"roco: report not written: {exc}", err=True)
        return
    c = report.content
    share = f"{c.inside} of {c.total} spheres in the {c.container}" if c.observed else "content not observed"
    typer.echo(
        f"roco: {'succeeded' if info.succeeded else 'failed'} in {info.ended - info.started:.1f} s wall; "  # type: ignore[operator]
        f"{report.sizes.count} communicates; {share}; report {path}"
    )


@app.command()
def up(
    port: Annotated[int, typer.Option(help="router TCP port on 127.0.0.1")] = 7447,
    runs_dir: Annotated[Path, typer.Option(help="where the fleet's run folder is made")] = Path("runs"),
    realtime: Annotated[bool, typer.Option(help="pace the simulation to wall time")] = True,
    seed: Annotated[int, typer.Option(min=0, help="jitter of the jar content's start positions")] = 0,
    pose_seed: Annotated[
        int | None, typer.Option(min=0, help="randomise the jar and bowl poses (±2 cm, ±10°) with this seed")
    ] = None,
) -> None:
    """Start router, recorder and all agents in the background; they keep running until
    ``roco down``."""
    state_file = runs_dir / FLEET_FILE
    if state_file.exists():
        raise fail(f"a fleet is already up ({state_file}); run 'roco down' first")
    run_dir = new_run_dir(runs_dir)
    endpoint = f"tcp/127.0.0.1:{port}"
    fleet = Fleet(run_dir, endpoint, env=_scene_env(realtime, seed, pose_seed))
    try:
        fleet.start_router()
        session = open_client(endpoint)
        fleet.start_recorder()
        fleet.wait_alive(session, ["recorder"], timeout=60)
        fleet.start_agents()
        waited = fleet.wait_alive(session, AGENT_ORDER, timeout=120)
        session.close()
    except LaunchError as exc:
        fleet.stop()
        raise fail(str(exc)) from None
    write_run_info(
        run_dir,
        RunInfo(
            started=time.time(),
            router=endpoint,
            processes=fleet.pids(),
            realtime=realtime,
            seed=seed,
            pose_seed=pose_seed,
        ),
    )
    state_file.write_bytes(msgspec.json.encode(FleetState(endpoint, str(run_dir), fleet.pids())))
    typer.echo(f"roco: fleet up on {endpoint} in {waited:.1f} s; run folder {run_dir}")


def _fleet_state(runs_dir: Path) -> FleetState | None:
    path = runs_dir / FLEET_FILE
    if not path.exists():
        return None
    return msgspec.json.decode(path.read_bytes(), type=FleetState)


@app.command()
def down(runs_dir: Annotated[Path, typer.Option()] = Path("runs")) -> None:
    """Stop the fleet ``roco up`` started (only the processes it started, by PID)."""
    state = _fleet_state(runs_dir)
    if state is None:
        raise fail(f"no fleet is up (no {runs_dir / FLEET_FILE})")
    order = [n for n in state.pids if n not in ("recorder", "router")] + ["recorder", "router"]
    for name in order:
        pid = state.pids.get(name)
        if pid is None:
            continue
        try:
            os.kill(pid, signal.SIGTERM)
        except ProcessLookupError:
            continue
        for _ in range(100):
            try:
                os.kill(pid, 0)
            except ProcessLookupError:
                break
            time.sleep(0.05)
    (runs_dir / FLEET_FILE).unlink()
    typer.echo(f"roco: fleet stopped; run folder {state.run_dir}")


def _endpoint(router: str | None, runs_dir: Path) -> str:
    if router:
        return router
    state = _fleet_state(runs_dir)
    return state.endpoint if state else os.environ.get("ROCO_ROUTER", DEFAULT_ROUTER)


@app.command()
def send(
    command: Annotated[str, typer.Argument(help="what the person says")],
    router: Annotated[
        str | None, typer.Option(help="router endpoint (default: the fleet of 'roco up')")
    ] = None,
    runs_dir: Annotated[Path, typer.Option()] = Path("runs"),
    timeout: Annotated[float, typer.Option(help="seconds to wait for the outcome")] = 900.0,
    priority: Annotated[int, typer.Option(help="larger is more urgent")] = 0,
) -> None:
    """Give a running fleet a command and wait for a_hi's final report."""
    endpoint = _endpoint(router, runs_dir)
    try:
        session = open_client(endpoint)
    except Exception:
        raise fail(f"no router answers at {endpoint}; is the fleet up?") from None
    reports: queue.SimpleQueue[HumanReport] = queue.SimpleQueue()
    dec = msgspec.json.Decoder(HumanReport)
    session.declare_subscriber(keys.HUMAN_OUT, lambda s: reports.put(dec.decode(s.payload.to_bytes())))
    if "a_hi" not in alive_agents(session):
        session.close()
        raise fail(f"a_hi is not alive at {endpoint}")
    request_id = uuid.uuid4().hex[:8]
    session.put(
        keys.HUMAN_IN, msgspec.json.encode(HumanInput(text=command, request_id=request_id, priority=priority))
    )
    deadline = time.monotonic() + timeout
    try:
        while True:
            try:
                report = reports.get(timeout=max(0.1, deadline - time.monotonic()))
            except queue.Empty:
                raise fail(f"no outcome within {timeout:.0f} s") from None
            if report.request_id != request_id:
                continue
            typer.echo(f"{report.kind.value}: {report.text}")
            if report.kind in FINAL_REPORTS:
                if report.kind is not ReportKind.SUCCEEDED:
                    raise typer.Exit(1)
                return
    finally:
        session.close()


@app.command()
def status(
    router: Annotated[str | None, typer.Option(help="router endpoint")] = None,
    runs_dir: Annotated[Path, typer.Option()] = Path("runs"),
) -> None:
    """List the agents that hold a liveliness token; exit 1 if any agent is missing."""
    endpoint = _endpoint(router, runs_dir)
    try:
        session = open_client(endpoint)
    except Exception:
        raise fail(f"no router answers at {endpoint}") from None
    alive = alive_agents(session)
    session.close()
    for name in (*AGENT_ORDER, "recorder"):
        typer.echo(f"{name:9s} {'alive' if name in alive else 'absent'}")
    if not set(AGENT_ORDER) <= alive:
        raise typer.Exit(1)


@app.command()
def report(run_dir: Annotated[Path, typer.Argument(help="a run folder")]) -> None:
    """Write RUN/report.md from the run's traffic record."""
    from services.report import write_report

    if not run_dir.is_dir():
        raise fail(f"{run_dir} is not a run folder")
    typer.echo(str(write_report(run_dir)))


def main() -> None:
    try:
        app()
    except KeyboardInterrupt:
        sys.exit(130)


if __name__ == "__main__":
    main()
