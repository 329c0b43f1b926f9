"""The live requirements monitor as the traffic recorder runs it: a traffic sink
(services/runtime/hooks.py ``TrafficSink``) that decodes each communicate the recorder wrote,
feeds it to a :class:`~services.spec_live.live.LiveMonitor` of the specification ``ROCO_SPEC``
names (else the shipped one), and appends each property it finds violated to the run folder's
``flags.jsonl`` (services/recorder/flags.py) at once, with a warning in the recorder's log.

The recorder loads it by name (services/recorder/recorder.py ``MONITOR``, as the specification
names the agents' implementations), so that the recorder imports no tool above it. Like any sink it never
raises: what goes wrong is logged once and the monitor stops; the traffic is recorded all
the same.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Any

import msgspec

from services.recorder.flags import append_flag
from services.recorder.record import TrafficRecord
from services.report.load import Message
from services.runtime.dedup import Dedup
from services.runtime.run_folder import read_run_info
from services.spec.decomposition import load_decomposition
from services.spec.model import SpecError, load, spec_path
from services.spec.requirements import leaves, properties_of, served
from services.spec_live.live import LiveMonitor, flag_of, live_properties
from shared.fipa_codec import DecodeError, decode
from shared.fipa_codec.languages import ContentError, decode_content

log = logging.getLogger(__name__)


class RequirementsSink:
    """Feeds ``monitor`` what the recorder writes in ``run_dir``; ``t0`` the run's start
    (POSIX s) that event times count from."""

    def __init__(self, run_dir: Path, monitor: LiveMonitor, t0: float | None) -> None:
        self.run_dir = run_dir
        self.monitor = monitor
        self.t0 = t0
        self.flags = 0
        self.recorded = 0
        """One past the highest ``seq`` written so far: the record's length when it began empty."""
        self._copies = Dedup()
        """The communicates fed, remembered as the runtime remembers what it received (the
        last ``DEFAULT_CAPACITY``: a long-running fleet's monitor stays bounded)."""
        self._broken = False

    def communicate(self, record: Any, payload: bytes) -> None:
        """One communicate the recorder wrote (its ``TrafficRecord`` and bytes)."""
        if isinstance(record, TrafficRecord):
            self.recorded = max(self.recorded, record.seq + 1)
        watched = isinstance(record, TrafficRecord) and record.channel in self.monitor.channels
        if self._broken or not watched:
            return
        try:
            m = self._message(record, payload)
            if m is not None:
                self._raise(self.monitor.arrive(m))
        except Exception:  # a sink never stops the recording
            log.exception("the live requirements monitor stopped")
            self._broken = True

    def finish(self) -> Path | None:
        """The traffic ended: evaluate what was held back. Returns None (no recording file)."""
        if not self._broken:
            try:
                self._raise(self.monitor.end())
            except Exception:
                log.exception("the live requirements monitor stopped")
        return None

    def _message(self, record: TrafficRecord, payload: bytes) -> Message | None:
        """``record`` decoded as the report's loader does (services/report/load.py); None for
        a copy of a communicate already fed or bytes that are no communicate."""
        if self._copies.seen(payload):
            return None
        try:
            comm = decode(payload)
        except DecodeError:
            return None
        content: msgspec.Struct | None = None
        if comm.content and comm.language is not None:
            try:
                content = decode_content(comm.language, comm.content)
            except ContentError:
                content = None
        if self.t0 is None:
            self.t0 = record.t
        return Message(record, record.t - self.t0, comm, content)

    def _raise(self, raised: list[Any]) -> None:
        for rid, outcome, m in raised:
            flag = flag_of(rid, outcome, m, self.recorded, time.time())
            append_flag(self.run_dir, flag)
            self.flags += 1
            log.warning("requirement violated: %s", flag.line())


def watched(path: Path) -> LiveMonitor:
    """A monitor of the properties of ``path``'s leaf requirements that can be violated live.
    Raises SpecError when the specification cannot be read. Loading it registers its content
    languages and terms, so the recorder decodes what the system's agents send."""
    load(path)
    d = load_decomposition(path)
    serving = served(d)
    return LiveMonitor(live_properties((r.id, properties_of(r, serving[r.id])) for r in leaves(d)))


def open_sink(process: str, run_dir: Path) -> RequirementsSink | None:
    """The sink of the recorder ``process`` writing ``run_dir``; None (logged) when the
    specification cannot be read or has no property that can be violated live."""
    try:
        monitor = watched(spec_path())
    except (SpecError, OSError) as exc:
        log.error("%s: no live requirements monitor: %s", process, exc)
        return None
    if not monitor.channels:
        return None
    try:
        t0: float | None = read_run_info(run_dir).started or None
    except (OSError, msgspec.DecodeError, msgspec.ValidationError):
        t0 = None
    return RequirementsSink(run_dir, monitor, t0)
