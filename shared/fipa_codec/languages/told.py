"""What a notice tells the person (docs/agents.md, a_hi "Notices"): the content of an
``inform`` of a notice protocol (services/spec/notices.py) as one sentence.

A content term says it itself when its class defines the hook ``told(self) -> str``
(:class:`Tells`; L_HC's ``Notice`` does: its text); any other term is told by its string form
(``str(term)``: a msgspec Struct's is ``Tipped(object='bowl', tilt_deg=170.0)``). The sentence
is at most :data:`~shared.fipa_codec.languages.l_hc.MAX_NOTICE_CHARS` characters, a Notice's
bound: a longer one is cut, its last character then ``…``."""

from __future__ import annotations

from typing import Protocol, runtime_checkable

from shared.fipa_codec.languages.l_hc import MAX_NOTICE_CHARS

CUT = "…"
"""The last character of a sentence cut to :data:`MAX_NOTICE_CHARS`."""


@runtime_checkable
class Tells(Protocol):
    """A content term that says itself to the person: ``told()`` returns its sentence (str;
    longer than :data:`MAX_NOTICE_CHARS` characters it is cut)."""

    def told(self) -> str: ...


def told(term: object) -> str:
    """The sentence ``term`` tells the person: its ``told()`` when its class defines one
    (:class:`Tells`), else ``str(term)``; cut to :data:`MAX_NOTICE_CHARS` characters (the last
    :data:`CUT`). Raises TypeError when ``told()`` returns something other than a str; an
    exception ``told()`` raises propagates."""
    if isinstance(term, Tells):
        said = term.told()
        if not isinstance(said, str):
            raise TypeError(f"{type(term).__name__}.told() returned {type(said).__name__}, not str")
    else:
        said = str(term)
    return said if len(said) <= MAX_NOTICE_CHARS else said[: MAX_NOTICE_CHARS - 1] + CUT
