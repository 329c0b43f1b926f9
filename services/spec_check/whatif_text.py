"""``roco spec what-if RUN``'s text: :func:`render` writes a :class:`~services.spec_check.whatif.WhatIf`
for a person, :func:`what_if_report` is what the CLI prints (docs/spec.md has a worked example).

Means are over the whole seconds of the clock the record spans, peaks the busiest of those
seconds; kbit/s are 1000 bit/s; "on the wire" counts each put's payload plus
:data:`~services.spec_check.placement.PUT_OVERHEAD_B`.
"""

from __future__ import annotations

import statistics
from collections import Counter, defaultdict
from collections.abc import Sequence
from pathlib import Path

from services.report.load import load_run
from services.spec.model import DEFAULT_SPEC, load
from services.spec_check.critical_path import CriticalPaths, Wait
from services.spec_check.placement import (
    PUT_OVERHEAD_B,
    RECORDER_DEFAULT,
    Edge,
    Flow,
    kbps,
    parse_placement,
    parse_rtt,
    peak_kbps,
)
from services.spec_check.whatif import WhatIf, declared_reply_by, size_rows, unseen_peers, what_if

CRITICAL_PATHS = "Round trips that cross a link on each conversation's critical path"
MERGED_PATHS = "Hand-overs between merged agents on each conversation's critical path, now in process"


def _ms(seconds: float) -> str:
    return f"{seconds * 1e3:.0f} ms" if seconds < 1 else f"{seconds:.2f} s"


def _rel(predicted: float, measured: float) -> str:
    return f"{(predicted - measured) / measured * 100:+.1f} %" if measured else "nothing measured"


# ---- traffic ---------------------------------------------------------------------------------


def _flow_line(name: str, f: Flow, window_s: int) -> str:
    return (
        f"    {name:<6} {f.communicates:>5} {f.payload_b / 1e3:>8.1f} kB "
        f"{kbps(f.payload_b, window_s):>8.1f} {peak_kbps(f.payload_per_s):>8.1f}"
    )


def _edge_lines(w: WhatIf, edge: Edge) -> list[str]:
    """One direction of a link: per channel, then all of it, then on the wire."""
    p, window = w.placement, w.window_s
    total = w.traffic.totals.get(edge, Flow())
    return [
        f"  {p.label(edge[0])} → {p.label(edge[1])}:",
        "    channel communicates  bytes   mean kbps peak kbps",
        *(_flow_line(ch, f, window) for ch, f in sorted(w.traffic.links.get(edge, {}).items())),
        _flow_line("all", total, window),
        f"    on the wire ({total.puts} puts, payload + {PUT_OVERHEAD_B} B each): "
        f"{total.wire_b / 1e3:.1f} kB, mean {kbps(total.wire_b, window):.1f} kbps, "
        f"peak {peak_kbps(total.wire_per_s):.1f} kbps",
    ]


def _wire_per_s(flows: Sequence[Flow]) -> Counter[int]:
    per_s: Counter[int] = Counter()
    for f in flows:
        per_s.update(f.wire_per_s)
    return per_s


def _traffic_lines(w: WhatIf) -> list[str]:
    p = w.placement
    if not p.links:
        return ["Links: none (one host)"]
    lines = [
        f"Traffic per link and direction (means over the record's {w.window_s} s; peaks: busiest second):"
    ]
    for a, b in p.links:
        both = [w.traffic.totals.get(e, Flow()) for e in ((a, b), (b, a))]
        wire = sum(f.wire_b for f in both)
        lines += [
            *_edge_lines(w, (a, b)),
            *_edge_lines(w, (b, a)),
            f"  link {p.label(a)}–{p.label(b)}, both ways on the wire: {wire / 1e3:.1f} kB, "
            f"mean {kbps(wire, w.window_s):.1f} kbps, peak {peak_kbps(_wire_per_s(both)):.1f} kbps",
        ]
    return lines + _measured_lines(w)


def _measured_lines(w: WhatIf) -> list[str]:
    """The prediction beside the relay's count of a two-host run placed as asked."""
    m, p = w.measured, w.placement
    if m is None:
        return []
    predicted = [w.traffic.totals.get(e, Flow()) for e in m.by_edge]
    lines = ["  measured on this run's link (the relay's count, link_bytes.jsonl), the same seconds:"]
    for (e, measured_b), f in zip(m.by_edge.items(), predicted, strict=True):
        lines.append(
            f"    {p.label(e[0])} → {p.label(e[1])}: measured {measured_b / 1e3:.1f} kB "
            f"({kbps(measured_b, w.window_s):.1f} kbps), predicted {f.wire_b / 1e3:.1f} kB "
            f"({_rel(f.wire_b, measured_b)})"
        )
    total_m, total_p = sum(m.by_edge.values()), sum(f.wire_b for f in predicted)
    peak_p, peak_m = peak_kbps(_wire_per_s(predicted)), kbps(max(m.per_s.values(), default=0), 1.0)
    lines.append(
        f"    both ways: mean measured {kbps(total_m, w.window_s):.1f} kbps, predicted "
        f"{kbps(total_p, w.window_s):.1f} kbps ({_rel(total_p, total_m)}); peak measured "
        f"{peak_m:.1f} kbps, predicted {peak_p:.1f} kbps ({_rel(peak_p, peak_m)})"
    )
    return lines


def _size_lines(w: WhatIf) -> list[str]:
    rows = size_rows(w)
    if not rows:
        return []
    lines = ["Sizes of the communicates that cross, against the specification's estimates:"]
    for r in rows:
        est = f"estimate {r.estimate[0]}–{r.estimate[1]} B" if r.estimate else "no estimate"
        out = f", {r.outside} outside" if r.outside else ""
        lines.append(
            f"  {r.channel} {r.protocol} {r.performative}: {len(r.sizes)}, {r.sizes[0]}–{r.sizes[-1]} B, "
            f"median {statistics.median(r.sizes):.0f} B ({est}{out})"
        )
    upper = sum(r.estimate[1] * len(r.sizes) if r.estimate else sum(r.sizes) for r in rows)
    lines.append(
        f"  each at its estimate's upper bound: {upper / 1e3:.1f} kB, a mean of "
        f"{kbps(upper, w.window_s):.1f} kbps over the {w.window_s} s (all links together)"
    )
    return lines


def _merge_lines(w: WhatIf) -> list[str]:
    if not w.placement.merged or w.merged_paths is None:
        return []
    lines = ["In one process (merged): off Zenoh and the record:"]
    lines += [
        f"  {ch}: {f.communicates} communicates, {f.payload_b / 1e3:.1f} kB, mean "
        f"{kbps(f.payload_b, w.window_s):.1f} kbps, peak {peak_kbps(f.payload_per_s):.1f} kbps"
        for ch, f in sorted(w.traffic.gone.items())
    ]
    one_way = w.one_way_s
    if one_way is None:
        return lines + _path_lines(w, w.merged_paths, MERGED_PATHS, None)
    title = (
        f"{MERGED_PATHS} (each ≈ {_ms(one_way)} recorded: arrival at the recorder less the publisher's time)"
    )
    return lines + _path_lines(w, w.merged_paths, title, 2 * one_way, verb="saves")


# ---- latency and deadlines ---------------------------------------------------------------------


def _path_lines(
    w: WhatIf, paths: CriticalPaths, title: str, per_trip_s: float | None, verb: str = "adds"
) -> list[str]:
    """Per conversation kind whose critical path ``paths`` counts crossings on: how many, their
    most round trips, and what that ``verb`` at ``per_trip_s`` a round trip (None: not given)."""
    found: dict[tuple[str, str, str], list[int]] = defaultdict(list)
    for c in w.convs:
        half = paths.half_trips(c)
        if half:
            found[(c.kind, c.initiator, c.participant)].append(half)
    if not found:
        return [f"{title}: none"]
    lines = [f"{title}:"]
    for (kind, a, b), halves in sorted(found.items(), key=lambda kv: -max(kv[1])):
        top = max(halves)
        added = f", {verb} up to {_ms(top * per_trip_s / 2)}" if per_trip_s is not None else ""
        lines.append(
            f"  {kind} {a}→{b}: {len(halves)} conversation(s), up to {top / 2:g} round trip(s){added}"
        )
    return lines


def _wait_line(what: str, ws: Sequence[Wait], budget_s: float | None, rtt_s: float | None) -> str:
    """One line on answered waits ``ws`` against their own reply-by (``budget_s`` None) or
    ``budget_s``: the tightest in time, those late in the record already, whether ``rtt_s``
    breaks some, and the smallest RTT that does."""
    late = sum(1 for x in ws if x.late(budget_s))
    parts = [f"{what}: {len(ws)}", *_tightest(ws, budget_s)]
    if late:
        parts.append(f"{late} answered after the reply-by in the record already")
    return "; ".join(parts + _rtt_parts(ws, budget_s, rtt_s))


def _rtt_parts(ws: Sequence[Wait], budget_s: float | None, rtt_s: float | None) -> list[str]:
    """Whether ``rtt_s`` breaks waits of ``ws`` in time (nothing without an RTT), and the
    smallest RTT that breaks one."""
    parts = []
    if rtt_s is not None:
        broken = sum(1 for x in ws if x.breaks(rtt_s, budget_s))
        parts.append(f"at RTT {_ms(rtt_s)}: " + (f"BREAKS {broken}" if broken else "holds"))
    breaks = [b for b in (x.breaks_at_s(budget_s) for x in ws) if b is not None]
    parts.append(f"first breaks at RTT ≥ {_ms(min(breaks))}" if breaks else "no RTT breaks one in time")
    return parts


def _tightest(ws: Sequence[Wait], budget_s: float | None) -> list[str]:
    """The wait in time in the record with the least room before ``budget_s`` (its own
    reply-by when None), in words; none when every one is late."""
    in_time = [x for x in ws if not x.late(budget_s) and x.recorded_s is not None]
    if not in_time:
        return []
    tight = min(in_time, key=lambda x: (x.budget_s if budget_s is None else budget_s) - (x.recorded_s or 0.0))
    budget = tight.budget_s if budget_s is None else budget_s
    return [
        f"tightest: reply-by {_ms(budget)} after sending, answered in {_ms(tight.recorded_s or 0.0)}, "
        f"{tight.half_trips / 2:g} round trip(s) cross"
    ]


def _deadline_lines(w: WhatIf) -> list[str]:
    groups: dict[tuple[str, str, str], list[Wait]] = defaultdict(list)
    for x in w.waits:
        if x.recorded_s is not None and x.half_trips:
            groups[(x.conversation.kind, x.asked.performative, x.asked.sender)].append(x)
    title = "Reply-by deadlines the agents sent, in waits that cross a link"
    lines = [f"{title}:" if groups else f"{title}: none"]
    lines += [
        "  " + _wait_line(f"{k} {p} by {a}", ws, None, w.rtt_s) for (k, p, a), ws in sorted(groups.items())
    ]
    unanswered = sum(1 for x in w.waits if x.recorded_s is None)
    if unanswered:
        lines.append(
            f"  {unanswered} communicate(s) with a reply-by got no answer in the record: not weighed"
        )
    return lines


def _openings(w: WhatIf) -> dict[tuple[str, str, str], list[Wait]]:
    """The answered waits of conversations' openings, by (initiator, channel, protocol)."""
    out: dict[tuple[str, str, str], list[Wait]] = defaultdict(list)
    for x in w.waits:
        c = x.conversation
        if x.asked is c.legs[0] and x.recorded_s is not None:
            out[(c.initiator, c.channel, c.protocol)].append(x)
    return out


def _role_lines(w: WhatIf) -> list[str]:
    if not w.roles:
        return []
    openings = _openings(w)
    lines = ["Reply-by the roles declare (reply_by_s), against the conversations they opened:"]
    local: list[str] = []
    unused: list[str] = []
    for r in w.roles:
        ws = openings.get((r.agent, r.channel, r.protocol), [])
        what = f"{r.agent} {r.channel} {r.protocol} {r.reply_by_s:g} s"
        if any(x.half_trips for x in ws):
            lines.append("  " + _wait_line(what, ws, r.reply_by_s, w.rtt_s))
        else:
            (local if ws else unused).append(what)
    if local:
        lines.append(f"  their answers cross no link: {'; '.join(local)}")
    if unused:
        lines.append(f"  opened no conversation in this run: {'; '.join(unused)}")
    return lines


def render(w: WhatIf) -> str:
    """``w`` as text for a person (the module docstring says how the figures count)."""
    rtt = f"RTT {_ms(w.rtt_s)} per link" if w.rtt_s is not None else "no RTT given (--rtt)"
    crossing = len(w.traffic.crossing)
    lines = [
        f"What if {w.run_dir} ran as: {w.placement.describe()}; {rtt}",
        f"record: {w.communicates} communicates over {w.window_s} s; {crossing} of them cross a link",
        *_traffic_lines(w),
        *_size_lines(w),
        *_path_lines(w, w.paths, CRITICAL_PATHS, w.rtt_s),
        *_deadline_lines(w),
        *_role_lines(w),
        *_merge_lines(w),
        *(f"note: {n}" for n in w.notes),
    ]
    if w.rtt_s is None:
        lines.append("deadlines: give --rtt to weigh them")
    else:
        lines.append(f"deadlines broken at RTT {_ms(w.rtt_s)}: {len(w.broken())}")
    return "\n".join(lines)


def what_if_report(
    run_dir: Path,
    *,
    hosts: str | None = None,
    merges: Sequence[str] = (),
    rtt: str | None = None,
    recorder_with: str = RECORDER_DEFAULT,
    spec_path: Path | None = None,
) -> tuple[bool, str]:
    """``roco spec what-if``: (no deadline breaks, the text). Raises
    :class:`~services.spec_check.placement.PlacementError` for options that do not read or a
    record without communicates, SpecError for a specification that does not load,
    FileNotFoundError for a run folder that is not there."""
    spec = load(spec_path or DEFAULT_SPEC)
    data = load_run(run_dir)
    unseen = unseen_peers(spec, (m.rec for m in data.messages))
    placement = parse_placement(spec.agent_names, hosts, merges, recorder_with, unseen)
    rtt_s = parse_rtt(rtt) if rtt is not None else None
    roles, notes = declared_reply_by(spec)
    w = what_if(run_dir, spec, placement, rtt_s, roles, data)
    w.notes += notes
    return not w.broken(), render(w)
