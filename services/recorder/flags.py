"""Requirements flagged violated while a run went on: the run folder's ``flags.jsonl``, and
the traffic recorder's answer about them over Zenoh.

The live requirements monitor (services/spec_live) runs inside the traffic recorder and
appends one :class:`LiveFlag` per property it finds violated, as soon as it finds it. The
recorder answers queries of ``roco/recorder/flags`` (services/runtime/keys.py
``RECORDER_FLAGS``) with the file's flags (:func:`flags_reply`), so that `roco status` lists
them for a fleet on any host (:func:`ask_flags`); the run's report shows them beside the
requirements' verdicts, and `roco run` / `roco scenario` exit non-zero when there is one. This
module is only the formats, so that all of them read them without importing the monitor.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import msgspec

from services.runtime import keys

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


MAX_REPLIED = 32
"""Flags an answer of the recorder carries at most (the first raised); it says how many there are."""
MAX_REPLY_BYTES = 256 * 1024
"""The largest answer :func:`ask_flags` decodes (:data:`MAX_REPLIED` flags with long texts fit)."""


class FlagsReply(msgspec.Struct, frozen=True, kw_only=True):
    """The recorder's answer on ``roco/recorder/flags``: the first ``flags`` of its run folder
    (at most :data:`MAX_REPLIED`) and ``total``, how many the folder holds."""

    flags: list[LiveFlag]
    total: int


_reply_decode = msgspec.json.Decoder(FlagsReply).decode


def flags_reply(run_dir: Path) -> bytes:
    """The recorder's answer (JSON :class:`FlagsReply`) about ``run_dir``'s flags. Raises
    OSError when ``flags.jsonl`` exists but cannot be read."""
    flags = read_flags(run_dir)
    return _encode(FlagsReply(flags=flags[:MAX_REPLIED], total=len(flags)))


def ask_flags(session: Any, timeout: float = 2.0) -> FlagsReply | None:
    """Ask the traffic recorder over ``session`` (a :class:`zenoh.Session`) for its flags;
    wait up to ``timeout`` s. None when no recorder answered in time, or its answer was not a
    :class:`FlagsReply` of at most :data:`MAX_REPLY_BYTES`."""
    for reply in session.get(keys.RECORDER_FLAGS, timeout=timeout):
        if reply.ok is None:
            continue
        payload = reply.ok.payload.to_bytes()
        if len(payload) > MAX_REPLY_BYTES:
            continue
        try:
            return _reply_decode(payload)
        except (msgspec.DecodeError, msgspec.ValidationError):
            continue
    return None


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


def violated_words(run_dir: Path) -> str:
    """``requirement R3.3 violated during the run: …`` for the requirements flagged in
    ``run_dir``, the first one's flag in words; empty when none was flagged. What `roco run`
    and `roco scenario` exit 1 with."""
    try:
        flags = read_flags(run_dir)
    except OSError as exc:
        return f"the live requirement flags cannot be read: {exc}"
    if not flags:
        return ""
    ids = sorted({f.requirement for f in flags})
    which = f"requirement{'s' if len(ids) > 1 else ''} {', '.join(ids)}"
    return f"{which} violated during the run: {flags[0].line()}"
