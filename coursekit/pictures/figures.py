"""The paper's genome figures, drawn from a live :class:`~coursekit.pictures.genome.Genome` (section 3.1, Figs. 5-7).

- :func:`draw_string` (Figs. 5 and 6): one chromosome string as its row of chromosomes, head and
  tail marked, under the expression tree of its open reading frame; chromosomes after the reading
  frame (non-coding) are greyed, and so is a whole string the PreHeader does not reach.
- :func:`draw_genome` (Fig. 7): every string of a genome side by side, beside its PreHeader
  drawn as the paper describes it, "a ring which contains all chromosome strings": the PreHeader
  chromosomes and the string roots on a ring, with the links decoding makes inside it.

Everything is read from the genome itself (its strings, the Karva reading of
:mod:`coursekit.pictures.genome` and :attr:`Genome.active`), so a mutated genome draws its own
figure. The tree layout (leaves left to right, each parent centred over its children) is a
dozen lines written here: matplotlib has none, and networkx's tree layouts need Graphviz.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Sequence

import matplotlib.pyplot as plt
from matplotlib.patches import FancyArrowPatch, Rectangle
from matplotlib.textpath import TextPath

from .genome import Genome, karva

if TYPE_CHECKING:
    import matplotlib.axes
    import matplotlib.figure

#: colours: head chromosomes, tail chromosomes, the PreHeader, non-coding ones
HEAD, TAIL, PRE, OFF = "#4c72b0", "#55a868", "#c44e52", "#c8c8c8"


def tree_layout(children: list, root: int = 0, widths: Sequence[float] | None = None) -> dict:
    """``{node: (x, depth)}``: leaves left to right in order, each parent centred over its children,
    and no two nodes of one depth closer than half their ``widths`` added up (default 1 each: leaves
    at x = 0, 1, 2, ...). Where a wide label would touch its neighbour, the leaves from the right
    one's subtree on move right until it does not."""
    width = [1.0] * len(children) if widths is None else [float(v) for v in widths]
    depth, first, leaves, levels = {}, {}, [], {}

    def walk(i, d):  # depths, leaves in order, each node's first leaf, nodes of each depth in order
        depth[i] = d
        levels.setdefault(d, []).append(i)
        for j in children[i]:
            walk(j, d + 1)
        if not children[i]:
            leaves.append(i)
        first[i] = first[children[i][0]] if children[i] else len(leaves) - 1

    def centre(i, x):
        for j in children[i]:
            centre(j, x)
        if children[i]:
            x[i] = (x[children[i][0]] + x[children[i][-1]]) / 2

    walk(root, 0)
    extra = [0.0] * len(leaves)
    while True:
        x, at = {}, 0.0
        for k, leaf in enumerate(leaves):
            at += ((width[leaves[k - 1]] + width[leaf]) / 2 + extra[k]) if k else 0.0
            x[leaf] = at
        centre(root, x)
        clash = next(((b, (width[a] + width[b]) / 2 - (x[b] - x[a])) for nodes in levels.values()
                      for a, b in zip(nodes, nodes[1:]) if x[b] - x[a] < (width[a] + width[b]) / 2 - 1e-9), None)
        if clash is None:
            return {i: (x[i], depth[i]) for i in depth}
        extra[first[clash[0]]] += clash[1]


def _node(ax, x, y, text, colour, coding, size=7.5):
    ax.text(x, y, text, ha="center", va="center", fontsize=size, color="white" if coding else "#777777",
            bbox=dict(boxstyle="round,pad=0.25", fc=colour if coding else "#eeeeee", ec=colour if coding else OFF, lw=1))


def _edge(ax, p, q, coding):
    ax.add_patch(FancyArrowPatch(p, q, arrowstyle="-", color="#555555" if coding else OFF, lw=1.2, zorder=0,
                                 shrinkA=7, shrinkB=7))


def draw_string(genome: Genome, k: int, ax: matplotlib.axes.Axes | None = None, *,
                title: bool = True) -> matplotlib.axes.Axes:
    """Draw string ``k`` of ``genome``: its expression tree over its row of chromosomes.

    Args:
        genome: the genome.
        k: index of the string (0-based).
        ax: matplotlib axes (a new figure when None).
        title: write "string k: coding / non-coding" above it.
    Returns:
        the axes.
    """
    if not 0 <= k < len(genome.strings):
        raise ValueError(f"k: string index must be in 0..{len(genome.strings) - 1}, got {k!r}")
    s = genome.strings[k]
    ax = ax or plt.subplots(figsize=(max(3.0, 0.55 * len(s)), 3.4))[1]
    linked = bool(genome.active[k])
    children, orf = karva(s.chromosomes, lambda c: c.arity)
    # The tree's labels are as wide as their names (the font's own widths, in points): the layout
    # keeps them apart at the scale at which the panel draws its chromosome boxes, in a smaller
    # font where the names would not fit the panel's width otherwise.
    size, margin = 7.5, 1.6
    panel = ax.get_position().width * ax.figure.get_figwidth() * 72
    label = [TextPath((0, 0), c.symbol, size=size).get_extents().width + 1.4 * size for c in s.chromosomes[:len(children)]]
    pos = tree_layout(children, widths=label)  # in points
    lo, hi = min(x - label[i] / 2 for i, (x, _) in pos.items()), max(x + label[i] / 2 for i, (x, _) in pos.items())
    fit = min(1.0, 0.8 * panel / (hi - lo))
    size *= fit
    units = max(len(s) + margin, margin / (1 - fit * (hi - lo) / panel))  # the panel's width, in boxes
    scale, left_x = fit * units / panel, min(x for x, _ in pos.values())  # points to boxes
    pos = {i: ((x - left_x) * scale, d) for i, (x, d) in pos.items()}
    lo, hi = (lo - left_x) * scale, (hi - left_x) * scale
    span = max(x for x, _ in pos.values())
    row_x = lambda i: (i - (len(s) - 1) / 2) * max(1.0, (span + 1) / len(s)) + span / 2  # noqa: E731
    depth = max(d for _, d in pos.values())
    row_y = -(depth + 1.6)
    for i, kids in enumerate(children[:orf]):
        for j in kids:
            _edge(ax, (pos[i][0], -pos[i][1]), (pos[j][0], -pos[j][1]), linked)
    for i, (x, d) in pos.items():
        _node(ax, x, -d, s.chromosomes[i].symbol, HEAD if i < s.head_length else TAIL, linked, size)
    for i, c in enumerate(s.chromosomes):
        coding = linked and i < orf
        colour = HEAD if i < s.head_length else TAIL
        x = row_x(i)
        ax.add_patch(Rectangle((x - 0.45, row_y - 0.9), 0.9, 1.8, fc=colour if coding else "#f2f2f2",
                               ec=colour if coding else OFF, lw=1.2))
        ax.text(x, row_y, c.symbol, rotation=90, ha="center", va="center", fontsize=7,
                color="white" if coding else "#888888")
        if i in pos and coding:  # tie each tree node to its place in the string
            ax.plot([pos[i][0], x], [-pos[i][1] - 0.25, row_y + 0.9], color=colour, lw=0.4, alpha=0.35, zorder=-1)
    h = s.head_length
    ax.annotate("", (row_x(h) - 0.5, row_y - 1.15), (row_x(0) - 0.5, row_y - 1.15),
                arrowprops=dict(arrowstyle="|-|", color=HEAD, lw=1, shrinkA=0, shrinkB=0, mutation_scale=3))
    ax.text((row_x(0) + row_x(h - 1)) / 2, row_y - 1.55, f"head (h={h})", ha="center", fontsize=7, color=HEAD)
    ax.text((row_x(h) + row_x(len(s) - 1)) / 2, row_y - 1.55, f"tail (t={s.tail_length})", ha="center",
            fontsize=7, color=TAIL)
    left, right = min(row_x(0) - 0.8, lo), max(row_x(len(s) - 1) + 0.8, hi)
    ax.set_xlim((left + right - max(units, right - left)) / 2, (left + right + max(units, right - left)) / 2)
    ax.set_ylim(row_y - 2.0, 0.7)
    ax.axis("off")
    if title:
        state = f"{orf} coding, {len(s) - orf} non-coding" if linked else "not linked by the PreHeader: inactive"
        ax.set_title(f"string {k}: {state}", fontsize=9)
    return ax


def draw_preheader(genome: Genome, ax: matplotlib.axes.Axes | None = None) -> matplotlib.axes.Axes:
    """Draw the PreHeader as the paper's ring: its chromosomes and the strings, linked as decoding reads them."""
    ax = ax or plt.subplots(figsize=(3.4, 3.4))[1]
    items = list(genome.preheader) + list(range(len(genome.strings)))
    kids, orf = karva(items, lambda it: 0 if isinstance(it, int) else it.arity)
    n = len(items)
    angle = [math.pi / 2 - 2 * math.pi * i / n for i in range(n)]
    xy = [(math.cos(a), math.sin(a)) for a in angle]
    ring = plt.Circle((0, 0), 1.0, fill=False, ls=":", color="#999999")
    ax.add_patch(ring)
    for i, its in enumerate(kids[:orf]):
        for j in its:
            ax.add_patch(FancyArrowPatch(xy[i], xy[j], arrowstyle="-|>", mutation_scale=10, color="#333333",
                                         shrinkA=14, shrinkB=14, connectionstyle="arc3,rad=0.15"))
    for i, it in enumerate(items):
        coding = i < orf
        if isinstance(it, int):
            active = bool(genome.active[it])
            _node(ax, *xy[i], f"string {it}", TAIL if active else OFF, active, size=8)
        else:
            _node(ax, *xy[i], it.symbol, PRE, coding, size=8)
    ax.set_xlim(-1.5, 1.5)
    ax.set_ylim(-1.4, 1.4)
    ax.set_aspect("equal")
    ax.axis("off")
    ax.set_title(f"PreHeader ring: {len(genome.preheader)} chromosomes, {len(genome.strings)} strings", fontsize=9)
    return ax


def draw_genome(genome: Genome, *, figsize: tuple[float, float] | None = None) -> matplotlib.figure.Figure:
    """Fig. 7 from a live genome: the PreHeader ring (when there is one) beside every string and its tree.

    Returns:
        the matplotlib Figure.
    """
    if not isinstance(genome, Genome):
        raise TypeError(f"genome: expected a coursekit.pictures.Genome, got {type(genome).__name__}")
    panels = (1 if genome.preheader else 0) + len(genome.strings)
    widths = ([3.2] if genome.preheader else []) + [max(2.6, 0.5 * len(s)) for s in genome.strings]
    fig, axes = plt.subplots(1, panels, figsize=figsize or (sum(widths), 3.8),
                             gridspec_kw={"width_ratios": widths}, squeeze=False)
    axes = list(axes[0])
    if genome.preheader:
        draw_preheader(genome, axes.pop(0))
    for k, ax in enumerate(axes):
        draw_string(genome, k, ax)
    fig.tight_layout()
    return fig
