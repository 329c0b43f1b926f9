"""deploy/mesa_files.py on a made-up dpkg database and file tree: the files of Mesa's packages
and their dependencies that the image lacks, with dependencies followed through alternatives,
virtual packages and Pre-Depends, the image's packages and documentation left out, and paths
resolved through a merged /usr's links."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _module() -> ModuleType:
    spec = importlib.util.spec_from_file_location("mesa_files", ROOT / "deploy" / "mesa_files.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["mesa_files"] = module
    spec.loader.exec_module(module)
    return module


mesa_files = _module()

STATUS = """\
Package: libegl-mesa0
Status: install ok installed
Architecture: amd64
Depends: libgbm1 (>= 17.1.0~rc2), libc6 (>= 2.34), libwayland-client0 | libx11-6
Description: free implementation of the EGL API
 -- Mesa vendor library

Package: libgbm1
Status: install ok installed
Pre-Depends: libdrm2:any
Depends: libc6

Package: libdrm-fake
Status: install ok installed
Provides: libdrm2 (= 2.4.114)

Package: libx11-6
Status: install ok installed
Depends: libc6

Package: libc6
Status: install ok installed

Package: libremoved
Status: deinstall ok config-files
"""

FILES = {
    "libegl-mesa0": ["/usr", "/usr/lib", "/usr/lib/x86_64-linux-gnu/libEGL_mesa.so.0",
                     "/usr/share/doc/libegl-mesa0/copyright", "/usr/share/glvnd/egl_vendor.d/50_mesa.json"],
    "libgbm1": ["/lib/x86_64-linux-gnu/libgbm.so.1"],
    "libdrm-fake": ["/usr/lib/x86_64-linux-gnu/libdrm.so.2"],
    "libx11-6": ["/usr/lib/x86_64-linux-gnu/libX11.so.6"],
    "libc6": ["/usr/lib/x86_64-linux-gnu/libc.so.6"],
}  # fmt: skip


@pytest.fixture
def system(tmp_path: Path) -> tuple[Path, Path]:
    """(admindir, root): the dpkg database and the file tree, /lib a link to usr/lib."""
    root = tmp_path / "root"
    (root / "usr" / "lib" / "x86_64-linux-gnu").mkdir(parents=True)
    (root / "lib").symlink_to("usr/lib")
    admindir = tmp_path / "dpkg"
    (admindir / "info").mkdir(parents=True)
    (admindir / "status").write_text(STATUS)
    for package, paths in FILES.items():
        (admindir / "info" / f"{package}:amd64.list").write_text("\n".join(paths) + "\n")
        for path in paths:
            target = root / path.lstrip("/")
            if target.suffix:
                target.parent.mkdir(parents=True, exist_ok=True)
                target.write_text(package)
    return admindir, root


def test_the_files_the_image_lacks(system: tuple[Path, Path]) -> None:
    admindir, root = system
    have = "Package: libc6\nStatus: install ok installed\n"
    assert mesa_files.files_to_add(admindir, have, ["libegl-mesa0"], root) == [
        "/usr/lib/x86_64-linux-gnu/libEGL_mesa.so.0",
        "/usr/lib/x86_64-linux-gnu/libX11.so.6",  # the alternative installed (not wayland)
        "/usr/lib/x86_64-linux-gnu/libdrm.so.2",  # libgbm1's Pre-Depends, a virtual package
        "/usr/lib/x86_64-linux-gnu/libgbm.so.1",  # listed at /lib/...: resolved through the link
        "/usr/share/glvnd/egl_vendor.d/50_mesa.json",
    ]


def test_what_the_image_has_is_left_out(system: tuple[Path, Path]) -> None:
    """Planted: the image has libx11-6 and libgbm1 already."""
    admindir, root = system
    have = (
        "Package: libx11-6\nStatus: install ok installed\n\nPackage: libgbm1\nStatus: install ok installed\n"
    )
    found = mesa_files.files_to_add(admindir, have, ["libegl-mesa0"], root)
    assert "/usr/lib/x86_64-linux-gnu/libX11.so.6" not in found
    assert "/usr/lib/x86_64-linux-gnu/libgbm.so.1" not in found
    assert "/usr/lib/x86_64-linux-gnu/libc.so.6" in found  # no libc6 in that image


def test_a_missing_dependency_is_named(system: tuple[Path, Path], capsys: pytest.CaptureFixture[str]) -> None:
    """Planted: libx11-6 not installed, so libegl-mesa0's `libwayland-client0 | libx11-6` has none."""
    admindir, _ = system
    (admindir / "status").write_text(
        STATUS.replace(
            "Package: libx11-6\nStatus: install ok installed",
            "Package: libx11-6\nStatus: deinstall ok config-files",
        )
    )
    have = admindir.parent / "have"
    have.write_text("")
    assert mesa_files.main(["--have", str(have), "--admindir", str(admindir), "libegl-mesa0"]) == 2
    assert capsys.readouterr().err == (
        "mesa_files.py: libegl-mesa0 needs libwayland-client0 | libx11-6, none installed: "
        "install it where this runs\n"
    )
    assert mesa_files.main(["--have", str(have), "--admindir", str(admindir), "libremoved"]) == 2
    assert (
        capsys.readouterr().err == "mesa_files.py: libremoved is not installed: install it where this runs\n"
    )
