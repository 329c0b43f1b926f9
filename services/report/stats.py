"""Communication statistics from the traffic record alone (no payload needed).

Paper §5.7: counts and sizes of communicates; Table 8: who sent how many to whom.
"""

from __future__ import annotations

from collections.abc import Sequence

from services.report import paper
from services.report.load import Message
from services.report.model import AgentMatrix, ChannelStats, SizeStats

SMALL_BYTES = 500
"""The paper's "0.5 kB" threshold (§5.7: 86 % of communicates are below it)."""


def size_stats(messages: Sequence[Message]) -> SizeStats:
    """Count, total, min/mean/max size (bytes on the wire) and the share below 500 B."""
    sizes = [m.rec.size for m in messages]
    if not sizes:
        return SizeStats(
            count=0,
            total_bytes=0,
            min_bytes=None,
            mean_bytes=None,
            max_bytes=None,
            under_500=0,
            share_under_500=None,
        )
    under = sum(1 for s in sizes if s < SMALL_BYTES)
    total = sum(sizes)
    return SizeStats(
        count=len(sizes),
        total_bytes=total,
        min_bytes=min(sizes),
        mean_bytes=total / len(sizes),
        max_bytes=max(sizes),
        under_500=under,
        share_under_500=under / len(sizes),
    )


def channel_stats(
    messages: Sequence[Message], channels: Sequence[str] = tuple(paper.CHANNEL_ENDS)
) -> list[ChannelStats]:
    """Communicates and bytes per channel: ``channels`` always (zero when unused; default the
    paper's C1..C6), then any other channel name the record holds, sorted."""
    counts: dict[str, list[int]] = {c: [0, 0] for c in channels}
    for m in messages:
        acc = counts.setdefault(m.rec.channel or "?", [0, 0])
        acc[0] += 1
        acc[1] += m.rec.size
    known = list(channels)
    order = known + sorted(c for c in counts if c not in known)
    return [ChannelStats(channel=c, count=counts[c][0], bytes=counts[c][1]) for c in order]


def agent_matrix(messages: Sequence[Message], order: Sequence[str] = tuple(paper.AGENTS)) -> AgentMatrix:
    """Table 8 of this run: rows receivers, columns senders. Agents in ``order`` (default the
    paper's: a_co, a_hi, a_km, a_pl, a_ta, ag_ex), then any others sorted."""
    cells: dict[str, dict[str, int]] = {}
    seen: set[str] = set()
    for m in messages:
        seen.add(m.rec.sender)
        for r in m.rec.receivers:
            seen.add(r)
            row = cells.setdefault(r, {})
            row[m.rec.sender] = row.get(m.rec.sender, 0) + 1
    agents = list(order) + sorted(seen - set(order))
    for a in agents:
        cells.setdefault(a, {})
    received = {a: sum(cells[a].values()) for a in agents}
    sent = {a: sum(cells[r].get(a, 0) for r in agents) for a in agents}
    return AgentMatrix(agents=agents, cells=cells, received=received, sent=sent, total=sum(received.values()))
