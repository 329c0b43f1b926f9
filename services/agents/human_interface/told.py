"""The outcomes a_hi told, kept so that a person's tool that missed one can ask for it.

a_hi's reports reach a person through an advanced publisher whose cache lives as long as a_hi's
process (services/runtime/reports.py). An outcome told just before a_hi died, or pushed out of
that cache, would be lost to a person who was cut off when it was told; so a_hi also keeps the
last :data:`MAX_TOLD` final reports of commands in :class:`Told`, its ``NOTE`` (written by the
runtime after every step, services/runtime/state_store.py, and so kept across a restart), and
answers a query of ``roco/human/outcomes`` with them (JSON list of ``HumanReport``, oldest
first). Status reports and answers to questions are not kept: they are asked again, not missed.
"""

from __future__ import annotations

import msgspec

from services.runtime.agent import FINAL_REPORTS, HumanReport, ReportKind

MAX_TOLD = 64
"""Final reports kept (the oldest forgotten first)."""
MAX_TOLD_TEXT = 2000
"""Characters of a kept report's text (a longer one is cut, with "…"): with :data:`MAX_TOLD`,
the answer stays under services/runtime/reports.py ``MAX_OUTCOMES_BYTES``."""


class Told(msgspec.Struct, kw_only=True):
    """a_hi's ``NOTE``: the final reports of commands it told, oldest first, at most
    :data:`MAX_TOLD`."""

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
