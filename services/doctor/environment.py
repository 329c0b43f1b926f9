"""Python, the libraries roco depends on, and ag_ex's compiled impedance law."""

from __future__ import annotations

import importlib.metadata
import importlib.util
import sys
import tomllib
from pathlib import Path

from packaging.requirements import InvalidRequirement, Requirement
from packaging.version import InvalidVersion, Version

from services.doctor.model import Check, Use

ROOT = Path(__file__).resolve().parents[2]
PYPROJECT = ROOT / "pyproject.toml"
MIN_PYTHON = (3, 11)
INSTALL = "pip install -e . in the repository (README, 'Two commands')"


def requirements(pyproject: Path = PYPROJECT) -> list[Requirement]:
    """roco's runtime requirements: ``[project] dependencies`` of ``pyproject`` when it is
    there (a source checkout), else the installed distribution's metadata. Raises nothing:
    an unreadable list is an empty one."""
    lines: list[str] = []
    if pyproject.is_file():
        try:
            lines = list(tomllib.loads(pyproject.read_text())["project"]["dependencies"])
        except (tomllib.TOMLDecodeError, KeyError, OSError):
            lines = []
    if not lines:
        try:
            lines = [r for r in importlib.metadata.requires("roco") or [] if "extra ==" not in r]
        except importlib.metadata.PackageNotFoundError:
            lines = []
    out = []
    for line in lines:
        try:
            out.append(Requirement(line))
        except InvalidRequirement:
            continue
    return out


def python_check(version: tuple[int, int, int] | None = None) -> Check:
    """Python ≥ 3.11 (``version`` defaults to this interpreter's)."""
    v = version or (sys.version_info.major, sys.version_info.minor, sys.version_info.micro)
    found = v[:2] >= MIN_PYTHON
    text = ".".join(map(str, v))
    return Check(
        "Python",
        Use.RUN,
        found,
        f"{text} ({sys.executable})" if found else f"{text}; roco needs ≥ 3.11",
        "" if found else "install Python ≥ 3.11 (Debian bookworm: apt-get install python3)",
    )


def library_check(req: Requirement) -> Check:
    """The installed version of ``req``'s distribution against its specifier."""
    try:
        installed = importlib.metadata.version(req.name)
    except importlib.metadata.PackageNotFoundError:
        return Check(req.name, Use.RUN, False, f"not installed (needs {req})", INSTALL)
    try:
        ok = req.specifier.contains(Version(installed), prereleases=True)
    except InvalidVersion:
        ok = False
    detail = installed if ok else f"{installed}, but roco needs {req}"
    return Check(req.name, Use.RUN, ok, detail, "" if ok else f"pip install '{req}'")


def compiled_law_check() -> Check:
    """Whether ``velma.control._impedance`` was built (without it ag_ex runs the same law in
    Python, about 4× slower; found by file, nothing is imported)."""
    found = importlib.util.find_spec("velma.control._impedance") is not None
    return Check(
        "compiled impedance law",
        Use.SPEED,
        found,
        "velma/control/_impedance built"
        if found
        else "not built: ag_ex runs the law in Python (≈ 4× slower)",
        "" if found else "a C++ compiler (apt-get install g++), then pip install -e . again",
    )


def compiled_runtime_check() -> Check:
    """Whether the agent runtime's hot path was compiled by mypyc and matches its sources
    (services/runtime/native.py; found by file and digest, nothing of it is imported)."""
    from services.runtime.native import COMPILED, compiled_path, stale

    folder = Path(__file__).resolve().parents[1] / "runtime"
    built = [n for n in COMPILED if compiled_path(folder, n) is not None]
    changed = sorted(stale(folder, built, {}))
    missing = sorted(set(COMPILED) - set(built))
    ok = not changed and not missing
    detail = (
        f"services/runtime: {', '.join(COMPILED)} compiled"
        if ok
        else f"runs from source: {', '.join(missing + changed)} ("
        + ("not compiled" if missing else "changed since compiled")
        + "; ≈ 85 % more CPU per round trip)"
    )
    return Check("compiled agent runtime", Use.SPEED, ok, detail, "" if ok else "pip install -e . again")


ROS2_EXTRA = "ros2"
ROS2_HOW = "pip install -e '.[ros2]' (rosbags, mcap, mcap-ros2-support)"


def extra_requirements(extra: str, pyproject: Path = PYPROJECT) -> list[Requirement]:
    """The requirements of roco's optional ``extra`` (``[project.optional-dependencies]`` of
    ``pyproject``, else the installed distribution's metadata); none when unreadable."""
    lines: list[str] = []
    try:
        lines = list(tomllib.loads(pyproject.read_text())["project"]["optional-dependencies"][extra])
    except (tomllib.TOMLDecodeError, KeyError, OSError):
        try:
            marker = f'extra == "{extra}"'
            lines = [r.split(";")[0] for r in importlib.metadata.requires("roco") or [] if marker in r]
        except importlib.metadata.PackageNotFoundError:
            lines = []
    out = []
    for line in lines:
        try:
            out.append(Requirement(line))
        except InvalidRequirement:
            continue
    return out


def ros2_extra_check() -> Check:
    """The ``ros2`` extra (rosbags, mcap, mcap-ros2-support) that ``roco export --mcap`` and
    reading its bags need: one line, every library of it installed at a version it allows."""
    found: list[str] = []
    lacking: list[str] = []
    for req in extra_requirements(ROS2_EXTRA):
        c = library_check(req)
        (found if c.found else lacking).append(f"{req.name} {c.detail}")
    ok = not lacking and bool(found)
    detail = ", ".join(found) if ok else "; ".join(lacking) or "the ros2 extra is not declared"
    return Check("ROS 2 formats (ros2 extra)", Use.EXPORT, ok, detail, "" if ok else ROS2_HOW)


def checks() -> list[Check]:
    """Python, every library of :func:`requirements`, the compiled law and runtime, the ros2
    extra."""
    return [
        python_check(),
        *(library_check(r) for r in requirements()),
        compiled_law_check(),
        compiled_runtime_check(),
        ros2_extra_check(),
    ]
