"""The sorting cell's content terms: L_ORD (a person's orders and their outcome, C1) and
L_BELT (moves of items on the belt, C2), both of the ontology O_Cell. The specification
(cell.toml, ``[languages.*]``) puts each term in its language; every process that loads the
specification decodes them."""

from __future__ import annotations

import msgspec


class Order(msgspec.Struct, frozen=True, tag="order", kw_only=True):
    """A person's order: sort ``count`` items of kind ``item`` (``bolt``, ``nut``…)."""

    item: str
    count: int


class Sorted(msgspec.Struct, frozen=True, tag="sorted", kw_only=True):
    """An order's outcome: ``count`` items of ``item`` are in bin ``bin``."""

    item: str
    count: int
    bin: int

    def told(self) -> str:
        """What the person reads."""
        return f"{self.count} {self.item}(s) sorted into bin {self.bin}"


class Refused(msgspec.Struct, frozen=True, tag="refused", kw_only=True):
    """Why an order is refused or failed, in words."""

    reason: str


class Move(msgspec.Struct, frozen=True, tag="move", kw_only=True):
    """Move ``count`` items on the belt to bin ``bin``."""

    count: int
    bin: int


class Moved(msgspec.Struct, frozen=True, tag="moved", kw_only=True):
    """The items moved: ``count`` are in bin ``bin``, which now holds ``total``."""

    count: int
    bin: int
    total: int


class Stuck(msgspec.Struct, frozen=True, tag="stuck", kw_only=True):
    """Why the belt did not move, in words."""

    reason: str


TERMS = (Order, Sorted, Refused, Move, Moved, Stuck)
