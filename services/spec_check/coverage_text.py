"""``roco spec coverage`` as text: the share exercised, then per channel's protocol and per
agent's FSM the items taken with their counts and the items never taken, each with why when
``unexercised.toml`` says (services/spec_check/coverage.py)."""

from __future__ import annotations

from services.spec_check.coverage import KINDS, Coverage, Item


def _pct(share: float) -> str:
    return f"{100 * share:.1f} %"


def headline(cov: Coverage) -> str:
    """``exercised: 172 of 210 items (81.9 %)``."""
    return f"exercised: {cov.exercised} of {len(cov.items)} items ({_pct(cov.share)})"


def transitions_lines(cov: Coverage) -> list[str]:
    """``transitions of the protocols (on any channel) and of the agents' FSMs: 97 of 100
    (97.0 %)``, then ``  fipa-request 20 of 20, …``."""
    per = cov.transitions()
    done, total = sum(d for d, _ in per.values()), sum(n for _, n in per.values())
    share = _pct(done / total) if total else "—"
    head = (
        f"transitions of the protocols (on any channel) and of the agents' FSMs: {done} of {total} ({share})"
    )
    return [head, "  " + ", ".join(f"{owner} {d} of {n}" for owner, (d, n) in per.items())]


def _taken(cov: Coverage, item: Item) -> str:
    text = f"    {item.name} ×{cov.counts[item]}"
    where = cov.where.get(item)
    if where:
        text += " (in " + ", ".join(f"{state} ×{n}" for state, n in sorted(where.items())) + ")"
    return text


def _never(cov: Coverage, item: Item) -> str:
    why = cov.why_not(item)
    return f"    {item.name}" + (f" — {why}" if why else "")


def _group(cov: Coverage, group: str, items: list[Item], detail: bool) -> list[str]:
    taken = [_taken(cov, i) for i in items if cov.counts[i]]
    never = [_never(cov, i) for i in items if not cov.counts[i]]
    declared = cov.fsm_of.get(group)
    title = f"{group} FSM ({declared.implementation})" if declared is not None else group
    shown = (["  taken:", *taken] if detail and taken else []) + (["  never taken:", *never] if never else [])
    return [f"{title}: {len(taken)} of {len(items)}", *shown]


def _notes(cov: Coverage) -> list[str]:
    notes = []
    if cov.crossings:
        notes.append(
            f"{cov.crossings} communicate(s) taken only as crossing another on the wire: on no transition"
        )
    if cov.rejected:
        notes.append(
            f"{cov.rejected} communicate(s) their protocol's state machine did not allow "
            "(in runs: roco spec verify RUN names them; in tests: planted on purpose)"
        )
    if cov.outside:
        notes.append(
            f"{cov.outside} communicate(s) of no channel's protocol of the specification "
            "(tests of other specifications, malformed payloads): not counted"
        )
    for agent, n in sorted(cov.errors.items()):
        notes.append(f"{agent}: {n} return(s) to the initial state after a transition function raised")
    for agent, n in sorted(cov.stray.items()):
        notes.append(f"{agent}: {n} FSM entr(ies) on no arc of its declared FSM (a test's own FSM)")
    for agent in cov.unknown_fsms:
        notes.append(
            f"{agent}: no FSM record declares its FSM (it never started in this evidence): not counted"
        )
    return notes + list(cov.evidence.notes)


def render(cov: Coverage, *, detail: bool = True) -> str:
    """The whole report; ``detail`` False leaves out the items taken (only never taken)."""
    lines = [f"Coverage of the {cov.spec} specification by"]
    lines += [f"  {s}" for s in cov.evidence.sources]
    lines.append(headline(cov))
    lines += [f"  {KINDS[k]}: {done} of {n}" for k, (done, n) in cov.by_kind().items() if n]
    lines += transitions_lines(cov)
    for group, items in cov.groups().items():
        lines += ["", *_group(cov, group, items, detail)]
    notes = _notes(cov)
    if notes:
        lines += ["", *(f"note: {n}" for n in notes)]
    return "\n".join(lines)
