"""The paper's creature figures, drawn from live genotypes, bodies and simulator state (sections 2.1-2.4).

- :func:`draw_genotype` and :func:`genotype_and_body` (Fig. 1): the morphology graph -- nodes,
  child links (terminal-only ones dashed), recursion as a self-loop with its limit, symmetry as a
  mirrored second link -- beside the body tree that expansion grows from it, each part coloured
  by the genotype node it was instantiated from.
- :func:`draw_recombination` (Fig. 2): two parent graphs and their child, every node coloured by
  the parent it came from (identified by its body attributes) and numbered by its LR position.
- :func:`aba_sweeps` (section 2.4, Featherstone's articulated-body algorithm): the three sweeps
  over a body tree, level by level as the batched simulator runs them, animated; the last frames
  show the joint accelerations :func:`~coursekit.creatures.physics.forward_dynamics` returns.
  :func:`aba_schedule` is the visiting order as plain data.
- :func:`draw_contacts`: the boxes of a posed body seen along its thinnest direction, the pairs
  the separating-axis test finds touching in red, with their contact normals and depths.

Graph layouts reuse :func:`coursekit.pictures.figures.tree_layout` (a spanning tree by first
visit; links outside it are drawn curved), so no Graphviz is needed.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike
import matplotlib.pyplot as plt
from matplotlib.patches import FancyArrowPatch, Polygon

from coursekit.pictures.figures import tree_layout

if TYPE_CHECKING:
    import matplotlib.axes
    import matplotlib.figure
    from matplotlib.animation import FuncAnimation

    from .body import BodyTree
    from .genotype import Creature

#: colour of genotype node i: NODE_COLOURS(i % 10)
NODE_COLOURS = plt.get_cmap("tab10")
PARENT_COLOURS = {"a": "#4c72b0", "b": "#dd8452", "both": "#8172b3", "new": "#bbbbbb"}


def _colour(i):
    return NODE_COLOURS(i % 10)


def _disc(ax, x, y, text, colour, size=9, r=0.28):
    ax.add_patch(plt.Circle((x, y), r, fc=colour, ec="black", lw=0.8, zorder=3))
    ax.text(x, y, text, ha="center", va="center", fontsize=size, color="white", zorder=4, fontweight="bold")


def _arrow(ax, p, q, rad=0.0, style="-", colour="#333333", label=None, r=0.28):
    """An arrow between the rims of two discs of radius ``r`` centred at ``p`` and ``q`` (data units)."""
    p, q = np.asarray(p, float), np.asarray(q, float)
    u = (q - p) / max(np.linalg.norm(q - p), 1e-9)
    ax.add_patch(FancyArrowPatch(p + r * u, q - r * u, arrowstyle="-|>", mutation_scale=11, color=colour, ls=style,
                                 lw=1.2, shrinkA=0, shrinkB=0, connectionstyle=f"arc3,rad={rad}", zorder=2))
    if label:
        mx, my = (p[0] + q[0]) / 2, (p[1] + q[1]) / 2
        ax.text(mx + 0.08, my, label, fontsize=7, color=colour, ha="left", va="center", zorder=5,
                bbox=dict(fc="white", ec="none", alpha=0.8, pad=0.5))


def _genotype_positions(nodes):
    """Node -> (x, y): a spanning tree of the child links by first visit from the root, laid out as a tree."""
    n = len(nodes)
    kids, seen, order = [[] for _ in range(n)], {0}, [0]
    for i in order:  # breadth first: each node hangs under the first node that links to it
        for link in nodes[i].children:
            if link.child not in seen:
                seen.add(link.child)
                kids[i].append(link.child)
                order.append(link.child)
    pos = tree_layout(kids)
    return {i: (x * 1.3, -y * 1.2) for i, (x, y) in pos.items()}, kids


def draw_genotype(creature: Creature, ax: matplotlib.axes.Axes | None = None, *, colours: Sequence | None = None,
                  labels: Sequence[str] | None = None, title: str | None = "genotype graph") -> matplotlib.axes.Axes:
    """Draw a creature's morphology graph (paper Fig. 1, left).

    Args:
        creature: a :class:`~coursekit.creatures.Creature`.
        ax: matplotlib axes (a new figure when None).
        colours: optional colour per node (default: :data:`NODE_COLOURS`).
        labels: optional text per node (default: the node index).
        title: axes title.
    Returns:
        the axes.
    """
    nodes = creature.nodes
    ax = ax or plt.subplots(figsize=(4, 3.5))[1]
    pos, tree = _genotype_positions(nodes)
    colours = colours or [_colour(i) for i in range(len(nodes))]
    labels = labels or [str(i) for i in range(len(nodes))]
    for i, node in enumerate(nodes):
        links = {}
        for link in node.children:
            links.setdefault(link.child, []).append(link)
        for child, group in links.items():
            copies = len(group) + sum(s.child == child for s in node.symmetry) * len(group)
            parts = [f"x{copies}" if copies > 1 else ""]
            parts += [f"mirror {'xyz'[s.axis]}" for s in node.symmetry if s.child == child]
            parts += ["terminal only"] if any(link.terminal_only for link in group) else []
            label = ", ".join(p for p in parts if p) or None
            in_tree = child in tree[i]
            _arrow(ax, pos[i], pos[child], rad=0.0 if in_tree else 0.35, style="--" if group[0].terminal_only else "-",
                   label=label)
        if node.recursion and node.recursive_limit > 0:
            x, y = pos[i]
            # a self-loop on the node's left, labelled with the recursion limit
            ax.add_patch(FancyArrowPatch((x - 0.25, y - 0.15), (x - 0.25, y + 0.15), arrowstyle="-|>",
                                         mutation_scale=11, connectionstyle="arc3,rad=-2.2", color="#333333", lw=1.2))
            ax.text(x - 0.72, y, f"recursion\nx{node.recursive_limit}" + (f", {len(node.recursion)} branches"
                    if len(node.recursion) > 1 else ""), ha="right", va="center", fontsize=7)
    for i in range(len(nodes)):
        _disc(ax, *pos[i], labels[i], colours[i])
    xs, ys = zip(*pos.values())
    ax.set_xlim(min(xs) - 1.6, max(xs) + 1.4)
    ax.set_ylim(min(ys) - 0.7, max(ys) + 0.7)
    ax.set_aspect("equal")
    ax.axis("off")
    ax.set_title(title, fontsize=10)
    return ax


def draw_body_tree(creature: Creature, ax: matplotlib.axes.Axes | None = None, *,
                   title: str | None = None) -> matplotlib.axes.Axes:
    """Draw the part tree that ``creature.expand()`` grows, each part coloured by its genotype node."""
    pheno = creature.expand()
    body = pheno.body
    ax = ax or plt.subplots(figsize=(4, 3.5))[1]
    pos = {b: (x, -y) for b, (x, y) in tree_layout(pheno.children).items()}
    parts = np.flatnonzero(~body.massless)  # a multi-DOF joint's massless frames are not parts
    up = body.part_parent()
    for b in parts[1:]:
        _arrow(ax, pos[int(up[b])], pos[int(b)], r=0.24)
    for b in parts:
        _disc(ax, *pos[int(b)], str(int(b)), _colour(int(body.node_id[b])), size=8, r=0.24)
    xs, ys = zip(*pos.values())
    ax.set_xlim(min(xs) - 0.6, max(xs) + 0.6)
    ax.set_ylim(min(ys) - 0.6, max(ys) + 0.6)
    ax.set_aspect("equal")
    ax.axis("off")
    ax.set_title(title or f"expanded body: {body.n_parts} parts (colour = genotype node)", fontsize=10)
    return ax


def genotype_and_body(creature: Creature, *, render_body: bool = True,
                      figsize: tuple[float, float] | None = None) -> matplotlib.figure.Figure:
    """Fig. 1 from a live creature: its genotype graph, the part tree it expands into and (optionally) the body.

    Returns:
        the matplotlib Figure.
    """
    panels = 3 if render_body else 2
    fig, axes = plt.subplots(1, panels, figsize=figsize or (4.2 * panels, 3.8))
    draw_genotype(creature, axes[0], title=f"genotype: {len(creature.nodes)} nodes")
    draw_body_tree(creature, axes[1])
    if render_body:
        from .render import render

        axes[2].imshow(render(creature, size=(400, 300), joint_axes=False))
        axes[2].axis("off")
        axes[2].set_title("the body in 3-D (colour = depth)", fontsize=10)
    fig.tight_layout()
    return fig


def _signature(node):
    return (tuple(np.round(node.size, 9)), node.joint_type, tuple(node.joint_pos), tuple(node.joint_axis),
            tuple(node.limits), node.force)


def origins(child: Creature, a: Creature, b: Creature) -> list[str]:
    """Per node of ``child``: ``"a"``, ``"b"``, ``"both"`` (identical in both parents) or ``"new"`` (from repair)."""
    sa = {_signature(n) for n in a.nodes}
    sb = {_signature(n) for n in b.nodes}
    out = []
    for node in child.nodes:
        s = _signature(node)
        out.append("both" if s in sa and s in sb else "a" if s in sa else "b" if s in sb else "new")
    return out


def _nodes(n):
    return f"{n} node" if n == 1 else f"{n} nodes"


def draw_recombination(a: Creature, b: Creature, child: Creature, *,
                       figsize: tuple[float, float] = (13, 4)) -> matplotlib.figure.Figure:
    """Fig. 2 from live creatures: parents ``a`` and ``b`` and their ``child``, nodes coloured by parent.

    Nodes are numbered by their LR (pre-order) position, the numbering the recombination uses.

    Returns:
        the matplotlib Figure.
    """
    fig, axes = plt.subplots(1, 3, figsize=figsize)
    draw_genotype(a, axes[0], colours=[PARENT_COLOURS["a"]] * len(a.nodes), title=f"parent a: {_nodes(len(a.nodes))}")
    draw_genotype(b, axes[1], colours=[PARENT_COLOURS["b"]] * len(b.nodes), title=f"parent b: {_nodes(len(b.nodes))}")
    where = origins(child, a, b)
    draw_genotype(child, axes[2], colours=[PARENT_COLOURS[w] for w in where],
                  title=f"child: {_nodes(where.count('a'))} from a, {where.count('b')} from b")
    handles = [plt.Line2D([], [], marker="o", ls="", color=c, markersize=9, label=k) for k, c in PARENT_COLOURS.items()
               if k in ("a", "b") or k in where]
    fig.legend(handles=handles, loc="lower center", ncol=len(handles), fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.06, 1, 0.94))
    return fig


# ------------------------------------------------------------------------- the ABA's sweeps


def aba_schedule(parent: ArrayLike) -> list[tuple[int, int, list[int]]]:
    """The articulated-body algorithm's visiting order over a tree, as the batched simulator runs it.

    Returns:
        ``[(sweep, depth, bodies)]``: sweep 1 (velocities, outward) over depths 0..D, sweep 2
        (articulated inertias, inward) over D..0, sweep 3 (accelerations, outward) over 0..D.
    """
    parent = np.asarray(parent)
    depth = np.zeros(len(parent), dtype=int)
    for b in range(len(parent)):  # parents precede children
        if parent[b] >= 0:
            if parent[b] >= b:
                raise ValueError("parent: bodies must be in pre-order (each parent before its children)")
            depth[b] = depth[parent[b]] + 1
    levels = [np.flatnonzero(depth == d).tolist() for d in range(depth.max() + 1)]
    out = [(1, d, lv) for d, lv in enumerate(levels)]
    out += [(2, d, levels[d]) for d in range(len(levels) - 1, -1, -1)]
    out += [(3, d, lv) for d, lv in enumerate(levels)]
    return out


SWEEPS = {1: ("sweep 1, outward: velocities", r"$v_i = X_i\,v_{\lambda(i)} + S_i\dot q_i$,  $c_i = v_i \times S_i \dot q_i$"),
          2: ("sweep 2, inward: articulated inertias", r"$I^A_i, p^A_i$;  $U_i = I^A_i S_i$, $d_i = S_i^T U_i$;  pass $I^a_i$ to the parent"),
          3: ("sweep 3, outward: accelerations", r"$\ddot q_i = (u_i - U_i^T a'_i)/d_i$,  $a_i = a'_i + S_i \ddot q_i$")}


def aba_sweeps(tree: BodyTree, qpos: ArrayLike, qvel: ArrayLike, tau: ArrayLike, *,
               interval: int = 700) -> FuncAnimation:
    """Animate the ABA's three sweeps on ``tree`` (a BodyTree) at state ``(qpos, qvel)`` with joint forces ``tau``.

    Each frame lights the depth level the sweep is working on; sweep 3 writes the joint
    accelerations of :func:`~coursekit.creatures.physics.forward_dynamics` at the bodies it finishes.

    Returns:
        a ``matplotlib.animation.FuncAnimation`` (in a notebook: ``HTML(anim.to_jshtml())``).
    """
    from matplotlib.animation import FuncAnimation

    from .physics import forward_dynamics

    qacc = np.asarray(forward_dynamics([tree], [qpos], [qvel], [tau])[0])
    parent = np.asarray(tree.parent)
    kids = [[] for _ in parent]
    for b in range(1, len(parent)):
        kids[parent[b]].append(b)
    pos = {b: (x, -y) for b, (x, y) in tree_layout(kids).items()}
    schedule = aba_schedule(parent)
    fig, ax = plt.subplots(figsize=(7, 4.6))
    xs, ys = zip(*pos.values())

    def draw(frame):
        ax.clear()
        sweep, depth, bodies = schedule[frame]
        done = {b for s, d, bs in schedule[:frame + 1] if s == 3 for b in bs}
        for b in range(1, len(parent)):
            p, q = pos[int(parent[b])], pos[b]
            active = b in bodies and sweep != 2 or (sweep == 2 and int(parent[b]) in bodies and b in
                                                    {c for s, d, bs in schedule[:frame] if s == 2 for c in bs})
            src, dst = (q, p) if sweep == 2 else (p, q)
            ax.add_patch(FancyArrowPatch(src, dst, arrowstyle="-|>", mutation_scale=12, shrinkA=12, shrinkB=12,
                                         color="#c44e52" if active else "#bbbbbb", lw=2 if active else 1))
        for b, (x, y) in pos.items():
            on = b in bodies
            ax.add_patch(plt.Circle((x, y), 0.27, fc="#c44e52" if on else "#4c72b0" if b in done else "#dddddd",
                                    ec="black", lw=0.8, zorder=3))
            ax.text(x, y, str(b), ha="center", va="center", fontsize=8, zorder=4, color="white" if on or b in done else "black")
            if b in done:
                value = qacc[:3] if b == 0 else qacc[5 + b]
                text = f"root $a$ = {np.linalg.norm(value):.2g} m/s²" if b == 0 else f"$\\ddot q$={value:.3g}"
                ax.text(x, y - 0.42, text, ha="center", va="top", fontsize=7, color="#4c72b0")
        name, formula = SWEEPS[sweep]
        ax.set_title(f"{name} — depth {depth}\n{formula}", fontsize=10)
        ax.set_xlim(min(xs) - 0.8, max(xs) + 0.8)
        ax.set_ylim(min(ys) - 0.9, max(ys) + 0.5)
        ax.set_aspect("equal")
        ax.axis("off")

    anim = FuncAnimation(fig, draw, frames=len(schedule), interval=interval)
    plt.close(fig)  # the animation is shown by the caller (to_jshtml), not as a still figure
    return anim


# ------------------------------------------------------------------------------ collisions


def draw_contacts(tree: BodyTree, qpos: ArrayLike, ax: matplotlib.axes.Axes | None = None) -> matplotlib.axes.Axes:
    """The posed body's boxes seen along their thinnest direction, touching pairs and contact normals marked.

    Args:
        tree: a BodyTree.
        qpos: its configuration (MuJoCo layout).
        ax: matplotlib axes (a new figure when None).
    Returns:
        ``(ax, contacts)`` with ``contacts`` a list of ``(body_a, body_b, depth, point, normal)``.
    """
    from .physics.contact import Contacts
    from .physics.model import Model
    from .physics.world import World

    world = World([tree], contacts=False)
    world.set_state([np.asarray(qpos, float)], [np.zeros(6 + tree.n_joints)])
    R, p = (np.asarray(v) for v in world.body_poses())
    model = Model([tree])
    order = np.asarray(model.order)
    found = Contacts(model).detect(R, p)
    _, ia, ib, normal, depth, point = (np.asarray(v) for v in found)
    # view along the direction the body is thinnest in: the smallest principal axis of the box corners
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], float)
    half = np.asarray(tree.half_extents)[order]
    corners = p[:, None, :] + np.einsum("bij,bkj->bki", R, signs[None] * half[:, None, :])
    centred = corners.reshape(-1, 3) - corners.reshape(-1, 3).mean(axis=0)
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    e1, e2 = vt[0], vt[1]
    ax = ax or plt.subplots(figsize=(5, 4))[1]
    touching = set(ia.tolist()) | set(ib.tolist())
    from scipy.spatial import ConvexHull

    boxes = [k for k in range(len(order)) if not tree.massless[order[k]]]  # massless frames have no box
    for k in boxes:
        xy = np.c_[corners[k] @ e1, corners[k] @ e2]
        hull = xy[ConvexHull(xy).vertices]
        hit = k in touching
        ax.add_patch(Polygon(hull, closed=True, fc="#f4a3a3" if hit else "#dde3ee", ec="#c44e52" if hit else "#4c72b0",
                             lw=1.2, alpha=0.75, zorder=2 if hit else 1))
        c = xy.mean(axis=0)
        ax.text(*c, str(int(order[k])), fontsize=7, ha="center", va="center", zorder=5)
    scale = 0.25 * np.ptp(centred @ e1)
    out = []
    for k in range(len(ia)):
        q = np.r_[point[k] @ e1, point[k] @ e2]
        n = np.r_[normal[k] @ e1, normal[k] @ e2]
        ax.plot(*q, "o", color="black", ms=4, zorder=6)
        ax.annotate("", q + scale * n, q, arrowprops=dict(arrowstyle="-|>", color="black", lw=1.2), zorder=6)
        ax.text(*(q + scale * n), f" {1000 * depth[k]:.0f} mm", fontsize=7, zorder=6)
        out.append((int(order[ia[k]]), int(order[ib[k]]), float(depth[k]), point[k], normal[k]))
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.axis("off")
    ax.set_title(f"{len(ia)} touching pairs (red) of {len(boxes)} boxes; arrows: contact normals", fontsize=9)
    return ax, out
