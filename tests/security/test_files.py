"""A credentials folder's files are written exclusively, with their mode from creation, fsynced
and renamed over the target (services/security/files.py): a pre-existing target or ``.tmp`` of
mode 0644 gives way to a 0600 secret, a stale ``.tmp`` (or a link planted there) is never written
through, and the data and the folder are fsynced before the write counts."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest

from services.security import certs
from services.security.files import write_file


def mode(path: Path) -> int:
    return stat.S_IMODE(path.lstat().st_mode)


@pytest.fixture
def fsyncs(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """What each os.fsync call was given: ``file`` or ``dir``."""
    seen: list[str] = []
    real = os.fsync

    def fsync(fd: int) -> None:
        seen.append("dir" if stat.S_ISDIR(os.fstat(fd).st_mode) else "file")
        real(fd)

    monkeypatch.setattr(os, "fsync", fsync)
    return seen


def test_a_secret_replaces_a_readable_target_and_tmp_with_mode_0600(
    tmp_path: Path, fsyncs: list[str]
) -> None:
    target = tmp_path / "key.pem"
    target.write_bytes(b"old")
    os.chmod(target, 0o644)
    stale = tmp_path / "key.pem.tmp"
    stale.write_bytes(b"an interrupted write's, readable by all")
    os.chmod(stale, 0o644)
    write_file(target, b"secret", secret=True)
    assert target.read_bytes() == b"secret" and mode(target) == 0o600
    assert not stale.exists()
    assert fsyncs == ["file", "dir"]  # the data, then the rename in its folder


def test_a_link_planted_as_tmp_is_not_written_through(tmp_path: Path) -> None:
    elsewhere = tmp_path / "elsewhere"
    elsewhere.write_bytes(b"untouched")
    folder = tmp_path / "certs"
    folder.mkdir()
    (folder / "password.tmp").symlink_to(elsewhere)
    write_file(folder / "password", b"secret", secret=True)
    assert elsewhere.read_bytes() == b"untouched"
    assert (folder / "password").read_bytes() == b"secret" and mode(folder / "password") == 0o600
    assert not (folder / "password").is_symlink()


def test_a_public_file_has_mode_0644_whatever_the_umask(tmp_path: Path, fsyncs: list[str]) -> None:
    old = os.umask(0o077)
    try:
        write_file(tmp_path / "sub" / "cert.pem", b"cert")
    finally:
        os.umask(old)
    assert mode(tmp_path / "sub" / "cert.pem") == 0o644
    assert fsyncs == ["file", "dir"]


def test_a_failed_write_leaves_the_target_and_no_tmp(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    target = tmp_path / "passwords.txt"
    target.write_bytes(b"a:1\n")

    def broken(fd: int) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "fsync", broken)
    with pytest.raises(OSError, match="No space"):
        write_file(target, b"a:2\n", secret=True)
    assert target.read_bytes() == b"a:1\n"
    assert not (tmp_path / "passwords.txt.tmp").exists()


def test_issued_credentials_are_fsynced_and_their_secrets_0600(tmp_path: Path, fsyncs: list[str]) -> None:
    out = tmp_path / "certs"
    out.mkdir()
    (out / certs.CA_KEY).write_bytes(b"")
    os.chmod(out / certs.CA_KEY, 0o644)  # a CA key left readable by all
    certs.issue(out, ["a_pl"])
    secrets = [out / certs.CA_KEY, out / "router.key", out / certs.PASSWORDS, out / "a_pl" / certs.KEY]
    secrets.append(out / "a_pl" / certs.PASSWORD)
    assert {p.name: mode(p) for p in secrets} == {p.name: 0o600 for p in secrets}
    assert mode(out / certs.CA_CERT) == 0o644
    written = [p for p in out.rglob("*") if p.is_file()]
    assert not [p for p in written if p.name.endswith(".tmp")]
    assert fsyncs.count("file") >= len(written) and fsyncs.count("dir") == fsyncs.count("file")
