"""``roco spec show``: the decomposition as the paper presents it (one table per step, as
Tables 1–2: requirements, decomposition, tasks, reallocated and new channels, what each
channel transmits; the fringe after the step), the agents' interfaces (paper §4 step 4),
and the agent/channel graph (Figures 6 and 10) as SVG or Graphviz DOT.
"""

from __future__ import annotations

import math
from html import escape

from services.spec.decomposition import Decomposition, Step, StepState, replay
from services.spec.model import ChannelProtocol, SystemSpec, interface
from shared.fipa_codec.languages import LANGUAGES


def _row(cells: list[str]) -> str:
    return "| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |"


def _decomposition_rows(s: Step) -> list[list[str]]:
    """The split of the step's goal and its parts' tasks, and the goals left outside."""
    rows: list[list[str]] = []
    if s.split and s.into:
        rows.append(["Decomposition", f"g_{s.split} := ⟨g_{s.into[0]}, g_{s.into[1]}⟩"])
        rows += [[f"g_{g} tasks", s.tasks.get(g, "")] for g in s.into]
    rows += [[f"g_{g} outside the system", task] for g, task in s.outside.items()]
    return rows


def _channel_rows(s: Step) -> list[list[str]]:
    """The channels the step reallocated, added and supplemented."""
    moved = [f"C{r.number}: {r.from_} ↦ {r.to}" for r in s.reallocated]
    new = ", ".join(f"C{c.number} ({c.ends[0]}, {c.ends[1]})" for c in s.new_channels)
    rows = [["Channel reallocation", ", ".join(moved) or "—"], ["New channels", new or "—"]]
    if s.supplemented:
        rows.append(["Supplemented", ", ".join(f"C{x.number}: {x.transmits}" for x in s.supplemented)])
    return rows


def _step_rows(state: StepState, texts: dict[str, str]) -> list[list[str]]:
    """The rows of one step's table (as the paper's Tables 1–2), the fringe after it last."""
    s = state.step
    rows: list[list[str]] = [["Requirements", "; ".join(f"{r}: {texts.get(r, '?')}" for r in s.requirements)]]
    rows += _decomposition_rows(s) + _channel_rows(s)
    for ch in sorted(state.channels.values(), key=lambda c: c.number):
        rows.append([f"C{ch.number} ({ch.ends[0]}, {ch.ends[1]}) transmits", "; ".join(ch.transmits)])
    rows.append(["Fringe", ", ".join(f"g_{g}" for g in state.fringe)])
    return rows


def _message_row(sender: str, perf: str, cp: ChannelProtocol) -> str:
    """One message of a channel's protocol: sender, performative, language, content, size."""
    langs = cp.languages.get(perf, "")
    lang = langs if isinstance(langs, str) else "/".join(langs)
    size = cp.sizes.get(perf)
    return _row(
        [
            sender,
            perf,
            lang or "—",
            ", ".join(cp.content_types(perf)) or ("any term" if lang else "—"),
            f"{size[0]}–{size[1]}" if size else "",
        ]
    )


def steps_markdown(d: Decomposition) -> str:
    """One Markdown table per decomposition step, then the fringe after it."""
    texts = {r.id: r.text for r in d.requirements}
    parts = [f"# Decomposition of g_{d.system}", ""]
    for state in replay(d):
        rows = _step_rows(state, texts)
        parts += [f"## Step {state.step.number}", "", "| | |", "|---|---|", *(_row(r) for r in rows), ""]
    return "\n".join(parts)


def interfaces_markdown(spec: SystemSpec) -> str:
    """Per agent: the performatives, languages and ontologies it sends and receives (paper §4
    step 4), derived from the channels."""
    lines = [
        "# Agent interfaces",
        "",
        "| agent | sends (performatives) | receives (performatives) | languages out / in | ontologies |",
        "|---|---|---|---|---|",
    ]
    for a in spec.agents:
        iface = interface(spec, a.name)
        out_p = sorted({k.performative for k in iface.sends})
        in_p = sorted({k.performative for k in iface.receives})
        out_l = sorted({lang for k in iface.sends for lang in k.languages})
        in_l = sorted({lang for k in iface.receives for lang in k.languages})
        onto = sorted({LANGUAGES[x].ontology for x in (*out_l, *in_l) if x in LANGUAGES})
        lines.append(
            _row(
                [
                    a.name,
                    ", ".join(out_p),
                    ", ".join(in_p),
                    f"{', '.join(out_l)} / {', '.join(in_l)}",
                    ", ".join(onto),
                ]
            )
        )
    return "\n".join(lines)


def channels_markdown(spec: SystemSpec) -> str:
    """Per channel and protocol, every message (paper §5.4, eq. 4, Figures 8–9): who sends it,
    the performative, its language, content schemas and size estimate."""
    parts = ["# Channels and their messages", ""]
    for ch in spec.channels:
        parts += [f"## {ch.name} ({ch.ends[0]}, {ch.ends[1]}): {ch.transmits}", ""]
        for cp in ch.protocols:
            other = ch.ends[1] if ch.ends[0] == cp.initiator else ch.ends[0]
            roles = spec.protocols[cp.protocol]
            parts += [
                f"{cp.protocol}, initiated by {cp.initiator}:",
                "",
                "| sender | performative | language | content | size estimate (B) |",
                "|---|---|---|---|---|",
            ]
            for sender, perfs in ((cp.initiator, roles.initiator), (other, roles.participant)):
                parts += [_message_row(sender, perf, cp) for perf in perfs]
            parts.append("")
    return "\n".join(parts)


def graph_dot(spec: SystemSpec) -> str:
    """Graphviz source of the agents (nodes) and channels (edges labelled with the channel
    and its protocols)."""
    lines = [
        f'graph "{spec.system}" {{',
        "  layout=circo;",
        '  node [shape=box, style=rounded, fontname="Helvetica"];',
    ]
    for a in spec.agents:
        lines.append(f'  {a.name} [label="{a.name}\\n(g_{a.group})"];')
    for e in spec.externals:  # outside the system: agents of other platforms
        lines.append(f'  {e.name} [label="{e.name}\\n(g_{e.group}, outside)", style="rounded,dashed"];')
    for ch in spec.channels:
        protos = ", ".join(p.protocol for p in ch.protocols)
        lines.append(f'  {ch.ends[0]} -- {ch.ends[1]} [label="{ch.name}: {protos}", fontsize=10];')
    lines.append("}")
    return "\n".join(lines)


def graph_svg(spec: SystemSpec, size: int = 640) -> str:
    """A self-contained SVG of the agents on a circle and the channels between them, each
    labelled with its name and protocols (no Graphviz needed)."""
    nodes = [*spec.agent_names, *spec.external_names]
    n = len(nodes)
    cx = cy = size / 2
    r = size * 0.36
    pos = {
        name: (
            cx + r * math.cos(2 * math.pi * i / n - math.pi / 2),
            cy + r * math.sin(2 * math.pi * i / n - math.pi / 2),
        )
        for i, name in enumerate(nodes)
    }
    out = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{size}" height="{size}" viewBox="0 0 {size} {size}" '
        'font-family="Helvetica, Arial, sans-serif">',
        f'<rect width="{size}" height="{size}" fill="white"/>',
        f'<text x="10" y="20" font-size="14">{escape(spec.system)}: agents and channels</text>',
    ]
    for ch in spec.channels:
        (x1, y1), (x2, y2) = pos[ch.ends[0]], pos[ch.ends[1]]
        mx, my = (x1 + x2) / 2, (y1 + y2) / 2
        protos = ", ".join(p.protocol for p in ch.protocols)
        out.append(
            f'<line x1="{x1:.1f}" y1="{y1:.1f}" x2="{x2:.1f}" y2="{y2:.1f}" stroke="#555" stroke-width="2"/>'
        )
        out.append(
            f'<text x="{mx:.1f}" y="{my - 4:.1f}" font-size="11" text-anchor="middle" fill="#124" '
            'stroke="white" stroke-width="3" paint-order="stroke">'
            f"{escape(ch.name)}: {escape(protos)}</text>"
        )
    for name in nodes:
        x, y = pos[name]
        dashed = ' stroke-dasharray="4 3"' if name in spec.external_names else ""  # outside the system
        out.append(
            f'<rect x="{x - 42:.1f}" y="{y - 18:.1f}" width="84" height="36" rx="8" '
            f'fill="#eef4ff" stroke="#124"{dashed}/>'
        )
        out.append(
            f'<text x="{x:.1f}" y="{y + 5:.1f}" font-size="13" text-anchor="middle">{escape(name)}</text>'
        )
    out.append("</svg>")
    return "\n".join(out)
