"""Render a described dataflow (Dataflow.describe(), or a live run's reply) as text, DOT or PNG."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # the CLI starts without importing the runtime
    from common.runtime.model.dataflow import (
        DataflowDescription,
        InputDescription,
        ServiceDescription,
    )


def _period(s: ServiceDescription) -> str:
    if s["period_s"] is None:
        return "event-driven"
    offset = f", offset {s['offset_s']:g} s" if s["offset_s"] else ""
    return f"every {s['period_s']:g} s{offset}"


def _readers(d: DataflowDescription) -> dict[tuple[str, str], list[str]]:
    out: dict[tuple[str, str], list[str]] = {}
    for s in d["services"]:
        for i in s["inputs"]:
            out.setdefault((i["source"], i["stream"]), []).append(s["name"])
    return out


def to_text(d: DataflowDescription, title: str) -> str:
    """One block per service: its period, inputs (type, policy) and outputs (type, readers)."""
    readers = _readers(d)
    lines = [f"{title}: {len(d['services'])} services, {len(d['links'])} links", ""]
    for s in d["services"]:
        lines.append(f"{s['name']}  ({_period(s)})")
        for i in s["inputs"]:
            wake = ", wakes it" if i["wake"] else ""
            lines.append(
                f"  in   {i['source'] + '/' + i['stream']:<22} {i['type']:<20} {i['policy']}{wake}"
            )
        for o in s["outputs"]:
            to = ", ".join(readers.get((s["name"], o["stream"]), [])) or "(record only)"
            lines.append(f"  out  {o['stream']:<22} {o['type']:<20} -> {to}")
        lines.append("")
    return "\n".join(lines).rstrip() + "\n"


def to_dot(d: DataflowDescription, title: str) -> str:
    """Graphviz DOT: a box per service, an edge per link labelled stream: type."""
    out = [f'digraph "{title}" {{', "  rankdir=LR;", '  node [shape=box, fontname="Helvetica"];']
    for s in d["services"]:
        out.append(f'  "{s["name"]}" [label="{s["name"]}\\n{_period(s)}"];')
    for s in d["services"]:
        for i in s["inputs"]:
            style = ", style=dashed" if i["wake"] else ""
            out.append(
                f'  "{i["source"]}" -> "{s["name"]}" '
                f'[label="{i["stream"]}: {i["type"]}\\n({i["policy"]})"{style}];'
            )
    out.append("}")
    return "\n".join(out) + "\n"


def to_png(d: DataflowDescription, title: str, path: Path) -> Path:
    """Draw the graph with matplotlib: services on a circle, links as labelled arrows."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = [s["name"] for s in d["services"]]
    n = max(1, len(names))
    # clockwise from the top, so a ring of services reads like the loop it is
    pos = {
        name: (math.sin(2 * math.pi * k / n), math.cos(2 * math.pi * k / n))
        for k, name in enumerate(names)
    }
    fig, ax = plt.subplots(figsize=(8, 7))
    # one arrow per (source, receiver) pair, labelled with every stream it carries
    edges: dict[tuple[str, str], list[InputDescription]] = {}
    for s in d["services"]:
        for i in s["inputs"]:
            edges.setdefault((i["source"], s["name"]), []).append(i)
    for (src, rcv), inputs in edges.items():
        (x0, y0), (x1, y1) = pos[src], pos[rcv]
        ax.annotate(
            "",
            xy=(x1, y1),
            xytext=(x0, y0),
            arrowprops={
                "arrowstyle": "-|>",
                "connectionstyle": "arc3,rad=0.15",
                "shrinkA": 38,
                "shrinkB": 38,
                "linestyle": "--" if any(i["wake"] for i in inputs) else "-",
            },
        )
        # the label sits beside the arc's middle, pushed off it to the arc's bulge side
        mx, my = (x0 + x1) / 2 + 0.12 * (y1 - y0), (y0 + y1) / 2 - 0.12 * (x1 - x0)
        label = "\n".join(f"{i['stream']}: {i['type']}" for i in inputs)
        ax.text(mx, my, label, ha="center", va="center", fontsize=8)
    for s in d["services"]:
        x, y = pos[s["name"]]
        ax.text(
            x,
            y,
            f"{s['name']}\n{_period(s)}",
            ha="center",
            va="center",
            fontsize=10,
            bbox={"boxstyle": "round,pad=0.5", "facecolor": "#dbe9f6", "edgecolor": "#2f5d8a"},
        )
    ax.set_xlim(-1.5, 1.5)
    ax.set_ylim(-1.4, 1.4)
    ax.set_aspect("equal")
    ax.axis("off")
    ax.set_title(title)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
