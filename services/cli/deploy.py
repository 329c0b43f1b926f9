"""``roco deploy``: credentials, access control and the compose file of a deployment
(docs/security.md, docs/deploy.md).

    roco deploy certs OUT [--tls/--no-tls] [--keep]     a private CA, the router's certificate,
                                                        one identity per agent + recorder +
                                                        operator, passwords, the router's ACL
    roco deploy issue OUT NAME                          (re-)issue one identity
    roco deploy revoke OUT NAME                         take one identity out (restart the router)
    roco deploy router OUT router_HOST [--ip A] [--dns N]  a meshed router's identity
    roco deploy acl [--tls/--no-tls]                    print the ACL the specification gives
    roco deploy table [--full]                          who may send what where (Markdown)
    roco deploy compose [--check] [--file F]            deploy/compose.yaml from the specification,
                                                        and compose.netfault.yaml beside it (another
                                                        system's: in its folder, services/deploy/
                                                        layout.py)

Bad input: one line starting with ``roco:``, exit 2. The work is services/deploy/'s.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from services.cli.common import MARKUP, CheckOnly, SpecFile, fail, shown
from services.spec.model import DEFAULT_SPEC, SpecError, SystemSpec, load

if TYPE_CHECKING:
    from services.deploy.layout import Layout
    from services.spec.generated import GeneratedFile

deploy_app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    rich_markup_mode=MARKUP,
    help="Credentials, access control and compose file of a deployment (docs/deploy.md).",
)


def _spec(path: Path | None) -> SystemSpec:
    try:
        return load(path or DEFAULT_SPEC)
    except SpecError as exc:
        raise fail(str(exc), code=2) from None


@deploy_app.command()
def certs(
    out: Annotated[Path, typer.Argument(help="the credentials folder to create (replaced)")],
    tls: Annotated[bool, typer.Option(help="match ACL subjects by certificate common name too")] = True,
    days: Annotated[int, typer.Option(min=1, help="validity of the certificates")] = 365,
    keep: Annotated[bool, typer.Option(help="leave a folder that already has an ACL as it is")] = False,
    spec: SpecFile = None,
) -> None:
    """Issue a deployment's credentials: CA, router certificate, identities, passwords, ACL.

    The identities are the specification's (--spec, ROCO_SPEC): one per agent, the recorder's
    and the operator's. With --keep and a folder that lacks some of them (revoked, or another
    system's), it says which and leaves the folder as it is. A folder it cannot write (e.g.
    the compose ``certs`` service's, not its user's): one ``roco:`` line, exit 1."""
    from services.deploy.deploy import kept_line, prepare
    from services.security.certs import ACL_FILE

    system = _spec(spec)
    if keep and (out / ACL_FILE).is_file():
        typer.echo(f"roco: {kept_line(out, system)}")
        return
    try:
        names = prepare(out, system, tls=tls, days=days)
    except OSError as exc:
        typer.echo(
            f"roco: cannot write the credentials in {out}: {exc.strerror or exc} (as uid {os.getuid()}; "
            f"in compose, ROCO_CERTS must be the services' user's: docs/deploy.md)",
            err=True,
        )
        raise typer.Exit(1) from None
    typer.echo(f"roco: credentials for {', '.join(names)} in {out} (keep {out / 'ca.key'} off the robot)")


@deploy_app.command()
def issue(
    out: Annotated[Path, typer.Argument(help="a credentials folder made by 'roco deploy certs'")],
    name: Annotated[str, typer.Argument(help="the identity: an agent, recorder or operator")],
    days: Annotated[int, typer.Option(min=1)] = 365,
    spec: SpecFile = None,
) -> None:
    """(Re-)issue one identity: new key, certificate and password; the ACL is rewritten."""
    from services.deploy.deploy import issue_identity
    from services.security.certs import CredentialError

    try:
        ident = issue_identity(out, _spec(spec), name, days)
    except CredentialError as exc:
        raise fail(str(exc), code=2) from None
    typer.echo(f"roco: issued {ident.name} ({ident.cert}); restart the router to accept the new password")


@deploy_app.command()
def revoke(
    out: Annotated[Path, typer.Argument(help="a credentials folder made by 'roco deploy certs'")],
    name: Annotated[str, typer.Argument(help="the identity to take out")],
    spec: SpecFile = None,
) -> None:
    """Take an identity out: its password, credentials and ACL subject (restart the router)."""
    from services.deploy.deploy import revoke_identity

    if not revoke_identity(out, _spec(spec), name):
        raise fail(f"no identity {name!r} in {out}", code=2)
    typer.echo(f"roco: revoked {name}; restart the router so that it reads {out}/acl.json and passwords.txt")


@deploy_app.command(short_help="(Re-)issue a meshed router's identity (mutual TLS between routers).")
def router(
    out: Annotated[Path, typer.Argument(help="a credentials folder made by 'roco deploy certs'")],
    name: Annotated[str, typer.Argument(help="the router's identity: router_<host>, e.g. router_robot")],
    ip: Annotated[list[str] | None, typer.Option(help="an address the other routers reach it at")] = None,
    dns: Annotated[list[str] | None, typer.Option(help="a host name the other routers reach it at")] = None,
    days: Annotated[int, typer.Option(min=1)] = 365,
    spec: SpecFile = None,
) -> None:
    """(Re-)issue a meshed router's identity (mutual TLS between routers) and let the routers
    trust one another in the ACL; start that router with ROCO_ROUTER_IDENTITY=NAME."""
    import ipaddress

    from services.deploy.deploy import issue_router
    from services.security.certs import CredentialError

    try:
        for a in ip or []:
            ipaddress.ip_address(a)
    except ValueError as exc:
        raise fail(str(exc), code=2) from None
    try:
        ident = issue_router(out, _spec(spec), name, dns or [], ip or [], days)
    except CredentialError as exc:
        raise fail(str(exc), code=2) from None
    typer.echo(
        f"roco: issued {ident.name} ({ident.cert}); restart the routers to read the new ACL and passwords"
    )


@deploy_app.command()
def acl(
    tls: Annotated[bool, typer.Option(help="subjects matched by certificate common name too")] = True,
    spec: SpecFile = None,
) -> None:
    """Print the router's access_control section the specification gives (JSON)."""
    from services.spec_check.acl import acl_config

    typer.echo(json.dumps(acl_config(_spec(spec), tls=tls), indent=1))


@deploy_app.command()
def table(
    full: Annotated[bool, typer.Option(help="every identity, flow and key expression")] = False,
    spec: SpecFile = None,
) -> None:
    """Print who may send what where (Markdown; docs/security.md)."""
    from services.spec_check.acl import channel_table, markdown_table

    typer.echo((markdown_table if full else channel_table)(_spec(spec)), nl=False)


ComposeFileOption = Annotated[
    Path | None,
    typer.Option(
        "--file",
        help="the compose file [default: deploy/compose.yaml of the system's folder: this checkout's for "
        "roco's kitchen]",
        show_default=False,
    ),
]


@deploy_app.command(short_help="Write deploy/compose.yaml from the specification, or check it.")
def compose(check: CheckOnly = False, file: ComposeFileOption = None, spec: SpecFile = None) -> None:
    """Write the compose file the specification gives: one service per agent (in its start
    order, the last one waiting for every other), beside the router, the recorder, the viewer
    and the one-shot certs service, which issues the specification's identities
    (services/deploy/compose.py); and beside it the override compose.netfault.yaml that grants
    NET_ADMIN for `roco fault net` (services/deploy/netfault.py). For a system that is not
    roco's kitchen, the file runs roco's images as they are, with the system's folder mounted
    read-only and ROCO_SPEC naming its specification (services/deploy/layout.py). With
    --check, write nothing: exit 0 when both files are what the specification gives (naming
    the identities), 1 (one line saying how the first that differs does) when not."""
    from services.deploy.compose import COMPOSE_FILE, ComposeError, compose_for
    from services.deploy.layout import LayoutError, default_file, layout_for

    spec_file = spec or DEFAULT_SPEC
    system = _spec(spec)
    path = file or default_file(spec_file, COMPOSE_FILE)
    try:
        layout = layout_for(spec_file, path)
        generated = compose_for(layout, f"roco deploy compose --spec {spec_file} --file {shown(path)}")
        if check:
            _check_compose(generated, path, system, layout)
        else:
            _write_compose(generated, path, system)
    except (ComposeError, LayoutError) as exc:
        raise fail(str(exc), code=2) from None


def _check_compose(generated: GeneratedFile, path: Path, system: SystemSpec, layout: Layout) -> None:
    """``roco deploy compose --check``: one line per file when both are what ``system`` gives in
    ``layout``; else raises :class:`typer.Exit` (1) after the line saying how the first
    differs. Raises ComposeError as ``GeneratedFile.check``."""
    from services.deploy import netfault
    from services.deploy.compose import described
    from services.deploy.compose_files import compose_problem

    problem = compose_problem(generated, path, system, shown)
    if problem is not None:
        raise fail(problem)
    typer.echo(f"roco: {shown(path)} is what the specification gives ({described(system, layout)})")
    typer.echo(f"roco: {shown(netfault.beside(path))} is what the specification gives")


def _write_compose(generated: GeneratedFile, path: Path, system: SystemSpec) -> None:
    """``roco deploy compose``: write both files (services/deploy/compose_files.py), saying what
    each holds. Raises ComposeError when a file cannot be written or ``system`` rendered."""
    from services.deploy import netfault
    from services.deploy.compose import hardware
    from services.deploy.compose_files import write_compose_files

    changed, override_changed = write_compose_files(generated, path, system)
    override = netfault.beside(path)
    agents = ", ".join(system.launch_order)
    if changed:
        others = ", ".join(["router", "recorder", "viewer", *hardware(system)])
        typer.echo(f"roco: wrote {shown(path)}: {others} and the agents {agents}")
    else:
        typer.echo(f"roco: {shown(path)} is up to date (the agents {agents})")
    if override_changed:
        typer.echo(f"roco: wrote {shown(override)}: NET_ADMIN for {', '.join(netfault.services(system))}")
    else:
        typer.echo(f"roco: {shown(override)} is up to date")
