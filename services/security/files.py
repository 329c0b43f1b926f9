"""Writing a credentials folder's files: each one whole or not at all, and on disk before it
counts as written.

:func:`write_file` creates a fresh temporary file beside the target exclusively (``O_CREAT |
O_EXCL``, never through a file or link already there; a secret with mode 0600 from its
creation), writes and fsyncs it, renames it over the target and fsyncs the folder, so that a
crash leaves the old file or the new one (POSIX ``rename(2)``; ``fsync(2)`` on a directory makes
the rename durable on Linux file systems). A ``.tmp`` left by an interrupted write is removed
first. Kept apart from issuing (services/security/certs.py) so that tools that write a folder's
plain files (services/deploy/deploy.py: ``acl.json``) need not load ``cryptography``.
"""

from __future__ import annotations

import os
from pathlib import Path

SECRET_MODE = 0o600
"""Mode of a key or password file (owner read/write only)."""
PUBLIC_MODE = 0o644
"""Mode of a certificate, the ACL and other files anyone may read."""
TMP_SUFFIX = ".tmp"
"""The temporary file of ``NAME`` is ``NAME.tmp`` in the same folder."""


def _fsync_folder(folder: Path) -> None:
    fd = os.open(folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def write_file(path: Path, data: bytes, *, secret: bool = False) -> None:
    """Replace ``path`` by a file holding ``data``, mode :data:`SECRET_MODE` when ``secret``
    else :data:`PUBLIC_MODE` (whatever the mode of a file that was there, and whatever the
    umask), creating its folder if needed (see the module docstring). Raises OSError (e.g.
    FileExistsError when another writer created ``NAME.tmp`` between this one's removing a stale
    one and creating its own: two writers of one folder at once)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + TMP_SUFFIX)
    tmp.unlink(missing_ok=True)  # an interrupted write's, or a planted file or link
    mode = SECRET_MODE if secret else PUBLIC_MODE
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0)
    fd = os.open(tmp, flags, mode)
    try:
        os.fchmod(fd, mode)  # the umask may have taken bits of a public file's mode
        with os.fdopen(fd, "wb", closefd=False) as f:
            f.write(data)
            f.flush()
        os.fsync(fd)
    except BaseException:
        os.close(fd)
        tmp.unlink(missing_ok=True)
        raise
    os.close(fd)
    try:
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    _fsync_folder(path.parent)
