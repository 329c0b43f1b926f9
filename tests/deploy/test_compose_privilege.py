"""Least privilege in deploy/compose.yaml: read as Docker would mount it over a real credentials
folder (``roco deploy certs`` plus a meshed router's identity), each service can read only its
own secrets — an agent or the recorder its own identity, the router its own key, the password
table and the ACL — and the CA's certificate; the CA's key only the one-shot ``certs`` service.
And what each service sees is enough: an agent's runtime and health check find their
identity, the router its configuration, in the folder as mounted."""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

import pytest

from services.deploy.compose import CERTS_HOST, CERTS_IN, COMPOSE_FILE, MESH_IDENTITY
from services.deploy.deploy import issue_router, prepare
from services.runtime.zenoh_config import client_config, router_config
from services.security import certs
from services.spec.model import default_spec

yaml = pytest.importorskip("yaml", reason="PyYAML reads the compose file: pip install -e '.[dev]'")

SPEC = default_spec()
MESHED = "router_hosta"
SECRET_NAMES = {certs.KEY, certs.PASSWORD, certs.CA_KEY, f"{certs.ROUTER}.key", certs.PASSWORDS}


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A deployment's credentials, as the ``certs`` service leaves them, and a meshed router's."""
    out = tmp_path_factory.mktemp("certs")
    prepare(out, SPEC, tls=True)
    issue_router(out, SPEC, MESHED, ["hosta"], [])
    return out


def expand(text: str, env: dict[str, str]) -> str:
    """``${VAR:-default}`` and ``${VAR-default}`` as compose interpolates them."""
    out = text
    while "${" in out:
        start = out.index("${")
        end = out.index("}", start)
        name, sep, default = out[start + 2 : end].partition(":-")
        if not sep:
            name, _, default = name.partition("-")
        out = out[:start] + (env.get(name) or default) + out[end + 1 :]
    return out


def credential_mounts(text: str, env: dict[str, str]) -> dict[str, list[tuple[str, str, bool]]]:
    """Per service: (entry in the credentials folder, path in the container, read-only) of each
    mount from ``ROCO_CERTS`` (``""``: the whole folder)."""
    services: dict[str, Any] = yaml.safe_load(text)["services"]
    found: dict[str, list[tuple[str, str, bool]]] = {}
    for name, service in services.items():
        found[name] = []
        for volume in service.get("volumes", []):
            assert isinstance(volume, str), (name, volume)
            if not volume.startswith(CERTS_HOST):
                continue
            source, target, *mode = expand(volume[len(CERTS_HOST) :], env).split(":")
            found[name].append((source.strip("/"), target, mode == ["ro"]))
    return found


def readable(folder: Path, entry: str) -> set[str]:
    """The files of ``folder`` a mount of ``entry`` exposes (relative paths)."""
    path = folder / entry
    if path.is_file():
        return {entry}
    return {str(p.relative_to(folder)) for p in path.rglob("*") if p.is_file()}


def owner(relative: str) -> str:
    """Whose secret a file of the folder is: an identity's folder is its own; the router's
    key, the password table (every identity's password) and the ACL are the router's; the CA's
    key, only the issuer's."""
    first = relative.split("/", 1)[0]
    if "/" in relative:
        return "router" if first.startswith(certs.ROUTER + "_") else first
    return {certs.CA_KEY: "certs", f"{certs.ROUTER}.key": "router", certs.PASSWORDS: "router"}.get(
        relative, ""
    )


def violations(text: str, folder: Path, env: dict[str, str]) -> list[str]:
    """Every secret a service other than its owner (or the one-shot ``certs``) could read, and
    every writable mount but the issuer's."""
    found = []
    for service, mounts in credential_mounts(text, env).items():
        for entry, target, read_only in mounts:
            if service == "certs":
                continue
            if not read_only:
                found.append(f"{service} may write {entry or 'the folder'} at {target}")
            for f in sorted(readable(folder, entry)):
                if Path(f).name in SECRET_NAMES and owner(f) != service:
                    found.append(f"{service} reads {f}, {owner(f) or 'nobody'}'s secret")
    return found


ENVS = [{}, {MESH_IDENTITY: MESHED}]


@pytest.mark.parametrize("env", ENVS, ids=["single router", "meshed router"])
def test_no_service_reads_another_ones_secret_or_the_ca_key(folder: Path, env: dict[str, str]) -> None:
    text = COMPOSE_FILE.read_text()
    assert violations(text, folder, env) == []
    mounts = credential_mounts(text, env)
    assert ("", CERTS_IN, False) in mounts["certs"]  # the issuer: the whole folder, writable
    assert mounts["world"] == mounts["viewer"] == []


def test_the_check_sees_the_whole_folder_mounted_in_an_agent(folder: Path) -> None:
    """The planted fault: the old file's mount of the whole folder into every service."""
    text = COMPOSE_FILE.read_text()
    planted = text.replace(
        f"      - {CERTS_HOST}/{certs.CA_CERT}:{CERTS_IN}/{certs.CA_CERT}:ro\n      - {CERTS_HOST}/a_pl:",
        f"      - {CERTS_HOST}:{CERTS_IN}:ro\n      - {CERTS_HOST}/a_pl:",
    )
    assert planted != text
    found = violations(planted, folder, {})
    assert "a_pl reads ca.key, certs's secret" in found
    assert (
        "a_pl reads a_km/key.pem, a_km's secret" in found
        and "a_pl reads passwords.txt, router's secret" in found
    )
    assert all(f.startswith("a_pl ") for f in found)


def view(folder: Path, mounts: list[tuple[str, str, bool]], into: Path) -> Path:
    """What a container sees at :data:`CERTS_IN`: the mounted entries copied to their targets."""
    for entry, target, _ in mounts:
        assert target.startswith(CERTS_IN + "/"), target
        dest = into / target[len(CERTS_IN) + 1 :]
        if (folder / entry).is_dir():
            shutil.copytree(folder / entry, dest)
        else:
            dest.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(folder / entry, dest)
    return into


@pytest.mark.parametrize("env", ENVS, ids=["single router", "meshed router"])
def test_each_service_finds_what_it_needs_in_its_mounts(
    folder: Path, tmp_path: Path, env: dict[str, str]
) -> None:
    mounts = credential_mounts(COMPOSE_FILE.read_text(), env)
    for name in [*SPEC.launch_order, "recorder"]:
        seen = view(folder, mounts[name], tmp_path / name)
        ident = certs.identity(seen, name)
        assert ident.cert.is_file() and ident.key.is_file() and ident.ca.is_file()
        client_config(["tls/router:7447"], identity=name, security=seen)  # as the agent's runtime
        with pytest.raises(certs.CredentialError):
            certs.identity(seen, "operator")  # a tool's identity is in no container
    seen = view(folder, mounts["router"], tmp_path / "router")
    router_config(["tls/0.0.0.0:7447"], security=seen, identity=env.get(MESH_IDENTITY))
