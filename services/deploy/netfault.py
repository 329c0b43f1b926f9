"""``deploy/compose.netfault.yaml``: the override that lets ``roco fault net --delay/--loss``
work on a compose fleet (docs/faults.md).

Delay and loss are ``tc qdisc … netem`` run in a service's container, which needs the
``NET_ADMIN`` capability; deploy/compose.yaml grants it to no service (a fleet that is not
being faulted needs none). This file adds ``cap_add: [NET_ADMIN]`` to every service a network
fault reaches: the router, the recorder, one per agent of the specification (in its start
order) and the viewer; Compose v2 and ``docker-compose`` 1.29 both merge an override's
``cap_add`` with the main file's (none has one now) and keep every other key. ``roco fault
net`` runs ``tc`` as root in the container (services/fault/compose.py), where the capability
counts. Used as a second ``-f``::

    docker compose -f deploy/compose.yaml -f deploy/compose.netfault.yaml -p roco up -d

``roco deploy compose`` writes it beside the main file and ``--check`` compares both.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

from services.deploy.compose import compose_generated
from services.spec.model import SystemSpec

IN_CHECKOUT = Path("deploy", "compose.netfault.yaml")
"""Where the override is in a checkout (beside deploy/compose.yaml)."""
NAME = IN_CHECKOUT.name

HEAD = """\
# The NET_ADMIN capability for `roco fault net SERVICE --delay/--loss` (tc netem in the service's
# container; docs/faults.md), added to deploy/compose.yaml by naming this file after it:
#
#   docker compose -f deploy/compose.yaml -f deploy/compose.netfault.yaml -p roco up -d
#                                                   (or docker-compose 1.29: same flags)
#
# Rendered by `roco deploy compose` beside compose.yaml from the specification (one service
# per agent) and services/deploy/netfault.py: change those, not this file.

services:
"""


def _key(name: str) -> str:
    """``name`` as a YAML key: plain when it is an identifier, else quoted (services/deploy/
    compose.py refuses a name that cannot be a service's)."""
    return name if re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", name) else json.dumps(name)


def services(spec: SystemSpec) -> list[str]:
    """The services a network fault reaches: the router, the recorder, ``spec``'s agents in
    its start order, the viewer (services/fault/compose.py ``COMPOSE_SERVICES``)."""
    return ["router", "recorder", *spec.launch_order, "viewer"]


def render(spec: SystemSpec) -> str:
    """The override ``spec`` gives: :data:`HEAD`, then ``cap_add: [NET_ADMIN]`` for each of
    :func:`services`."""
    body = "".join(f"  {_key(name)}:\n    cap_add: [NET_ADMIN]\n" for name in services(spec))
    return HEAD + body


def beside(compose_file: Path) -> Path:
    """The override's path beside ``compose_file``."""
    return compose_file.with_name(NAME)


def _named_difference(text: str, spec: SystemSpec) -> str | None:
    missing = [s for s in services(spec) if f"\n  {_key(s)}:\n" not in text]
    return f"no NET_ADMIN for {', '.join(missing)}" if missing else None


NETFAULT = compose_generated(
    "compose override",
    IN_CHECKOUT,
    render,
    _named_difference,
    lambda spec: f"NET_ADMIN for {', '.join(services(spec))}",
)
"""``deploy/compose.netfault.yaml`` (services/spec/generated.py)."""
check = NETFAULT.check
write = NETFAULT.write
bring_up_to_date = NETFAULT.bring_up_to_date
