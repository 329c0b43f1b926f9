"""``roco run``: the whole system of its specification (``--spec``) on one command, to the end
of the task (services/scenario/runner.py), and how a run of ``roco run`` and ``roco scenario``
starts and ends: the report written, one line of outcome, the exit status."""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from services.cli.common import (
    AclOption,
    GatewayOption,
    LiveOption,
    RecordOption,
    Ros2DomainOption,
    Ros2NamespaceOption,
    Ros2Option,
    RunsDirMade,
    SpecFile,
    TlsOption,
    ViewOption,
    chosen_spec,
    fail,
    new_run_folder,
    port_free,
    security_switches,
    stop_on_signals,
)
from services.cli.report import finish_report
from services.cli.ros2 import ros2_args
from services.cli.run_env import live_watch, scene_env, viewer_env
from services.runtime.run_folder import RunInfo
from services.spec.model import load

if TYPE_CHECKING:
    from services.live.watch import LiveWatch

run_app = typer.Typer()


@run_app.command(short_help="Run the whole system on one command, to the end of the task.")
def run(
    command: Annotated[str, typer.Argument(help="what the person says, e.g. 'pour the jar into the bowl'")],
    runs_dir: RunsDirMade = Path("runs"),
    realtime: Annotated[bool, typer.Option(help="pace the simulation to wall time")] = False,
    timeout: Annotated[float, typer.Option(help="give up after this many seconds")] = 900.0,
    quiet: Annotated[bool, typer.Option(help="print only the outcome")] = False,
    seed: Annotated[int, typer.Option(min=0, help="jitter of the jar content's start positions")] = 0,
    pose_seed: Annotated[
        int | None, typer.Option(min=0, help="randomise the jar and bowl poses (±2 cm, ±10°) with this seed")
    ] = None,
    record: RecordOption = True,
    view: ViewOption = False,
    acl: AclOption = None,
    tls: TlsOption = None,
    live: LiveOption = None,
    gateway: GatewayOption = None,
    ros2: Ros2Option = False,
    ros2_domain: Ros2DomainOption = 0,
    ros2_namespace: Ros2NamespaceOption = "/",
    spec: SpecFile = None,
) -> None:
    """Start router, recorder and one process per agent of the specification (and the ACL
    gateway with `--gateway`, the ROS 2 face with `--ros2`); give the command to the agent that
    plays the person's role (a_hi in the kitchen); wait for the outcome; stop everything; write
    the run folder's report. Exit 0 only on success with no requirement flagged violated
    during the run (docs/spec.md, the live monitor), 130 when interrupted (Ctrl-C: the fleet
    is stopped, the report written)."""
    from services.scenario.model import Scenario, Step

    path = chosen_spec(spec)
    system = load(path)
    if system.playing("person") is None:
        raise fail(f'no agent of {system.system} plays the person\'s role (role = "person")', code=2)
    security_switches(acl, tls)
    face = ros2_args(ros2, ros2_domain, ros2_namespace)
    scenario = Scenario(
        name="", steps=(Step(say=command),), seed=seed, pose_seed=pose_seed, timeout_s=timeout
    )
    watch = live_watch("roco run", live, quiet, system)
    run_scenario(
        scenario,
        runs_dir,
        spec=path,
        realtime=realtime,
        quiet=quiet,
        record=record,
        view=view,
        watch=watch,
        gateway=gateway,
        ros2=face,
    )


def _run_echo(say: Callable[[str], None], quiet: bool) -> Callable[[str], None]:
    """The runner's progress lines to ``say`` (with ``quiet``: only those to the person)."""
    return lambda line: say(line) if not quiet or "→ person" in line else None


def run_scenario(
    sc: object,
    runs_dir: Path,
    *,
    spec: Path,
    realtime: bool,
    quiet: bool,
    record: bool = True,
    view: bool = False,
    watch: LiveWatch | None = None,
    gateway: int | None = None,
    ros2: tuple[str, ...] | None = None,
) -> None:
    """Run scenario ``sc`` (services/scenario/model.py) with a fleet of the specification
    ``spec`` in a new run folder under ``runs_dir``
    and end as `roco run` and `roco scenario` do: the report written, one line of outcome,
    exit 1 on failure (:func:`exit_on_failure`), 130 when interrupted. The port of
    ``gateway`` is checked free before anything starts."""
    from services.fleet.launcher import spec_env
    from services.monitor import progress_line
    from services.scenario.model import Scenario
    from services.scenario.runner import ScenarioRunner

    assert isinstance(sc, Scenario)
    if gateway is not None:
        port_free(gateway, "--gateway")
    scene = scene_env(realtime, sc.seed, sc.pose_seed)
    run_dir = new_run_folder(runs_dir)
    env = scene | viewer_env(record, view) | spec_env(spec)
    info = RunInfo(
        started=time.time(),
        realtime=realtime,
        seed=sc.seed,
        pose_seed=sc.pose_seed,
        scenario=sc.name,
    )
    stop_on_signals()
    with watch if watch is not None else contextlib.nullcontext():
        runner = ScenarioRunner(
            sc,
            run_dir,
            env=env,
            echo=_run_echo(watch.line if watch is not None else typer.echo, quiet),
            traffic_lines=None if quiet else progress_line,
            info=info,
            on_session=watch.attach if watch is not None else None,
            gateway=gateway,
            ros2=ros2,
        )
        outcome = runner.run()
    finish_report(run_dir, info, interrupted=outcome.interrupted)
    if sc.name:
        typer.echo(outcome.summary())
    exit_on_failure(sc.name, outcome.ok, info.detail, run_dir, outcome.raised_line())


def exit_on_failure(name: str, ok: bool, detail: str, run_dir: Path, raised: str = "") -> None:
    """Exit 1 with one line when the run failed (scenario ``name``, or ``roco run`` when
    empty), a requirement was flagged violated during it (services/recorder/flags.py
    ``violated_words``) or an agent raised (``raised``: services/runtime/raised.py
    ``raised_text``, "" when none did)."""
    from services.recorder.flags import violated_words

    violated = violated_words(run_dir)
    also = "; ".join(x for x in (violated, raised and f"agents raised: {raised}") if x)
    if not ok:
        what = "the task failed" if not name else f"scenario “{name}” did not go as expected"
        raise fail(f"{what}: {detail}{also and '; ' + also} (run folder {run_dir})")
    if also:
        raise fail(f"{also} (run folder {run_dir})")
