"""Foreign names and the peers that use them: a name cannot be taken over by another peer.

The HTTP transport carries no proof of who sent a message (FIPA SC00084 has none), so the
gateway binds each foreign agent name (``local@platform``) to the peer that first used it:
the IP address the message came from and the answer addresses it gave (its ``:reply-to``'s,
else its ``:sender``'s, else the envelope's ``from``'s). While the name is bound, a message
under it from another IP address, or giving other answer addresses, is refused (HTTP 403,
counted ``refused.identity``): nobody can redirect the answers meant for the first peer, nor
speak in its conversations. The binding lasts as long as the name has conversations open
(a message opens its conversation; it ends when its protocol's state machine says so,
services/gateway/conversations.py: after ``agree`` and ``inform``, after ``refuse``, not after
``agree`` alone; one unanswered for ``conversation_s``, or the oldest beyond
``max_conversations``, is taken as ended) and ``linger_s`` after the last one ended; then the
name is free again. Instead, the operator may bind every name of a platform to a fixed list of
addresses (``roco gateway --platform``): answers to its agents go there only, whoever sent the
message, and a message giving other addresses is refused.

At most ``max_names`` names are bound at once; a new name beyond them is refused (HTTP 503,
counted ``refused.busy``) until one is free.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

from services.gateway.bounds import DEFAULT_LIMITS, Limits

__all__ = ["Identities", "IdentityError"]


class IdentityError(Exception):
    """A claim refused: ``reason`` (``identity``: the name is another peer's; ``busy``: no
    room for another name) and ``text``, one line."""

    def __init__(self, reason: str, text: str) -> None:
        super().__init__(text)
        self.reason = reason
        self.text = text


@dataclass
class _Binding:
    peer: str
    addresses: tuple[str, ...]
    last: float
    open: dict[str, float] = field(default_factory=dict)  # conversation → when it was opened


def _key(conversation: str | None) -> str:
    return conversation if conversation is not None else ""


class Identities:
    """The bindings of foreign names (module docstring); thread-safe. ``platforms`` maps a
    platform (the part of a name after ``@``) to the addresses all its agents are answered at;
    ``clock`` gives seconds (monotonic)."""

    def __init__(
        self,
        limits: Limits = DEFAULT_LIMITS,
        platforms: Mapping[str, tuple[str, ...]] | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.limits = limits
        self.platforms = dict(platforms or {})
        self.clock = clock
        self._bound: dict[str, _Binding] = {}
        self._lock = threading.Lock()

    def _platform(self, name: str) -> tuple[str, ...] | None:
        return self.platforms.get(name.partition("@")[2])

    def claim(self, name: str, peer: str, addresses: tuple[str, ...], conversation: str | None) -> None:
        """``peer`` (an IP address) sends a message as ``name`` in ``conversation``, giving
        ``addresses`` for answers (possibly none). Binds the name when it is free; raises
        IdentityError when it is bound to another peer or other addresses, or no name can be
        bound."""
        fixed = self._platform(name)
        if fixed is not None:
            if not set(addresses) <= set(fixed):
                raise IdentityError(
                    "identity", f"{name}: its platform is answered only at the addresses configured for it"
                )
            return
        now = self.clock()
        with self._lock:
            binding = self._binding(name, peer, addresses, now)
            binding.last = now
            key = _key(conversation)
            binding.open.pop(key, None)
            binding.open[key] = now
            while len(binding.open) > self.limits.max_conversations:
                del binding.open[next(iter(binding.open))]  # the oldest

    def addresses(self, name: str) -> tuple[str, ...]:
        """Where answers to ``name`` go: its platform's configured addresses, else those its
        peer gave; () when the name is not bound."""
        fixed = self._platform(name)
        if fixed is not None:
            return fixed
        with self._lock:
            binding = self._bound.get(name)
            return binding.addresses if binding is not None else ()

    def answered(self, name: str, conversation: str | None, final: bool) -> None:
        """An answer to ``name`` in ``conversation`` went out; ``final``: the conversation is
        over (its tracker finished, services/gateway/conversations.py), so it ends here too."""
        with self._lock:
            binding = self._bound.get(name)
            if binding is None:
                return
            binding.last = self.clock()
            if final:
                binding.open.pop(_key(conversation), None)

    def ended(self, name: str, conversation: str | None) -> None:
        """``name``'s ``conversation`` is over without an answer going out (its own message
        ended it, or was refused and not answered)."""
        self.answered(name, conversation, final=True)

    def bound(self) -> int:
        """How many names are bound now."""
        with self._lock:
            return len(self._bound)

    def _binding(self, name: str, peer: str, addresses: tuple[str, ...], now: float) -> _Binding:
        """``name``'s binding to ``peer`` and ``addresses``: the live one, or a new one when
        the name is free (under the lock). Raises IdentityError as :meth:`claim` does."""
        binding = self._bound.get(name)
        if binding is not None and self._ended(binding, now):
            del self._bound[name]
            binding = None
        if binding is None:
            return self._bind(name, peer, addresses, now)
        if binding.peer != peer or (addresses and set(addresses) != set(binding.addresses)):
            raise IdentityError("identity", f"{name} is in use by another peer until its conversations end")
        return binding

    def _bind(self, name: str, peer: str, addresses: tuple[str, ...], now: float) -> _Binding:
        """Bind the free ``name``, sweeping ended bindings when the names are all in use."""
        if len(self._bound) >= self.limits.max_names:
            self._sweep(now)
        if len(self._bound) >= self.limits.max_names:
            raise IdentityError("busy", f"{self.limits.max_names} foreign names in use: try later")
        binding = self._bound[name] = _Binding(peer, addresses, now)
        return binding

    def _ended(self, binding: _Binding, now: float) -> bool:
        """Drop ``binding``'s conversations open too long; whether the binding has ended."""
        stale = [k for k, t in binding.open.items() if now - t > self.limits.conversation_s]
        for k in stale:
            del binding.open[k]
        return not binding.open and now - binding.last > self.limits.linger_s

    def _sweep(self, now: float) -> None:
        for name in [n for n, b in self._bound.items() if self._ended(b, now)]:
            del self._bound[name]
