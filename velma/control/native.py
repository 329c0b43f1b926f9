"""The C++ extension ``velma.control._impedance`` (velma/control/_impedance.cpp: the compiled
impedance law, velma/control/compiled.py, and the MuJoCo side of the cycle, ``Plant`` of
velma/control/_plant.hpp), or why it did not import. Imports neither Pinocchio nor MuJoCo: the
world process steps MuJoCo through the ``Plant`` without loading Pinocchio (the extension uses
Pinocchio's headers only)."""

from __future__ import annotations

from types import ModuleType

try:  # built by `pip install` (setup.py); absent when no C++ compiler was found
    from velma.control import _impedance as extension
except ImportError as exc:  # pragma: no cover - depends on the build
    extension = None  # type: ignore[assignment]
    IMPORT_ERROR: str | None = str(exc)
else:
    IMPORT_ERROR = None


def native_module() -> ModuleType | None:
    """The compiled module (``velma.control._impedance``), or None when it is not built
    (``IMPORT_ERROR`` says why)."""
    return extension
