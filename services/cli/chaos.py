"""``roco chaos``: fault services at random while the robot carries out a command, then judge
what was kept (services/scenario/chaos.py)."""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from services.cli.common import (
    AclOption,
    LiveOption,
    RecordOption,
    RunsDirMade,
    SpecFile,
    TlsOption,
    fail,
    new_run_folder,
    security_switches,
    stop_on_signals,
)
from services.cli.report import finish_report
from services.cli.run_env import kitchen_spec, live_watch, scene_env, viewer_env
from services.runtime.run_folder import RunInfo
from services.scenario.model import DEFAULT_COMMAND
from services.spec.model import default_spec, load
from shared.settings import Settings

if TYPE_CHECKING:
    from services.hosts.link import Shaping
    from services.scenario.model import Scenario
    from services.scenario.runner import Hosting

chaos_app = typer.Typer()


_CHAOS_DEFAULT = ",".join(default_spec().agent_names)
CHAOS_NEEDS = "judges the kitchen's task (the content poured, no object dropped, ag_ex's ledger)"
"""Why `roco chaos` runs the kitchen only (services/scenario/chaos.py ``verdict``)."""


def _check_chaos_hosting(hosts: bool, acl: bool | None, tls: bool | None, link: tuple[object, ...]) -> None:
    """Exit 2 when `roco chaos --hosts` cannot make two hosts here or is asked to run without
    access control or TLS, or when the ``link`` options (--delay-ms, --jitter-ms, --loss-pct,
    --cut) come without --hosts; without --hosts, the security options are checked."""
    if hosts:
        from services.hosts.netns import unavailable

        why = unavailable()
        if why:
            raise fail(f"--hosts cannot make two hosts here: {why}", code=2)
        if acl is False or tls is False:
            raise fail("--hosts always runs with access control and mutual TLS", code=2)
        return
    if any(v is not None for v in link):
        raise fail("--delay-ms, --jitter-ms, --loss-pct and --cut shape and cut the link of --hosts", code=2)
    security_switches(acl, tls)


def _chaos_scenario(
    seed: int,
    gap_s: tuple[float, float],
    services: str,
    count: int | None,
    kinds: str,
    command: str,
    hosts: bool,
    cut_s: tuple[float, float],
) -> Scenario:
    """The chaos scenario of `roco chaos`'s options (services/scenario/chaos.py); exit 2 when
    they are wrong, or when ag_ex is faulted while the kitchen lives in it."""
    from services.scenario.chaos import HOSTS_DEFAULT, chaos_scenario

    try:
        sc = chaos_scenario(
            seed,
            gap_s=gap_s,
            services=HOSTS_DEFAULT if hosts and services == _CHAOS_DEFAULT else _listed(services),
            count=count,
            kinds=_listed(kinds),
            command=command,
            hosts=hosts,
            cut_s=cut_s,
        )
    except ValueError as exc:
        raise fail(str(exc), code=2) from None
    if any(s.fault is not None and s.fault.service == "ag_ex" for s in sc.steps) and not _world_apart():
        world = Settings.env_name("world")
        raise fail(f"{world}=loop keeps the kitchen in ag_ex, which a fault starts anew: unset it", code=2)
    return sc


def _listed(text: str) -> tuple[str, ...]:
    """The non-empty items of a comma-separated option, stripped."""
    return tuple(s.strip() for s in text.split(",") if s.strip())


def _chaos_shaping(delay_ms: float | None, jitter_ms: float | None, loss_pct: float | None) -> Shaping:
    """The link of `roco chaos --hosts` (20 ± 5 ms, 1 % loss unless told); exit 2 when wrong."""
    from services.hosts.link import Shaping

    try:
        return Shaping(
            20.0 if delay_ms is None else delay_ms,
            5.0 if jitter_ms is None else jitter_ms,
            1.0 if loss_pct is None else loss_pct,
        )
    except ValueError as exc:
        raise fail(str(exc), code=2) from None


def _two_hosts(run_dir: Path, shaping: Shaping, env: dict[str, str]) -> Hosting:
    """The fleet on two hosts joined by a ``shaping`` link, for the scenario runner."""
    from services.hosts.fleet import TwoHosts, TwoHostsHosting

    return TwoHostsHosting(TwoHosts(run_dir, shaping, env=env))


_CHAOS_ALWAYS = ("fault", "back after", "up again after")
"""What `roco chaos --quiet` still says: the lines of the faults and of the services back."""


def _chaos_echo(say: Callable[[str], None], quiet: bool) -> Callable[[str], None]:
    """The runner's progress lines to ``say`` (with ``quiet``: only the faults')."""
    return lambda line: say(line) if not quiet or any(w in line for w in _CHAOS_ALWAYS) else None


@chaos_app.command(short_help="Fault services at random during a task; check that nothing is lost.")
def chaos(
    seed: Annotated[
        int, typer.Option(min=0, help="draws the order, kinds, times and lengths of the faults")
    ] = 0,
    count: Annotated[
        int | None, typer.Option(min=1, help="this many random faults instead of each service once")
    ] = None,
    services: Annotated[
        str,
        typer.Option(
            help="comma-separated services to fault (agents, recorder, router; with --hosts "
            "router_brain, router_robot, link instead of router), or all",
            show_default="every agent; with --hosts also both routers and the link",
        ),
    ] = _CHAOS_DEFAULT,
    kinds: Annotated[str, typer.Option(help="comma-separated fault kinds: kill, pause, restart")] = (
        "kill,pause,restart"
    ),
    command: Annotated[str, typer.Option(help="what the person asks for")] = DEFAULT_COMMAND,
    gap: Annotated[str, typer.Option(help="MIN,MAX seconds between faults (uniform)")] = "3,8",
    runs_dir: RunsDirMade = Path("runs"),
    realtime: Annotated[bool, typer.Option(help="pace the simulation to wall time")] = False,
    quiet: Annotated[bool, typer.Option(help="print only the faults and the verdict")] = False,
    record: RecordOption = False,
    acl: AclOption = None,
    tls: TlsOption = None,
    live: LiveOption = None,
    hosts: Annotated[
        bool,
        typer.Option(
            "--hosts",
            help="on two hosts of this machine (brain, robot; root): fault both hosts' services, "
            "their routers (router_brain, router_robot) and the link between them (link: cut 2-6 s)",
        ),
    ] = False,
    delay_ms: Annotated[
        float | None,
        typer.Option(min=0, help="with --hosts: one-way delay of the link (ms)", show_default="20"),
    ] = None,
    jitter_ms: Annotated[
        float | None, typer.Option(min=0, help="with --hosts: ± this much (ms)", show_default="5")
    ] = None,
    loss_pct: Annotated[
        float | None,
        typer.Option(min=0, max=99, help="with --hosts: packets lost each way (%)", show_default="1"),
    ] = None,
    cut: Annotated[
        str | None,
        typer.Option(
            help="with --hosts: MIN,MAX seconds a cut of the link lasts (uniform; over the routers' "
            "30 s lease the mesh is closed and made again)",
            show_default="2,6",
        ),
    ] = None,
    busy_processes: Annotated[
        int,
        typer.Option(
            "--load",
            min=0,
            help="this many processes beside the fleet, each keeping a core busy (a busy machine)",
        ),
    ] = 0,
    spec: SpecFile = None,
) -> None:
    """Kill, pause or restart services at random times while the robot carries out a command (each
    service once by default; `--load N`: N processes keep a core busy each), then say whether
    the task was done, no command was lost, nothing was executed twice, no object was dropped,
    the traffic record is intact and no agent raised (RUN/chaos.md). Exit 0 only if all six
    hold. With `--hosts` the fleet runs on the two hosts of `roco hosts` (link 20 ± 5 ms, 1 %
    loss unless told; mutual TLS between the routers, access control on) and the link is cut as
    well. On compose use `roco fault` (docs/recovery.md). The kitchen only: another system
    (--spec) is refused."""
    from services.fleet.launcher import spec_env
    from services.scenario.chaos import verdict, write_chaos_report
    from services.scenario.load import BusyLoad
    from services.scenario.runner import ScenarioRunner

    try:
        busy = BusyLoad(busy_processes)
    except ValueError as exc:
        raise fail(f"--load: {exc}", code=2) from None

    path = kitchen_spec(spec, "roco chaos", CHAOS_NEEDS)
    _check_chaos_hosting(hosts, acl, tls, (delay_ms, jitter_ms, loss_pct, cut))
    low, high = _span("--gap", gap)
    cut_s = _span("--cut", cut) if cut is not None else (2.0, 6.0)
    sc = _chaos_scenario(seed, (low, high), services, count, kinds, command, hosts, cut_s)
    shaping = _chaos_shaping(delay_ms, jitter_ms, loss_pct) if hosts else None
    scene = scene_env(realtime, 0, None)
    run_dir = new_run_folder(runs_dir)
    env = scene | viewer_env(record, False) | spec_env(path)
    info = RunInfo(started=time.time(), realtime=realtime, seed=0, scenario=sc.name)
    stop_on_signals()
    hosting = _two_hosts(run_dir, shaping, env) if shaping is not None else None
    watch = live_watch(f"roco chaos --seed {seed}", live, quiet, load(path))
    with watch if watch is not None else contextlib.nullcontext():
        runner = ScenarioRunner(
            sc,
            run_dir,
            env=env,
            echo=_chaos_echo(watch.line if watch is not None else typer.echo, quiet),
            info=info,
            on_session=watch.attach if watch is not None else None,
            hosting=hosting,
        )
        began = time.monotonic()
        with busy:
            outcome = runner.run()
        loaded = busy.line(time.monotonic() - began)
    finish_report(run_dir, info, interrupted=outcome.interrupted)
    v = verdict(run_dir, outcome)
    path = write_chaos_report(run_dir, sc, outcome, v, loaded)
    typer.echo(path.read_text())
    if not v.ok:
        raise fail(f"the chaos run did not keep everything (see {path})")


def _span(option: str, value: str) -> tuple[float, float]:
    """``MIN,MAX`` seconds of ``option``; a clear error (exit 2) unless 0 <= MIN <= MAX <= 3600."""
    try:
        low, high = (float(x) for x in value.split(","))
    except ValueError:
        raise fail(f"{option} takes MIN,MAX seconds, not {value!r}", code=2) from None
    if not 0 <= low <= high <= 3600:
        raise fail(f"{option} needs 0 <= MIN <= MAX <= 3600, not {value!r}", code=2)
    return low, high


def _world_apart() -> bool:
    """The kitchen is a world process of its own (velma/world/mode.py); a bad ROCO_WORLD is
    refused with one line."""
    from velma.world.mode import world_in_process

    try:
        return world_in_process()
    except ValueError as exc:
        raise fail(str(exc), code=2) from None
