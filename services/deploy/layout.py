"""Where a compose file finds the system it runs and the host's folders (docs/deploy.md,
"Your own system in containers").

roco's kitchen (the shipped specification) is the image's own system: its file,
``deploy/compose.yaml`` of roco's checkout, builds the images with the checkout as the context,
keeps the run folders in the checkout's ``runs/`` and the credentials in ``deploy/certs/``
(:data:`KITCHEN`). Another system (a specification and a package beside it, anywhere: services/
spec/model.py ``system_root``) runs in roco's images as they are, which its file does not
build: its folder is mounted read-only at :data:`SYSTEM_IN` in every roco service and
``ROCO_SPEC`` names its specification there; the run folders are its ``runs/``, and the
credentials are beside the folder, in ``<folder>-certs``: every service mounts the system's
folder, and no service may see another's credentials (:func:`layout_for`).

Paths are written relative to the compose file's folder, where Compose resolves them.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path

from services.spec.model import DEFAULT_SPEC, system_root
from shared.settings import Settings, deployment_name

SYSTEM_IN = "/system"
"""Where another system's folder is in the containers (read-only)."""
RUNS_IN = "/runs"
"""Where the run folders are in the containers."""
FLEET_MOUNT = "fleet:/var/lib/roco/fleet"
"""The volume of the fleet's run name (deploy/entrypoint.sh)."""
RUNS_VARIABLE = deployment_name("runs")
CERTS_VARIABLE = deployment_name("certs")
SPEC_VARIABLE = Settings.env_name("spec")

IN_SYSTEM = Path("deploy", "compose.yaml")
"""Where ``roco deploy compose`` writes a system's file by default, in its folder (and where
``roco spec new-agent`` brings it up to date): the place of the kitchen's in roco's checkout."""

_WRITABLE = re.compile(r"[A-Za-z0-9._/@+-]+")
"""A path a compose file writes as it is: in a short volume syntax (no ``:``), uninterpolated
(no ``$``) and a plain YAML scalar."""


class LayoutError(ValueError):
    """A system whose folder a compose file cannot name (one line)."""


@dataclass(frozen=True)
class Layout:
    """Where a compose file finds the host's folders and the system, as it writes them.

    ``runs`` and ``certs``: the defaults of ``ROCO_RUNS`` and ``ROCO_CERTS``; ``system``: the
    system's folder, mounted read-only at :data:`SYSTEM_IN` in every roco service, and
    ``spec`` its specification's file name there (``ROCO_SPEC``); ``system`` None: the system
    is the image's own (roco's kitchen), whose images the file builds from roco's checkout."""

    runs: str = "../runs"
    certs: str = "./certs"
    system: str | None = None
    spec: str = ""

    @property
    def builds(self) -> bool:
        """Whether the file builds the images (roco's checkout is its build context)."""
        return self.system is None

    @property
    def spec_in(self) -> str:
        """The specification's path in the containers (another system's)."""
        return f"{SYSTEM_IN}/{self.spec}"

    @property
    def certs_host(self) -> str:
        """The credentials folder on the host: ``ROCO_CERTS``, else :attr:`certs`."""
        return f"${{{CERTS_VARIABLE}:-{self.certs}}}"

    @property
    def runs_host(self) -> str:
        """The run folders on the host: ``ROCO_RUNS``, else :attr:`runs`."""
        return f"${{{RUNS_VARIABLE}:-{self.runs}}}"

    @property
    def system_mount(self) -> str | None:
        """The read-only mount of the system's folder (None: the kitchen's, in the image)."""
        return None if self.system is None else f"{self.system}:{SYSTEM_IN}:ro"

    def mounts(self) -> list[str]:
        """What every roco service mounts: the run folders, the fleet's run name and, for
        another system, its folder."""
        system = [] if self.system_mount is None else [self.system_mount]
        return [f"{self.runs_host}:{RUNS_IN}", FLEET_MOUNT, *system]


KITCHEN = Layout()
"""roco's kitchen: ``deploy/compose.yaml`` of the checkout."""


def is_kitchen(spec_file: Path) -> bool:
    """Whether ``spec_file`` is the shipped specification (roco's kitchen)."""
    return spec_file.resolve() == DEFAULT_SPEC.resolve()


def _relative(path: str) -> str:
    """``path`` (relative, normalised) as a compose file writes a relative host path: starting
    with ``.`` (``cell`` → ``./cell``), else Compose reads a volume's name."""
    path = os.path.normpath(path)
    return path if path in (".", "..") or path.startswith("../") else f"./{path}"


def _writable(path: str, system: Path) -> str:
    """``path``, when a compose file can write it; LayoutError naming ``system`` else."""
    if not _WRITABLE.fullmatch(path):
        raise LayoutError(
            f"{system}: a compose file cannot name {path!r}: a path of letters, digits and . _ / @ + - "
            f"(move the system's folder, or write the compose file elsewhere)"
        )
    return path


def layout_for(spec_file: Path, compose_file: Path) -> Layout:
    """The layout of a compose file at ``compose_file`` for the specification ``spec_file``:
    :data:`KITCHEN` for the shipped one; for another, its folder relative to the compose
    file's, its ``runs/`` and the credentials folder ``<folder>-certs`` beside it (outside the
    folder every service mounts). Raises LayoutError when a path cannot be written in a compose
    file (a ``:``, ``$``, space, …)."""
    if is_kitchen(spec_file):
        return KITCHEN
    root = system_root(spec_file)
    system = _relative(os.path.relpath(root, compose_file.resolve().parent))
    return Layout(
        runs=_writable(_relative(os.path.join(system, "runs")), root),
        certs=_writable(_relative(os.path.join(system, "..", f"{root.name}-certs")), root),
        system=_writable(system, root),
        spec=_writable(spec_file.resolve().name, root),
    )


def default_file(spec_file: Path, kitchen_file: Path) -> Path:
    """Where ``roco deploy compose`` writes the compose file of ``spec_file`` unless told:
    ``kitchen_file`` for the shipped specification, else :data:`IN_SYSTEM` in the system's
    folder (never roco's own file)."""
    return kitchen_file if is_kitchen(spec_file) else system_root(spec_file) / IN_SYSTEM


def project_name(spec_file: Path) -> str:
    """A Compose project name for ``spec_file``'s system: its file name's stem in lower-case
    letters, digits, ``_`` and ``-`` (``cell.toml`` → ``cell``), else ``roco``."""
    name = re.sub(r"[^a-z0-9_-]", "", spec_file.stem.lower()).lstrip("_-")
    return name or "roco"
