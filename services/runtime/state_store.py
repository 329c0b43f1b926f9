"""Where an agent keeps what must survive its restart (no accepted command lost).

The folder is ``ROCO_STATE_DIR`` when set (compose mounts a volume there), else
``<ROCO_RUN_DIR>/state`` (a local fleet: a restart within the same run keeps it, a new run
starts empty), else none (nothing is kept: tests and one-off agents). Each agent writes one
file, ``<folder>/<agent>.json``, atomically (a temporary file renamed over the old one), and
only when its content changed.

What an agent keeps is the open conversations of its roles declared with ``keep``
(services/runtime/roles/) and its ``NOTE``, written and taken back by the runtime itself
(:class:`KeptConversations`, in a :class:`StateFile`; the agent gets each conversation back
through :meth:`~services.runtime.agent.Agent.on_restored`).
"""

from __future__ import annotations

import logging
import os
from pathlib import Path
from typing import Generic, TypeVar

import msgspec

from shared.settings import Settings

ENV_STATE_DIR = Settings.env_name("state_dir")
T = TypeVar("T")
log = logging.getLogger(__name__)


NO_DATA = msgspec.Raw(b"null")
"""The ``data`` of a kept conversation without any (JSON null)."""


class KeptConversation(msgspec.Struct, kw_only=True, frozen=True):
    """One open conversation of a role declared with ``keep``: its role (``channel``,
    ``protocol``), the protocol ``state`` it was in, ``opening``: the communicate that opened
    it (FIPA SC00061 msgpack, :meth:`~services.runtime.roles.Conversation.keep`), and
    ``data``: the agent's data of it as JSON (an instance of the msgspec Struct the role
    declares; :data:`NO_DATA`: none)."""

    channel: str
    protocol: str
    state: str
    opening: bytes
    data: msgspec.Raw = msgspec.field(default_factory=lambda: NO_DATA)


class KeptConversations(msgspec.Struct, kw_only=True):
    """The state file of an agent whose roles keep their conversations: them, oldest first,
    and the agent's ``note`` (JSON of its ``NOTE`` Struct: what it keeps besides them, e.g.
    a_co's progress made while no subscription was agreed; :data:`NO_DATA`: none)."""

    conversations: list[KeptConversation]
    note: msgspec.Raw = msgspec.field(default_factory=lambda: NO_DATA)


def state_dir() -> Path | None:
    """The folder for agents' kept state, or None when neither variable is set (the
    environment read now)."""
    read = Settings.from_env(only=("state_dir", "run_dir"))
    if read.state_dir is not None:
        return read.state_dir
    return read.run_dir / "state" if read.run_dir is not None else None


class StateFile(Generic[T]):
    """One agent's kept state: a msgspec-encodable value of type ``kind`` in JSON.

    ``path`` None makes every call a no-op (nothing is kept)."""

    def __init__(self, path: Path | None, kind: type[T]) -> None:
        self.path = path
        self.kind = kind
        self._last: bytes | None = None
        self._encoder = msgspec.json.Encoder()

    @classmethod
    def for_agent(cls, agent: str, kind: type[T]) -> StateFile[T]:
        """The state file of ``agent`` in :func:`state_dir` (no-op when there is none)."""
        folder = state_dir()
        return cls(folder / f"{agent}.json" if folder is not None else None, kind)

    def load(self) -> T | None:
        """The kept value, or None when there is none. A file that does not decode is moved
        aside to ``<name>.corrupt`` with a warning (a restart must not be stopped by it)."""
        if self.path is None or not self.path.exists():
            return None
        data = self.path.read_bytes()
        try:
            value = msgspec.json.decode(data, type=self.kind)
        except (msgspec.DecodeError, msgspec.ValidationError) as exc:
            aside = self.path.with_suffix(".corrupt")
            self.path.replace(aside)
            log.warning("kept state %s does not decode (%s); moved to %s", self.path, exc, aside)
            return None
        self._last = data
        return value

    def save(self, value: T) -> bool:
        """Write ``value`` if it differs from what was last written; returns True if written.
        Raises OSError when the folder cannot be written."""
        if self.path is None:
            return False
        data = self._encoder.encode(value)
        if data == self._last:
            return False
        self.path.parent.mkdir(parents=True, exist_ok=True)
        tmp = self.path.with_name(f".{self.path.name}.{os.getpid()}.tmp")
        tmp.write_bytes(data)
        os.replace(tmp, self.path)
        self._last = data
        return True

    def clear(self) -> None:
        """Remove the kept value (nothing to keep any more)."""
        if self.path is None or self._last == b"":
            return
        self.path.unlink(missing_ok=True)
        self._last = b""
