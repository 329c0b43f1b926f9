"""Stand-ins for the Zenoh samples a session hands a callback or a query's reply carries: only
``payload.to_bytes()`` is read (services/runtime/counters.py, reports.py)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class Payload:
    """A sample's payload: ``data`` as ``to_bytes`` gives it."""

    data: bytes

    def to_bytes(self) -> bytes:
        return self.data


@dataclass
class Sample:
    """A sample carrying ``payload``."""

    payload: Payload


def sample(data: bytes) -> Sample:
    """A sample whose payload is ``data``."""
    return Sample(Payload(data))
