"""The files that Debian packages and their dependencies add to an image that lacks them
(deploy/Dockerfile, stage ``mesa``: Mesa's software OpenGL for the robot image).

Usage: python3 deploy/mesa_files.py --have STATUS [--admindir DIR] PACKAGE...

Prints, one per line, every file and symbolic link of PACKAGE and of every package it depends
on (``Depends`` and ``Pre-Depends``, recursively; of alternatives ``a | b`` the first one
installed; a virtual name by the installed package that ``Provides`` it), as installed on this
system (dpkg's ``DIR/status`` and ``DIR/info/*.list``, default ``/var/lib/dpkg``), leaving out
the packages installed in the image (dpkg's status file ``STATUS`` copied from it) and
documentation (``/usr/share/doc``, ``man``, ``info``, ``locale``, ``lintian``). Paths are
canonical (the folder resolved: ``/lib/x86_64-linux-gnu/x`` is printed as
``/usr/lib/x86_64-linux-gnu/x`` on a merged ``/usr``), so that copying them onto the image
never puts a folder where the image has a link. Format of the status file: Debian Policy
§5.6 (deb-control fields), dpkg's ``Status: install ok installed``.

Exit status 2 with one line on standard error when a PACKAGE or a dependency with no
alternative installed is missing here: its files could not be copied.
"""

from __future__ import annotations

import argparse
import os
import re
import sys
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

SKIP_PREFIXES = (
    "/usr/share/doc/",
    "/usr/share/man/",
    "/usr/share/info/",
    "/usr/share/locale/",
    "/usr/share/lintian/",
)
"""Files nobody reads at run time."""
_NAME = re.compile(r"^\s*([A-Za-z0-9][A-Za-z0-9+.-]*)")


class MissingPackage(LookupError):
    """A package named, or one it needs, is not installed here."""


@dataclass
class Installed:
    """The installed packages of a dpkg status file: each one's dependencies (a list of
    alternatives, each a list of names) and which names each virtual name stands for."""

    depends: dict[str, list[list[str]]] = field(default_factory=dict)
    provided_by: dict[str, list[str]] = field(default_factory=dict)

    def resolve(self, name: str) -> str | None:
        """The installed package ``name`` is, or the first one that provides it; None."""
        if name in self.depends:
            return name
        return next(iter(self.provided_by.get(name, [])), None)


def _names(field_value: str) -> list[str]:
    """The package names of a deb-control relation (``a (>= 1) | b:any``), in order."""
    names = []
    for part in field_value.split("|"):
        if m := _NAME.match(part):
            names.append(m.group(1))
    return names


def stanzas(text: str) -> Iterable[dict[str, str]]:
    """The stanzas of a deb-control file: field name to value (continuation lines joined)."""
    for block in re.split(r"\n\s*\n", text):
        fields: dict[str, str] = {}
        last = ""
        for line in block.splitlines():
            if line[:1] in (" ", "\t") and last:
                fields[last] += " " + line.strip()
            elif ":" in line:
                last, _, value = line.partition(":")
                fields[last] = value.strip()
        if fields:
            yield fields


def installed(status_text: str) -> Installed:
    """The packages marked ``install ok installed`` in a dpkg status file's text."""
    found = Installed()
    for fields in stanzas(status_text):
        if fields.get("Status", "").split()[-1:] != ["installed"] or "Package" not in fields:
            continue
        name = fields["Package"]
        relations = ", ".join(v for k in ("Pre-Depends", "Depends") if (v := fields.get(k)))
        found.depends[name] = [_names(r) for r in relations.split(",") if r.strip()]
        for virtual in _names(fields.get("Provides", "").replace(",", "|")):
            found.provided_by.setdefault(virtual, []).append(name)
    return found


def closure(here: Installed, roots: Iterable[str]) -> set[str]:
    """``roots`` and every package they depend on, recursively, as installed ``here``. Raises
    MissingPackage for a root, or a dependency none of whose alternatives is installed."""
    todo = []
    for root in roots:
        if (name := here.resolve(root)) is None:
            raise MissingPackage(f"{root} is not installed")
        todo.append(name)
    seen: set[str] = set()
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        seen.add(name)
        for alternatives in here.depends[name]:
            chosen = next((p for a in alternatives if (p := here.resolve(a)) is not None), None)
            if chosen is None:
                raise MissingPackage(f"{name} needs {' | '.join(alternatives)}, none installed")
            todo.append(chosen)
    return seen


def package_files(admindir: Path, package: str) -> list[str]:
    """The paths dpkg lists for ``package`` (``info/<package>.list`` or ``<package>:<arch>.list``)."""
    lists = [admindir / "info" / f"{package}.list", *sorted((admindir / "info").glob(f"{package}:*.list"))]
    for path in lists:
        if path.exists():
            return [line for line in path.read_text().splitlines() if line.strip()]
    return []


def files_to_add(admindir: Path, have_status: str, roots: Iterable[str], root: Path = Path("/")) -> list[str]:
    """The canonical paths (files and links, below ``root``) of ``roots``' closure here,
    without the packages in ``have_status`` nor documentation; sorted."""
    here = installed((admindir / "status").read_text())
    have = set(installed(have_status).depends)
    found: set[str] = set()
    for package in sorted(closure(here, roots) - have):
        for listed in package_files(admindir, package):
            on_disk = root / listed.lstrip("/")
            if not os.path.lexists(on_disk) or on_disk.is_dir():  # a folder, or a link to one (/lib)
                continue
            real = Path(os.path.realpath(on_disk.parent)) / on_disk.name
            path = "/" + str(real.relative_to(root.resolve()))
            if not path.startswith(SKIP_PREFIXES):
                found.add(path)
    return sorted(found)


def main(argv: list[str] | None = None) -> int:
    """The command line (see the module)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--have", type=Path, required=True, help="dpkg status file of the image to add to")
    parser.add_argument("--admindir", type=Path, default=Path("/var/lib/dpkg"))
    parser.add_argument("packages", nargs="+")
    args = parser.parse_args(argv)
    try:
        paths = files_to_add(args.admindir, args.have.read_text(), args.packages)
    except MissingPackage as exc:
        print(f"mesa_files.py: {exc}: install it where this runs", file=sys.stderr)
        return 2
    sys.stdout.write("".join(f"{p}\n" for p in paths))
    return 0


if __name__ == "__main__":
    sys.exit(main())
