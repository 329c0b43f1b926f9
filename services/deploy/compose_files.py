"""A deployment's two compose files together (``roco deploy compose``): deploy/compose.yaml
and the override compose.netfault.yaml beside it (services/deploy/netfault.py), written or
checked against what the specification gives."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from services.deploy import netfault
from services.deploy.compose import ComposeError

if TYPE_CHECKING:
    from services.spec.generated import GeneratedFile
    from services.spec.model import SystemSpec


def compose_problem(
    generated: GeneratedFile, path: Path, system: SystemSpec, shown: Callable[[Path], str]
) -> str | None:
    """How the first of the compose file ``path`` and its override (:func:`netfault.beside`)
    that is not what ``system`` gives differs, each named by ``shown``; None when both are.
    Raises ComposeError as ``GeneratedFile.check``."""
    override = netfault.beside(path)
    return generated.check(path, system, shown(path)) or netfault.check(override, system, shown(override))


def write_compose_files(generated: GeneratedFile, path: Path, system: SystemSpec) -> tuple[bool, bool]:
    """Write the compose file ``path`` and its override beside it (the folder made when
    missing); whether each changed. Raises ComposeError when a file cannot be written or
    ``system`` rendered."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ComposeError(f"{path.parent}: cannot make the folder: {exc.strerror or exc}") from None
    changed = generated.write(path, system)
    return changed, netfault.write(netfault.beside(path), system)
