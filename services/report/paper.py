"""The paper's experiment figures (§5.7, Tables 7 and 8), reproduced for comparison.

All values are copied from ``paper.md`` §5.7; where the paper contradicts itself both
readings are kept (``MAX_SIZE_ALT_B``, ``TABLE8_TOTAL`` vs ``COMMUNICATES``). Sizes are in
bytes (the paper writes "b" and "kB" for the same unit), times in seconds from the start of
the paper's log, bandwidths in kbit/s.
"""

from __future__ import annotations

from typing import NamedTuple

SYSTEM = "RoCo"
"""The ``system`` of the paper's Robot Companion's specification: a run of it is compared with
these figures; a run of another system is not."""

AGENTS: tuple[str, ...] = ("a_co", "a_hi", "a_km", "a_pl", "a_ta", "ag_ex")
"""Agent order of Table 8 (columns, senders)."""

CHANNEL_ENDS: dict[str, tuple[str, str]] = {
    "C1": ("a_co", "a_ta"),
    "C2": ("a_co", "a_hi"),
    "C3": ("a_co", "a_pl"),
    "C4": ("a_pl", "a_km"),
    "C5": ("ag_ex", "a_ta"),
    "C6": ("a_ta", "a_km"),
}
"""The two agents each channel connects (paper §5.2)."""

TASK_END_S = 778.0
"""The task took 778 s, counted from the start of the log (Table 7: command at 83 s)."""
COMMAND_T_S = 83.0
"""Table 7: a_hi receives the command at 83 s."""
COMMUNICATES = 1856
"""§5.7 text: 1856 messages exchanged (Table 8's totals add up to 1865)."""
SHARE_UNDER_500 = 0.86
"""§5.7: 86 % of the messages are below 0.5 kB."""
MIN_SIZE_B = 231
MEAN_SIZE_B = 654
MAX_SIZE_B = 98_000
"""§5.7: "the maximum is equal to 98 kb"."""
MAX_SIZE_ALT_B = 852_000
"""§5.7, one paragraph earlier: "going up to 852 kB"."""
INITIAL_KNOWLEDGE = (0.0, 37.0)
"""Table 7: a_km receives the initial knowledge 0–37 s (C5, C6)."""


class PaperPlan(NamedTuple):
    """One planning process of §5.7: its number, request time, end of the C4 traffic, time the plan
    reached a_co (s), C4 communicates, mean and peak C4 bandwidth (kbit/s; None: not given)."""

    number: int
    requested: float
    generated_until: float
    received: float
    c4_communicates: int
    mean_kbps: float
    peak_kbps: float | None


PLANS: tuple[PaperPlan, ...] = (
    PaperPlan(1, 97.0, 152.0, 153.0, 1598, 32.0, 150.0),
    PaperPlan(2, 681.0, 682.0, 682.0, 57, 32.0, None),
)
"""Planning #1 and #2 (Table 7, §5.7 text, Figure 13)."""

TABLE7: tuple[tuple[str, str, str], ...] = (
    ("0–37", "a_km receives an initial knowledge about the environment", "C5, C6"),
    ("83", "a_hi receives a new command, and requests a_co to coordinate its execution", "C2"),
    ("97", "a_co requests a_pl for the plan #1", "C3"),
    ("97–152", "a_pl generates the plan #1, and queries a_km", "C4"),
    ("153", "a_co receives the generated plan #1 from a_pl", "C3"),
    ("153–681", "a_ta executes the plan, reports its state to a_co", "C1"),
    (
        "293–315, 674–680",
        "a_km receives information about the modified environment from a_ta",
        "C5, C6",
    ),
    ("300", "the jar is grasped with the left gripper", "—"),
    ("315", "the jar is pulled out of the cabinet", "—"),
    ("495", "the bowl is grasped with the right gripper", "—"),
    ("508", "the bowl is pulled out of the cabinet", "—"),
    ("620", "the bowl is put down on the table and released", "—"),
    ("680", "the bowl is localized", "—"),
    ("681", "a_co requests a_pl for the plan #2", "C3"),
    ("681–682", "a_pl generates the plan #2, and querries a_km", "C4"),
    ("682", "a_co receives the generated plan #2 from a_pl", "C3"),
    ("682–778", "a_ta executes the plan, reports its state to a_co", "C1"),
    ("674–682", "a_km receives information about the environment from a_ta", "C5, C6"),
    ("763", "the content of the jar is poured into the bowl", "—"),
    ("778", "the task is finished", "—"),
)
"""Table 7 verbatim: (time [s], event, channels used)."""

TABLE8: dict[str, dict[str, int]] = {
    "a_co": {"a_hi": 1, "a_pl": 2, "a_ta": 8},
    "a_km": {"a_pl": 925, "a_ta": 83, "ag_ex": 24},
    "a_pl": {"a_co": 2, "a_km": 730},
    "a_ta": {"a_co": 4, "a_km": 71},
    "ag_ex": {"a_km": 14, "a_ta": 1},
}
"""Table 8 verbatim: receiver → sender → number of messages. The paper has no a_hi row
(a_hi received nothing) and counts a_km ↔ ag_ex messages although no channel joins them."""

TABLE8_TOTAL = 1865
"""Table 8's grand total (the text says 1856)."""


def table8_received() -> dict[str, int]:
    """Table 8's "Received" column (row sums)."""
    return {r: sum(row.values()) for r, row in TABLE8.items()}


def table8_sent() -> dict[str, int]:
    """Table 8's "send" row (column sums)."""
    sent = dict.fromkeys(AGENTS, 0)
    for row in TABLE8.values():
        for s, n in row.items():
            sent[s] += n
    return sent


def channel_of(a: str, b: str) -> str | None:
    """The channel joining agents ``a`` and ``b`` (either order), or None."""
    for name, ends in CHANNEL_ENDS.items():
        if {a, b} == set(ends):
            return name
    return None


def table8_channel_counts() -> dict[str, int]:
    """Communicates per channel derived from Table 8 (key ``"none"``: pairs without a
    channel, i.e. a_km ↔ ag_ex). C4 gives 1655 = 1598 + 57, the text's two planning runs."""
    out: dict[str, int] = {}
    for receiver, row in TABLE8.items():
        for sender, n in row.items():
            key = channel_of(sender, receiver) or "none"
            out[key] = out.get(key, 0) + n
    return out
