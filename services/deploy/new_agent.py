"""A new agent added to a system (``roco spec new-agent``): its folder written from the
specification (services/spec_check/new_agent.py), then the system's names module and, where
they exist, its compose file and override brought up to date."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from services.spec_check.new_agent import Scaffold


def add_agent(path: Path, name: str, root: Path | None, say: Callable[[str], None]) -> Scaffold:
    """Write the folder of agent ``name`` of the specification ``path`` below ``root`` (None:
    the specification's folder), then bring the names module, deploy/compose.yaml and
    deploy/compose.netfault.yaml up to date, saying to ``say`` what each became. Nothing is
    written when a file cannot be rendered or the folder exists. Raises SpecError,
    FileExistsError, ComposeError or LayoutError."""
    from services.deploy import netfault
    from services.deploy.compose import COMPOSE, compose_for
    from services.deploy.layout import KITCHEN, layout_for
    from services.spec import render_names
    from services.spec.model import load, system_root
    from services.spec_check.new_agent import write_agent

    system = load(path)
    home = root or system_root(path)
    compose_at = home / COMPOSE.relative  # a checkout's (--root): the kitchen's layout, else the system's
    compose_file = compose_for(KITCHEN if root is not None else layout_for(path, compose_at))
    files = [(compose_file, compose_at), (netfault.NETFAULT, home / netfault.NETFAULT.relative)]
    for generated, at in files:  # what cannot be rendered is refused before anything is written
        if at.is_file():
            generated.render(system)
    scaffold = write_agent(system, name, home)
    say(f"wrote {scaffold.module}")
    names = render_names.names_file(path, system) if root is None else home / render_names.NAMES.relative
    say(render_names.NAMES.bring_up_to_date_at(names, system))
    for generated, at in files:
        say(generated.bring_up_to_date_at(at, system))
    return scaffold
