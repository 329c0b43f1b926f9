"""What agents told the person through a_hi: every ``inform`` of a notice protocol in the
traffic (one initiator ``inform`` that nothing answers, by its state machine:
services/spec/notices.py; ``roco-notify`` and any a new agent's table declares), or carrying an
L_HC ``Notice``, in the order it crossed the wire, with what its content tells the person
(shared/fipa_codec/languages/told.py: a ``Notice``'s text, a term's own ``told()``, else its
string form). A notice whose content did not decode (a_hi answered it not-understood) is no
row: a_hi told the person nothing of it. a_hi passes on at most a few per sender a second
(services/agents/human_interface/notices.py): the record holds all that were sent."""

from __future__ import annotations

from collections.abc import Collection, Sequence

from services.report.load import Message
from services.report.model import NoticeRow
from shared.fipa_codec.languages.l_hc import Notice
from shared.fipa_codec.languages.told import told


def notice_rows(messages: Sequence[Message], protocols: Collection[str] = ()) -> list[NoticeRow]:
    """One row per ``inform`` of one of ``protocols`` (the specification's notice protocols)
    or carrying a ``Notice``, with content: when (s since the run start), who said it, its
    severity and what it names (a ``Notice``'s; none for another term) and its text. A term
    whose ``told()`` fails is shown by its string form."""
    rows = []
    for m in messages:
        if m.performative != "inform" or m.content is None:
            continue
        notice = isinstance(m.content, Notice)
        if not notice and m.rec.protocol not in protocols:
            continue
        try:
            text = told(m.content)
        except Exception:  # a term's own told() is the sender's code: any error of it
            text = told(str(m.content))
        rows.append(
            NoticeRow(
                t=m.t,
                sender=m.sender,
                severity=m.content.severity.value if isinstance(m.content, Notice) else "",
                text=text,
                about=list(m.content.about) if isinstance(m.content, Notice) else [],
            )
        )
    return rows
