"""deploy/slim_venv.py on a made-up venv: build-only files and test suites go, a wheel's copies
of one shared library become links to the full version, ELF files are stripped (a stand-in
``strip`` records which) except auditwheel's ``*.libs``, and what a package imports stays."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _module() -> ModuleType:
    spec = importlib.util.spec_from_file_location("slim_venv", ROOT / "deploy" / "slim_venv.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["slim_venv"] = module
    spec.loader.exec_module(module)
    return module


slim_venv = _module()
ELF = b"\x7fELF" + b"\0" * 60


def _venv(root: Path) -> Path:
    site = root / "lib" / "python3.11" / "site-packages"
    files = {
        "pkg/__init__.py": b"x = 1\n",
        "pkg/tests/test_pkg.py": b"def test(): pass\n",
        "pkg/testing/__init__.py": b"# a package's public test helpers: kept\n",
        "pkg/include/pkg.h": b"int f(void);\n",
        "pkg/_ext.cpython-311-x86_64-linux-gnu.so": ELF + b"ext",
        "pkg/src.pyx": b"cdef int x\n",
        "cmeel.prefix/include/eigen3/Eigen/Core": b"// header\n",
        "cmeel.prefix/lib/libfoo.so": ELF + b"foo",
        "cmeel.prefix/lib/libfoo.so.6": ELF + b"foo",
        "cmeel.prefix/lib/libfoo.so.6.0.5": ELF + b"foo",
        "cmeel.prefix/lib/libbar.so": ELF + b"bar",
        "cmeel.prefix/lib/libstatic.a": b"!<arch>\n",
        "cmeel.prefix/lib/cmake/foo/fooConfig.cmake": b"# cmake\n",
        "pkg.libs/libpatched-1a2b.so": ELF + b"patched",
    }
    for name, data in files.items():
        path = site / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
    return site


def test_slimming_keeps_what_runs_and_drops_what_builds(tmp_path: Path) -> None:
    venv = tmp_path / "venv"
    site = _venv(venv)
    log = tmp_path / "stripped.txt"
    strip = tmp_path / "strip"
    strip.write_text(f'#!/bin/sh\necho "$2" >> {log}\n')
    strip.chmod(0o755)
    assert slim_venv.main([str(venv), "--strip", str(strip)]) == 0
    left = {str(p.relative_to(site)) for p in site.rglob("*") if p.is_file() or p.is_symlink()}
    assert left == {
        "pkg/__init__.py",
        "pkg/testing/__init__.py",
        "pkg/_ext.cpython-311-x86_64-linux-gnu.so",
        "cmeel.prefix/lib/libfoo.so",
        "cmeel.prefix/lib/libfoo.so.6",
        "cmeel.prefix/lib/libfoo.so.6.0.5",
        "cmeel.prefix/lib/libbar.so",
        "pkg.libs/libpatched-1a2b.so",
    }
    lib = site / "cmeel.prefix" / "lib"
    assert (lib / "libfoo.so").readlink() == Path("libfoo.so.6.0.5")
    assert (lib / "libfoo.so.6").readlink() == Path("libfoo.so.6.0.5")
    assert (lib / "libfoo.so").read_bytes() == ELF + b"foo" and not (lib / "libfoo.so.6.0.5").is_symlink()
    stripped = {str(Path(line).relative_to(site)) for line in log.read_text().split()}
    assert stripped == {
        "pkg/_ext.cpython-311-x86_64-linux-gnu.so",
        "cmeel.prefix/lib/libfoo.so.6.0.5",
        "cmeel.prefix/lib/libbar.so",
    }  # not the links, not auditwheel's patched library


def test_a_failing_strip_and_a_folder_without_site_packages_are_errors(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert slim_venv.main([str(tmp_path)]) == 2
    assert capsys.readouterr().err == f"slim_venv: {tmp_path} has no lib/python3.*/site-packages\n"
    venv = tmp_path / "venv"
    _venv(venv)
    with pytest.raises(RuntimeError, match="not an ELF file"):
        slim_venv.main([str(venv), "--strip", str(_failing(tmp_path))])


def _failing(tmp_path: Path) -> Path:
    strip = tmp_path / "bad-strip"
    strip.write_text('#!/bin/sh\necho "strip: $2: not an ELF file" >&2\nexit 1\n')
    strip.chmod(0o755)
    return strip
