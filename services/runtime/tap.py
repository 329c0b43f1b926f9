"""The traffic tap: every communicate a transport puts, appended to a folder (``ROCO_TAP_DIR``)
so that a test run leaves a record of what its agents said (``roco spec coverage --tests``,
docs/spec.md).

A test suite starts agents on in-process buses (services/runtime/memory_transport.py) and
whole fleets (every agent process on Zenoh); there is no traffic recorder in the first case,
and a fleet's run folder lives in a temporary folder. With ``ROCO_TAP_DIR`` set, every
:class:`~services.runtime.memory_transport.MemoryBus` and every
:class:`~services.runtime.transport.ZenohTransport` appends what it puts on a communicate key
(``roco/fipa/**``, a batch as each of its communicates) to ``<tap>/traffic-<pid>.msgpack``, one
file per process: a stream of :class:`TapEntry`, each a msgpack ``bin`` holding one entry
(the recorder's framing, services/recorder/record.py). Each entry names its ``group``: the bus
it crossed (``bus-<pid>-<n>``) or the fleet (its run folder, else its router endpoints), so
that a reader follows a conversation only among the communicates of one group (tests reuse
conversation-ids across buses).

Unset (the default), no bus or transport has a tap: a put costs one attribute test.
"""

from __future__ import annotations

import itertools
import os
import threading
from collections.abc import Iterator
from pathlib import Path

import msgspec

from services.runtime import keys
from shared.fipa_codec.batch import unpack
from shared.settings import Settings

TAP_PREFIX = "traffic-"
TAP_SUFFIX = ".msgpack"


class TapEntry(msgspec.Struct, frozen=True, array_like=True):
    """One communicate put: its ``group`` (module docstring), the POSIX time ``t`` (s) it was
    put, its Zenoh ``key`` and its msgpack ``payload`` (FIPA SC00061, one communicate)."""

    group: str
    t: float
    key: str
    payload: bytes


_encoder = msgspec.msgpack.Encoder()
_decoder = msgspec.msgpack.Decoder(TapEntry)
_buses = itertools.count()


class Appender:
    """One file appended to by every thread of a process, each record with one ``write`` on a
    descriptor opened with ``O_APPEND`` (so records of several processes do not interleave
    within a record). Reopened after a fork. Raises OSError when the file cannot be opened."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._lock = threading.Lock()
        self._fd = -1
        self._pid = 0

    def write(self, data: bytes) -> None:
        with self._lock:
            if self._pid != os.getpid():
                self.path.parent.mkdir(parents=True, exist_ok=True)
                self._fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
                self._pid = os.getpid()
            os.write(self._fd, data)


_appenders: dict[Path, Appender] = {}
_appenders_lock = threading.Lock()


def appender(path: Path) -> Appender:
    """The process's one :class:`Appender` of ``path``."""
    with _appenders_lock:
        found = _appenders.get(path)
        if found is None:
            found = _appenders[path] = Appender(path)
        return found


class Tap:
    """Appends communicates to the tap folder (module docstring). :meth:`from_env` gives None
    when ``ROCO_TAP_DIR`` is unset."""

    def __init__(self, folder: Path, group: str) -> None:
        self.folder = folder
        self.group = group
        self._file = appender(folder / f"{TAP_PREFIX}{os.getpid()}{TAP_SUFFIX}")

    @classmethod
    def from_env(cls, group: str) -> Tap | None:
        folder = Settings.from_env(only=("tap_dir",)).tap_dir
        return None if folder is None else cls(folder, group)

    def put(self, t: float, key: str, payload: bytes) -> None:
        """Append ``payload`` put on ``key`` at ``t`` (POSIX s) when ``key`` is a communicate
        key, a batch as each of its communicates; anything else is not tapped. An OSError
        (the folder cannot be written) is left to the caller: a test run that asked for a tap
        must not lose it silently."""
        if not keys.is_communicate_key(key):
            return
        data = b"".join(
            _encoder.encode(_encoder.encode(TapEntry(self.group, t, key, part))) for part in unpack(payload)
        )
        self._file.write(data)


def bus_group() -> str:
    """A new in-process bus's group: ``bus-<pid>-<n>``."""
    return f"bus-{os.getpid()}-{next(_buses)}"


def fleet_group(endpoints: list[str]) -> str:
    """A Zenoh session's group: its fleet's run folder (``ROCO_RUN_DIR``), else its router
    endpoints."""
    run_dir = Settings.from_env(only=("run_dir",)).run_dir
    return f"fleet-{run_dir.resolve()}" if run_dir is not None else "router-" + ",".join(endpoints)


def tap_files(folder: Path) -> list[Path]:
    """The tap files of ``folder``, by name."""
    return sorted(folder.glob(f"{TAP_PREFIX}*{TAP_SUFFIX}"))


def read_tap(path: Path, *, limit: int) -> Iterator[TapEntry]:
    """The entries of one tap file in the order written. Reads at most ``limit`` bytes of it
    (raises ValueError naming the file when it is larger); a truncated or corrupt tail (a
    process killed while writing) ends the stream there. Raises OSError when it cannot be
    read."""
    size = path.stat().st_size
    if size > limit:
        raise ValueError(f"{path}: {size} bytes, more than the {limit} read")
    data = path.read_bytes()
    pos = 0
    while pos < len(data):
        width = {0xC4: 1, 0xC5: 2, 0xC6: 4}.get(data[pos])
        if width is None:
            return
        start = pos + 1 + width
        end = start + int.from_bytes(data[pos + 1 : start], "big")
        if end > len(data):
            return
        try:
            yield _decoder.decode(data[start:end])
        except (msgspec.DecodeError, msgspec.ValidationError):
            return
        pos = end
