"""Requirements flagged violated while a run went on: the run folder's ``flags.jsonl``.

The live requirements monitor (services/spec_live) runs inside the traffic recorder and
appends one :class:`LiveFlag` per property it finds violated, as soon as it finds it; `roco
status` lists them while the fleet runs, the run's report shows them beside the requirements'
verdicts, and `roco run` / `roco scenario` exit non-zero when there is one. This module is
only the file's format, so that all of them read it without importing the monitor.
"""

from __future__ import annotations

import time
from pathlib import Path

import msgspec

FLAGS_JSONL = "flags.jsonl"
"""The run folder's flags: one JSON :class:`LiveFlag` per line, in the order they were raised."""


class LiveFlag(msgspec.Struct, frozen=True, kw_only=True):
    """One property found violated during the run: ``requirement`` its leaf requirement's id,
    ``prop`` the property's text, ``event`` the communicate that violated it in words
    (``C1 a_ta → a_co inform SWStatus Preempted``), ``why`` what it came before (the step
    awaited), ``t`` its arrival at the recorder (POSIX s), ``seq`` its place in the traffic
    record (``traffic.jsonl`` ``seq``), ``recorded`` how many communicates the record held
    when the flag was raised, ``flagged`` when it was raised (POSIX s)."""

    requirement: str
    prop: str
    event: str
    why: str
    t: float
    seq: int
    recorded: int
    flagged: float

    def line(self, t0: float | None = None) -> str:
        """``R3.3 “…”: C1 a_ta → a_co inform … at 14:02:07 (…)``; with ``t0`` (POSIX s, the
        run's start) the time is ``21.3 s`` into the run."""
        when = f"{self.t - t0:.1f} s" if t0 is not None else time.strftime("%H:%M:%S", time.localtime(self.t))
        return f"{self.requirement} “{self.prop}”: {self.event} at {when} ({self.why})"


_encode = msgspec.json.Encoder().encode
_decode = msgspec.json.Decoder(LiveFlag).decode


def append_flag(run_dir: Path, flag: LiveFlag) -> None:
    """Append ``flag`` to ``run_dir/flags.jsonl`` (one write). Raises OSError."""
    with (run_dir / FLAGS_JSONL).open("ab") as f:
        f.write(_encode(flag) + b"\n")


def read_flags(run_dir: Path) -> list[LiveFlag]:
    """The flags of ``run_dir`` (none when it has no ``flags.jsonl``); a line that is not a
    flag (cut short by a killed recorder) is skipped. Raises OSError when the file exists but
    cannot be read."""
    path = run_dir / FLAGS_JSONL
    if not path.exists():
        return []
    flags = []
    for line in path.read_bytes().splitlines():
        try:
            flags.append(_decode(line))
        except (msgspec.DecodeError, msgspec.ValidationError):
            continue
    return flags
