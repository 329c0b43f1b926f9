"""The person's side of an interface agent: what an agent of role ``person`` (the
specification's ``role = "person"``: a_hi in the kitchen) uses to hear a person and answer.

A person's tools (``roco send``, ``roco run``, the scenario runner) speak three keys, whatever
the system (services/runtime/keys.py, services/runtime/human.py):

- ``roco/human/in`` carries :class:`HumanInput` (JSON: a line, its request id); the agent
  hears it: :class:`PersonFace` posts it to the agent's queue ``r``;
- ``roco/human/out`` carries :class:`HumanReport` (JSON: accepted, progress, the final outcome,
  notices); the agent says it with :meth:`PersonFace.tell` and :meth:`PersonFace.notice`;
- ``roco/human/outcomes`` answers with the final reports kept (:class:`Told`, a JSON list), for
  a tool that missed an outcome.

The access control grants these keys to the agent of role ``person`` only
(services/spec_check/acl.py). An agent's behaviour takes the person's lines from ``self.r`` as
:class:`HumanInput` events and answers each with reports of its ``request_id``, the last of a
kind in ``FINAL_REPORTS`` (``roco send`` waits for it; ``done_as_asked`` sets its exit status).

a_hi's reports reach a person through an advanced publisher whose cache lives as long as the
agent's process (services/runtime/reports.py). An outcome told just before the agent died, or
pushed out of that cache, would be lost to a person who was cut off when it was told; so the
face also keeps the last :data:`MAX_TOLD` final reports of commands in :class:`Told` (a_hi's
``NOTE``, written by the runtime after every step, services/runtime/state_store.py, and so kept
across a restart) and answers a query of ``roco/human/outcomes`` with them (oldest first).
Status reports and answers to questions are not kept: they are asked again, not missed.
"""

from __future__ import annotations

import logging
from typing import Any, Protocol

import msgspec

from services.runtime import keys
from services.runtime.human import (
    FINAL_REPORTS,
    MAX_LINE_CHARS,
    HumanInput,
    HumanReport,
    ReportKind,
    RequestKind,
)


class Interface(Protocol):
    """What :class:`PersonFace` uses of its agent (services/runtime/agent.py ``Agent``)."""

    @property
    def engine(self) -> Any: ...  # its ``transport`` (services/runtime/engine.py ``Engine``)

    @property
    def log(self) -> logging.Logger | logging.LoggerAdapter[logging.Logger]: ...

    def post(self, event: Any) -> None: ...

    def emit(self, key: str, payload: bytes) -> None: ...


MAX_INPUT_BYTES = 64 * 1024
"""The largest ``roco/human/in`` payload read (bytes): a larger one is dropped with a warning
before it is decoded. Lines up to :data:`MAX_LINE_CHARS` characters (4 bytes each at most)
fit, so an over-long line still reaches the agent and is answered."""
assert MAX_INPUT_BYTES > 4 * MAX_LINE_CHARS

MAX_TOLD = 64
"""Final reports kept (the oldest forgotten first)."""
MAX_TOLD_TEXT = 2000
"""Characters of a kept report's text (a longer one is cut, with "…"): with :data:`MAX_TOLD`,
the answer stays under services/runtime/reports.py ``MAX_OUTCOMES_BYTES``."""


class Told(msgspec.Struct, kw_only=True):
    """The final reports of commands an interface agent told, oldest first, at most
    :data:`MAX_TOLD` (a_hi's ``NOTE``)."""

    reports: list[HumanReport] = msgspec.field(default_factory=list)

    def keep(self, report: HumanReport) -> bool:
        """Keep ``report`` when it is the final report of a command (a kind in
        ``FINAL_REPORTS`` other than ``status`` and ``answer``), its text cut to :data:`MAX_TOLD_TEXT`; the
        oldest kept is forgotten past :data:`MAX_TOLD`. Whether it was kept."""
        if report.kind not in FINAL_REPORTS or report.kind in (ReportKind.STATUS, ReportKind.ANSWER):
            return False
        if len(report.text) > MAX_TOLD_TEXT:
            report = msgspec.structs.replace(report, text=report.text[: MAX_TOLD_TEXT - 1] + "…")
        self.reports.append(report)
        del self.reports[:-MAX_TOLD]
        return True

    def answer(self) -> bytes:
        """The answer to a query of ``roco/human/outcomes``: the kept reports as JSON."""
        return msgspec.json.encode(self.reports)


class PersonFace:
    """An interface agent's receptor and effector for a person (module docstring): made in the
    agent's ``setup`` (``self.person = PersonFace(self)``; a_hi passes its ``NOTE`` as ``told``
    so the outcomes survive a restart), then :meth:`open`. Call :meth:`tell` and :meth:`notice`
    from the agent's behaviours (its thread)."""

    def __init__(self, agent: Interface, told: Told | None = None) -> None:
        self.agent = agent
        self.told = told if told is not None else Told()
        """The final reports kept for ``roco/human/outcomes``."""
        self._decode = msgspec.json.Decoder(HumanInput).decode

    def open(self) -> None:
        """Hear ``roco/human/in`` (each line posted to the agent as a :class:`HumanInput`; a
        payload over :data:`MAX_INPUT_BYTES` or not a HumanInput is logged and dropped) and,
        on a Zenoh transport, answer ``roco/human/outcomes`` with :attr:`told`."""
        transport = self.agent.engine.transport
        transport.subscribe(keys.HUMAN_IN, self._on_line)
        if (serve := getattr(transport, "serve", None)) is not None:  # a ZenohTransport
            serve(keys.HUMAN_OUTCOMES, self.told.answer)  # on Zenoh's thread: encoded under the GIL

    def _on_line(self, key: str, payload: bytes) -> None:
        if len(payload) > MAX_INPUT_BYTES:
            self.agent.log.warning(
                "ignored human input of %d bytes (at most %d read)", len(payload), MAX_INPUT_BYTES
            )
            return
        try:
            self.agent.post(self._decode(payload))
        except msgspec.DecodeError as exc:
            self.agent.log.warning("ignored malformed human input: %s", exc)

    def tell(
        self, request_id: str, kind: ReportKind, text: str, *, request: RequestKind | None = None
    ) -> HumanReport:
        """Say ``text`` to the person about their request ``request_id`` (its ``kind``: a final
        kind ends the request for the person's tool; ``request`` what the line asked, when
        known), keep it when it is a final report of a command (:meth:`Told.keep`) and return it."""
        report = HumanReport(request_id=request_id, kind=kind, text=text, request=request)
        self.agent.emit(keys.HUMAN_OUT, msgspec.json.encode(report))
        self.told.keep(report)
        return report

    def notice(
        self, sender: str, text: str, *, severity: str = "", about: tuple[str, ...] = ()
    ) -> HumanReport:
        """Tell the person something no request of theirs asked: a ``notice`` report naming the
        agent ``sender`` (``severity`` and the things it is ``about``, when known)."""
        report = HumanReport(
            request_id="", kind=ReportKind.NOTICE, text=text, sender=sender, severity=severity, about=about
        )
        self.agent.emit(keys.HUMAN_OUT, msgspec.json.encode(report))
        return report
