"""services/runtime/native.py: the runtime's mypyc-compiled modules are used when they were
compiled from the sources there are, and the sources when those changed since (or when
``ROCO_INTERPRETED=1``)."""

from __future__ import annotations

import importlib
import importlib.machinery
import json
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

import services.runtime
from services.runtime.native import COMPILED, MANIFEST, compiled_path, source_digest, stale, use_fresh_sources

SUFFIX = importlib.machinery.EXTENSION_SUFFIXES[0]


def _module(folder: Path, name: str, text: str, *, compiled: bool, manifest: bool) -> Path:
    """``name``.py with ``text`` in ``folder``, a stand-in extension beside it (not loadable:
    importing it fails) and the manifest naming the source's digest."""
    source = folder / f"{name}.py"
    source.write_text(text)
    if compiled:
        (folder / f"{name}{SUFFIX}").write_bytes(b"not an extension")
    if manifest:
        (folder / MANIFEST).write_text(json.dumps({name: source_digest(source)}))
    return source


def test_a_module_compiled_from_its_source_is_not_stale(tmp_path: Path) -> None:
    _module(tmp_path, "m", "X = 1\n", compiled=True, manifest=True)
    assert stale(tmp_path, ["m"], {}) == {}


def test_an_edited_source_or_no_manifest_runs_from_source(tmp_path: Path) -> None:
    source = _module(tmp_path, "m", "X = 1\n", compiled=True, manifest=True)
    source.write_text("X = 2\n")
    assert stale(tmp_path, ["m"], {}) == {"m": source}
    (tmp_path / MANIFEST).unlink()
    assert stale(tmp_path, ["m"], {}) == {"m": source}


def test_one_edited_source_runs_every_compiled_module_from_source(tmp_path: Path) -> None:
    """Compiled modules call each other's compiled code: one from its source takes the rest."""
    first = _module(tmp_path, "m", "X = 1\n", compiled=True, manifest=False)
    second = _module(tmp_path, "n", "Y = 1\n", compiled=True, manifest=False)
    (tmp_path / MANIFEST).write_text(json.dumps({"m": source_digest(first), "n": source_digest(second)}))
    assert stale(tmp_path, ["m", "n"], {}) == {}
    second.write_text("Y = 2\n")
    assert stale(tmp_path, ["m", "n"], {}) == {"m": first, "n": second}


def test_roco_interpreted_runs_every_compiled_module_from_source(tmp_path: Path) -> None:
    source = _module(tmp_path, "m", "X = 1\n", compiled=True, manifest=True)
    _module(tmp_path, "plain", "Y = 1\n", compiled=False, manifest=False)
    assert stale(tmp_path, ["m", "plain"], {"ROCO_INTERPRETED": "1"}) == {"m": source}


@pytest.fixture
def package(tmp_path: Path) -> Iterator[Path]:
    """A package ``nativepkg`` on sys.path, removed (with its finder) afterwards."""
    folder = tmp_path / "nativepkg"
    folder.mkdir()
    (folder / "__init__.py").write_text("")
    finders = list(sys.meta_path)
    sys.path.insert(0, str(tmp_path))
    yield folder
    sys.path.remove(str(tmp_path))
    sys.meta_path[:] = finders
    for name in [n for n in sys.modules if n == "nativepkg" or n.startswith("nativepkg.")]:
        del sys.modules[name]


def test_an_edited_module_is_imported_from_its_source(package: Path) -> None:
    _module(package, "m", "WHERE = 'compiled'\n", compiled=True, manifest=True)
    (package / "m.py").write_text("WHERE = 'source'\n")
    with pytest.raises(ImportError):  # Python prefers the (here unloadable) extension
        importlib.import_module("nativepkg.m")
    sys.modules.pop("nativepkg.m", None)
    assert use_fresh_sources("nativepkg", package, ["m"]) == {"m": package / "m.py"}
    assert importlib.import_module("nativepkg.m").WHERE == "source"


def test_the_installed_runtime_uses_what_it_compiled() -> None:
    """Where setup.py compiled the runtime (CI requires it), those modules are the compiled
    ones unless their sources changed since."""
    folder = Path(services.runtime.__file__).parent
    built = [n for n in COMPILED if compiled_path(folder, n) is not None]
    if not built:
        pytest.skip("the runtime was not compiled here")
    fresh = set(built) - set(stale(folder, built, {}))
    for name in fresh:
        module = importlib.import_module(f"services.runtime.{name}")
        assert module.__file__ is not None and module.__file__.endswith(SUFFIX), module.__file__


def test_setup_compiles_the_modules_the_runtime_knows_as_compiled() -> None:
    """setup.py's ``RUNTIME_COMPILED`` (what mypyc builds) and native.py's ``COMPILED`` (what
    is checked for staleness) name the same modules: each list is where its own code needs it
    (setup.py cannot import the package in its build environment), so this test keeps them one
    fact."""
    import ast

    root = Path(services.runtime.__file__).resolve().parents[2]
    tree = ast.parse((root / "setup.py").read_text())
    built = next(
        ast.literal_eval(node.value)
        for node in tree.body
        if isinstance(node, ast.Assign)
        and any(isinstance(t, ast.Name) and t.id == "RUNTIME_COMPILED" for t in node.targets)
    )
    assert tuple(Path(p).stem for p in built) == COMPILED
    assert all(Path(p).parent == Path("services/runtime") for p in built)
