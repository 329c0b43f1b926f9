"""The run folder: what one run of the system leaves behind (``runs/<timestamp>/``).

| file | written by | content |
|---|---|---|
| ``run.json`` | launcher | :class:`RunInfo` |
| ``traffic.jsonl``, ``traffic.msgpack`` | traffic recorder | see ``services.recorder.record`` |
| ``logs/<agent>.log`` | each agent process | its log |
| ``km_store/`` | a_km | the knowledge base (Oxigraph on disk), kept across a_km restarts |
| ``faults.jsonl`` | traffic recorder | injected faults, when any (docs/faults.md) |
| ``fsm/<agent>.<pid>.jsonl`` | each agent | its FSM, transitions, time-outs (runtime/fsm_record.py) |
| ``launch_env.json`` | launcher | the environment its processes got (``roco fault start``) |
| ``report.md``, ``figures/`` | the run's end (``roco run``, ``down``…), ``roco report`` | the report |

A folder is a run folder when it holds ``run.json`` or ``traffic.jsonl``
(:func:`check_run_folder`).
"""

from __future__ import annotations

import errno
import json
import os
import time
from pathlib import Path

import msgspec

from shared.settings import PREFIX, Settings

RUN_INFO = "run.json"
LAUNCH_ENV = "launch_env.json"
"""The run folder's record of the environment the launcher gives its processes."""
TRAFFIC_JSONL = "traffic.jsonl"
"""The traffic record's metadata (services/recorder/record.py writes it)."""


class RunFolderError(ValueError):
    """A runs folder where no run folder can be made, or a folder that is not a run folder; the
    message is one line naming the path, the problem and, where there is one, the fix."""


class RunCommand(msgspec.Struct, kw_only=True):
    """One command the fleet was given and how it ended: ``text`` as the person said it;
    ``sent`` and ``ended`` POSIX s (None: not known; ``ended`` None: it had not ended when the
    fleet stopped); ``outcome`` a_hi's final report kind (``succeeded``, ``failed``,
    ``stopped``, ``not-understood``; services/runtime/human.py ``ReportKind``) or a_co's C2
    outcome, None when it had not ended; ``detail`` the outcome's sentence."""

    text: str
    sent: float | None = None
    outcome: str | None = None
    detail: str = ""
    ended: float | None = None


class RunInfo(msgspec.Struct, kw_only=True):
    """Facts about a run. Times are POSIX seconds; ``command_sent`` is when the human command
    reached a_hi; ``succeeded`` is None while running, and for a fleet that ended without
    being given a command. ``processes`` maps agent name to PID."""

    command: str = ""
    started: float = 0.0
    command_sent: float | None = None
    ended: float | None = None
    succeeded: bool | None = None
    detail: str = ""
    router: str = ""
    processes: dict[str, int] = {}
    realtime: bool = False
    seed: int = 0
    """Jitter of the jar content's start positions (ag_ex's ROCO_SEED)."""
    pose_seed: int | None = None
    """Randomisation of the jar and bowl poses (ag_ex's ROCO_POSE_SEED; None: none)."""
    scenario: str = ""
    """The scenario's name (``roco scenario``), empty for a single ``roco run`` command."""
    commands: list[str] = []
    """Every sentence said to a_hi, in order (``command`` is the first)."""
    outcomes: list[RunCommand] = []
    """Every command given and how it ended, in order; filled when the run ends."""
    raised: dict[str, dict[str, int]] = {}
    """Each agent whose error counters (``handler_errors``, ``behaviour_errors``) were above
    zero when the commands ended, with them (services/runtime/raised.py); filled when the run ends."""
    crashed: dict[str, list[int]] = {}
    """Each agent that exited during the run though nobody stopped it, and was started again:
    its exit codes, in order; filled when the run ends."""


_WHY = {
    errno.ENOTDIR: "a file is in the way, not a folder",
    errno.EEXIST: "a file is in the way, not a folder",
    errno.EACCES: "no permission to write there",
    errno.EPERM: "no permission to write there",
    errno.EROFS: "it is on a read-only file system",
    errno.ENOSPC: "no space is left on its device",
    errno.EDQUOT: "the disk quota is used up",
    errno.ENOENT: "folders cannot be made there",
}


def new_run_dir(root: Path) -> Path:
    """Create and return ``root/<YYYYmmdd-HHMMSS>[-n]/`` with a ``logs/`` subfolder, ``root``
    and its parents made as needed. Raises :class:`RunFolderError` (one line: the path, why,
    and ``--runs-dir`` as the fix) when it cannot be made or written to, having made nothing
    a run could be started in."""
    try:
        root.mkdir(parents=True, exist_ok=True)
        stamp = time.strftime("%Y%m%d-%H%M%S")
        path = root / stamp
        n = 1
        while path.exists():
            path = root / f"{stamp}-{n}"
            n += 1
        (path / "logs").mkdir(parents=True)
        probe = path / (RUN_INFO + ".tmp")  # a folder made is not yet a folder written to
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        why = _WHY.get(exc.errno or 0, (exc.strerror or str(exc)).lower())
        raise RunFolderError(
            f"cannot make a run folder in {root}: {why}; give --runs-dir a folder you can write to"
        ) from None
    return path


BAG_METADATA = "metadata.yaml"
"""The file that makes a folder a rosbag2 folder (``roco export --mcap`` writes one: services/ros2)."""


def is_bag_folder(path: Path) -> bool:
    """True when ``path`` is a rosbag2 folder holding an MCAP file (:data:`BAG_METADATA` and a
    ``*.mcap`` in it), which the commands that read a run's traffic take in its place."""
    return path.is_dir() and (path / BAG_METADATA).is_file() and any(path.glob("*.mcap"))


def check_run_folder(path: Path) -> None:
    """Raise :class:`RunFolderError` unless ``path`` is a run folder: a folder holding
    ``run.json`` or ``traffic.jsonl`` (what ``roco run``, ``roco up`` and compose runs leave)."""
    if not path.exists():
        raise RunFolderError(f"{path}: no such run folder")
    if not path.is_dir():
        raise RunFolderError(f"{path} is not a run folder: it is a file")
    if not ((path / RUN_INFO).is_file() or (path / TRAFFIC_JSONL).is_file()):
        raise RunFolderError(
            f"{path} is not a run folder: it holds neither {RUN_INFO} nor {TRAFFIC_JSONL}; "
            "give one that roco run or roco up made (runs/<timestamp>/)"
        )


def write_run_info(run_dir: Path, info: RunInfo) -> None:
    """Write ``run.json`` atomically."""
    tmp = run_dir / (RUN_INFO + ".tmp")
    tmp.write_bytes(msgspec.json.format(msgspec.json.encode(info)))
    tmp.replace(run_dir / RUN_INFO)


def read_run_info(run_dir: Path) -> RunInfo:
    """Read ``run.json``; raises FileNotFoundError or msgspec.DecodeError."""
    return msgspec.json.decode((run_dir / RUN_INFO).read_bytes(), type=RunInfo)


def spec_of_run(run_dir: Path) -> Path | None:
    """The specification file a run's processes were given (``ROCO_SPEC`` in its
    ``launch_env.json``, which the launcher sets whenever it is not the shipped one); None when
    the run used the shipped one or the folder has no readable record."""
    try:
        kept = json.loads((run_dir / LAUNCH_ENV).read_text())
    except (OSError, ValueError):
        return None
    named = kept.get(Settings.env_name("spec")) if isinstance(kept, dict) else None
    return Path(named) if isinstance(named, str) and named else None


def spec_for_run(run_dir: Path | None) -> Path:
    """The specification a tool reads a run with when no ``--spec`` is given: ``ROCO_SPEC``'s
    file, else the one run ``run_dir`` used (:func:`spec_of_run`), else the shipped one."""
    from services.spec.model import DEFAULT_SPEC, spec_path

    named = spec_path()
    if named != DEFAULT_SPEC:
        return named
    return (spec_of_run(run_dir) if run_dir is not None else None) or DEFAULT_SPEC


def load_launch_env(run_dir: Path) -> dict[str, str] | None:
    """The environment a fleet's processes were started with: this process's environment
    without its ``ROCO_*`` variables, then those of ``launch_env.json``; None when the run
    folder has no (readable) record."""
    try:
        kept = json.loads((run_dir / LAUNCH_ENV).read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(kept, dict):
        return None
    env = {k: v for k, v in os.environ.items() if not k.startswith(PREFIX)}
    env.update({str(k): str(v) for k, v in kept.items()})
    return env
