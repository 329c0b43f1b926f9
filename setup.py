"""Build of roco's compiled modules: the impedance control law (velma/control/_impedance.cpp)
and, when MuJoCo's headers are there, the MuJoCo side of ag_ex's cycle (velma/control/_plant.hpp);
and the agent runtime's hot path, compiled from its typed Python by mypyc (``RUNTIME_COMPILED``).

Everything else is in pyproject.toml. The module is compiled against the headers of
Pinocchio (the ``pin`` wheel: Pinocchio and Boost under ``cmeel.prefix/include``), Eigen
(the ``cmeel-eigen`` wheel) and pybind11, all build requirements in pyproject.toml, so a
C++17 compiler is all a machine needs besides them. MuJoCo's headers come from the ``mujoco``
wheel (also a build requirement; only its headers: nothing is linked, see _plant.hpp). The
extension is optional: without a compiler the install goes on and roco runs the Python law
(velma/control/compiled.py says so in a warning). ``ROCO_BUILD_NATIVE=0`` skips it on purpose
(scripts/build_image.sh does, to resolve the dependencies quickly).
"""

from __future__ import annotations

import hashlib
import importlib.util
import json
import os
import sys
from pathlib import Path

from pybind11.setup_helpers import Pybind11Extension
from setuptools import setup


def _cmeel_include() -> list[str]:
    """Include folders of the cmeel wheels (Pinocchio, Boost; Eigen in its ``eigen3``) in the
    build's environment: the first ``cmeel.prefix/include`` on ``sys.path`` that has
    Pinocchio's headers (pip's isolated build environment comes first there)."""
    for entry in sys.path:
        root = Path(entry) / "cmeel.prefix" / "include"
        if (root / "pinocchio").is_dir():
            return [str(root), str(root / "eigen3")]
    return []


def _mujoco_include() -> list[str]:
    """The ``include`` folder of the ``mujoco`` wheel in the build's environment (found
    without importing it), or nothing: then the module has the law only."""
    spec = importlib.util.find_spec("mujoco")
    for folder in (spec.submodule_search_locations or []) if spec is not None else []:
        root = Path(folder) / "include"
        if (root / "mujoco" / "mujoco.h").is_file():
            return [str(root)]
    return []


ext_modules = []
mujoco_include = _mujoco_include()
if os.environ.get("ROCO_BUILD_NATIVE", "1") != "0":
    ext_modules.append(
        Pybind11Extension(
            "velma.control._impedance",
            ["velma/control/_impedance.cpp"],
            include_dirs=_cmeel_include() + mujoco_include,
            # Pinocchio's own interface definitions (its CMake config, pinocchioTargets.cmake):
            # its joint variant has more alternatives than Boost.MPL's default limit of 20
            define_macros=[
                ("BOOST_MPL_LIMIT_LIST_SIZE", "30"),
                ("BOOST_MPL_LIMIT_VECTOR_SIZE", "30"),
                ("BOOST_MPL_CFG_NO_PREPROCESSED_HEADERS", None),
                ("BOOST_FUSION_INVOKE_MAX_ARITY", "12"),
                *([("ROCO_WITH_MUJOCO", None)] if mujoco_include else []),
            ],
            depends=["velma/control/_plant.hpp"],
            extra_compile_args=["-O2", "-Wno-deprecated-declarations"],
            cxx_std=17,
            optional=True,
        )
    )

RUNTIME_COMPILED = (
    "services/runtime/protocol_state.py",
    "services/runtime/replies.py",
    "services/runtime/lookups.py",
    "services/runtime/dedup.py",
    "services/runtime/intake.py",
    "services/runtime/admission.py",
    "services/runtime/emission.py",
)
"""The agent runtime's hot path compiled by mypyc (the protocol state, the replies awaited, the
specification's kept answers and the duplicate filter of every communicate sent and
received, the checks of a received one and ``admit``, which runs them all in one call, and
``emission``, which sends one in one call;
services/runtime/native.py). Each is compiled on its own (``separate``): its
extension and its ``__mypyc`` library lie beside its source."""


def _runtime_extensions() -> list:  # type: ignore[type-arg]
    """mypyc's extensions of ``RUNTIME_COMPILED``, or none (with a warning) when mypyc is
    missing or fails: roco then runs those modules interpreted, as they are written."""
    try:
        from mypyc.build import mypycify

        # the build environment has the build requirements only: the types of msgspec, zenoh
        # and the rest are taken as Any there, and the modules they import are not reported on
        # (the code is mypy-clean against them elsewhere: CI's mypy)
        options = ["--ignore-missing-imports", "--follow-imports=silent"]
        extensions = mypycify([*options, *RUNTIME_COMPILED], separate=True, opt_level="3")
    except (Exception, SystemExit) as exc:  # any failure (mypy exits): the interpreted runtime works
        print(f"setup.py: the runtime is not compiled ({type(exc).__name__}: {exc}); it runs interpreted")
        return []
    for extension in extensions:
        extension.optional = True  # a compiler error leaves that module interpreted
    # what was compiled, by content: services/runtime/native.py runs a module whose source
    # differs from it (edited since) from its source
    digests = {Path(p).stem: hashlib.sha256(Path(p).read_bytes()).hexdigest() for p in RUNTIME_COMPILED}
    Path("services/runtime/_compiled.json").write_text(json.dumps(digests, indent=1) + "\n")
    return extensions


if os.environ.get("ROCO_BUILD_NATIVE", "1") != "0":
    ext_modules += _runtime_extensions()

# the extensions are built side by side, one per core (build_ext --parallel): the control law's one
# C++ file takes most of the build, the runtime's C files compile beside it
setup(ext_modules=ext_modules, options={"build_ext": {"parallel": os.cpu_count() or 1}})
