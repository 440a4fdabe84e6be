"""A gallery session without widgets: population, selection, history, lineage (paper sections 3.3, 3.4).

In the paper's GUI (Figure 10) the user picks pictures and one of the seven operators; the
rest of the screen is bred from the picks. :class:`Evolution` is that loop as a plain Python
object (the widgets of :mod:`.gallery` only mirror it): every action returns a message for the
user, and :meth:`Evolution.why_not` says why an action does not fit the selection (the widget
disables its button and shows the reason).

:class:`GalleryState` is what a session is: the population, the selection in click order, the
earlier generations (undo) and the undone ones (redo), each with the :class:`Origin` of every
picture (the operator and the parents, indices into the generation before), from which
:meth:`Evolution.lineage` rebuilds the picks and operators that made a picture. The random
generator's state is part of the session: a resumed session continues exactly as the original
would have.

Every breeding action is ``commit(prepare(action))``: :meth:`Evolution.prepare` breeds the new
generation from a copy of the random generator without changing the session, and
:meth:`Evolution.commit` makes it happen if the session is still the one it was bred from. The
gallery uses the split to breed ahead, in a thread, while the student chooses.

Sessions are saved as JSON (``coursekit.gallery/2``; ``coursekit.gallery/1`` files, which had
no origins, redo or random state, still load). :meth:`GalleryState.from_dict` checks every
field (types, indices, sizes) and names the bad one, so a broken file is refused before
anything overwrites it.

No slot is wasted (:mod:`.variety`): a random population is never flat, black or one colour, and a child
whose preview looks like a parent's or another child's is bred again.
"""

from __future__ import annotations

import contextlib
import copy
import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Mapping, NamedTuple

import numpy as np

from coursekit.atomic import atomic_write

from . import operators as O
from . import primitives as P
from .genome import Genome
from .breeding import Origin, Prepared, breed
from .variety import random_population

__all__ = ["GALLERY_FORMAT", "Origin", "Generation", "Ancestor", "GalleryState", "Evolution", "Prepared"]

GALLERY_FORMAT = "coursekit.gallery/2"
_OLD_FORMATS = ("coursekit.gallery/1",)
_BIT_GENERATORS = ("PCG64", "PCG64DXSM", "MT19937", "Philox", "SFC64")


START = Origin("start")


class Generation(NamedTuple):
    """One screen of the session: its pictures, what was selected, and how each was made."""

    population: list
    selected: list
    origins: list


@dataclass(frozen=True)
class Ancestor:
    """A picture of :meth:`Evolution.lineage`: ``generation`` number, ``index`` in it, the
    ``genome``, the ``operator`` that made it and its ``parents`` (indices in generation - 1)."""

    generation: int
    index: int
    genome: Genome
    operator: str
    parents: tuple[int, ...]


def _genome_json(g: Genome) -> str:
    """``json.dumps(g.to_dict())``, kept with the genome (made again after a primitive is
    redefined: the dict holds the expression, which names the primitives)."""
    cached = g.__dict__.get("_json")
    if cached is None or cached[0] != P.REDEFINED:
        cached = (P.REDEFINED, json.dumps(g.to_dict()))
        object.__setattr__(g, "_json", cached)
    return cached[1]


def _is_int(v) -> bool:
    return isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_))


def _check_selection(sel, n: int, where: str) -> list[int]:
    if not isinstance(sel, list):
        raise ValueError(f"gallery: {where} = {sel!r} must be a list of picture indices")
    for k, i in enumerate(sel):
        if not _is_int(i) or not 0 <= i < n:
            raise ValueError(f"gallery: {where}[{k}] = {i!r} is not a picture index (an integer 0..{n - 1})")
    if len(set(sel)) != len(sel):
        raise ValueError(f"gallery: {where} = {sel!r} selects a picture twice")
    return [int(i) for i in sel]


def _check_origins(origins, n: int, where: str) -> list[Origin]:
    if not isinstance(origins, list) or len(origins) != n:
        raise ValueError(f"gallery: {where} must be a list of {n} origins (one per picture)")
    for k, o in enumerate(origins):
        if not isinstance(o, Origin) or not isinstance(o.operator, str):
            raise ValueError(f"gallery: {where}[{k}] = {o!r} is not an Origin")
        for j, p in enumerate(o.parents):
            if not _is_int(p) or not 0 <= p < n:
                raise ValueError(f"gallery: {where}[{k}].parents[{j}] = {p!r} is not a picture index "
                                 f"(an integer 0..{n - 1})")
    return origins


@dataclass
class GalleryState:
    """Population, selection (in click order), earlier generations (``history``, oldest
    first), undone ones (``future``, the next redo last), the :class:`Origin` of every
    picture, the generation number and the random generator's state (``rng_state``)."""

    population: list[Genome]
    selected: list[int] = field(default_factory=list)
    history: list[Generation] = field(default_factory=list)
    generation: int = 0
    future: list[Generation] = field(default_factory=list)
    origins: list[Origin] | None = None
    rng_state: dict | None = None

    def __post_init__(self):
        if isinstance(self.population, (str, bytes)) or not hasattr(self.population, "__iter__"):
            raise TypeError(f"gallery: population must be a non-empty list of genomes, got {type(self.population).__name__}")
        self.population = list(self.population)
        if self.origins is None:
            self.origins = [START] * len(self.population)
        self.history = [Generation(*h) if len(h) == 3 else Generation(h[0], h[1], [START] * len(h[0]))
                        for h in self.history]
        self.future = [Generation(*h) for h in self.future]
        self.check()

    @property
    def first_generation(self) -> int:
        """The number of ``history[0]`` (older generations were dropped)."""
        return self.generation - len(self.history)

    def check(self) -> None:
        """ValueError naming the first field that is not a valid session."""
        pop = self.population
        if not isinstance(pop, list) or not pop:
            raise ValueError("gallery: population must be a non-empty list of genomes")
        n = len(pop)
        for k, g in enumerate(pop):
            if not isinstance(g, Genome):
                raise ValueError(f"gallery: population[{k}] is a {type(g).__name__}, not a Genome")
        self.selected = _check_selection(self.selected, n, "selected")
        self.origins = _check_origins(self.origins, n, "origins")
        if not _is_int(self.generation) or self.generation < len(self.history):
            raise ValueError(f"gallery: generation = {self.generation!r} must be an integer >= "
                             f"{len(self.history)} (the number of earlier generations kept)")
        self.generation = int(self.generation)
        for name, steps in (("history", self.history), ("future", self.future)):
            for k, (p, s, o) in enumerate(steps):
                if not isinstance(p, list) or len(p) != n:
                    raise ValueError(f"gallery: {name}[{k}].population must be a list of {n} genomes "
                                     f"(the size of the gallery)")
                for j, g in enumerate(p):
                    if not isinstance(g, Genome):
                        raise ValueError(f"gallery: {name}[{k}].population[{j}] is a {type(g).__name__}, "
                                         f"not a Genome")
                _check_selection(s, n, f"{name}[{k}].selected")
                _check_origins(o, n, f"{name}[{k}].origins")
        if self.rng_state is not None:
            _generator(self.rng_state)

    # ---- files ----------------------------------------------------------------------------
    def to_dict(self) -> dict:
        """JSON-ready dict (``"format": "coursekit.gallery/2"``)."""
        def gen(g: Generation):
            return {"population": [x.to_dict() for x in g.population], "selected": list(g.selected),
                    "origins": [o.to_dict() for o in g.origins]}
        d = {"format": GALLERY_FORMAT, "generation": self.generation, **gen(self.current),
             "history": [gen(h) for h in self.history], "future": [gen(f) for f in self.future]}
        if self.rng_state is not None:
            d["rng"] = self.rng_state
        return d

    def to_json(self) -> str:
        """``json.dumps(self.to_dict())``, byte for byte, made quickly enough to autosave on every
        click: each genome's text is made once and kept with it (genomes are immutable, and a
        session's history repeats them at every save: 600 genomes after 30 generations of 20
        took 40-60 ms a save to turn into dicts and dump, the autosave most of a click's time)."""
        d = json.dumps

        def body(g: Generation) -> str:
            return (f'"population": [{", ".join(map(_genome_json, g.population))}], "selected": {d(list(g.selected))}, '
                    f'"origins": {d([o.to_dict() for o in g.origins])}')

        def gens(items) -> str:
            return ", ".join("{" + body(g) + "}" for g in items)
        text = (f'{{"format": {d(GALLERY_FORMAT)}, "generation": {d(self.generation)}, {body(self.current)}, '
                f'"history": [{gens(self.history)}], "future": [{gens(self.future)}]')
        if self.rng_state is not None:
            text += f', "rng": {d(self.rng_state)}'
        return text + "}"

    @property
    def current(self) -> Generation:
        return Generation(self.population, self.selected, self.origins)

    @classmethod
    def from_dict(cls, d: dict) -> GalleryState:
        """Inverse of :meth:`to_dict`: every field checked, ValueError naming the bad one."""
        if not isinstance(d, dict):
            raise ValueError(f"gallery: expected a JSON object, got {type(d).__name__}")
        fmt = d.get("format")
        if fmt != GALLERY_FORMAT and fmt not in _OLD_FORMATS:
            raise ValueError(f"gallery: format {fmt!r} is not {GALLERY_FORMAT!r}")
        for key in ("generation", "population", "selected", "history"):
            if key not in d:
                raise ValueError(f"gallery: the field {key!r} is missing")

        def genomes(v, where):
            if not isinstance(v, list) or not v:
                raise ValueError(f"gallery: {where} must be a non-empty list of genomes")
            out = []
            for k, g in enumerate(v):
                try:
                    out.append(Genome.from_dict(g))
                except ValueError as e:
                    raise ValueError(f"gallery: {where}[{k}]: {e}") from None
            return out

        def origins(v, n, where):
            if v is None:
                return [START] * n
            if not isinstance(v, list):
                raise ValueError(f"gallery: {where} must be a list of origins")
            out = []
            for k, o in enumerate(v):
                if (not isinstance(o, dict) or not isinstance(o.get("operator"), str)
                        or not isinstance(o.get("parents"), list)):
                    raise ValueError(f"gallery: {where}[{k}] = {o!r} is not "
                                     f"{{'operator': name, 'parents': [indices]}}")
                out.append(Origin(o["operator"], tuple(o["parents"])))
            return out

        def generation(h, where):
            if not isinstance(h, dict):
                raise ValueError(f"gallery: {where} must be an object with 'population' and 'selected'")
            pop = genomes(h.get("population"), f"{where}.population")
            return Generation(pop, h.get("selected"), origins(h.get("origins"), len(pop), f"{where}.origins"))

        pop = genomes(d["population"], "population")
        steps = {}
        for name in ("history", "future"):
            v = d.get(name, [])
            if not isinstance(v, list):
                raise ValueError(f"gallery: {name} must be a list of generations")
            steps[name] = [generation(h, f"{name}[{k}]") for k, h in enumerate(v)]
        return cls(pop, d["selected"], steps["history"], d["generation"], steps["future"],
                   origins(d.get("origins"), len(pop), "origins"), d.get("rng"))

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> GalleryState:
        """Read and check a session file; ValueError naming the file and the bad field."""
        path = Path(path)
        try:
            d = json.loads(path.read_text(encoding="utf-8"))
        except (json.JSONDecodeError, UnicodeDecodeError, RecursionError) as e:
            raise ValueError(f"path: {str(path)!r} is not a gallery session ({type(e).__name__}: {e})") from None
        try:
            return cls.from_dict(d)
        except ValueError as e:
            raise ValueError(f"path: {str(path)!r}: {e}") from None


def _generator(state) -> np.random.Generator:
    """A Generator in the saved ``bit_generator.state``; ValueError naming the field."""
    name = state.get("bit_generator") if isinstance(state, dict) else None
    if name not in _BIT_GENERATORS:
        raise ValueError(f"gallery: rng = {state!r} is not a saved random state "
                         f"(its bit_generator must be one of {', '.join(_BIT_GENERATORS)})")
    bg = getattr(np.random, name)()
    try:
        bg.state = state
    except (TypeError, ValueError, KeyError, OverflowError) as e:
        raise ValueError(f"gallery: rng: broken {name} state ({e})") from None
    return np.random.Generator(bg)


def options(name: str, value: Mapping | None, what: str) -> Mapping:
    """``value`` (``{}`` for None) when it is a mapping; a TypeError naming ``name`` otherwise."""
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise TypeError(f"{name}: expected a dict of {what}, got {type(value).__name__}")
    return value


class Evolution:
    """The gallery's logic without widgets: every action returns a message for the user.

    Args:
        state: the session.
        rng: the random generator; default: the one saved in ``state`` (a resumed session
            then continues as the original would have), else a fresh one.
        mutations, recombinations: ``{name: operator}``; default the paper's seven.
        genome_params: keyword arguments of :meth:`Genome.random` for random pictures.
        autosave: JSON file the session is written to after every change (atomically).
        max_history: earlier generations kept for undo.
    """

    def __init__(self, state: GalleryState, rng: np.random.Generator | None = None, *,
                 mutations: Mapping[str, Callable] | None = None, recombinations: Mapping[str, Callable] | None = None,
                 genome_params: Mapping | None = None, autosave: str | os.PathLike[str] | None = None,
                 max_history: int = 50) -> None:
        if rng is None:
            rng = _generator(state.rng_state) if state.rng_state is not None else np.random.default_rng()
        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"rng: expected numpy.random.Generator, got {type(rng).__name__}")
        state.check()
        self.state, self.rng = state, rng
        self.mutations = dict(O.MUTATIONS if mutations is None else options("mutations", mutations, "{name: operator}"))
        self.recombinations = dict(O.RECOMBINATIONS if recombinations is None else
                                   options("recombinations", recombinations, "{name: operator}"))
        for kind, ops in (("mutations", self.mutations), ("recombinations", self.recombinations)):
            for name, op in ops.items():
                if not callable(op):
                    raise TypeError(f"{kind}[{name!r}]: expected an operator function, got {type(op).__name__}")
        clash = set(self.mutations) & set(self.recombinations)
        if clash:
            raise ValueError(f"recombinations: {sorted(clash)} are also mutations' names")
        self.genome_params = dict(options("genome_params", genome_params, "Genome.random options"))
        if autosave is not None and not isinstance(autosave, (str, os.PathLike)):
            raise TypeError(f"autosave: expected the path of a JSON file, got {type(autosave).__name__}")
        self.autosave = Path(autosave) if autosave is not None else None
        self.max_history = max_history
        self._held = None  # inside saved_after(): whether a save is waiting
        self.save()

    @property
    def size(self) -> int:
        return len(self.state.population)

    def save(self) -> None:
        """Write the session (with the random state) to the autosave file, if one was given
        (inside :meth:`saved_after`, at its end)."""
        if self._held is not None:
            self._held = True
            return
        self.state.rng_state = self.rng.bit_generator.state
        if self.autosave is not None:
            atomic_write(self.autosave, self.state.to_json())

    @contextlib.contextmanager
    def saved_after(self):
        """The saves of the block made once, when it ends (also when it fails): the gallery puts a
        click's pictures on screen first and writes the file after (a save of a long session takes
        a few ms)."""
        if self._held is not None:  # nested: the outer block saves
            yield
            return
        self._held = False
        try:
            yield
        finally:
            waiting, self._held = self._held, None
            if waiting:
                self.save()

    # ---- selection ------------------------------------------------------------------------
    def select(self, i: int, on: bool | None = None) -> str:
        """Toggle (or set) the selection of picture ``i``."""
        if not _is_int(i) or not 0 <= i < self.size:
            raise ValueError(f"i: {i!r} is not a picture index (0..{self.size - 1})")
        sel = self.state.selected
        on = (i not in sel) if on is None else on
        if on and i not in sel:
            sel.append(int(i))
        elif not on and i in sel:
            sel.remove(i)
        self.save()
        return self.why_not("evolve") or "choose an operator"

    def clear_selection(self) -> str:
        self.state.selected.clear()
        self.save()
        return "selection cleared"

    def why_not(self, action: str) -> str | None:
        """Why ``action`` (an operator's name, ``"evolve"``, ``"undo"``, ``"redo"``, ``"new
        random"``) does not fit now, or None when it does."""
        return self._why_not(action, len(self.state.selected))

    def _why_not(self, action: str, k: int) -> str | None:
        """:meth:`why_not` with ``k`` pictures selected."""
        n = self.size
        if action in self.mutations or action == "evolve":
            if k == 0:
                return "select a picture to breed from (click it)"
        elif action in self.recombinations:
            if k < 2:
                return f"select {2 - k} more picture{'s' if k == 0 else ''} to recombine"
        elif action == "undo":
            return None if self.state.history else "nothing to undo"
        elif action == "redo":
            return None if self.state.future else "nothing to redo"
        elif action == "new random":
            return None
        else:
            raise ValueError(f"action: {action!r} is not an operator, 'evolve', 'undo', 'redo' or 'new random'")
        if k >= n:
            return f"unselect a picture: all {n} are kept, which leaves no room for children"
        return None

    # ---- breeding -------------------------------------------------------------------------
    def prepare(self, action: str) -> Prepared:
        """What the breeding ``action`` (an operator's name or ``"evolve"``) would make now,
        bred without changing the session: the random generator is copied, the population and
        the selection are read once. :meth:`commit` then makes it happen, exactly as the action
        would have (every breeding action is ``commit(prepare(action))``). The gallery breeds
        ahead this way, in a thread, while the student is still choosing."""
        if action != "evolve" and action not in self.mutations and action not in self.recombinations:
            raise ValueError(f"action: {action!r} is not an operator or 'evolve'")
        s = self.state
        population, selected, generation = tuple(s.population), tuple(s.selected), s.generation
        rng = copy.deepcopy(self.rng)
        before = rng.bit_generator.state
        outcome = self._why_not(action, len(selected))
        if outcome is None:
            outcome = breed(action, list(population), list(selected), rng, self.mutations, self.recombinations)
            if not isinstance(outcome, str):
                outcome = (*outcome[:2], f"generation {generation + 1}: {outcome[2]}")
        return Prepared(action, population, selected, before, rng.bit_generator.state, self._operators(), outcome)

    def commit(self, prepared: Prepared) -> str:
        """Make a prepared action (:meth:`prepare`) happen: the new generation (or the reason it
        could not be bred), and the random state it left. A ``prepared`` from another state (the
        selection changed since, say) raises a ValueError: prepare again."""
        if not prepared.fits(self):
            raise ValueError("prepared: it was bred from another state of the session (the population, "
                             "the selection, the random state or the operators changed since); prepare it again")
        self.rng.bit_generator.state = prepared.rng_after
        if isinstance(prepared.outcome, str):
            return prepared.outcome
        return self._commit(*prepared.outcome)

    def _operators(self) -> tuple:
        return tuple(self.mutations.items()), tuple(self.recombinations.items())

    def _commit(self, population: list, origins: list[Origin], message: str) -> str:
        bad = [type(g).__name__ for g in population if not isinstance(g, Genome)]
        if bad:
            return f"the operator returned {bad[0]}, not a Genome: nothing changed"
        s = self.state
        s.history.append(s.current)
        del s.history[: max(0, len(s.history) - self.max_history)]
        s.future.clear()
        s.population, s.selected, s.origins = list(population), [], list(origins)
        s.generation += 1
        self.save()
        return message

    def mutate(self, name: str) -> str:
        """Parents (the selection) stay; the rest are children by mutation ``name``, none
        looking like a parent or another child (:func:`~.variety.distinct_children`)."""
        if name not in self.mutations:
            raise ValueError(f"name: {name!r} is not one of the mutations {list(self.mutations)}")
        return self.commit(self.prepare(name))

    def recombine(self, name: str) -> str:
        """Parents stay; the rest are children of random parent pairs by ``name``, none looking
        like a parent or another child (:func:`~.variety.distinct_children`)."""
        if name not in self.recombinations:
            raise ValueError(f"name: {name!r} is not one of the recombinations {list(self.recombinations)}")
        return self.commit(self.prepare(name))

    def next_generation(self) -> str:
        """Evolve: children by a random operator each (recombination too when two or more are
        selected)."""
        return self.commit(self.prepare("evolve"))

    def randomize(self) -> str:
        """A new random population (the old one goes to the history), none flat, black or one colour."""
        pop = random_population(self.rng, self.size, **self.genome_params)
        return self._commit(pop, [Origin("random")] * len(pop), "new random population")

    # ---- undo, redo, branch ---------------------------------------------------------------
    def undo(self) -> str:
        """Back to the previous generation (any number of steps; redo goes forward again)."""
        if not self.state.history:
            return "nothing to undo"
        self._back()
        self.save()
        return f"back to generation {self.state.generation}"

    def _back(self) -> None:
        """One generation back, not yet saved."""
        s = self.state
        s.future.append(s.current)
        s.population, s.selected, s.origins = s.history.pop()
        s.generation -= 1

    def redo(self) -> str:
        """Forward again to the generation the last undo left."""
        s = self.state
        if not s.future:
            return "nothing to redo"
        s.history.append(s.current)
        s.population, s.selected, s.origins = s.future.pop()
        s.generation += 1
        self.save()
        return f"forward to generation {s.generation}"

    def branch(self, generation: int, index: int) -> str:
        """Go back to ``generation`` (undo, so redo returns) with only picture ``index`` of it
        selected: the next operator breeds a new branch from that ancestor."""
        s = self.state
        if not _is_int(generation) or not s.first_generation <= generation <= s.generation:
            raise ValueError(f"generation: {generation!r} is not a generation kept in the session "
                             f"({s.first_generation}..{s.generation})")
        if not _is_int(index) or not 0 <= index < self.size:
            raise ValueError(f"index: {index!r} is not a picture index (0..{self.size - 1})")
        while s.generation > generation:
            self._back()
        s.selected[:] = [int(index)]
        self.save()  # once: the autosave never holds a branch half made
        return f"branch from generation {generation}, picture #{index}: choose an operator"

    def lineage(self, i: int) -> list[Ancestor]:
        """The pictures that made picture ``i``: itself, then its parents, their parents ...,
        newest generation first, as far back as the history goes. A picture kept from the
        generation before is followed to its first appearance (its origin there)."""
        if not _is_int(i) or not 0 <= i < self.size:
            raise ValueError(f"i: {i!r} is not a picture index (0..{self.size - 1})")
        s = self.state
        steps = s.history + [s.current]
        out: list[Ancestor] = []
        wanted = {int(i)}
        for back in range(len(steps) - 1, -1, -1):
            gen, number = steps[back], s.generation - (len(steps) - 1 - back)
            nxt: set[int] = set()
            for j in sorted(wanted):
                o = gen.origins[j]
                if o.operator == "kept" and back > 0:
                    nxt.update(o.parents)  # the same picture one generation earlier
                    continue
                out.append(Ancestor(number, j, gen.population[j], o.operator, tuple(o.parents)))
                if back > 0:
                    nxt.update(o.parents)
            wanted = nxt
            if not wanted:
                break
        return out
