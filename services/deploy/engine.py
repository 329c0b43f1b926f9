"""The Docker engine and Compose on this host, as roco's tools use them (docs/deploy.md).

- :func:`compose_command`: ``docker compose`` (Compose v2, the plugin) where it answers, else
  Debian's ``docker-compose`` (1.29); both take the same ``-f FILE -p PROJECT`` flags;
- :func:`running_fleets`: the compose projects with a running roco container, read from the
  labels Compose v1 and v2 both put on a container (``com.docker.compose.project``,
  ``com.docker.compose.service``, ``com.docker.compose.project.config_files``);
- :func:`run_name`: the run a compose fleet is in (deploy/entrypoint.sh writes it to the
  ``fleet`` volume and says it in the router's log), :func:`runs_folder` where its run folders
  are on the host, :func:`down` to stop it (``roco down --compose``).

The command runner and the program lookup are injectable: tests give the answers of an engine
without one.
"""

from __future__ import annotations

import re
import shutil
import subprocess
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

Runner = Callable[[Sequence[str]], "subprocess.CompletedProcess[str]"]
"""Runs a command line, capturing text output."""
Which = Callable[[str], str | None]
"""``shutil.which``: a program's path, or None."""

TIMEOUT_S = 120.0
PROBE_SERVICE = "router"
"""The service whose container marks a running roco compose fleet (every fleet has one)."""
FLEET_RUN_FILE = "/var/lib/roco/fleet/run"
"""Where deploy/entrypoint.sh keeps the run's name in the ``fleet`` volume."""
RUN_LINE = re.compile(r"roco-entrypoint: run ([A-Za-z0-9._-]+)")
"""The router's log line that names its run (deploy/entrypoint.sh)."""


def run_command(args: Sequence[str]) -> subprocess.CompletedProcess[str]:
    """Run ``args`` (at most :data:`TIMEOUT_S`); a missing program is exit code 127, a timeout
    124."""
    try:
        return subprocess.run(list(args), capture_output=True, text=True, timeout=TIMEOUT_S, check=False)
    except FileNotFoundError as exc:
        return subprocess.CompletedProcess(list(args), 127, "", str(exc))
    except subprocess.TimeoutExpired:
        return subprocess.CompletedProcess(list(args), 124, "", f"no answer within {TIMEOUT_S:.0f} s")


def last_line(text: str) -> str:
    """The last non-blank line of ``text``, stripped ("" when none)."""
    lines = [line.strip() for line in text.strip().splitlines() if line.strip()]
    return lines[-1] if lines else ""


def compose_command(run: Runner = run_command, which: Which | None = None) -> list[str] | None:
    """``["docker", "compose"]`` when ``docker compose version`` succeeds, else
    ``["docker-compose"]`` when that program is on PATH, else None. ``which``: shutil.which, as it
    is when called."""
    which = which or shutil.which
    if which("docker") is not None and run(["docker", "compose", "version"]).returncode == 0:
        return ["docker", "compose"]
    if which("docker-compose") is not None:
        return ["docker-compose"]
    return None


@dataclass(frozen=True)
class ComposeFleet:
    """A running compose fleet: its ``project`` and the compose ``files`` it was started with
    (empty when its containers do not say)."""

    project: str
    files: tuple[Path, ...] = ()

    def file(self) -> Path | None:
        """The first of :attr:`files` that is on this host (an absolute path to a file)."""
        return next((f for f in self.files if f.is_absolute() and f.is_file()), None)


def running_fleets(run: Runner = run_command, which: Which | None = None) -> list[ComposeFleet]:
    """The compose projects whose :data:`PROBE_SERVICE` container runs, by project name; [] when
    there is no ``docker`` or no engine answers."""
    if (which or shutil.which)("docker") is None:
        return []
    label = "com.docker.compose"
    out = run(
        [
            "docker",
            "ps",
            "--filter",
            f"label={label}.service={PROBE_SERVICE}",
            "--format",
            f'{{{{.Label "{label}.project"}}}}\t{{{{.Label "{label}.project.config_files"}}}}',
        ]
    )
    if out.returncode != 0:
        return []
    found: dict[str, ComposeFleet] = {}
    for line in out.stdout.splitlines():
        project, _, files = line.strip().partition("\t")
        if project:
            found[project] = ComposeFleet(project, tuple(Path(f) for f in files.split(",") if f))
    return [found[p] for p in sorted(found)]


def run_name(base: Sequence[str], run: Runner = run_command) -> str | None:
    """The run of the compose fleet ``base`` (``docker compose -f FILE -p PROJECT``) names: the
    ``fleet`` volume's record, read in the router's container, else the router's log line; None
    when neither says."""
    out = run([*base, "exec", "-T", PROBE_SERVICE, "cat", FLEET_RUN_FILE])
    name = out.stdout.strip() if out.returncode == 0 else ""
    if re.fullmatch(r"[A-Za-z0-9._-]+", name):
        return name
    logs = run([*base, "logs", "--no-color", PROBE_SERVICE])
    names = RUN_LINE.findall(logs.stdout + logs.stderr)
    return names[-1] if names else None


class ComposeFailed(RuntimeError):
    """A compose or docker command failed; the message is one line."""


def base_command(
    file: Path, project: str | None, run: Runner = run_command, which: Which | None = None
) -> list[str]:
    """``docker compose -f FILE [-p PROJECT]`` (or ``docker-compose …``); ComposeFailed when
    neither is installed."""
    cmd = compose_command(run, which)
    if cmd is None:
        raise ComposeFailed("neither 'docker compose' nor 'docker-compose' is installed")
    return [*cmd, "-f", str(file), *(["-p", project] if project else [])]


def runs_folder(base: Sequence[str], run: Runner = run_command) -> Path | None:
    """The host folder mounted at ``/runs`` in the router's container of the compose fleet
    ``base`` (its ``ROCO_RUNS``, as Docker resolved it); None when it has no container or mount."""
    ps = run([*base, "ps", "-q", PROBE_SERVICE])
    ids = ps.stdout.split() if ps.returncode == 0 else []
    if not ids:
        return None
    fmt = '{{range .Mounts}}{{if eq .Destination "/runs"}}{{.Source}}{{end}}{{end}}'
    out = run(["docker", "inspect", "-f", fmt, ids[0]])
    source = out.stdout.strip() if out.returncode == 0 else ""
    return Path(source) if source else None


def down(base: Sequence[str], volumes: bool = False, run: Runner = run_command) -> None:
    """``docker compose … down`` (``-v``: the named volumes too): the services stop in reverse
    start order, each within its ``stop_grace_period``; ComposeFailed with compose's last line."""
    out = run([*base, "down", *(["-v"] if volumes else [])])
    if out.returncode != 0:
        why = last_line(out.stderr) or last_line(out.stdout) or f"exit code {out.returncode}"
        raise ComposeFailed(f"{' '.join(base[:2])} down failed: {why}")
