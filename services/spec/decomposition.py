"""The requirement tree and the binary decomposition of a specification (paper §4 steps 1–2,
§5.1–5.2, Figure 5, Tables 1–2), as data, replayed and checked.

Schema (TOML, beside the channels in the same file; every field below is validated):

    [[requirements]]              the requirement tree (Figure 5)
    id = "R1"                     unique
    parent = "R"                  absent for the root; must name another requirement
    text = "..."
    evidence = [{ channel = "C2", protocol = "fipa-request", performative = "request",
                  content = "HumanCommand", at_least = 1 }, ...]
                                  the communicates that exercise the requirement in a run, all
                                  of them (``roco spec trace``, services/spec/requirements.py);
                                  absent: one communicate on every channel serving it
    properties = [{ text = "...", exercised = 2, steps = [{ name = "cmd", channel = "C2", ... },
                  { channel = "C2", performative = "agree", answers = "cmd" }] }, ...]
                                  what must have happened for the requirement to be met, all of
                                  them in one run (services/spec/properties.py); when given,
                                  ``evidence`` is not used
    task = true                   a failed command of a run violates it (default false)

    [[steps]]                     the decomposition, in order (Tables 1–2)
    number = 1                    1, 2, 3, ...
    requirements = ["R"]          the requirements this step addresses
    split = "RoCo"                the group of the current fringe that is split (absent: a step
    into = ["ac", "ec"]           that only supplements channels); the two new groups
    tasks = { ac = "...", ec = "..." }          what each new group does
    reallocated = [{ number = 1, from = "ac", to = "da" }]   channel k's end moves from the
                                  split group to one of the new groups (paper: C^k_{q,q'} ↦ C^k_{p,q'})
    new_channels = [{ number = 2, ends = ["da", "hi"], transmits = "..." }]
    supplemented = [{ number = 6, transmits = "..." }]       more content on an existing channel
    outside = { xp = "..." }      groups outside the system (their tasks) that this step's new
                                  channels may join: agents of other platforms (docs/gateway.md), which
                                  no agent of the system substitutes but an external role
                                  (``[[externals]]``) does; a channel joins at most one of them

The first step splits the system's own group (``system``). :func:`replay` computes the fringe
and the channels after every step; :mod:`services.spec.check` checks them against the rules
of §4 and against the agents and channels of the specification.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import msgspec

from services.spec.model import DEFAULT_SPEC, SpecError, one_line, read_text
from services.spec.properties import Property


class Evidence(msgspec.Struct, frozen=True, forbid_unknown_fields=True, kw_only=True):
    """Communicates that exercise a requirement: on ``channel``, in ``protocol`` (None: any of
    the channel's), with ``performative`` (None: any), carrying the content term ``content``
    (its type name in its language, as ``contents`` of ``[[channels]]`` names it; None: any
    content or none); at least ``at_least`` of them (copies not counted) in one run.
    Checked against the channels by services/spec/requirements.py ``evidence_problems``."""

    channel: str
    protocol: str | None = None
    performative: str | None = None
    content: str | None = None
    at_least: int = 1

    def describe(self) -> str:
        """``C2 fipa-request request HumanCommand`` (only the fields given; ``≥2`` when more
        than one is needed)."""
        parts = [self.channel, self.protocol, self.performative, self.content]
        words = " ".join(p for p in parts if p is not None)
        return f"{words} ≥{self.at_least}" if self.at_least > 1 else words


class Requirement(msgspec.Struct, frozen=True, forbid_unknown_fields=True, kw_only=True):
    """A node of the requirement tree (``parent`` None for the root); ``properties``: what must
    have happened in a run for it to be met (:class:`~services.spec.properties.Property`, all
    of them); without them, ``evidence``: the communicates that exercise it in a run
    (:class:`Evidence`, all of them; empty: one on each channel serving it); ``task``: a failed
    command of a run violates it."""

    id: str
    text: str
    parent: str | None = None
    properties: tuple[Property, ...] = ()
    evidence: tuple[Evidence, ...] = ()
    task: bool = False


class Reallocation(msgspec.Struct, frozen=True, forbid_unknown_fields=True, kw_only=True):
    """Channel ``number``'s end moves from group ``from_`` (the split group) to group ``to``."""

    number: int
    from_: str = msgspec.field(name="from")
    to: str


class NewChannel(msgspec.Struct, frozen=True, forbid_unknown_fields=True, kw_only=True):
    """Channel ``number`` created between groups ``ends``, transmitting ``transmits``."""

    number: int
    ends: tuple[str, str]
    transmits: str


class Supplement(msgspec.Struct, frozen=True, forbid_unknown_fields=True, kw_only=True):
    """Channel ``number`` also transmits ``transmits`` (paper §4 step 2d)."""

    number: int
    transmits: str


class Step(msgspec.Struct, frozen=True, forbid_unknown_fields=True, kw_only=True):
    """One decomposition step (see the module docstring)."""

    number: int
    requirements: tuple[str, ...]
    split: str | None = None
    into: tuple[str, str] | None = None
    tasks: dict[str, str] = {}
    reallocated: tuple[Reallocation, ...] = ()
    new_channels: tuple[NewChannel, ...] = ()
    supplemented: tuple[Supplement, ...] = ()
    outside: dict[str, str] = {}


class Decomposition(msgspec.Struct, frozen=True, kw_only=True):
    """The ``system`` group's requirement tree and decomposition steps."""

    system: str
    requirements: tuple[Requirement, ...] = ()
    steps: tuple[Step, ...] = ()


@dataclass
class ChannelState:
    """Channel ``number`` at some step: its current ``ends`` (groups) and everything it
    ``transmits`` (the creation text, then supplements)."""

    number: int
    ends: tuple[str, str]
    transmits: list[str] = field(default_factory=list)

    @property
    def name(self) -> str:
        return f"C{self.number}"


@dataclass
class StepState:
    """The result of a step: the fringe (groups that exist) and the channels."""

    step: Step
    fringe: list[str]
    channels: dict[int, ChannelState]


def load_decomposition(path: Path = DEFAULT_SPEC) -> Decomposition:
    """The requirement tree and steps of the specification file ``path``. Raises SpecError
    naming the file and the problem (not TOML, a field of the wrong type or unknown)."""
    try:
        data = tomllib.loads(read_text(path))
    except tomllib.TOMLDecodeError as exc:
        raise SpecError(f"{path}: not TOML: {one_line(exc)}") from None
    try:
        return msgspec.convert(
            {k: data[k] for k in ("system", "requirements", "steps") if k in data}, Decomposition
        )
    except msgspec.ValidationError as exc:
        raise SpecError(f"{path}: {one_line(exc)}") from None


def _split(fringe: list[str], step: Step) -> list[str]:
    """The fringe with the goal the step splits replaced by its two parts, in place."""
    if step.split is None or step.into is None or step.split not in fringe:
        return fringe
    i = fringe.index(step.split)
    return [*fringe[:i], *step.into, *fringe[i + 1 :]]


def _reallocate(channels: dict[int, ChannelState], step: Step) -> None:
    """Each reallocated channel's end moved from the split goal to the part that takes it."""
    for r in step.reallocated:
        ch = channels.get(r.number)
        if ch is not None and r.from_ in ch.ends:
            ch.ends = (r.to, ch.ends[1]) if ch.ends[0] == r.from_ else (ch.ends[0], r.to)


def _add(channels: dict[int, ChannelState], step: Step) -> None:
    """The step's new channels, each with its creation text."""
    for n in step.new_channels:
        channels[n.number] = ChannelState(n.number, n.ends, [n.transmits])


def _supplement(channels: dict[int, ChannelState], step: Step) -> None:
    """What the step adds to what existing channels transmit."""
    for sup in step.supplemented:
        if sup.number in channels:
            channels[sup.number].transmits.append(sup.transmits)


_CHANNEL_RULES = (_reallocate, _add, _supplement)
"""What a step does to the channels, in the order it is applied (after the split)."""


def replay(d: Decomposition) -> list[StepState]:
    """The fringe and channels after each step, in order. Applies the steps as written; what
    does not make sense (an unknown group, a channel that does not exist) is left for
    :func:`services.spec.check.check_decomposition` to report, not raised here."""
    fringe = [d.system]
    channels: dict[int, ChannelState] = {}
    out: list[StepState] = []
    for step in d.steps:
        fringe = _split(fringe, step)
        for rule in _CHANNEL_RULES:
            rule(channels, step)
        out.append(
            StepState(
                step,
                list(fringe),
                {k: ChannelState(c.number, c.ends, list(c.transmits)) for k, c in channels.items()},
            )
        )
    return out
