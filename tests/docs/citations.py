"""Citations that reach outside the repository: a note named as a source that the repository
does not hold, or an absolute path into some machine's home or work folder.

The notes are the reference files a checkout may have beside it but never in it (the robot's
facts, the platform's pitfalls, the design notes; :data:`OUTSIDE_NOTES`). A mention of one is
fine when it names a file of the repository (a path from the repository's root or from the
citing file's folder) or sits in a URL (another project's file of the same name). The robot's
facts are in velma/model/README.md; a platform pitfall is stated where it matters.

Absolute paths (:data:`ABSOLUTE_PATH`): into ``home``, ``Users``, ``work`` or ``root`` at the top
of the file system, or a Windows drive's ``Users``; system paths (``/tmp``, ``/var/tmp``,
``/usr``, ``/dev``) are not flagged. Tests are read for the notes only: their data may quote a
foreign program's output, paths of its build machine included.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from pathlib import Path

from tests.docs.doccheck import Finding, Repository

OUTSIDE_NOTES = ("velma-facts", "platform-notes", "design")
"""File stems (``.md``) of the notes that live outside the repository."""
NOTE = re.compile(r"[\w./~:-]*(?<![\w-])(?:" + "|".join(re.escape(s) for s in OUTSIDE_NOTES) + r")\.md\b")
"""A mention of one of the notes, with the path or URL before it."""
ABSOLUTE_PATH = re.compile(r"(?<![\w.~/-])(?:/(?:home|Users|work|root)/[\w.-]+|[A-Za-z]:\\{1,2}Users\\)")
"""An absolute path into a home or work folder (not preceded by a word, as in ``roco/work/x``)."""
SCANNED = ("services", "velma", "shared", "scripts", "tests", "docs")
"""The folders read, besides the top-level Markdown files."""
NOTES_ONLY = ("tests",)
"""The folders read for the notes only, not for absolute paths."""
TEXT_SUFFIXES = frozenset(
    {
        ".py",
        ".pyi",
        ".md",
        ".toml",
        ".xml",
        ".yaml",
        ".yml",
        ".sh",
        ".cpp",
        ".hpp",
        ".h",
        ".ttl",
        ".txt",
        ".cfg",
        ".ini",
    }
)
MAX_BYTES = 2_000_000
"""A larger file is data, not prose: it is skipped."""
LEADING = "\"'`([<*"
TRAILING = "\"'`)]>*,.;:"


def scanned_files(repo: Repository) -> list[Path]:
    """The repository's text files (tracked or new, not ignored; the file system when it is not
    a git checkout) under :data:`SCANNED`, and its top-level Markdown files, sorted."""
    files = repo.files if repo.files is not None else {p for p in repo.root.rglob("*") if p.is_file()}
    out = []
    for path in files:
        parts = path.relative_to(repo.root).parts
        top_md = len(parts) == 1 and path.suffix == ".md"
        if (top_md or (len(parts) > 1 and parts[0] in SCANNED)) and path.suffix in TEXT_SUFFIXES:
            out.append(path)
    return sorted(out)


def _held(mention: str, path: Path, repo: Repository) -> bool:
    """Whether ``mention`` (a path ending in one of the notes' names) is a URL or names a file
    of the repository, from its root or from ``path``'s folder."""
    if "://" in mention:
        return True
    cited = mention.lstrip(LEADING).rstrip(TRAILING)
    if cited.startswith("/"):
        return False
    return any(repo.has_file((base / cited).resolve()) for base in (repo.root, path.parent))


def text_findings(text: str, path: Path, repo: Repository) -> list[Finding]:
    """The citations of ``text`` (the file ``path`` of ``repo``) that reach outside the
    repository, at most one per line (a note's mention first: it shows its whole path)."""
    shown = repo.relative(path)
    findings: list[Finding] = []
    for number, line in enumerate(text.splitlines(), start=1):
        outside = [m.group(0) for m in NOTE.finditer(line) if not _held(m.group(0), path, repo)]
        if outside:
            cited = outside[0].lstrip(LEADING).rstrip(TRAILING)
            findings.append(Finding(shown, number, f"cites {cited}, which the repository does not hold"))
            continue
        absolute = None if shown.split("/", 1)[0] in NOTES_ONLY else ABSOLUTE_PATH.search(line)
        if absolute:
            findings.append(
                Finding(shown, number, f"names {absolute.group(0)}…, a path outside the repository")
            )
    return findings


def findings(repo: Repository, files: Iterable[Path] | None = None) -> list[Finding]:
    """Every citation outside the repository in ``files`` (default :func:`scanned_files`)."""
    out: list[Finding] = []
    for path in scanned_files(repo) if files is None else files:
        if path.stat().st_size > MAX_BYTES:
            continue
        out += text_findings(path.read_text(encoding="utf-8", errors="replace"), path, repo)
    return out
