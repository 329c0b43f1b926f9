"""What agents told the person through a_hi: every L_HC ``Notice`` in the traffic (protocol
``roco-notify``, an ``inform`` to a_hi; shared/fipa_codec/languages/l_hc.py), in the order it
crossed the wire. A notice a_hi did not read (not-understood) is no ``Notice`` here: its
content does not decode. a_hi passes on at most a few per sender a second
(services/agents/human_interface/notices.py): the record holds all that were sent."""

from __future__ import annotations

from collections.abc import Sequence

from services.report.load import Message
from services.report.model import NoticeRow
from shared.fipa_codec.languages.l_hc import Notice


def notice_rows(messages: Sequence[Message]) -> list[NoticeRow]:
    """One row per ``inform`` carrying a ``Notice``: when (s since the run start), who said
    it, its severity, what it names and its text."""
    return [
        NoticeRow(
            t=m.t,
            sender=m.sender,
            severity=m.content.severity.value,
            text=m.content.text,
            about=list(m.content.about),
        )
        for m in messages
        if m.performative == "inform" and isinstance(m.content, Notice)
    ]
