"""The run folder: what one run of the system leaves behind (``runs/<timestamp>/``).

| file | written by | content |
|---|---|---|
| ``run.json`` | launcher | :class:`RunInfo` |
| ``traffic.jsonl``, ``traffic.msgpack`` | traffic recorder | see ``services.recorder.record`` |
| ``logs/<agent>.log`` | each agent process | its log |
| ``km_store/`` | a_km | the knowledge base (Oxigraph on disk), kept across a_km restarts |
| ``faults.jsonl`` | traffic recorder | injected faults, when any (docs/faults.md) |
| ``launch_env.json`` | launcher | the environment its processes got (``roco fault start``) |
| ``report.md`` | ``roco report`` | the experiment report |
"""

from __future__ import annotations

import time
from pathlib import Path

import msgspec

RUN_INFO = "run.json"


class RunInfo(msgspec.Struct, kw_only=True):
    """Facts about a run. Times are POSIX seconds; ``command_sent`` is when the human command
    reached a_hi; ``succeeded`` is None while running. ``processes`` maps agent name to PID."""

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


def new_run_dir(root: Path) -> Path:
    """Create and return ``root/<YYYYmmdd-HHMMSS>[-n]/`` with a ``logs/`` subfolder."""
    stamp = time.strftime("%Y%m%d-%H%M%S")
    path = root / stamp
    n = 1
    while path.exists():
        path = root / f"{stamp}-{n}"
        n += 1
    (path / "logs").mkdir(parents=True)
    return path


def write_run_info(run_dir: Path, info: RunInfo) -> None:
    """Write ``run.json`` atomically."""
    tmp = run_dir / (RUN_INFO + ".tmp")
    tmp.write_bytes(msgspec.json.format(msgspec.json.encode(info)))
    tmp.replace(run_dir / RUN_INFO)


def read_run_info(run_dir: Path) -> RunInfo:
    """Read ``run.json``; raises FileNotFoundError or msgspec.DecodeError."""
    return msgspec.json.decode((run_dir / RUN_INFO).read_bytes(), type=RunInfo)
