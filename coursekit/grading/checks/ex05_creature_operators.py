"""Checks for exercise 05 (the creature operators: expansion, recombination, mutation).

Seed paper sections 2.3 (phenotype expansion), 2.2.1 (recombination with LR numbering) and
2.2.2 (mutation), checked as properties of the student's results -- never against one
reference output:

- ``creatures.expand``: the student's expansion returns one record per part
  (``node``, ``parent``, ``depth``, ``scale``, ``mirrored``, ``gain``). Every part's children
  are compared with what its genotype node implies (links, terminal-only links, symmetric
  copies, recursion up to the limit); the part total with an independent count by the
  recursion formula; scales, mirror parity and the force sign locally; the depth-first order
  (every part's parent is the part just before it or one of that part's ancestors; where the cap
  cuts the expansion short, only the path to the last part is unfinished, so the parts kept are the
  first ``max_parts`` of the walk); the order of one part's children (each applicable link's child,
  then its mirrored twins; the recursion copies last); and the part cap.
- ``creatures.crossover``: every node of the child is identified (by its body attributes) as
  the node at some LR position of a parent; the positions must follow alternating blocks
  ``[0, n)`` from ``a``, the next ``m`` from ``b``, the next ``n`` from ``a`` again, ...; every
  taken node is kept; links between taken nodes survive; ``n`` and ``m`` vary between calls.
- ``creatures.mutate``: valid children, values only from the predefined lists, a change rate
  scaled by the creature's size and by ``rate``, all six modification steps plus deletion and
  addition seen over many calls, and a size step that moves one half extent to a neighbouring
  value in ``SIZES`` (the exercise's ``mutate_size``; judged on nodes whose size alone changed).

Each check's second property is its *job*, a gate: more than the root is expanded wherever the
genotype has links; in at least a quarter of the calls the child of a recombination holds nodes
found only in ``a`` and nodes found only in ``b``; at least a quarter of the mutations at rate 1
change the creature. Until it holds nothing else is judged, so an expansion that returns the
root alone and deep copies score 0.

Each check's *point* (:func:`~.properties.point`, judged with :func:`~.properties.all_of`) is the
operator's definition and weighs half its points: every part as its genotype node implies (children,
depth, scale, mirroring); alternating LR blocks of random lengths (a, b, a, ...: some child of the
long parents goes back to ``a``), every taken node kept with its links; deletions, additions and all six
modification steps, about one node a call, scaled by ``rate``. The cap, the depth-first order, the order of
one part's children, the loop repair, values from the lists, the size step, determinism and untouched inputs
are details with small shares.

All three also check determinism for a seed and that inputs stay unmodified. Expansion and
recombination are checked exactly. The mutation statistics (changed nodes per call at rate 1
and 0.1, over 160 calls each, and every kind of change at least once) use wide bounds, set out
at :data:`MEAN_CHANGED`: an implementation that follows the notebook's rule fails them only by
a deviation of many standard deviations.
"""

from __future__ import annotations

import json

from coursekit.grading.checks import Check, creature_expansion as expansion, creature_mutation as mutation
from coursekit.grading.checks import creature_recombination as recombination
from coursekit.grading.checks import exercise, register
from coursekit.grading.checks.creature_cases import valid_creatures
from coursekit.grading.checks.properties import COPY_OBJECT, all_of, deterministic, point, unmodified


#: The order of one part's children (s27: a depth-first expansion that grew the recursion copies before the links
#: kept 4/4, and under the part cap other parts than the library's).
CHILD_ORDER = "children in the exercise's order"

#: Hint ladders (formative ``hint(...)``): a nudge, where to look, a concrete pointer; never the answer.
HINTS = {
    "creatures.expand": (
        ("expands more than the root", (
            "Expanding follows the genotype's links from the root: each link makes a child part of the node it points to.",
            "Walk the graph depth-first from node 0, one part record per visit, until the recursion limits stop it.")),
        ("walks depth first", (
            "Depth first: after a part come its first child's whole subtree, then its next child's; not a level at a time.",
            "Print node and parent of your parts for a small creature: is every part's parent the part just before it "
            "or one of that part's ancestors?",
            "A helper that appends a part and then grows each child in turn walks depth first; a queue walks breadth first.")),
        (CHILD_ORDER, (
            "One part's children come in the order section 1 lists them, which also decides what the part cap keeps.",
            "Print node and mirrored of one part's children, for a creature with a node that has links, symmetry "
            "entries and recursion entries: which kind comes first, and where does each twin come?",
            "Collect a part's children in one list, in the order of the two numbered rules, before growing any of "
            "them; then grow them in that list's order.")),
    ),
    "creatures.crossover": (
        ("the child holds nodes of both parents", (
            "The child takes nodes from a and from b in alternating blocks, not all from one parent.",
            "Draw the block lengths with the rng, then copy the nodes of the current parent for each block.")),
    ),
    "creatures.mutate": (
        ("changes the creature", (
            "Mutation must change something: a node's value, a link, a new or deleted node.",
            "Work on a copy of the creature and change each value with a probability that grows with rate.")),
    ),
}


#: Each check's *point* (:func:`~.properties.point`): the operator's definition, judged as one property that weighs
#: as much as all the others together. Before (s26, a study of honest answers), the rules of a definition counted
#: one by one: a crossover with one cut kept 4/4, one that lost the links between its blocks 95 %, one that dropped
#: orphans 86 %; a mutation at every node or ignoring rate 88 %, one that never deletes or adds 69 %; an expansion
#: ignoring terminal-only links 65 %, with unmirrored twins 85 %.
EXPAND_POINT = "every part as its genotype node implies (children, recursion depth, scale, mirroring)"
_EXPAND = (
    ("returns a list of part records", expansion.valid),
    ("expands more than the root", expansion.grows),
    ("parents precede children", expansion.in_order),
    ("walks depth first", expansion.depth_first),
    (CHILD_ORDER, expansion.children_in_order),
    (EXPAND_POINT, all_of(expansion.counts, expansion.depths, expansion.scales, expansion.mirrors)),
    ("part cap respected", expansion.capped),
)

register(Check(
    hints=HINTS.get("creatures.expand", ()),
    name="creatures.expand", function="expand", params=("creature", "max_parts"), points=4.0,
    title="phenotype expansion", output="json", cases=expansion.make_cases, gates=2,
    reference=('coursekit.creatures.phenotype:expand', 'coursekit.creatures.genotype:Creature.expand',
               'coursekit.grading.checks.creature_expansion:full_count',
               'coursekit.grading.checks.creature_expansion:_expected_children'),
    props=_EXPAND,
    # depth first counts 2 like the cap: the order numbers the body and decides which parts the cap keeps
    # (s27: a breadth-first expansion got every part right and kept 4/4; 3.5/4, now 3.56/4 with the child order);
    # the order of one part's children counts 1, the smallest share: the walk is right and only one rule of the
    # numbering is misread (recursion copies first: 4/4 before, now 3.78/4)
    weights=point(EXPAND_POINT, _EXPAND, (("walks depth first", 2), ("part cap respected", 2))),
))


CROSSOVER_POINT = "alternating LR blocks of random lengths, every taken node kept with its links"
_CROSSOVER = (
    ("returns a valid creature", valid_creatures(recombination.CASES)),
    ("the child holds nodes of both parents", recombination.mixes),
    (CROSSOVER_POINT, all_of(recombination.blocks, recombination.kept, recombination.links_kept,
                             recombination.random_blocks, recombination.alternates)),
    ("the repair leaves no loop", recombination.no_loops),
    ("deterministic for a seed", deterministic("basic", parse=json.loads)),
    ("inputs unchanged", unmodified({0: "a", 1: "b"}, COPY_OBJECT, what="the creature {name}")),
)

register(Check(
    hints=HINTS.get("creatures.crossover", ()),
    name="creatures.crossover", function="crossover", params=("a", "b", "rng"), points=4.0,
    title="LR recombination", output="json", cases=recombination.make_cases, gates=2,
    # and the library's other recombination and its repair step (red team: graft 2.67/4, a block loop + repair 4/4),
    # withheld: the exercise's evolution runs on the student's operators
    reference=('coursekit.creatures.operators:crossover', 'coursekit.creatures.operators:graft',
               'coursekit.creatures.operators:repair'),
    props=_CROSSOVER,
    # no loop repair (a student's walk: a crash in 1.6 % of random crossovers) is a detail that can stop a run
    weights=point(CROSSOVER_POINT, _CROSSOVER, (("the repair leaves no loop", 3),)),
))


MUTATE_POINT = "deletes, adds and modifies in six steps, about one node per call, scaled by rate"
_MUTATE = (
    ("returns a valid creature", valid_creatures(mutation.CASES)),
    ("changes the creature", mutation.changes),
    ("values from the predefined lists", mutation.in_lists),
    (MUTATE_POINT, all_of(mutation.all_kinds, mutation.frequency, mutation.rate)),
    ("a size moves to a neighbouring value", mutation.neighbouring_size),
    ("deterministic for a seed", deterministic("basic", parse=json.loads)),
    ("input unchanged", unmodified({0: "c"}, COPY_OBJECT, what="the creature {name}")),
)

register(Check(
    hints=HINTS.get("creatures.mutate", ()),
    name="creatures.mutate", function="mutate", params=("c", "rng"), points=4.0,
    title="creature mutation", output="json", cases=mutation.make_cases, gates=2,
    reference=('coursekit.creatures.operators:mutate', 'coursekit.creatures.operators:repair'),
    props=_MUTATE,
    weights=point(MUTATE_POINT, _MUTATE, (("values from the predefined lists", 2),)),
))


exercise("05_creature_operators", ["creatures.expand", "creatures.crossover", "creatures.mutate"])
