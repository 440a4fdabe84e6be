"""The paper's figures drawn from live data (issue 14, item 4): what each drawing shows is read from the data.

Each test checks the drawing against the data structure it draws: coding and non-coding
chromosomes of a genome, the PreHeader's links, the body tree's parts and colours, the origin of
every node of a recombined child, the ABA's visiting order, and collisions the contact code finds.
"""

import gc

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from matplotlib.colors import to_hex  # noqa: E402
from matplotlib.patches import Rectangle  # noqa: E402

from coursekit.creatures import Creature, operators  # noqa: E402
from coursekit.creatures import figures as cf  # noqa: E402
from coursekit.creatures.physics import forward_dynamics, random_body_tree, random_state  # noqa: E402
from coursekit.pictures import Genome  # noqa: E402
from coursekit.pictures import figures as pf  # noqa: E402


@pytest.fixture(autouse=True)
def _close():
    yield
    plt.close("all")


@settings(max_examples=40, deadline=None)
@given(st.lists(st.integers(0, 30), min_size=0, max_size=25))
def test_tree_layout_puts_parents_over_their_children_and_leaves_apart(picks):
    children = [[]]
    for p in picks:
        children[p % len(children)].append(len(children))
        children.append([])
    pos = pf.tree_layout(children)
    assert set(pos) == set(range(len(children)))
    for i, kids in enumerate(children):
        for j in kids:
            assert pos[j][1] == pos[i][1] + 1
        if kids:
            xs = [pos[j][0] for j in kids]
            assert pos[i][0] == pytest.approx((min(xs) + max(xs)) / 2) and xs == sorted(xs)
    leaves = [pos[i][0] for i, k in enumerate(children) if not k]
    assert len(set(leaves)) == len(leaves)


def _cells(ax):
    """(coding?, symbol) of every chromosome box of a drawn string, left to right."""
    boxes = sorted((p for p in ax.patches if isinstance(p, Rectangle)), key=lambda p: p.get_x())
    return [to_hex(p.get_facecolor()) != "#f2f2f2" for p in boxes]


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(1, 3), st.sampled_from([1, 3, 5]))
def test_a_drawn_string_greys_exactly_its_non_coding_chromosomes(seed, h, n_strings):
    g = Genome.random(np.random.default_rng(seed), n_strings=n_strings, head_length=h)
    active = g.active
    for k, s in enumerate(g.strings):
        ax = plt.subplots()[1]
        pf.draw_string(g, k, ax)
        assert _cells(ax) == [i in active[k] for i in range(len(s))]
        tree_labels = [t.get_text() for t in ax.texts if t.get_rotation() == 0 and t.get_text() in {c.symbol for c in s.chromosomes}]
        assert len(tree_labels) == len(list(g._string_tree(k).walk()))  # one tree node per chromosome read
        plt.close(ax.figure)


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(1, 12), st.sampled_from([(13, 3.6, 3), (4, 3.4, 1)]))
def test_no_two_labels_of_a_drawn_tree_overlap(seed, h, panels):
    # lesson 02's Figures 8 and 9 (three panels in a 13-inch figure) once drew "color-noise" over "angle"
    width, height, n = panels
    g = Genome.random(np.random.default_rng(seed), n_strings=1, head_length=h)
    fig, axes = plt.subplots(1, n, figsize=(width, height), squeeze=False)
    pf.draw_string(g, 0, axes[0, -1])
    fig.canvas.draw()
    boxes = [t.get_bbox_patch().get_window_extent() for t in axes[0, -1].texts if t.get_bbox_patch() is not None]
    assert len(boxes) == len(list(g._string_tree(0).walk()))
    for i, a in enumerate(boxes):
        for b in boxes[i + 1:]:
            overlap = min(a.x1, b.x1) - max(a.x0, b.x0), min(a.y1, b.y1) - max(a.y0, b.y0)
            assert min(overlap) < 0.5, f"two tree labels overlap by {overlap} pixels"
    plt.close(fig)


def test_the_genome_figure_has_the_preheader_ring_and_one_panel_per_string():
    g = Genome.random(np.random.default_rng(7), n_strings=3, head_length=3)
    fig = pf.draw_genome(g)
    assert len(fig.axes) == 1 + 3
    ring = fig.axes[0]
    labels = {t.get_text() for t in ring.texts}
    assert {"string 0", "string 1", "string 2"} <= labels and {c.symbol for c in g.preheader} <= labels
    links = [p for p in ring.patches if type(p).__name__ == "FancyArrowPatch"]
    assert len(links) == sum(len(n.children) for n in g.decode().walk() if n.site[0] == "pre")
    with pytest.raises(TypeError, match="genome"):
        pf.draw_genome("not a genome")
    with pytest.raises(ValueError, match="k: string index"):
        pf.draw_string(g, 3)


def test_figure1_shows_two_genotype_nodes_and_six_parts_coloured_by_node():
    snake = Creature.figure1_snake(segments=4)
    fig = cf.genotype_and_body(snake, render_body=False)
    graph, tree = fig.axes
    graph_discs = [p for p in graph.patches if isinstance(p, plt.Circle)]
    tree_discs = [p for p in tree.patches if isinstance(p, plt.Circle)]
    assert len(graph_discs) == 2 and len(tree_discs) == 6
    node_id = snake.expand().body.node_id
    assert [to_hex(d.get_facecolor()) for d in tree_discs] == [to_hex(cf.NODE_COLOURS(int(n))) for n in node_id]
    texts = " ".join(t.get_text() for t in graph.texts)
    assert "recursion\nx3" in texts and "terminal only" in texts and "mirror y" in texts


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_every_node_of_a_recombined_child_is_traced_to_its_parent(seed):
    rng = np.random.default_rng(seed)
    a, b = Creature.random(rng, n_nodes=(2, 5)), Creature.random(rng, n_nodes=(2, 5))
    child = operators.crossover(a, b, rng)
    where = cf.origins(child, a, b)
    assert len(where) == len(child.nodes) and where[0] in ("a", "both")  # the root comes from the first parent
    assert set(cf.origins(a, a, b)) <= {"a", "both"} and set(cf.origins(b, a, b)) <= {"b", "both"}
    fig = cf.draw_recombination(a, b, child)
    discs = [p for p in fig.axes[2].patches if isinstance(p, plt.Circle)]
    assert [to_hex(d.get_facecolor()) for d in discs] == [to_hex(cf.PARENT_COLOURS[w]) for w in where]


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(1, 20))
def test_the_aba_schedule_visits_every_body_once_per_sweep_parents_first_outward(seed, n):
    tree = random_body_tree(np.random.default_rng(seed), n)
    sched = cf.aba_schedule(tree.parent)
    for sweep in (1, 2, 3):
        visits = [b for s, _, bs in sched if s == sweep for b in bs]
        assert sorted(visits) == list(range(tree.n_bodies))
        when = {b: k for k, b in enumerate(visits)}
        for b in range(1, tree.n_bodies):
            before = when[tree.parent[b]] < when[b]
            assert before if sweep != 2 else not before
    with pytest.raises(ValueError, match="pre-order"):
        cf.aba_schedule([-1, 2, 0])


@pytest.mark.filterwarnings("ignore:Animation was deleted without rendering")
def test_the_aba_animation_ends_with_the_simulators_joint_accelerations():
    rng = np.random.default_rng(3)
    tree = random_body_tree(rng, 6)
    qpos, qvel = random_state(rng, tree)
    tau = rng.normal(size=tree.n_joints)
    anim = cf.aba_sweeps(tree, qpos, qvel, tau)
    frames = len(cf.aba_schedule(tree.parent))
    anim._func(frames - 1)
    shown = {t.get_text() for t in anim._fig.axes[0].texts}
    qacc = forward_dynamics([tree], [qpos], [qvel], [tau])[0]
    for b in range(1, tree.n_bodies):
        assert f"$\\ddot q$={qacc[5 + b]:.3g}" in shown
    anim._func(0)
    assert "sweep 1" in anim._fig.axes[0].get_title()
    del anim  # never rendered on purpose: collected here, under this test's filter, not in a later test's
    gc.collect()


def test_bending_a_body_until_two_boxes_touch_shows_that_contact():
    tree = random_body_tree(np.random.default_rng(0), 12, size_range=(0.1, 0.35))
    q, _ = random_state(np.random.default_rng(0), tree, inside=1.0)
    q[:7] = [0, 0, 0, 1, 0, 0, 0]
    straight = q.copy()
    straight[7:] = 0
    _, none = cf.draw_contacts(tree, straight)
    for s in np.linspace(0, 1, 51):
        bent = q.copy()
        bent[7:] *= s
        _, found = cf.draw_contacts(tree, bent)
        if found:
            break
    assert none == [] and found and s > 0
    for a, b, depth, point, normal in found:
        assert depth > 0 and a != b and tree.parent[a] != b and tree.parent[b] != a
        assert np.linalg.norm(normal) == pytest.approx(1.0)
