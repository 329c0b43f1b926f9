"""Files rendered from the specification and kept in the repository (``deploy/compose.yaml``,
``services/spec/names.py``): read one with a bound, say how it differs from what the
specification gives, write it atomically, bring a checkout's copy up to date (``roco spec
new-agent``). Each file gives its own rendering and the difference it can name (an agent
without a service, a channel without a name); the rest is here, once."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from services.spec.model import SystemSpec


@dataclass(frozen=True)
class GeneratedFile:
    """A ``what`` (e.g. "compose file") at ``relative`` in a checkout, at most ``max_bytes``
    long, rendered from a specification by ``render`` and written by ``command`` (e.g. "roco
    deploy compose"). ``named_difference(text, spec)`` names what the text lacks or has beyond
    the specification's, or None (the first differing line is said then); ``wrote(spec)`` says
    what a write put in it. Failures raise ``error`` (one line)."""

    what: str
    relative: Path
    command: str
    max_bytes: int
    error: type[Exception]
    render: Callable[[SystemSpec], str]
    named_difference: Callable[[str, SystemSpec], str | None]
    wrote: Callable[[SystemSpec], str]

    def read(self, path: Path) -> str:
        """The text of the file at ``path``. Raises ``error`` when it is missing, unreadable,
        larger than ``max_bytes`` or not UTF-8."""
        try:
            size = path.stat().st_size
            if size > self.max_bytes:
                raise self.error(f"{path}: {size} bytes, more than a {self.what} holds ({self.max_bytes})")
            return path.read_bytes().decode("utf-8")
        except FileNotFoundError:
            raise self.error(f"{path}: no such {self.what}") from None
        except (OSError, UnicodeDecodeError) as exc:
            raise self.error(f"{path}: cannot read it: {exc}") from None

    def difference(self, text: str, spec: SystemSpec) -> str | None:
        """How ``text`` differs from what ``spec`` gives (one phrase), or None when it does not."""
        wanted = self.render(spec)
        if text == wanted:
            return None
        named = self.named_difference(text, spec)
        if named is not None:
            return named
        ours, theirs = text.splitlines(), wanted.splitlines()
        first = next((i for i, (a, b) in enumerate(zip(ours, theirs, strict=False)) if a != b), None)
        if first is None:
            shorter = min(len(ours), len(theirs))
            return "its end differs" if len(ours) == len(theirs) else f"line {shorter + 1} differs"
        return f"line {first + 1} differs"

    def check(self, path: Path, spec: SystemSpec, shown: str | None = None) -> str | None:
        """None when the file at ``path`` is what ``spec`` gives; else one line saying how it
        differs and how to bring it up to date, naming the file ``shown`` (default: ``path``).
        Raises ``error`` as :meth:`read`."""
        how = self.difference(self.read(path), spec)
        if how is None:
            return None
        return f"{shown or path} differs from what the specification gives ({how}): run `{self.command}`"

    def write(self, path: Path, spec: SystemSpec) -> bool:
        """Write what ``spec`` gives to ``path`` (a temporary file, then a rename); False when
        it already held exactly that. Raises ``error`` as ``render`` does, and when it cannot be
        written."""
        text = self.render(spec)
        try:
            if self.read(path) == text:
                return False
        except self.error:  # missing or unreadable: written anew
            pass
        tmp = path.with_name(path.name + ".tmp")
        try:
            tmp.write_text(text)
            tmp.replace(path)
        except OSError as exc:
            raise self.error(f"{path}: cannot write it: {exc.strerror or exc}") from None
        return True

    def bring_up_to_date(self, root: Path, spec: SystemSpec) -> str:
        """Render checkout ``root``'s copy from ``spec`` (``roco spec new-agent``); the line
        that tells the user what was done. Raises ``error`` as :meth:`write`."""
        return self.bring_up_to_date_at(root / self.relative, spec)

    def bring_up_to_date_at(self, path: Path, spec: SystemSpec) -> str:
        """Render the copy at ``path`` from ``spec`` when there is one; the line that tells the
        user what was done. Raises ``error`` as :meth:`write`."""
        if not path.is_file():
            return f"no {self.what} at {path}: `{self.command} --file F` writes one elsewhere"
        if self.write(path, spec):
            return f"wrote {path}: {self.wrote(spec)}"
        return f"{path} is up to date"
