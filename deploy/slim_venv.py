"""Slim a built virtual environment for the runtime image (deploy/Dockerfile, build stage).

Usage: python3 deploy/slim_venv.py VENV [--strip PROGRAM]

What a running roco never reads goes; every package stays importable:

- build-only files: C/C++ headers and sources, Cython sources, static libraries (``.a``), CMake
  and pkg-config files (e.g. Pinocchio's and Boost's headers under ``cmeel.prefix/include``,
  ≈ 200 MB);
- the packages' own test suites (folders named ``tests``);
- copies: a wheel cannot hold a symbolic link, so a shared library ships once per name
  (``libassimp.so``, ``libassimp.so.6``, ``libassimp.so.6.0.5``); the copies become links to
  the longest name;
- symbol tables: ``strip --strip-unneeded`` on shared objects and executables (the dynamic
  symbols the loader needs stay), except in auditwheel's ``<package>.libs`` folders, whose
  libraries patchelf rewrote.

Prints what it removed and the size before and after. Exit status 2 with a line on standard
error when VENV has no ``lib/python3.*/site-packages``.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

BUILD_ONLY_SUFFIXES = frozenset(
    {".a", ".h", ".hh", ".hpp", ".hxx", ".c", ".cc", ".cpp", ".pyx", ".pxd", ".pxi"}
)
"""Files only a compiler reads."""
BUILD_ONLY_DIRS = frozenset({"include", "cmake", "pkgconfig"})
"""Folders only a compiler or a build system reads."""
TEST_DIRS = frozenset({"tests"})
"""Folders of a package's own tests (never imported by the package)."""
ELF = b"\x7fELF"


def site_packages(venv: Path) -> Path:
    """The ``site-packages`` folder of ``venv``; ValueError if it has none."""
    found = sorted(venv.glob("lib/python3.*/site-packages"))
    if not found:
        raise ValueError(f"{venv} has no lib/python3.*/site-packages")
    return found[0]


def size_of(root: Path) -> int:
    """Bytes of the regular files below ``root`` (links not followed)."""
    return sum(p.lstat().st_size for p in root.rglob("*") if p.is_file() and not p.is_symlink())


def remove_build_only(site: Path) -> int:
    """Remove headers, sources, static libraries, build-system files and test suites; return
    how many files and folders went."""
    gone = 0
    for folder in sorted(site.rglob("*"), key=lambda p: len(p.parts)):
        drop = folder.name in BUILD_ONLY_DIRS | TEST_DIRS
        if drop and folder.is_dir() and not folder.is_symlink():  # (not below one removed)
            shutil.rmtree(folder)
            gone += 1
    for path in site.rglob("*"):
        if path.suffix in BUILD_ONLY_SUFFIXES and (path.is_file() or path.is_symlink()):
            path.unlink()
            gone += 1
    return gone


def link_copies(site: Path) -> int:
    """Make each copy of a file in the same folder a link to the copy with the longest name
    (the shared library's full version); return how many became links."""
    by_folder: dict[tuple[Path, int], list[Path]] = defaultdict(list)
    for path in site.rglob("*.so*"):
        if path.is_file() and not path.is_symlink():
            by_folder[(path.parent, path.stat().st_size)].append(path)
    linked = 0
    for (_, _), paths in by_folder.items():
        if len(paths) < 2:
            continue
        contents: dict[bytes, list[Path]] = defaultdict(list)
        for path in paths:
            contents[path.read_bytes()].append(path)
        for same in contents.values():
            keep = max(same, key=lambda p: (len(p.name), p.name))
            for copy in same:
                if copy != keep:
                    copy.unlink()
                    copy.symlink_to(keep.name)
                    linked += 1
    return linked


def is_elf(path: Path) -> bool:
    """Whether ``path`` is an ELF file (a shared object or an executable)."""
    with path.open("rb") as f:
        return f.read(4) == ELF


def strip_symbols(venv: Path, strip: str) -> int:
    """``strip --strip-unneeded`` every ELF file of ``venv`` outside ``*.libs`` folders; return
    how many were stripped. RuntimeError if ``strip`` fails on one."""
    stripped = 0
    for path in sorted(venv.rglob("*")):
        if not path.is_file() or path.is_symlink() or any(p.endswith(".libs") for p in path.parts):
            continue
        if not is_elf(path):
            continue
        out = subprocess.run(
            [strip, "--strip-unneeded", str(path)], capture_output=True, text=True, check=False
        )
        if out.returncode != 0:
            raise RuntimeError(f"{strip} {path}: {out.stderr.strip()}")
        stripped += 1
    return stripped


def main(argv: list[str] | None = None) -> int:
    """Slim the venv named on the command line (see the module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("venv", type=Path)
    parser.add_argument("--strip", default="strip", help="the strip program (binutils)")
    args = parser.parse_args(argv)
    try:
        site = site_packages(args.venv)
    except ValueError as exc:
        print(f"slim_venv: {exc}", file=sys.stderr)
        return 2
    before = size_of(args.venv)
    gone = remove_build_only(site)
    linked = link_copies(site)
    stripped = strip_symbols(args.venv, args.strip)
    after = size_of(args.venv)
    print(
        f"slim_venv: {args.venv}: {before / 1e6:.0f} MB -> {after / 1e6:.0f} MB "
        f"({gone} build-only files/folders removed, {linked} copies linked, {stripped} ELF files stripped)"
    )
    return 0


if __name__ == "__main__":
    os.umask(0o022)
    sys.exit(main())
