"""A scenario as data (TOML): what the person says, to what the world is subjected, when,
and what each command is expected to end in.

    name = "urgent command mid-pour"
    [[steps]]
    say = "pour the jar into the bowl"
    expect = "succeeded"
    [[steps]]
    say = "urgently bring the cup to the table"
    after = { step = "tilt_pour" }     # when a_ta reports a plan step containing this
    expect = "succeeded"

A step does exactly one of: ``say`` (a sentence to a_hi, with an optional ``priority``),
``disturb`` (move an object in the simulated world by ``dx, dy, dz`` metres and tip it by
``tilt`` radians about the world's x axis: a person moving or knocking it), ``restart``
(stop an agent's process and start it again), ``fault`` (a process fault of one service:
``kill`` — SIGKILL, started again ``down_s`` later; ``pause`` — SIGSTOP, SIGCONT ``down_s``
later; ``restart`` — SIGTERM, then started again at once). It runs when its ``after``
trigger holds: ``step`` (a_ta reported a plan step whose path contains the text), ``ended``
(the n-th ``say`` command, counted from 1, has ended), ``knowledge`` (a_km has the initial
observation: the default of the first step), ``renewed`` (a_ta has renewed a_km's picture of a
power-cycled robot's kitchen: a C6 ``WorldUpdate`` that ``renews``), ``seconds`` (wall
seconds after the step before ran); with no trigger a step runs right after the one before. A
trigger may add ``delay_s`` (wall seconds to wait once it holds, e.g. ``after = { step =
"tilt_pour/tilt", delay_s = 0.3 }`` to act half-way through the tilt).
A ``say`` step's ``from`` says who says it: ``"person"`` (the default: the line a person types,
on a_hi's human input) or ``"gateway"`` (an agent of another FIPA platform: a fipa-request of a
``Sentence`` posted to a_hi through the fleet's ACL gateway, C8, which the run then starts:
docs/gateway.md; its final answer, ``inform`` or ``failure`` of a ``SentenceReport``, is the
command's outcome).
``expect`` is the final report kind of a ``say`` command (``succeeded``,
``failed``, ``stopped``, ``not-understood``, or ``answer`` for a question such as "what is in the
bowl?"); ``expect_text`` a text its final report must contain.
"""

from __future__ import annotations

import tomllib
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import msgspec

from services.spec.model import default_spec
from velma.world.mode import WORLD_SERVICE

if TYPE_CHECKING:
    from services.spec.model import SystemSpec

LIBRARY = Path(__file__).parent / "library"
"""The scenarios shipped with roco (``roco scenario --list``)."""
FINAL_KINDS = frozenset({"succeeded", "failed", "stopped", "not-understood", "answer"})
AGENTS = frozenset(default_spec().agent_names)
SERVICES = AGENTS | {"recorder", "router", WORLD_SERVICE}
"""What a ``fault`` step can hit: the agents, the traffic recorder, the Zenoh router and the
world process (the robot's power: restarted, its kitchen starts anew)."""
FAULT_KINDS = frozenset({"kill", "pause", "restart"})
SPEAKERS = ("person", "gateway")
"""Who a ``say`` step's sentence comes from (``from``): a person, or an agent of another FIPA
platform through the ACL gateway."""
MOVABLE = ("jar", "bowl", "cup")
DEFAULT_COMMAND = "pour the jar into the bowl"
"""The command roco's examples, ``roco chaos`` and the benchmarks give (the task the robot was built for)."""
"""The free bodies of the kitchen a ``disturb`` step can move (velma/executor/ground_truth.py
CONTAINERS; repeated here so that reading a scenario needs no physics engine)."""


class ScenarioError(ValueError):
    """A scenario file that cannot be read or does not make sense; the message says where."""


class Trigger(msgspec.Struct, frozen=True, forbid_unknown_fields=True, kw_only=True):
    """When a step runs (see module docstring); at most one field set."""

    step: str | None = None
    ended: int | None = None
    knowledge: bool = False
    renewed: bool = False
    seconds: float | None = None
    delay_s: float = 0.0
    """Wall seconds to wait once the trigger holds (0..60), e.g. to fault a step half-way."""


class Disturb(msgspec.Struct, frozen=True, forbid_unknown_fields=True, kw_only=True):
    """Move ``object`` (a free body of the kitchen) by (dx, dy, dz) metres, world frame, and
    turn it by ``tilt`` radians about the world's x axis through its origin (a knock)."""

    object: str
    dx: float = 0.0
    dy: float = 0.0
    dz: float = 0.0
    tilt: float = 0.0


class Fault(msgspec.Struct, frozen=True, forbid_unknown_fields=True, kw_only=True):
    """A process fault of ``service``: ``kind`` kill, pause or restart; ``down_s`` how long
    it stays killed or paused (s)."""

    service: str
    kind: str
    down_s: float = 2.0


class Step(msgspec.Struct, frozen=True, forbid_unknown_fields=True, kw_only=True):
    """One thing that happens in a scenario (see module docstring)."""

    say: str | None = None
    priority: int = 0
    from_: str = msgspec.field(default="person", name="from")
    """Who says ``say``: one of :data:`SPEAKERS`."""
    disturb: Disturb | None = None
    restart: str | None = None
    fault: Fault | None = None
    after: Trigger | None = None
    expect: str | None = None
    expect_text: str | None = None

    @property
    def action(self) -> str:
        if self.say is not None:
            return "say"
        if self.disturb is not None:
            return "disturb"
        return "fault" if self.fault is not None else "restart"


class Scenario(msgspec.Struct, frozen=True, forbid_unknown_fields=True, kw_only=True):
    """A whole scenario: its steps in order, the scene's seeds, and how long it may take (wall
    seconds)."""

    name: str
    description: str = ""
    steps: tuple[Step, ...]
    seed: int = 0
    pose_seed: int | None = None
    timeout_s: float = 1200.0

    @property
    def commands(self) -> list[Step]:
        """The ``say`` steps, in order (command n is ``commands[n - 1]``)."""
        return [s for s in self.steps if s.say is not None]


def _check(scenario: Scenario, where: str) -> Scenario:
    if not scenario.steps:
        raise ScenarioError(f"{where}: no steps")
    said = 0
    for i, step in enumerate(scenario.steps, 1):
        for rule in _STEP_RULES:
            problem = rule(step, i, said)
            if problem is not None:
                raise ScenarioError(f"{where}: {problem}")
        said += step.say is not None
    return scenario


def _one_action(step: Step, i: int, said: int) -> str | None:
    actions = [
        step.say is not None,
        step.disturb is not None,
        step.restart is not None,
        step.fault is not None,
    ]
    if sum(actions) != 1:
        return f"step {i} must do exactly one of say, disturb, restart, fault"
    return None


def _fault_rule(step: Step, i: int, said: int) -> str | None:
    f = step.fault
    if f is None:
        return None
    if f.service not in SERVICES:
        return f"step {i}: no service {f.service!r} (services: {', '.join(sorted(SERVICES))})"
    if f.kind not in FAULT_KINDS:
        return f"step {i}: fault kind must be one of {', '.join(sorted(FAULT_KINDS))}, not {f.kind!r}"
    if not 0 <= f.down_s <= 600:
        return f"step {i}: down_s must be within 0..600 s, not {f.down_s}"
    return None


def _disturb_rule(step: Step, i: int, said: int) -> str | None:
    if step.disturb is not None and step.disturb.object not in MOVABLE:
        return f"step {i}: cannot move {step.disturb.object!r} (movable: {', '.join(MOVABLE)})"
    return None


def _from_rule(step: Step, i: int, said: int) -> str | None:
    if step.from_ not in SPEAKERS:
        return f"step {i}: from must be one of {', '.join(SPEAKERS)}, not {step.from_!r}"
    if step.from_ != "person" and step.say is None:
        return f"step {i}: only a say step comes from someone"
    if step.from_ != "person" and step.priority:
        return f"step {i}: a sentence from the gateway has no priority (a person's line has)"
    return None


def _restart_rule(step: Step, i: int, said: int) -> str | None:
    if step.restart is not None and step.restart not in AGENTS:
        return f"step {i}: no agent {step.restart!r} to restart"
    return None


def _expect_rule(step: Step, i: int, said: int) -> str | None:
    if step.expect is not None and step.expect not in FINAL_KINDS:
        return f"step {i}: expect must be one of {', '.join(sorted(FINAL_KINDS))}, not {step.expect!r}"
    if (step.expect is not None or step.expect_text is not None) and step.say is None:
        return f"step {i}: only a say step can expect an outcome"
    return None


def _after_rule(step: Step, i: int, said: int) -> str | None:
    t = step.after
    if t is None:
        return None
    if sum([t.step is not None, t.ended is not None, t.knowledge, t.renewed, t.seconds is not None]) != 1:
        return f"step {i}: after needs exactly one of step, ended, knowledge, renewed, seconds"
    if not 0 <= t.delay_s <= 60:
        return f"step {i}: after.delay_s must be within 0..60, not {t.delay_s}"
    if t.seconds is not None and not 0 <= t.seconds <= 3600:
        return f"step {i}: after.seconds must be within 0..3600, not {t.seconds}"
    if t.ended is not None and not 1 <= t.ended <= said:
        return f"step {i}: after.ended = {t.ended}, but only {said} command(s) before it"
    return None


_STEP_RULES: tuple[Callable[[Step, int, int], str | None], ...] = (
    _one_action,
    _fault_rule,
    _disturb_rule,
    _from_rule,
    _restart_rule,
    _expect_rule,
    _after_rule,
)
"""The rules a step of a scenario follows, in the order they are checked: each takes the step,
its number (from 1) and how many commands were said before it, and gives what is wrong (after
the file's name) or None."""


def parse_scenario(text: str, where: str = "<scenario>") -> Scenario:
    """A scenario from TOML text. Raises ScenarioError naming the problem."""
    from services.spec.model import one_line

    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{where}: not TOML: {one_line(exc)}") from None
    try:
        scenario = msgspec.convert(data, Scenario)
    except msgspec.ValidationError as exc:
        raise ScenarioError(f"{where}: {one_line(exc)}") from None
    return _check(scenario, where)


def load_scenario(name_or_path: str | Path) -> Scenario:
    """A scenario from a file, or by name from the library (``LIBRARY/<name>.toml``).
    Raises ScenarioError when there is none or it is malformed."""
    path = Path(name_or_path)
    if not path.exists():
        path = LIBRARY / f"{name_or_path}.toml"
    if not path.exists():
        known = ", ".join(sorted(p.stem for p in LIBRARY.glob("*.toml")))
        raise ScenarioError(
            f"no scenario file {name_or_path!r} and none of that name in the library ({known})"
        )
    from services.spec.model import read_text

    return parse_scenario(read_text(path, "scenario file", ScenarioError), str(path))


def library() -> dict[str, Scenario]:
    """Every scenario in the library, by file stem."""
    return {p.stem: load_scenario(p) for p in sorted(LIBRARY.glob("*.toml"))}


def missing_kitchen_agents(system: SystemSpec) -> tuple[str, ...]:
    """The Robot Companion's agents ``system`` lacks, whose names the scenarios' steps use:
    none for the kitchen, also grown by agents of its own (docs/spec.md's walk-through)."""
    return tuple(a for a in default_spec().launch_order if a not in system.agent_names)
