"""Writes ``velma.xml`` (the MJCF model of the Velma robot: velma/model/robot_mjcf.py) and
``kitchen.xml`` (the scene of the pouring experiment: velma/model/kitchen_mjcf.py).

Run ``python -m velma.model.generate`` after changing a number in either writer; both XML files
are the output and are kept in the repository (``--check``, and a test, say whether they are up
to date). Where each number comes from: velma/model/README.md and the writers' docstrings.
"""

from __future__ import annotations

import sys

from velma.model import KITCHEN_XML, VELMA_XML
from velma.model.kitchen_mjcf import build_kitchen
from velma.model.robot_mjcf import build


def main(argv: list[str] | None = None) -> int:
    """Write velma.xml and kitchen.xml (or ``--check``: exit 1 when either differs from the
    generator's output)."""
    args = sys.argv[1:] if argv is None else argv
    outputs = ((VELMA_XML, build()), (KITCHEN_XML, build_kitchen()))
    if "--check" in args:
        return 0 if all(path.read_text() == text for path, text in outputs) else 1
    for path, text in outputs:
        path.write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
