"""Interactive gallery where the user is the fitness function (paper sections 3.3 and 3.4).

The paper's Qt GUI (Figure 10) lets the user pick pictures and choose one of the four
mutations or three recombinations. :class:`GalleryState` is that evolution as a plain Python
object - population, selection, history - with no widgets; :class:`Gallery` mirrors it in
ipywidgets: a grid of thumbnails you click to select (clicks on the pictures arrive through
``ipyevents``, since ``ipywidgets.Image`` has no click events; a toggle under each picture does
the same), one button per operator, "next generation", "undo" and "new random". Every change is
autosaved atomically to a JSON file (``coursekit.gallery/1``) when a path is given.

Operators are parameters: pass your own ``transposition(genome, rng)`` (or any of the seven)
in ``mutations=`` / ``recombinations=`` and the gallery breeds with it.

No slot is wasted (:mod:`.variety`): a random population is never flat or black, and a child
whose 32 x 32 preview looks like a parent's or another child's (mean difference below 1/255)
is bred again (a bounded number of times, from the session's ``rng``).
"""

from __future__ import annotations

from coursekit.atomic import atomic_write

import io
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Mapping

import numpy as np

from . import operators as O
from .evaluate import render
from .genome import Genome
from .variety import distinct_children, random_population

__all__ = ["GalleryState", "Evolution", "Gallery", "GALLERY_FORMAT", "png_bytes"]

GALLERY_FORMAT = "coursekit.gallery/1"


@dataclass
class GalleryState:
    """Population, selection (in click order) and history of earlier generations."""

    population: list[Genome]
    selected: list[int] = field(default_factory=list)
    history: list[tuple[list[Genome], list[int]]] = field(default_factory=list)
    generation: int = 0

    def to_dict(self) -> dict:
        """JSON-ready dict (``"format": "coursekit.gallery/1"``)."""
        return {"format": GALLERY_FORMAT, "generation": self.generation, "selected": list(self.selected),
                "population": [g.to_dict() for g in self.population],
                "history": [{"population": [g.to_dict() for g in pop], "selected": list(sel)}
                            for pop, sel in self.history]}

    @classmethod
    def from_dict(cls, d) -> "GalleryState":
        """Inverse of :meth:`to_dict`; ValueError for foreign or malformed sessions."""
        if not isinstance(d, dict) or d.get("format") != GALLERY_FORMAT:
            got = d.get("format") if isinstance(d, dict) else type(d).__name__
            raise ValueError(f"gallery: format {got!r} is not {GALLERY_FORMAT!r}")
        try:
            pop = [Genome.from_dict(g) for g in d["population"]]
            hist = [([Genome.from_dict(g) for g in h["population"]], [int(i) for i in h["selected"]])
                    for h in d["history"]]
            state = cls(pop, [int(i) for i in d["selected"]], hist, int(d["generation"]))
        except (KeyError, TypeError) as e:
            raise ValueError(f"gallery: missing or malformed field ({e})") from None
        if any(not 0 <= i < len(pop) for i in state.selected):
            raise ValueError(f"gallery: selected {state.selected} out of range for {len(pop)} pictures")
        return state


class Evolution:
    """The gallery's logic without widgets: every action returns a message for the user."""

    def __init__(self, state: GalleryState, rng: np.random.Generator, *,
                 mutations: Mapping[str, Callable] | None = None,
                 recombinations: Mapping[str, Callable] | None = None,
                 genome_params: Mapping | None = None, autosave=None, max_history: int = 50):
        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"rng: expected numpy.random.Generator, got {type(rng).__name__}")
        self.state, self.rng = state, rng
        self.mutations = dict(O.MUTATIONS if mutations is None else mutations)
        self.recombinations = dict(O.RECOMBINATIONS if recombinations is None else recombinations)
        self.genome_params = dict(genome_params or {})
        self.autosave = Path(autosave) if autosave is not None else None
        self.max_history = max_history
        self.save()

    @property
    def size(self) -> int:
        return len(self.state.population)

    def save(self) -> None:
        """Write the session to the autosave file (atomically), if one was given."""
        if self.autosave is not None:
            atomic_write(self.autosave, json.dumps(self.state.to_dict()))

    def select(self, i: int, on: bool | None = None) -> str:
        """Toggle (or set) the selection of picture ``i``."""
        if not 0 <= i < self.size:
            raise ValueError(f"i: {i} is not a picture index (0..{self.size - 1})")
        sel = self.state.selected
        on = (i not in sel) if on is None else on
        if on and i not in sel:
            sel.append(i)
        elif not on and i in sel:
            sel.remove(i)
        self.save()
        return f"{len(sel)} selected"

    def _commit(self, population: list[Genome], message: str) -> str:
        bad = [type(g).__name__ for g in population if not isinstance(g, Genome)]
        if bad:
            return f"the operator returned {bad[0]}, not a Genome: nothing changed"
        s = self.state
        s.history.append((s.population, s.selected))
        del s.history[: max(0, len(s.history) - self.max_history)]
        s.population, s.selected, s.generation = population, [], s.generation + 1
        self.save()
        return message

    def _parents(self) -> list[Genome]:
        return [self.state.population[i] for i in self.state.selected]

    def mutate(self, name: str) -> str:
        """Parents (the selection) stay; the rest are children by mutation ``name``, none
        looking like a parent or another child (:func:`~.variety.distinct_children`)."""
        parents = self._parents()
        if not parents:
            return "select at least one picture to mutate"
        op = self.mutations[name]

        def children():
            k = len(parents)
            while True:
                yield op(parents[k % len(parents)], self.rng)
                k += 1
        try:
            pop = list(parents) + distinct_children(parents, children(), self.size - len(parents),
                                                    again=lambda c, kept: op(c, self.rng))
        except Exception as e:  # a student's operator: report, keep the gallery alive
            return f"{name} failed: {type(e).__name__}: {e}"
        return self._commit(pop, f"generation {self.state.generation + 1}: {name} of {len(parents)} parent(s)")

    def recombine(self, name: str) -> str:
        """Parents stay; the rest are children of random parent pairs by ``name``, none looking
        like a parent or another child (:func:`~.variety.distinct_children`)."""
        parents = self._parents()
        if len(parents) < 2:
            return "select at least two pictures to recombine"
        op = self.recombinations[name]

        def children():
            while True:
                i, j = self.rng.choice(len(parents), size=2, replace=False)
                yield from op(parents[i], parents[j], self.rng)

        def again(child, kept):  # crossed once more, with a parent or a sibling kept so far
            mates = list(parents) + kept
            return op(child, mates[int(self.rng.integers(len(mates)))], self.rng)[0]
        try:
            pop = list(parents) + distinct_children(parents, children(), self.size - len(parents),
                                                    again=again)
        except Exception as e:
            return f"{name} failed: {type(e).__name__}: {e}"
        return self._commit(pop[: self.size], f"generation {self.state.generation + 1}: {name} of "
                                              f"{len(parents)} parents")

    def next_generation(self) -> str:
        """Children by a random operator each: recombination when two or more are selected."""
        parents = self._parents()
        if not parents:
            return "select at least one picture"
        ops = [(name, op, False) for name, op in self.mutations.items()]
        if len(parents) > 1:
            ops += [(name, op, True) for name, op in self.recombinations.items()]
        name = ops[0][0]

        def children():
            nonlocal name
            while True:
                name, op, pair = ops[int(self.rng.integers(len(ops)))]
                if pair:
                    i, j = self.rng.choice(len(parents), size=2, replace=False)
                    yield op(parents[i], parents[j], self.rng)[int(self.rng.integers(2))]
                else:
                    yield op(parents[int(self.rng.integers(len(parents)))], self.rng)

        def again(child, kept):  # one more mutation
            return list(self.mutations.values())[int(self.rng.integers(len(self.mutations)))](child, self.rng)
        try:
            pop = list(parents) + distinct_children(parents, children(), self.size - len(parents),
                                                    again=again if self.mutations else None)
        except Exception as e:
            return f"{name} failed: {type(e).__name__}: {e}"
        return self._commit(pop, f"generation {self.state.generation + 1}: mixed operators")

    def randomize(self) -> str:
        """A new random population (the old one goes to the history), none flat or black."""
        pop = random_population(self.rng, self.size, **self.genome_params)
        return self._commit(pop, "new random population")

    def undo(self) -> str:
        """Back to the previous generation (any number of steps)."""
        s = self.state
        if not s.history:
            return "nothing to undo"
        s.population, s.selected = s.history.pop()
        s.generation -= 1
        self.save()
        return f"back to generation {s.generation}"


def png_bytes(image: np.ndarray) -> bytes:
    """Encode an (H, W, 3) float image in [0, 1] as PNG."""
    from PIL import Image as PILImage

    buf = io.BytesIO()
    PILImage.fromarray(np.round(image * 255).astype(np.uint8)).save(buf, format="PNG")
    return buf.getvalue()


class Gallery:
    """The clickable gallery (ipywidgets); ``gallery.widget`` is what to display.

    Args:
        rng: the random generator (the session is reproducible from its seed).
        population: starting genomes (default: ``n`` random ones, none flat or black:
            :func:`~coursekit.pictures.variety.random_population`).
        n: number of pictures (default 20, Sims' 4 x 5).
        columns: thumbnails per row.
        size: thumbnail size in pixels.
        mutations, recombinations: ``{name: operator}``; defaults are the paper's seven. Pass
            your own functions to breed with them.
        genome_params: keyword arguments of :meth:`Genome.random` for random pictures.
        autosave: JSON file the session is written to after every change (atomically).
        render_options: extra keyword arguments of :func:`render` (window, time, device).
    """

    def __init__(self, rng: np.random.Generator, population=None, *, n: int = 20, columns: int = 5,
                 size: int = 96, mutations=None, recombinations=None, genome_params=None,
                 autosave=None, render_options=None):
        import ipywidgets as W

        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"rng: expected numpy.random.Generator, got {type(rng).__name__}")
        genome_params = dict(genome_params or {})
        if population is None:
            if isinstance(n, bool) or not isinstance(n, int) or n < 2:
                raise ValueError(f"n: {n!r} must be an integer >= 2")
            population = random_population(rng, n, **genome_params)
        state = population if isinstance(population, GalleryState) else GalleryState(list(population))
        self.evolution = Evolution(state, rng, mutations=mutations, recombinations=recombinations,
                                   genome_params=genome_params, autosave=autosave)
        self.size = size
        self.render_options = dict(render_options or {})
        self._syncing = False

        from ipyevents import Event

        self.images, self.toggles, self._clicks = [], [], []
        for i in range(self.evolution.size):
            im = W.Image(format="png", layout=W.Layout(width=f"{size}px", height=f"{size}px", border="3px solid transparent"))
            click = Event(source=im, watched_events=["click"], prevent_default_action=True)
            click.on_dom_event(lambda event, i=i: self.click(i))
            self.images.append(im)
            self._clicks.append(click)
            t = W.ToggleButton(description=f"#{i}", layout=W.Layout(width=f"{size}px"))
            t.observe(lambda change, i=i: self._on_toggle(i, change), names="value")
            self.toggles.append(t)
        tiles = [W.VBox([im, t]) for im, t in zip(self.images, self.toggles)]
        self.buttons = {}
        for name in list(self.evolution.mutations) + list(self.evolution.recombinations):
            self.buttons[name] = W.Button(description=name.replace("_", " "))
            self.buttons[name].on_click(lambda b, name=name: self._act(name))
        for name in ("next generation", "undo", "new random"):
            self.buttons[name] = W.Button(description=name, button_style="primary" if name == "next generation" else "")
            self.buttons[name].on_click(lambda b, name=name: self._act(name))
        self.status = W.HTML()
        grid = W.GridBox(tiles, layout=W.Layout(grid_template_columns=f"repeat({columns}, {size + 8}px)"))
        mut = W.HBox([W.Label("mutate:")] + [self.buttons[n] for n in self.evolution.mutations])
        rec = W.HBox([W.Label("recombine:")] + [self.buttons[n] for n in self.evolution.recombinations])
        ctl = W.HBox([self.buttons[n] for n in ("next generation", "undo", "new random")])
        self.widget = W.VBox([grid, mut, rec, ctl, self.status])
        self._sync("select pictures you like, then choose an operator")

    @classmethod
    def load(cls, path, rng: np.random.Generator, **kwargs) -> "Gallery":
        """Resume a session from an autosave file (it keeps autosaving there)."""
        text = Path(path).read_text()
        try:
            d = json.loads(text)
        except json.JSONDecodeError as e:
            raise ValueError(f"path: {str(path)!r} is not a gallery session ({e})") from None
        kwargs.setdefault("autosave", path)
        return cls(rng, GalleryState.from_dict(d), **kwargs)

    @property
    def state(self) -> GalleryState:
        return self.evolution.state

    def export(self, i: int, path, size=2048) -> Path:
        """Save picture ``i`` at full resolution with its genome (see :func:`save_image`)."""
        from .files import save_image

        if not 0 <= i < self.evolution.size:
            raise ValueError(f"i: {i} is not a picture index (0..{self.evolution.size - 1})")
        return save_image(path, self.state.population[i], size, **self.render_options)

    def _ipython_display_(self):  # pragma: no cover - notebook display
        from IPython.display import display
        display(self.widget)

    def click(self, i: int) -> None:
        """What a click on picture ``i`` does: select it, or unselect it if it was selected."""
        self.toggles[i].value = not self.toggles[i].value

    def _on_toggle(self, i, change):
        if not self._syncing:
            self._sync(self.evolution.select(i, bool(change["new"])), images=False)

    def apply(self, name: str) -> str:
        """What the button ``name`` does (an operator's name, ``"next generation"``, ``"undo"``
        or ``"new random"``), pictures redrawn; returns the status message. Use this (and
        :meth:`click`) to drive the gallery from code: changing ``gallery.evolution`` directly
        changes the session but not the pictures on screen."""
        if name not in self.buttons:
            raise ValueError(f"name: {name!r} is not one of {list(self.buttons)}")
        return self._act(name)

    def _act(self, name):
        ev = self.evolution
        if name in ev.mutations:
            msg = ev.mutate(name)
        elif name in ev.recombinations:
            msg = ev.recombine(name)
        elif name == "next generation":
            msg = ev.next_generation()
        elif name == "undo":
            msg = ev.undo()
        else:
            msg = ev.randomize()
        self._sync(msg)
        return msg

    def _sync(self, message: str, images: bool = True):
        """Mirror the state in the widgets."""
        self._syncing = True
        try:
            s = self.state
            if images:
                pics = render(s.population, self.size, **self.render_options)
                for im, pic in zip(self.images, pics):
                    im.value = png_bytes(pic)
            for i, t in enumerate(self.toggles):
                t.value = i in s.selected
                self.images[i].layout.border = "3px solid #2e7d32" if i in s.selected else "3px solid transparent"
                t.button_style = "success" if i in s.selected else ""
                t.icon = "check" if i in s.selected else ""
            self.status.value = (f"<b>generation {s.generation}</b> &middot; {len(s.selected)} selected "
                                 f"&middot; {message}")
        finally:
            self._syncing = False
