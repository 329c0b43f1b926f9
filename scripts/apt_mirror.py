"""The Debian mirror this host's apt uses, for debootstrap (scripts/build_image.sh).

    python3 scripts/apt_mirror.py [--root DIR] [--suite bookworm]

Prints the URI of the Debian archive that apt on this host is configured with, read from
``ROOT/etc/apt/sources.list``, ``ROOT/etc/apt/sources.list.d/*.list`` (one-line format) and
``ROOT/etc/apt/sources.list.d/*.sources`` (deb822 format; sources.list(5)), so that an
air-gapped site's own mirror or proxy is used without editing the build script. Exit 1 with one
line on stderr when none is found.

Which entry: a ``deb`` (not ``deb-src``) entry that is enabled and has the ``main`` component,
whose suite is ``--suite`` itself (the target release), else a Debian release name or alias
(``bullseye``, ``trixie``, ``stable``, …; a host on another release still names a mirror that
holds ``--suite``). Suites ending in ``-security``, ``-updates``, ``-backports`` or
``-proposed-updates`` are never taken (their archives hold only updates), nor URIs of the
security archive. Among equals the first in apt's reading order wins (``sources.list``, then
``sources.list.d/`` in file-name order). An Ubuntu host's archive names no Debian suite and is
not taken. Standard library only: it runs on the host's Python before anything is installed.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import NamedTuple

DEBIAN_SUITES = frozenset(
    {
        "buster", "bullseye", "bookworm", "trixie", "forky", "duke", "sid",
        "oldoldstable", "oldstable", "stable", "testing", "unstable",
    }
)  # fmt: skip
"""Debian release names and aliases (https://www.debian.org/releases/)."""
UPDATE_SUFFIXES = ("-security", "-updates", "-backports", "-proposed-updates", "-backports-sloppy")


class Entry(NamedTuple):
    """One apt source: its type (``deb``, ``deb-src``), URI, suite and components."""

    type: str
    uri: str
    suite: str
    components: tuple[str, ...]


def one_line_entries(text: str) -> Iterator[Entry]:
    """The entries of a one-line-format file (``deb [opts] URI SUITE COMPONENT…``)."""
    for raw in text.splitlines():
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        kind, _, rest = line.partition(" ")
        rest = rest.strip()
        if rest.startswith("["):  # options: [arch=amd64 signed-by=…]
            rest = rest.partition("]")[2].strip()
        fields = rest.split()
        if kind in ("deb", "deb-src") and len(fields) >= 2:
            yield Entry(kind, fields[0], fields[1], tuple(fields[2:]))


def deb822_entries(text: str) -> Iterator[Entry]:
    """The entries of a deb822 ``.sources`` file: stanzas separated by blank lines, fields
    ``Types``, ``URIs``, ``Suites``, ``Components``, ``Enabled`` (continuation lines start
    with a space; ``#`` lines are comments)."""
    for stanza in _stanzas(text):
        if stanza.get("enabled", "yes").lower() == "no":
            continue
        components = tuple(stanza.get("components", "").split())
        for kind in stanza.get("types", "").split():
            for uri in stanza.get("uris", "").split():
                for suite in stanza.get("suites", "").split():
                    yield Entry(kind, uri, suite, components)


def _stanzas(text: str) -> Iterator[dict[str, str]]:
    fields: dict[str, str] = {}
    last = ""
    for raw in [*text.splitlines(), ""]:
        if raw.startswith("#"):
            continue
        if not raw.strip():
            if fields:
                yield fields
            fields, last = {}, ""
        elif raw[0] in " \t" and last:
            fields[last] += " " + raw.strip()
        else:
            name, sep, value = raw.partition(":")
            if sep:
                last = name.strip().lower()
                fields[last] = value.strip()


def entries(root: Path) -> Iterator[Entry]:
    """Every apt source under ``root`` in apt's reading order."""
    apt = root / "etc" / "apt"
    main = apt / "sources.list"
    if main.is_file():
        yield from one_line_entries(main.read_text(errors="replace"))
    parts = apt / "sources.list.d"
    if parts.is_dir():
        for path in sorted(parts.iterdir()):
            if path.suffix == ".list" and path.is_file():
                yield from one_line_entries(path.read_text(errors="replace"))
            elif path.suffix == ".sources" and path.is_file():
                yield from deb822_entries(path.read_text(errors="replace"))


def debian_mirror(root: Path = Path("/"), suite: str = "bookworm") -> str | None:
    """The mirror URI for debootstrap of ``suite`` (the module docstring says which), without a
    trailing ``/``; None when apt under ``root`` names none."""
    candidates = [
        e
        for e in entries(root)
        if e.type == "deb"
        and "main" in e.components
        and not e.suite.endswith(UPDATE_SUFFIXES)
        and "security" not in e.uri
    ]
    for wanted in (lambda s: s == suite, lambda s: s in DEBIAN_SUITES):
        for e in candidates:
            if wanted(e.suite.removesuffix("/")):
                return e.uri.rstrip("/")
    return None


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="apt_mirror.py", description=__doc__.split("\n\n")[0])
    parser.add_argument("--root", type=Path, default=Path("/"), help="the root apt's files are read under")
    parser.add_argument("--suite", default="bookworm", help="the release debootstrap installs")
    args = parser.parse_args(argv)
    mirror = debian_mirror(args.root, args.suite)
    if mirror is None:
        where = args.root / "etc" / "apt"
        print(
            f"apt_mirror.py: no Debian mirror with 'main' in {where}/sources.list or sources.list.d/; "
            "give one with --mirror URI or DEBIAN_MIRROR=URI",
            file=sys.stderr,
        )
        return 1
    print(mirror)
    return 0


if __name__ == "__main__":
    sys.exit(main())
