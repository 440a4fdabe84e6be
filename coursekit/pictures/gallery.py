"""Interactive gallery where the user is the fitness function (paper sections 3.3 and 3.4).

The paper's Qt GUI (Figure 10) lets the user pick pictures and choose one of the four
mutations or three recombinations. :class:`Gallery` is that window in ipywidgets, mirroring a
widget-free session (:class:`~.session.Evolution`, :class:`~.session.GalleryState`):

- a grid of thumbnails you click to select (clicks on the pictures arrive through
  ``ipyevents``, since ``ipywidgets.Image`` has no click events; a toggle under each picture
  does the same), in click order, which is the parents' order;
- one button per operator, **evolve** (a random operator per child), **undo**, **redo** and
  **new random**; a button whose action does not fit the selection is disabled, and the line
  under the buttons says why;
- **zoom** and **pan** (the genomes are evaluated over a new window of the plane, never
  enlarged) and a reset;
- the **lineage** of a picture: the picks and operators that made it, generation by
  generation; clicking an ancestor branches from it (back to its generation, it selected);
- **keys** while the mouse is over the gallery: arrows move a cursor, space or enter selects,
  ``e`` evolves, ``u`` undoes, ``y`` redoes, ``l`` shows the lineage, ``+`` / ``-`` zoom,
  shift + arrows pan, ``0`` resets the view, escape clears the selection;
- a status line (generation, selection, view, what the last action did).

**Breeding ahead.** While the student is still looking, the gallery breeds the next generation
for the current selection in a background thread (with the last breeding button pressed,
evolve at first), thumbnails included (:meth:`Evolution.prepare`: the random generator is
copied, nothing in the session changes). Pressing that button then only commits it
(:meth:`Evolution.commit`) and sends the pictures: the session is bit for bit the one the
button would have bred (a test compares). Any other change (a pick, zoom, undo) makes the
prepared generation stale, and it is bred again or not used. Only the library's own operators
are run ahead: a student's operator runs when its button is pressed, and no other time.

Every change is autosaved atomically to a JSON file (:mod:`.session`) when a path is given,
with the random state, so a resumed session continues exactly as the original would have.

Operators are parameters: pass your own ``transposition(genome, rng)`` (or any of the seven)
in ``mutations=`` / ``recombinations=`` and the gallery breeds with it.
"""

from __future__ import annotations

import atexit
import base64
import gc
import html
import io
import os
from collections import OrderedDict
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from contextlib import ExitStack
from pathlib import Path
from typing import Any

import numpy as np

from . import operators as O
from .evaluate import render
from .frame import parse_window
from .genome import Genome
from .session import GALLERY_FORMAT, Ancestor, Evolution, GalleryState, Generation, Origin, options
from .textures import preload
from .variety import random_population

__all__ = ["GalleryState", "Evolution", "Gallery", "GALLERY_FORMAT", "Origin", "Generation", "Ancestor",
           "png_bytes", "thumbnail_bytes", "thumbnail_url", "DEFAULT_WINDOW"]

DEFAULT_WINDOW = (0.0, 0.0, 1.0, 1.0)
_SELECTED, _CURSOR, _PLAIN = "#2e7d32", "#1565c0", "transparent"
_ACTIONS = ("evolve", "undo", "redo", "new random")
_ALIASES = {"next generation": "evolve"}  # the button's name before redo and lineage came
_unfreeze_at_exit = False  # Gallery._freeze_heap has registered gc.unfreeze with atexit
_KEEP = 256  # thumbnails kept: the parents of a generation (and undone ones) are not rendered again


def png_bytes(image: np.ndarray) -> bytes:
    """Encode an (H, W, 3) float image in [0, 1] as PNG."""
    from PIL import Image as PILImage

    buf = io.BytesIO()
    PILImage.fromarray(np.round(image * 255).astype(np.uint8)).save(buf, format="PNG", compress_level=1)
    return buf.getvalue()


def genome_png(genome: Genome) -> bytes:
    """A genome's notebook picture (``Genome._repr_png_``): ``REPR_SIZE`` pixels square, rendered in this process."""
    return png_bytes(render([genome], size=(genome.REPR_SIZE, genome.REPR_SIZE), workers=1)[0])


Genome.picture_png = staticmethod(genome_png)


def thumbnail_bytes(image: np.ndarray) -> bytes:
    """Encode an (H, W, 3) float image in [0, 1] as a thumbnail: JPEG, quality 92, no chroma
    subsampling. Measured on 128^2 random pictures: 0.16 ms and 7.7 kB each, against 1.4 ms
    and 21 kB for PNG (fastest compression), which noise-like pictures hardly compress; a
    thumbnail is for the eye (files keep every bit: :func:`~.files.save_image`)."""
    from PIL import Image as PILImage

    buf = io.BytesIO()
    PILImage.fromarray(np.round(image * 255).astype(np.uint8)).save(buf, format="JPEG", quality=92, subsampling=0)
    return buf.getvalue()


def thumbnail_url(image: np.ndarray) -> bytes:
    """A thumbnail (:func:`thumbnail_bytes`) as a ``data:`` URL, the value of a gallery picture
    (``ipywidgets.Image(format="url")``). The page shows it as it comes: an image of raw bytes
    is wrapped in a ``Blob`` and given an object URL first, which in Chromium costs some 1.5 ms
    per picture on the page's one thread (about 30 ms of an Evolve click's 20 new pictures)."""
    return b"data:image/jpeg;base64," + base64.b64encode(thumbnail_bytes(image))


class Gallery:
    """The clickable gallery (ipywidgets); ``gallery.widget`` is what to display.

    Args:
        rng: the random generator (the session is reproducible from its seed); ``None``
            with a saved :class:`GalleryState` continues its saved random state.
        population: starting genomes, or a :class:`GalleryState` (default: ``n`` random
            ones, none flat, black or one colour: :func:`~coursekit.pictures.variety.random_population`).
        n: number of pictures (default 20, Sims' 4 x 5).
        columns: thumbnails per row.
        size: thumbnail size in pixels.
        mutations, recombinations: ``{name: operator}``; defaults are the paper's seven. Pass
            your own functions to breed with them.
        genome_params: keyword arguments of :meth:`Genome.random` for random pictures.
        autosave: JSON file the session is written to after every change (atomically).
        render_options: extra keyword arguments of :func:`render` (time, device); the window
            is the gallery's view (:meth:`zoom`, :meth:`pan`).
        lineage_size: thumbnail size in the lineage view.
        breed_ahead: breed the next generation in a background thread while the student
            chooses (see the module's docstring; the library's operators only). The session
            is the same either way.
    """

    def __init__(self, rng: np.random.Generator | None = None, population: Sequence[Genome] | None = None, *,
                 n: int = 20, columns: int = 5, size: int = 96, mutations: Mapping[str, Callable] | None = None,
                 recombinations: Mapping[str, Callable] | None = None, genome_params: dict | None = None,
                 autosave: str | os.PathLike[str] | None = None, render_options: dict | None = None,
                 lineage_size: int = 56, breed_ahead: bool = True) -> None:
        import ipywidgets as W
        from ipyevents import Event

        if rng is not None and not isinstance(rng, np.random.Generator):
            raise TypeError(f"rng: expected numpy.random.Generator, got {type(rng).__name__}")
        for name, value in (("columns", columns), ("size", size), ("lineage_size", lineage_size)):
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
                raise ValueError(f"{name}: {value!r} must be an integer >= 1")
        genome_params = dict(options("genome_params", genome_params, "Genome.random options"))
        if not isinstance(breed_ahead, (bool, np.bool_)):
            raise TypeError(f"breed_ahead: expected True or False, got {breed_ahead!r}")
        preload()  # the stock pictures decoded now, not in the first click that shows one
        if population is None:
            if isinstance(n, bool) or not isinstance(n, int) or n < 2:
                raise ValueError(f"n: {n!r} must be an integer >= 2")
            rng = np.random.default_rng() if rng is None else rng
            population = random_population(rng, n, **genome_params)
        state = population if isinstance(population, GalleryState) else GalleryState(population)
        self.evolution = Evolution(state, rng, mutations=mutations, recombinations=recombinations,
                                   genome_params=genome_params, autosave=autosave)
        self.size, self.lineage_size = size, lineage_size
        self.render_options = dict(options("render_options", render_options, "render options (time, device, window)"))
        self.window = parse_window(self.render_options.pop("window", DEFAULT_WINDOW))
        self.cursor = 0
        self._syncing = False
        self._pngs: OrderedDict = OrderedDict()  # id(genome) -> (genome, thumbnail data: URL), this view
        self._view = None
        self.breed_ahead = bool(breed_ahead)
        self._ahead = None  # (Prepared, view, [(child, thumbnail)]): bred while the student chooses
        self._ahead_wanted = None  # what the last breeding ahead was asked for
        self._ahead_ticket = 0  # the latest request: an older one still queued is skipped
        self._ahead_pool = None  # one thread, started on the first request
        self._ahead_action = "evolve"  # the last breeding button pressed

        self.images, self.toggles, self._clicks = [], [], []
        for i in range(self.evolution.size):
            im = W.Image(format="url", layout=W.Layout(width=f"{size}px", height=f"{size}px",
                                                       border=f"3px solid {_PLAIN}"))
            click = Event(source=im, watched_events=["click"], prevent_default_action=True)
            click.on_dom_event(lambda event, i=i: self.click(i))
            self.images.append(im)
            self._clicks.append(click)
            t = W.ToggleButton(description=f"#{i}", layout=W.Layout(width=f"{size + 6}px"))
            t.observe(lambda change, i=i: self._on_toggle(i, change), names="value")
            self.toggles.append(t)
        tiles = [W.VBox([im, t]) for im, t in zip(self.images, self.toggles)]
        auto = W.Layout(width="auto")  # every label fits ("random interpolation" included)
        self.buttons = {}
        for name in list(self.evolution.mutations) + list(self.evolution.recombinations):
            self.buttons[name] = W.Button(description=name.replace("_", " "), layout=auto)
        for name in _ACTIONS:
            self.buttons[name] = W.Button(description=name, layout=auto,
                                          button_style="primary" if name == "evolve" else "")
        views = {"zoom in": ("search-plus", "zoom in (+)"), "zoom out": ("search-minus", "zoom out (-)"),
                 "pan left": ("arrow-left", "pan left (shift + left)"), "pan right": ("arrow-right", "pan right"),
                 "pan up": ("arrow-up", "pan up"), "pan down": ("arrow-down", "pan down"),
                 "reset view": ("", "back to the unit square (0)"), "lineage": ("sitemap", "lineage of the cursor (l)")}
        for name, (icon, tip) in views.items():
            self.buttons[name] = W.Button(description="" if icon and name != "lineage" else name, icon=icon,
                                          tooltip=tip, layout=W.Layout(width="auto"))
        for name, b in self.buttons.items():
            b.on_click(lambda b, name=name: self._act(name))
        self.hint = W.HTML()
        self.status = W.HTML()
        self.lineage_box = W.VBox()
        self.lineage_tiles: list[tuple[int, int, object]] = []  # (generation, index, branch button)
        grid = W.GridBox(tiles, layout=W.Layout(grid_template_columns=f"repeat({columns}, {size + 12}px)"))
        mut = W.HBox([W.Label("mutate:")] + [self.buttons[n] for n in self.evolution.mutations])
        rec = W.HBox([W.Label("recombine:")] + [self.buttons[n] for n in self.evolution.recombinations])
        ctl = W.HBox([self.buttons[n] for n in _ACTIONS])
        view = W.HBox([W.Label("view:")] + [self.buttons[n] for n in views])
        self.widget = W.VBox([grid, mut, rec, ctl, self.hint, view, self.status, self.lineage_box])
        self._keys = Event(source=self.widget, watched_events=["keydown"], prevent_default_action=True)
        self._keys.on_dom_event(self._on_key)
        self._sync("select pictures you like (click them), then choose an operator")
        self._freeze_heap()

    @staticmethod
    def _freeze_heap() -> None:
        """Collect once, then move everything alive into the collector's permanent
        generation (:func:`gc.freeze`), once the first generation is on screen.

        By then the heap holds what lives as long as the session: torch, the widgets, the
        operators' and the renderer's caches, the genomes. A click makes tens of thousands of
        short-lived objects (candidate genomes, decoded trees, previews); their allocations
        trigger Python's cycle collector, and each of its full collections walks every
        tracked object, the long-lived ones included: that was a good part of the slowest
        clicks. Frozen objects are never walked again (nor collected: what the session drops
        is still freed by reference counting, only a cycle among frozen objects would stay).
        Nothing the genomes or pictures depend on changes. What was frozen before (an earlier
        gallery's) is unfrozen first, so that a gallery made again (a notebook cell run
        again) lets the collector free the one it replaces. At exit the heap is unfrozen, so
        that the interpreter's last collection finds everything (extension modules such as
        OpenImageIO's bindings otherwise report their objects as leaked)."""
        global _unfreeze_at_exit
        gc.unfreeze()
        gc.collect()
        gc.freeze()
        if not _unfreeze_at_exit:
            atexit.register(gc.unfreeze)
            _unfreeze_at_exit = True

    @classmethod
    def load(cls, path: str | os.PathLike[str], rng: np.random.Generator | None = None, **kwargs: Any) -> Gallery:
        """Resume a session from an autosave file (it keeps autosaving there).

        Every field is checked first (:meth:`GalleryState.from_dict`): a broken file raises a
        ValueError naming the field and is left as it is. Without ``rng`` the session's saved
        random state continues, so the resumed session breeds exactly what the original
        would have."""
        state = GalleryState.load(path)
        kwargs.setdefault("autosave", path)
        return cls(rng, state, **kwargs)

    @property
    def state(self) -> GalleryState:
        return self.evolution.state

    # ---- actions --------------------------------------------------------------------------
    def click(self, i: int) -> None:
        """What a click on picture ``i`` does: select it, or unselect it if it was selected."""
        self._check_index(i)
        self.cursor = i
        self.toggles[i].value = not self.toggles[i].value

    def _on_toggle(self, i, change):
        if not self._syncing:
            with self.evolution.saved_after():
                self._sync(self.evolution.select(i, bool(change["new"])), images=False)

    def apply(self, name: str) -> str:
        """What the button ``name`` does (an operator's name, ``"evolve"``, ``"undo"``,
        ``"redo"``, ``"new random"``, ``"zoom in"``, ``"zoom out"``, ``"pan left"`` ...,
        ``"reset view"``, ``"lineage"``), pictures redrawn; returns the status message. Use
        this (and :meth:`click`, :meth:`key`) to drive the gallery from code: changing
        ``gallery.evolution`` directly changes the session but not the pictures on screen."""
        name = _ALIASES.get(name, name)
        key = name.replace("/", "_").replace(" ", "_") if isinstance(name, str) else name
        if name not in self.buttons and key in self.buttons:  # a button's label: "head tail rotation", "head/tail rotation"
            name = key
        if name not in self.buttons:
            raise ValueError(f"name: {name!r} is not one of {list(self.buttons)}")
        return self._act(name)

    def redo(self) -> str:
        """Forward again to the generation the last undo left (the redo button)."""
        return self._act("redo")

    def lineage(self, i: int) -> list[Ancestor]:
        """The picks and operators that made picture ``i`` (:meth:`Evolution.lineage`)."""
        return self.evolution.lineage(i)

    def branch(self, generation: int, index: int) -> str:
        """Back to ``generation`` with its picture ``index`` selected (clicking an ancestor
        in the lineage view); redo returns to where you were."""
        msg = self.evolution.branch(generation, index)
        self.cursor = index
        self._sync(msg)
        self.show_lineage(index)
        return msg

    def zoom(self, factor: float) -> str:
        """Zoom the view by ``factor`` (2: twice as close) about its centre."""
        if not (isinstance(factor, (int, float)) and np.isfinite(factor) and factor > 0):
            raise ValueError(f"factor: {factor!r} must be a positive number")
        x0, y0, x1, y1 = self.window
        cx, cy, hw, hh = (x0 + x1) / 2, (y0 + y1) / 2, (x1 - x0) / (2 * factor), (y1 - y0) / (2 * factor)
        if not 1e-6 <= 2 * abs(hw) <= 1e6:
            return "the view cannot zoom further"
        self.window = (cx - hw, cy - hh, cx + hw, cy + hh)
        self._sync("zoomed in" if factor > 1 else "zoomed out")  # the view itself is in the status line
        return self.status_text()

    def pan(self, dx: float, dy: float) -> str:
        """Move the view by ``(dx, dy)`` of its own width and height (right and down > 0)."""
        for name, v in (("dx", dx), ("dy", dy)):
            if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) or not np.isfinite(v):
                raise ValueError(f"{name}: {v!r} must be a finite number")
        x0, y0, x1, y1 = self.window
        w, h = x1 - x0, y1 - y0
        window = (x0 + dx * w, y0 + dy * h, x1 + dx * w, y1 + dy * h)
        try:
            self.window = parse_window(window)
        except ValueError:  # so far out that the view's edges meet (or overflow)
            return "the view cannot pan further"
        self._sync("panned")
        return self.status_text()

    def reset_view(self) -> str:
        """Back to the unit square."""
        self.window = DEFAULT_WINDOW
        self._sync("view reset to the unit square")
        return self.status_text()

    def key(self, key: str, shift: bool = False) -> str:
        """What pressing ``key`` (a DOM ``KeyboardEvent.key``) does over the gallery."""
        n, cols = self.evolution.size, self._columns()
        moves = {"ArrowLeft": -1, "ArrowRight": 1, "ArrowUp": -cols, "ArrowDown": cols}
        pans = {"ArrowLeft": (-0.25, 0), "ArrowRight": (0.25, 0), "ArrowUp": (0, -0.25), "ArrowDown": (0, 0.25)}
        if key in moves and shift:
            return self.pan(*pans[key])
        if key in moves:
            self.cursor = min(n - 1, max(0, self.cursor + moves[key]))
            self._sync(f"cursor on #{self.cursor}: space selects it", images=False)
        elif key in (" ", "Enter"):
            self.click(self.cursor)
        elif key == "Escape":
            self._sync(self.evolution.clear_selection(), images=False)
        elif key in ("e", "E"):
            self._act("evolve")
        elif key in ("u", "U", "z"):
            self._act("undo")
        elif key in ("y", "Y", "Z"):
            self._act("redo")
        elif key in ("+", "="):
            self.zoom(2.0)
        elif key in ("-", "_"):
            self.zoom(0.5)
        elif key == "0":
            self.reset_view()
        elif key in ("l", "L"):
            self.show_lineage(self.cursor)
        return self.status_text()

    def _on_key(self, event):
        self.key(event.get("key", ""), bool(event.get("shiftKey")))

    def _act(self, name):
        ev = self.evolution
        views = {"zoom in": lambda: self.zoom(2.0), "zoom out": lambda: self.zoom(0.5),
                 "pan left": lambda: self.pan(-0.25, 0), "pan right": lambda: self.pan(0.25, 0),
                 "pan up": lambda: self.pan(0, -0.25), "pan down": lambda: self.pan(0, 0.25),
                 "reset view": self.reset_view, "lineage": lambda: self.show_lineage(self.cursor)}
        if name in views:
            views[name]()
            return self.status_text()
        self._settle()
        with ev.saved_after():  # the pictures go to the screen before the session goes to its file
            if name in ev.mutations or name in ev.recombinations or name == "evolve":
                msg = self._breed(name)
            elif name == "undo":
                msg = ev.undo()
            elif name == "redo":
                msg = ev.redo()
            else:
                msg = ev.randomize()
            self._sync(msg)
        if self.lineage_box.children:
            self.lineage_box.children = ()
            self.lineage_tiles = []
        return msg

    # ---- breeding ahead -------------------------------------------------------------------
    def _breed(self, name: str) -> str:
        """The breeding button ``name`` pressed: the generation bred ahead for it when it fits
        the session as it is (and its thumbnails, when they are of this view), else bred now."""
        ev, ahead, self._ahead = self.evolution, self._ahead, None
        self._ahead_action = name
        if ahead is not None and ahead[0].action == name and ahead[0].fits(ev):
            prepared, view, thumbs = ahead
            if view == self._view_key() == self._view:
                for g, url in thumbs:
                    self._pngs[id(g)] = (g, url)
            return ev.commit(prepared)
        if name in ev.mutations:
            return ev.mutate(name)
        return ev.recombine(name) if name in ev.recombinations else ev.next_generation()

    def _ahead_key(self):
        """What breeding ahead would breed now (None: nothing, or not with these operators)."""
        ev = self.evolution
        action = self._ahead_action
        if not self.breed_ahead or ev.why_not(action):
            return None
        library = {id(op) for op in (*O.MUTATIONS.values(), *O.RECOMBINATIONS.values())}
        if not all(id(op) in library for op in (*ev.mutations.values(), *ev.recombinations.values())):
            return None  # a student's operator runs only when its button is pressed
        return action, tuple(ev.state.selected), tuple(map(id, ev.state.population)), self._view_key()

    def _breed_ahead(self) -> None:
        """Ask the background thread to breed the next generation for the session as it is."""
        key = self._ahead_key()
        if key == self._ahead_wanted:
            return
        self._ahead_wanted = key
        self._ahead_ticket += 1
        if key is None:
            return
        if self._ahead_pool is None:
            self._ahead_pool = ThreadPoolExecutor(1, thread_name_prefix="coursekit-breed-ahead")
        self._ahead_pool.submit(self._bred_ahead, self._ahead_ticket, key[0])

    def _bred_ahead(self, ticket: int, action: str) -> None:
        """In the thread: :meth:`Evolution.prepare` and the children's thumbnails. What fails
        here is left to the button, which breeds again and reports it."""
        if ticket != self._ahead_ticket:  # a newer request came while this one waited
            return
        try:
            view = size, window, options = self._view_key()  # read once: the view may change meanwhile
            prepared, thumbs = self.evolution.prepare(action), []
            if not isinstance(prepared.outcome, str):
                kids = prepared.outcome[0][len(prepared.selected):]
                if all(isinstance(g, Genome) for g in kids):
                    pics = render(kids, size, window=window, **dict(options))
                    thumbs = [(g, thumbnail_url(p)) for g, p in zip(kids, pics)]
            self._ahead = (prepared, view, thumbs)
        except Exception:  # pragma: no cover - the button breeds again and says what failed
            self._ahead = None

    def _settle(self) -> None:
        """Wait until the background thread has finished what it was asked (before anything
        here breeds, renders or reads what it bred)."""
        if self._ahead_pool is not None:
            self._ahead_pool.submit(int).result()

    # ---- the lineage view -----------------------------------------------------------------
    def show_lineage(self, i: int) -> list[Ancestor]:
        """Show the lineage of picture ``i`` under the gallery: one row per generation, each
        ancestor with its operator and parents; clicking one branches from it."""
        import ipywidgets as W
        from ipyevents import Event

        ancestors = self.lineage(i)
        self._settle()
        pics = render([a.genome for a in ancestors], self.lineage_size, window=self.window,
                      **self.render_options) if ancestors else []
        columns, self.lineage_tiles = [], []
        by_gen: dict[int, list] = {}
        for a, pic in zip(ancestors, pics):
            by_gen.setdefault(a.generation, []).append((a, pic))
        width = f"{self.lineage_size + 44}px"
        for g in sorted(by_gen):  # oldest first: read left to right, as the pictures were bred
            tiles = [W.HTML(f"<b>gen {g}</b>")]
            for a, pic in by_gen[g]:
                im = W.Image(value=thumbnail_url(pic), format="url",
                             layout=W.Layout(width=f"{self.lineage_size}px", height=f"{self.lineage_size}px"))
                ev = Event(source=im, watched_events=["click"], prevent_default_action=True)
                ev.on_dom_event(lambda e, g=a.generation, j=a.index: self.branch(g, j))
                im._coursekit_event = ev  # keep the listener alive with its image
                made = a.operator if not a.parents else f"{a.operator} of " + ", ".join(f"#{p}" for p in a.parents)
                b = W.Button(description=f"#{a.index}", tooltip=f"branch from generation {g}, #{a.index}",
                             layout=W.Layout(width=f"{self.lineage_size}px"))
                b.on_click(lambda b, g=a.generation, j=a.index: self.branch(g, j))
                self.lineage_tiles.append((a.generation, a.index, b))
                tiles += [im, b, W.HTML(f"<small>{html.escape(made.replace('_', ' '))}</small>",
                                        layout=W.Layout(width=width))]
            columns.append(W.VBox(tiles, layout=W.Layout(width=width, margin="0 4px 6px 0")))
        head = W.HTML(f"<b>lineage of #{i}</b>: oldest generation on the left; click an ancestor to branch from it")
        self.lineage_box.children = [head, W.HBox(columns, layout=W.Layout(flex_flow="row wrap"))]
        self._sync(f"lineage of #{i}: {len(ancestors)} picture(s) in {len(by_gen)} generation(s)", images=False)
        return ancestors

    # ---- mirroring the state --------------------------------------------------------------
    def export(self, i: int, path: str | os.PathLike[str], size: int | tuple[int, int] = 2048, **options: Any) -> Path:
        """Save picture ``i`` in the current view at full resolution with its genome (see
        :func:`save_image`; up to 4096 x 4096)."""
        from .files import save_image

        self._check_index(i)
        opts = {**self.render_options, "window": self.window, **options}
        self._settle()
        return save_image(path, self.state.population[i], size, **opts)

    def _check_index(self, i) -> None:
        if isinstance(i, bool) or not isinstance(i, (int, np.integer)) or not 0 <= i < self.evolution.size:
            raise ValueError(f"i: {i!r} is not a picture index (0..{self.evolution.size - 1})")

    def _ipython_display_(self):  # pragma: no cover - notebook display
        from IPython.display import display
        display(self.widget)

    def _columns(self) -> int:
        cols = self.widget.children[0].layout.grid_template_columns
        return int(cols.split("(")[1].split(",")[0])

    def _scale(self) -> str:
        x0, y0, x1, y1 = self.window
        z = 1.0 / abs(x1 - x0)
        return f"{z:.3g}x at ({(x0 + x1) / 2:.3g}, {(y0 + y1) / 2:.3g})"

    def status_text(self) -> str:
        """The status line as plain text."""
        return html.unescape(self.status.value.replace("<b>", "").replace("</b>", ""))

    def _cached(self, cache: OrderedDict, genomes, make) -> list:
        """``make(missing genomes) -> values`` through ``cache`` (this view only). Genomes are
        keyed by identity (kept ones are the same objects; hashing a genome costs more than
        encoding its thumbnail), each entry holding its genome so that the id stays its own."""
        view = self._view_key()
        if self._view != view:
            self._pngs.clear()
            self._view = view
        todo = list({id(g): g for g in genomes if cache.get(id(g), (None,))[0] is not g}.values())
        if todo:
            for g, value in zip(todo, make(todo)):
                cache[id(g)] = (g, value)
        out = []
        for g in genomes:
            cache.move_to_end(id(g))
            out.append(cache[id(g)][1])
        while len(cache) > _KEEP:
            cache.popitem(last=False)
        return out

    def _view_key(self) -> tuple:
        return self.size, self.window, tuple(sorted(self.render_options.items()))

    def _thumbnails(self) -> list[bytes]:
        """Thumbnails of the population in the current view (each genome rendered once)."""
        self._settle()
        return self._cached(self._pngs, self.state.population, lambda todo: [
            thumbnail_url(p) for p in render(todo, self.size, window=self.window, **self.render_options)])

    def _sync(self, message: str, images: bool = True):
        """Mirror the state in the widgets.

        Each widget's changes go to the page as one message (``hold_sync``: a toggle's value,
        style and icon, a border's four sides, a button's state and tooltip), in the order a
        student looks: the thumbnails, their frames and toggles, the status line, then the
        buttons and the hint (the page handles the messages one by one, a few ms each)."""
        self._syncing = True
        try:
            with ExitStack() as held:  # exits last-in first-out
                for w in [self.hint, *self.buttons.values(), self.status, *self.toggles,
                          *(im.layout for im in self.images), *self.images]:
                    held.enter_context(w.hold_sync())
                self._mirror(message, images)
        finally:
            self._syncing = False
        self._breed_ahead()  # for the session as it is now on screen

    def _mirror(self, message: str, images: bool):
        """Set every widget to the state (inside :meth:`_sync`'s held messages)."""
        s, ev = self.state, self.evolution
        if images:
            for im, url in zip(self.images, self._thumbnails()):
                im.value = url
        for i, t in enumerate(self.toggles):
            on = i in s.selected
            t.value = on
            colour = _SELECTED if on else (_CURSOR if i == self.cursor else _PLAIN)
            style = "dashed" if i == self.cursor else "solid"
            self.images[i].layout.border = f"3px {style} {colour}"
            t.button_style = "success" if on else ""
            t.icon = "check" if on else ""
        reasons = {}
        for name, b in self.buttons.items():
            if name in ev.mutations or name in ev.recombinations or name in _ACTIONS:
                reason = ev.why_not(name)
                b.disabled = bool(reason)
                b.tooltip = reason or ("a random operator per child" if name == "evolve" else name)
                reasons[name] = reason
        hint = reasons["evolve"] or next((r for n, r in reasons.items() if n in ev.recombinations and r), None)
        self.hint.value = (f"<i style='color:#666'>{html.escape(hint)}</i>" if hint
                           else "<i style='color:#666'>ready: press an operator, or evolve for a mix</i>")
        picks = ", ".join(f"#{i}" for i in s.selected)
        message = message.removeprefix(f"generation {s.generation}: ")  # said once, in bold
        view = "" if self.window == DEFAULT_WINDOW else f" &middot; view {html.escape(self._scale())}"
        self.status.value = (f"<b>generation {s.generation}</b> &middot; {len(s.selected)} selected"
                             f"{' (' + picks + ')' if picks else ''}{view} &middot; {html.escape(message)}")
