"""Which router of a running fleet is which (``roco status``): the Zenoh id of every router its
run folder's logs say started, named as an operator knows it (brain, robot, or its endpoint)."""

from __future__ import annotations

from pathlib import Path

ROUTER_LOG_LIMIT = 16 * 2**20
"""Bytes of a router's log read for the lines that name it (its start lines come first)."""


def routers_named(run_dir: Path | None, endpoint: str, mine: set[str]) -> dict[str, str]:
    """Zenoh id → a name of every router of the fleet of ``run_dir`` (:func:`router_names`),
    and of the routers ``mine`` a session reached (``at <endpoint>``) otherwise unnamed."""
    names = router_names(run_dir)
    names.update({z: f"at {endpoint}" for z in mine if z not in names})
    return names


def router_names(run_dir: Path | None) -> dict[str, str]:
    """Zenoh id → a name an operator knows, for every router the run folder's logs say started
    (``logs/router*.stderr``; services/runtime/router.py prints ``roco router ZID listening on
    ENDPOINTS`` at each start): ``brain`` and ``robot`` for the routers of `roco hosts`
    (router_brain, router_robot), else ``at`` its endpoints. Empty without a run folder."""
    names: dict[str, str] = {}
    if run_dir is None:
        return names
    for log in sorted((run_dir / "logs").glob("router*.stderr")):
        process = log.name.removesuffix(".stderr")
        try:
            with log.open("rb") as f:
                text = f.read(ROUTER_LOG_LIMIT).decode("utf-8", "replace")
        except OSError:
            continue
        for line in text.splitlines():
            if not line.startswith("roco router ") or " listening on " not in line:
                continue
            zid, _, rest = line.removeprefix("roco router ").partition(" listening on ")
            host = process.removeprefix("router_") if process.startswith("router_") else ""
            names[zid.strip()] = host or f"at {rest.split(';')[0].strip()}"
    return names
