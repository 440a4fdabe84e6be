"""What a breeding action makes (paper section 3.4): the gallery's children, as a pure function.

:func:`breed` is one click of the gallery without the session: from a population, the
selection (the parents, in click order), the random generator and the operators, it makes the
next generation, the parents kept first, the rest children none of which looks like a parent or
a sibling (:func:`~.variety.distinct_children`), each with its :class:`Origin`. Parents with
fewer distinct children than there are slots (two siblings that differ at one chromosome cross
into little more than themselves) get the rest mutated once more, and the message says how many.
:class:`~.session.Evolution` prepares an action with it (:class:`Prepared`: what it read and
what it made) and commits it; the gallery prepares the next one in a thread while the student
chooses.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass

import numpy as np

from . import operators as O
from .genome import Genome
from .variety import distinct_children

__all__ = ["Origin", "Prepared", "breed"]


@dataclass(frozen=True)
class Origin:
    """How a picture was made: ``operator`` (an operator's name, ``"kept"`` for a selected
    picture carried over, ``"random"``, or ``"start"`` for a given first generation) and its
    ``parents``, indices into the generation before."""

    operator: str
    parents: tuple[int, ...] = ()

    def to_dict(self) -> dict:
        return {"operator": self.operator, "parents": list(self.parents)}


@dataclass(frozen=True, eq=False)
class Prepared:
    """A breeding action worked out ahead (:meth:`~.session.Evolution.prepare`): what it read (the
    population, the selection, the random state, the operators) and what it made (``outcome``:
    the new ``(population, origins, message)``, or a message saying why nothing was bred)."""

    action: str
    population: tuple
    selected: tuple
    rng_before: dict
    rng_after: dict
    operators: tuple
    outcome: tuple | str

    def fits(self, evolution) -> bool:
        """Was this bred from the :class:`~.session.Evolution`'s session as it is now (then
        committing it is the action)?"""
        s = evolution.state
        return (tuple(s.selected) == self.selected and len(s.population) == len(self.population)
                and all(a is b for a, b in zip(s.population, self.population))
                and self._same_operators(evolution._operators())
                and _same(evolution.rng.bit_generator.state, self.rng_before))

    def _same_operators(self, operators: tuple) -> bool:
        return all(len(a) == len(b) and all(x[0] == y[0] and x[1] is y[1] for x, y in zip(a, b))
                   for a, b in zip(operators, self.operators))


def _same(a, b) -> bool:
    """Equal random states (nested dicts of numbers and, for MT19937, Philox and SFC64, arrays)."""
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return np.array_equal(a, b)
    return type(a) is type(b) and a == b


def _children(name: str, make: Callable, again: Callable | None, mutate: Callable | None, population: list,
              sel: list) -> tuple | str:
    """Children from ``make()`` -> (genome, Origin) through :func:`distinct_children`;
    the parents (the selection) open the new generation as ``kept``. Returns the generation,
    the origins and how many children were mutated once more (``mutate``)."""
    parents = [population[i] for i in sel]
    made: dict[int, tuple] = {}  # id(child) -> (child, Origin): the origin of every draw
    rescued: set[int] = set()  # ids of the children mutate() made

    def children() -> Iterator:
        while True:
            child, origin = make()
            made[id(child)] = (child, origin)
            yield child

    def redo(child, kept):
        new, extra, label = again(child, kept)
        if isinstance(extra, Genome):  # crossed with a sibling: its parents
            extra = made.get(id(extra), (None, Origin(name)))[1].parents
        old = made.get(id(child), (None, Origin(name)))[1]
        parents_ = tuple(sorted(set(old.parents) | set(extra)))
        made[id(new)] = (new, Origin(old.operator if label is None else f"{old.operator}+{label}", parents_))
        return new

    def rescue(child):
        new, label = mutate(child)
        old = made.get(id(child), (None, Origin(name)))[1]
        made[id(new)] = (new, Origin(f"{old.operator}+{label}", old.parents))
        rescued.add(id(new))
        return new
    try:
        kids = distinct_children(parents, children(), len(population) - len(parents),
                                 again=redo if again is not None else None,
                                 mutate=rescue if mutate is not None else None)
    except Exception as e:  # a student's operator: report, keep the gallery alive
        return f"{name} failed: {type(e).__name__}: {e}"
    origins = [Origin("kept", (i,)) for i in sel]
    origins += [made.get(id(k), (k, Origin(name)))[1] for k in kids]
    return list(parents) + list(kids), origins, sum(id(k) in rescued for k in kids)


#: What the library's operators make, for the status line ("too few distinct crossings").
_NOUNS = {"crossover": "crossings", "random_copy": "random copies", "random_interpolation": "interpolations",
          "transposition": "transpositions", "root_transposition": "root transpositions",
          "substitution": "substitutions", "head_tail_rotation": "head/tail rotations"}


def breed(action: str, population: list, sel: list, rng: np.random.Generator, mutations: Mapping[str, Callable],
          recombinations: Mapping[str, Callable]) -> tuple | str:
    """The generation ``(population, origins, message)`` that ``action`` (a mutation's or a
    recombination's name in ``mutations`` / ``recombinations``, or ``"evolve"``: a random
    operator per child, recombination too when two or more are selected) breeds from
    ``population`` with the pictures ``sel`` selected, drawing from ``rng``; or a message
    saying what failed (a student's operator raised).

    When the parents have too few distinct children by ``action`` for the slots (two siblings
    differing at one chromosome, a tiny coding part), the remaining children are mutated once
    more by a random one of the library's mutations among ``mutations`` (not ``action``; a
    student's operator runs only when its own button is pressed, or evolve), their
    :class:`Origin` says so (``"crossover+substitution"``) and so does the message."""
    parents = [population[i] for i in sel]
    running = [action]  # the operator running now, named if it fails
    library = {id(op) for op in O.MUTATIONS.values()}
    others = tuple(m for m, op in mutations.items() if m != action and id(op) in library)

    def fitting(names, child, first=None):  # (mutant, name): ``first``, or a random one of ``names``; a library
        left = [m for m in names if m != first]  # mutation that does not fit the child (a root transposition of
        while True:                              # heads of one chromosome) gives way to another of them
            name = first if first is not None else left.pop(int(rng.integers(len(left))))
            first, running[0] = None, name
            try:
                return mutations[name](child, rng), name
            except ValueError:
                if not left or id(mutations[name]) not in library:
                    raise

    def mutate(child):  # once more, by another mutation: one that fits the child
        out = fitting(others, child)
        running[0] = action
        return out
    if action in mutations:  # parents stay; the rest are children by this mutation
        op = mutations[action]
        count = iter(range(10**9))

        def make():
            j = sel[next(count) % len(sel)]
            return op(population[j], rng), Origin(action, (j,))

        def again(c, kept):
            return op(c, rng), (), None
        message = f"{action} of {len(sel)} parent{'s' if len(sel) > 1 else ''}"
        why = f"the parent{'s have' if len(sel) > 1 else ' has'} too few distinct {{noun}} for {{n}} children"
    elif action in recombinations:  # parents stay; children of random parent pairs
        op = recombinations[action]
        pending: list = []

        def make():
            if not pending:
                i, j = rng.choice(len(sel), size=2, replace=False)
                pair = op(population[sel[i]], population[sel[j]], rng)
                pending.extend((c, Origin(action, (sel[i], sel[j]))) for c in pair)
            return pending.pop(0)

        def again(child, kept):  # crossed once more, with a parent or a sibling kept so far
            mates = [(p, (i,)) for i, p in zip(sel, parents)] + [(k, k) for k in kept]
            mate, extra = mates[int(rng.integers(len(mates)))]
            return op(child, mate, rng)[0], extra, None
        message = f"{action} of {len(sel)} parents"
        why = "the parents differ too little for {n} distinct {noun}"
    elif action == "evolve":
        ops = [(name, op, False) for name, op in mutations.items()]
        if len(sel) > 1:
            ops += [(name, op, True) for name, op in recombinations.items()]

        def make():
            name, op, pair = ops[int(rng.integers(len(ops)))]
            running[0] = name
            if pair:
                i, j = rng.choice(len(sel), size=2, replace=False)
                kids = op(population[sel[i]], population[sel[j]], rng)
                return kids[int(rng.integers(2))], Origin(name, (sel[i], sel[j]))
            j = sel[int(rng.integers(len(sel)))]
            kid, name = fitting(mutations, population[j], first=name)
            return kid, Origin(name, (j,))

        def again(child, kept):  # one more mutation
            kid, name = fitting(mutations, child)
            return kid, (), name
        message = "mixed operators"
        running[0] = ops[0][0]
    else:
        raise ValueError(f"action: {action!r} is not one of the operators {[*mutations, *recombinations]} or 'evolve'")
    redraw = None if action == "evolve" and not mutations else again
    rescue = mutate if action != "evolve" and others else None
    out = _children(action, make, redraw, rescue, population, sel)
    if isinstance(out, str):
        return out.replace(f"{action} failed", f"{running[0]} failed", 1)
    population, origins, rescued = out
    if rescued:
        n = len(population) - len(sel)
        noun = _NOUNS.get(action, f"children by {action.replace('_', ' ')}")
        message += f"; {rescued} of {n} children mutated once more: " + why.format(n=n, noun=noun)
    return population, origins, message
