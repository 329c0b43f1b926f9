"""Log records as one line each: control characters escaped, so that text a peer chose (a
sentence, an agent name, a reason) cannot start a line that reads as another event.

Every C0 and C1 control character, DEL and the Unicode line and paragraph separators
(U+2028, U+2029) are written as escapes (``\\n``, ``\\r``, ``\\t``, ``\\x1b``, ``\\u2028``);
a backslash stays as it is. A traceback is part of its record's line, its line ends written
``\\n``.
"""

from __future__ import annotations

import logging

__all__ = ["FORMAT", "OneLineFormatter", "escape_controls"]

FORMAT = "%(asctime)s %(name)s %(levelname)s %(message)s"
"""The layout of roco's log lines (time, logger, level, message)."""

_ESCAPES = {c: f"\\x{c:02x}" for c in [*range(0x20), *range(0x7F, 0xA0)]}
_ESCAPES.update({ord("\n"): "\\n", ord("\r"): "\\r", ord("\t"): "\\t", 0x2028: "\\u2028", 0x2029: "\\u2029"})


def escape_controls(text: str) -> str:
    """``text`` with its control characters and line separators escaped (module docstring)."""
    return text.translate(_ESCAPES)


class OneLineFormatter(logging.Formatter):
    """A :class:`logging.Formatter` (default layout :data:`FORMAT`) whose every record is one
    line (module docstring)."""

    def __init__(self, fmt: str = FORMAT) -> None:
        super().__init__(fmt)

    def format(self, record: logging.LogRecord) -> str:
        return escape_controls(super().format(record))
