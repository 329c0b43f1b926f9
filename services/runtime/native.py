"""The agent runtime's modules compiled by mypyc, and their sources when the compiled ones are
stale.

setup.py compiles ``COMPILED`` (the protocol state of every conversation, the replies awaited,
the specification's kept answers, the duplicate filter, the checks of a received communicate
and their taking in with one call, and the sending of one with another: the Python run for
every communicate sent and received)
into extension modules beside their sources; Python imports an extension before a source of the
same name. An editable install keeps the extensions while their sources are edited: a module
whose source changed since it was compiled would run old code. ``use_fresh_sources``, called by
the package (services/runtime/__init__.py) before any of them is imported, makes such a module
load from its source instead and says so once (rebuild: ``pip install -e .``), and with it
every other compiled module (they call each other's compiled code, which takes only their
compiled objects); what was compiled is known by content (``MANIFEST``), so a checkout that
only touches a file changes nothing.
``ROCO_INTERPRETED=1`` loads every one from its source (to profile the Python with cProfile,
or to compare). What compiling saves per communicate: docs/benchmarks.md, "Python per
communicate" (scripts/profile_runtime.py --cpu).
"""

from __future__ import annotations

import importlib.machinery
import importlib.util
import json
import logging
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from types import ModuleType

try:  # CPython's own SHA-256; ``hashlib`` would also load OpenSSL (≈ 3.3 MiB resident in every agent)
    from _sha256 import sha256  # Python 3.11
except ImportError:  # pragma: no cover - 3.12 renamed it; another interpreter: hashlib's
    try:
        from _sha2 import sha256
    except ImportError:
        from hashlib import sha256

COMPILED = ("protocol_state", "replies", "lookups", "dedup", "intake", "admission", "emission")
"""Modules of services/runtime that setup.py compiles (its ``RUNTIME_COMPILED``)."""
MANIFEST = "_compiled.json"
"""Beside the modules: {module name: SHA-256 of the source compiled} (setup.py writes it)."""

log = logging.getLogger("roco.native")


class _SourceFinder:
    """Finds the modules named in ``sources`` (full name → path of the .py) from their sources.
    A meta path finder by its ``find_spec`` alone: ``importlib.abc`` would import
    ``importlib.resources`` and with it ``tempfile``, ``shutil``, ``bz2``, ``lzma`` and
    ``random`` (≈ 0.9 MiB resident in every agent)."""

    def __init__(self, sources: dict[str, Path]) -> None:
        self.sources = sources

    def find_spec(
        self, fullname: str, path: Sequence[str] | None, target: ModuleType | None = None
    ) -> importlib.machinery.ModuleSpec | None:
        source = self.sources.get(fullname)
        if source is None:
            return None
        return importlib.util.spec_from_file_location(fullname, source)


def compiled_path(folder: Path, name: str) -> Path | None:
    """The extension module of ``name`` in ``folder`` (any of this interpreter's suffixes), or
    None when there is none."""
    for suffix in importlib.machinery.EXTENSION_SUFFIXES:
        candidate = folder / f"{name}{suffix}"
        if candidate.is_file():
            return candidate
    return None


def source_digest(source: Path) -> str:
    """SHA-256 (hex) of a source file's bytes, as setup.py records it."""
    return sha256(source.read_bytes()).hexdigest()


def stale(folder: Path, names: Sequence[str], environ: Mapping[str, str] | None = None) -> dict[str, Path]:
    """The modules of ``names`` in ``folder`` to load from their sources: all with an
    extension when one of them has a source that differs from what was compiled (``MANIFEST``,
    written by setup.py: the source's SHA-256 when it was compiled; no manifest, or no entry,
    counts as differing: compiled modules call each other's compiled code, so one from its
    source takes the others along), or when ``ROCO_INTERPRETED=1`` in ``environ`` (default
    ``os.environ``, read now); name → the .py's path."""
    sources = {n: folder / f"{n}.py" for n in names if compiled_path(folder, n) is not None}
    sources = {n: s for n, s in sources.items() if s.is_file()}
    if not sources:  # nothing compiled (a checkout that was not built): settings not even read
        return {}
    if _interpreted(environ):
        return sources
    try:
        compiled_from = json.loads((folder / MANIFEST).read_text())
    except (OSError, ValueError):
        compiled_from = {}
    changed = any(compiled_from.get(n) != source_digest(s) for n, s in sources.items())
    return sources if changed else {}


def _interpreted(environ: Mapping[str, str] | None = None) -> bool:
    """``ROCO_INTERPRETED`` of ``environ`` (default ``os.environ``), read now. shared.settings
    (with msgspec) is imported here, only where a compiled module is found."""
    from shared.settings import Settings

    return Settings.from_env(environ, only=("interpreted",)).interpreted


def use_fresh_sources(package: str, folder: Path, names: Sequence[str] = COMPILED) -> dict[str, Path]:
    """Make the modules of ``package`` (its folder ``folder``) that ``stale`` names load from
    their sources (a finder first on ``sys.meta_path``), warning once for those whose source is
    newer than their extension; returns them (name → .py)."""
    sources = stale(folder, names)
    if not sources:
        return {}
    sys.meta_path.insert(0, _SourceFinder({f"{package}.{n}": p for n, p in sources.items()}))
    if not _interpreted():
        log.warning(
            "%s: a compiled module changed since compiled; %s run from source (pip install -e . "
            "compiles again)",
            package,
            ", ".join(sorted(sources)),
        )
    return sources
