"""Gallery sessions and clicks, headless: session files (every field checked, the random state
kept, the first format still read), what a click costs, writes and sends to the widgets (issue 12,
gallery click p95), and breeding ahead (changes nothing but the wait). The gallery as a student
drives it: ``test_pictures_gallery.py``."""

import json

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import numpy as np
import pytest

from coursekit.pictures import operators as O
from coursekit.pictures.gallery import Gallery, GalleryState
from coursekit.profile import sized
from tests.test_pictures_gallery import SMALL, gallery, saved  # noqa: F401  (the fixture, shared)


# ---- session files: every field checked, the random state kept --------------------------------

def test_a_resumed_session_continues_exactly_as_the_original(tmp_path):
    def play(g, steps):
        for picks, button in steps:
            for i in picks:
                g.click(i)
            g.apply(button)
    first = [([1], "transposition"), ([0, 3], "crossover")]
    then = [([2], "evolve"), ([], "new random"), ([0, 1], "random_copy")]
    make = dict(n=5, size=8, genome_params=SMALL)
    original = Gallery(np.random.default_rng(42), **make)
    play(original, first + then)
    interrupted = Gallery(np.random.default_rng(42), autosave=tmp_path / "s.json", **make)
    play(interrupted, first)
    del interrupted                          # the kernel dies
    resumed = Gallery.load(tmp_path / "s.json", size=8, genome_params=SMALL)
    play(resumed, then)
    assert [g.to_json() for g in resumed.state.population] == [g.to_json() for g in original.state.population]
    assert resumed.state.generation == original.state.generation == 5


BAD_SESSIONS = [
    (lambda d: d["history"][0].update(selected=[9]), r"history\[0\]\.selected\[0\] = 9 is not a picture index"),
    (lambda d: d.update(population=[]), "population must be a non-empty list"),
    (lambda d: d.update(selected=[0, 0]), "selects a picture twice"),
    (lambda d: d.update(selected=[1.9]), r"selected\[0\] = 1.9 is not a picture index"),
    (lambda d: d.update(selected=[True]), r"selected\[0\] = True is not a picture index"),
    (lambda d: d.update(generation=-5), "generation = -5 must be an integer"),
    (lambda d: d.update(generation="abc"), "generation = 'abc' must be an integer"),
    (lambda d: d.update(generation=0), "generation = 0 must be an integer >= 1"),
    (lambda d: d["history"][0]["population"].pop(), r"history\[0\]\.population must be a list of 5 genomes"),
    (lambda d: d["population"][2].update(strings=7), r"population\[2\]: genome: 'strings'"),
    (lambda d: d["origins"][1].update(parents=[8]), r"origins\[1\]\.parents\[0\] = 8"),
    (lambda d: d.update(rng={"bit_generator": "PCG64", "state": "x"}), "rng: broken PCG64 state"),
    (lambda d: d.update(rng=[1, 2]), "rng = .* is not a saved random state"),
    (lambda d: d.pop("selected"), "'selected' is missing"),
]


@pytest.mark.parametrize("damage, message", BAD_SESSIONS)
def test_a_broken_session_file_is_refused_naming_the_field_and_left_untouched(tmp_path, damage, message):
    path = tmp_path / "s.json"
    g = Gallery(np.random.default_rng(5), n=5, size=8, genome_params=SMALL, autosave=path)
    g.click(0)
    g.apply("substitution")
    d = json.loads(path.read_text())
    damage(d)
    path.write_text(json.dumps(d))
    before = path.read_bytes()
    with pytest.raises(ValueError, match=message):
        Gallery.load(path, size=8)
    assert path.read_bytes() == before


def test_a_session_of_the_first_format_still_loads(tmp_path):
    g = Gallery(np.random.default_rng(6), n=4, size=8, genome_params=SMALL)
    g.click(1)
    g.apply("transposition")
    old = {"format": "coursekit.gallery/1", "generation": 1, "selected": [2],
           "population": [x.to_dict() for x in g.state.population],
           "history": [{"population": [x.to_dict() for x in h.population], "selected": h.selected}
                       for h in g.state.history]}
    (tmp_path / "old.json").write_text(json.dumps(old))
    resumed = Gallery.load(tmp_path / "old.json", np.random.default_rng(0), size=8)
    assert resumed.state.population == g.state.population and resumed.state.selected == [2]
    assert resumed.apply("undo") == "back to generation 0"
    assert json.loads((tmp_path / "old.json").read_text())["format"] == "coursekit.gallery/2"


# ---- what a click costs (issue 12: gallery click p95) ----------------------------------------

def test_a_gallery_decodes_the_stock_pictures_when_it_starts():
    from coursekit.pictures import textures as T
    from coursekit.pictures.primitives import PIXMAPS

    T.pixmap.cache_clear()
    Gallery(np.random.default_rng(0), n=4, size=12, genome_params=SMALL)
    assert T.pixmap.cache_info().currsize == len(PIXMAPS)


class _Cycle:
    def __init__(self):
        self.me = self


def test_a_gallery_freezes_the_heap_it_starts_with_and_the_next_one_frees_what_was_dropped():
    import gc
    import weakref

    try:
        dropped = _Cycle()
        first = Gallery(np.random.default_rng(0), n=4, size=12, genome_params=SMALL)
        assert gc.get_freeze_count() > 0
        walked = {id(o) for o in gc.get_objects()}  # generations 0-2: what a collection walks
        assert id(first) not in walked and not any(id(g) in walked for g in first.state.population)
        assert id(dropped) not in walked
        gone = weakref.ref(dropped)
        del dropped
        gc.collect()
        assert gone() is not None  # frozen: the collector no longer looks at it
        Gallery(np.random.default_rng(1), n=4, size=12, genome_params=SMALL)
        assert gone() is None  # a new gallery unfreezes and collects before freezing again
        first.apply("new random")  # a gallery keeps working with a frozen heap
        assert first.state.generation == 1
    finally:
        gc.unfreeze()


def test_the_autosave_text_is_json_dumps_of_the_state_byte_for_byte(tmp_path):
    """The autosave keeps each genome's text with the genome: the file must still be exactly
    ``json.dumps(state.to_dict())`` -- after evolving, undoing (a future), branching and
    selecting -- and a primitive redefined afterwards must show in it."""
    from coursekit.pictures import primitives as P

    g = Gallery(np.random.default_rng(11), n=6, size=16, autosave=tmp_path / "s.json")
    moves = ["evolve", "substitution", "crossover", "evolve", "random_interpolation"]
    for k, move in enumerate(moves):
        for i in (k % 6, (k + 2) % 6):
            g.click(i)
        g.apply(move)
        assert (tmp_path / "s.json").read_text() == json.dumps(g.evolution.state.to_dict())
    g.apply("undo")
    g.apply("undo")
    g.click(1)
    state = g.evolution.state
    assert state.future and state.history
    assert (tmp_path / "s.json").read_text() == json.dumps(state.to_dict())
    assert GalleryState.from_dict(json.loads(state.to_json())).to_dict() == state.to_dict()
    before = P.REDEFINED
    P.REDEFINED += 1  # as register_primitive(..., replace=True) does: expressions are read anew
    try:
        first = state.population[0]
        object.__setattr__(first, "_json", (before, '"stale"'))
        assert state.to_json() == json.dumps(state.to_dict())
    finally:
        P.REDEFINED = before


def test_a_click_sends_each_widget_once_and_the_status_line_after_every_picture(gallery):
    """What the page receives of an Evolve click (ipywidgets' messages, caught at each widget's
    comm): one message per changed widget, its changes together; the status line after every
    picture, frame and toggle (a page showing the new generation's line shows the new grid),
    then the buttons."""
    import ipywidgets as W

    sent = []

    class Comm:  # stands in for the kernel's comm of each widget
        kernel, comm_id = True, "test"

        def __init__(self, widget):
            self.widget = widget

        def send(self, data=None, buffers=None, **kw):
            sent.append((self.widget, set(data["state"]) | {p[0] for p in data.get("buffer_paths", [])}))

        def on_msg(self, callback):
            pass

        def close(self, *args, **kw):
            pass

    def on(widget):
        widget.comm = Comm(widget)
        for child in getattr(widget, "children", ()):
            on(child)
        if isinstance(getattr(widget, "layout", None), W.Widget):
            widget.layout.comm = Comm(widget.layout)

    on(gallery.widget)
    gallery.click(1)
    sent.clear()
    before = [im.value for im in gallery.images]
    gallery.apply("evolve")
    widgets = [w for w, _ in sent]
    assert len(widgets) == len(set(map(id, widgets))), "a widget was sent more than once"
    pictures = [i for i, (w, keys) in enumerate(sent) if "value" in keys and any(w is im for im in gallery.images)]
    changed = [im for im, old in zip(gallery.images, before) if im.value != old]
    assert len(pictures) == len(changed) >= gallery.evolution.size - 1  # every new picture (the parent moved to #0)
    status = next(i for i, w in enumerate(widgets) if w is gallery.status)
    grid = [i for i, w in enumerate(widgets) if any(w is x for x in gallery.toggles + gallery.images)
            or any(w is im.layout for im in gallery.images)]
    buttons = [i for i, w in enumerate(widgets) if any(w is b for b in gallery.buttons.values())]
    assert max(grid) < status < min(buttons), "the status line is not between the grid and the buttons"
    assert buttons and set(pictures) <= set(grid)
    toggle = next(keys for w, keys in sent if w is gallery.toggles[1])
    assert {"value", "button_style", "icon"} <= toggle  # the unselected parent's toggle: one message


def test_a_click_writes_the_session_once_after_its_pictures_are_on_the_widgets(gallery, tmp_path, monkeypatch):
    # the pictures go to the screen first; the file follows, once per click, and holds the click
    from coursekit.pictures import session

    writes = []
    original = session.atomic_write

    def write(path, text):
        writes.append([im.value for im in gallery.images])
        original(path, text)

    monkeypatch.setattr(session, "atomic_write", write)
    gallery.click(0)
    gallery.click(2)
    assert len(writes) == 2  # a selection is saved too, once each
    writes.clear()
    gallery.apply("evolve")
    assert len(writes) == 1
    assert writes[0] == [im.value for im in gallery.images]  # written when the new pictures were set
    assert saved(tmp_path).population == gallery.state.population
    assert saved(tmp_path).generation == gallery.state.generation



def test_branching_back_several_generations_writes_the_autosave_once_with_the_branch_made(gallery, tmp_path, monkeypatch):
    # A reader of the autosave (a browser test, a second notebook) must never see a branch half
    # made: a generation on the way back, or the ancestor's generation with its old picks.
    from coursekit.pictures import session

    for i in (1, 4, 2):
        gallery.click(i)
        gallery.apply("evolve")
    writes = []
    original = session.atomic_write

    def write(path, text):
        writes.append(json.loads(text))
        original(path, text)

    monkeypatch.setattr(session, "atomic_write", write)
    gallery.branch(1, 3)
    assert [(w["generation"], w["selected"]) for w in writes] == [(1, [3])]
    gallery.apply("undo")  # undo still saves its step
    assert [(w["generation"], w["selected"]) for w in writes][1:] == [(0, [1])]

def test_a_click_that_fails_still_saves_what_changed(gallery, tmp_path, monkeypatch):
    gallery.click(0)
    monkeypatch.setattr(Gallery, "_sync", lambda self, *a, **k: (_ for _ in ()).throw(RuntimeError("page gone")))
    with pytest.raises(RuntimeError, match="page gone"):
        gallery.apply("evolve")
    assert saved(tmp_path).generation == gallery.state.generation == 1


# ---- breeding ahead -------------------------------------------------------------------------


def _seen(g):
    """What a student has of a gallery: the session (random state included) and the pictures."""
    g._settle()
    return g.state.to_json(), g.evolution.rng.bit_generator.state, [bytes(im.value) for im in g.images]


def test_prepare_changes_nothing_and_commit_is_the_action():
    from coursekit.pictures.session import Evolution

    def evolution():
        return Evolution(GalleryState(Gallery(np.random.default_rng(5), n=6, size=8, genome_params=SMALL,
                                              breed_ahead=False).state.population), np.random.default_rng(6))

    a, b = evolution(), evolution()
    for ev in (a, b):
        ev.select(1)
        ev.select(3)
    before = a.state.to_json(), a.rng.bit_generator.state
    prepared = a.prepare("crossover")
    assert (a.state.to_json(), a.rng.bit_generator.state) == before  # nothing happened yet
    assert a.commit(prepared) == b.recombine("crossover")
    assert a.state.to_json() == b.state.to_json() and a.rng.bit_generator.state == b.rng.bit_generator.state
    assert a.state.population[2] is prepared.outcome[0][2]  # the very children prepared


def test_a_prepared_generation_of_another_state_is_refused():
    g = Gallery(np.random.default_rng(5), n=6, size=8, genome_params=SMALL, breed_ahead=False)
    ev = g.evolution
    ev.select(1)
    prepared = ev.prepare("evolve")
    ev.select(2)  # the selection changed since
    with pytest.raises(ValueError, match="prepared: it was bred from another state"):
        ev.commit(prepared)
    ev.select(2)
    ev.rng.random()  # the random state moved on
    with pytest.raises(ValueError, match="prepared"):
        ev.commit(prepared)


def test_a_generation_bred_ahead_is_the_one_the_button_breeds():
    a = Gallery(np.random.default_rng(7), n=6, size=12, genome_params=SMALL, breed_ahead=False)
    b = Gallery(np.random.default_rng(7), n=6, size=12, genome_params=SMALL)
    hits = []
    for picks, button in [([1], "evolve"), ([0, 4], "crossover"), ([2, 1], "crossover"), ([3], "transposition"),
                          ([5], "transposition"), ([], "undo"), ([0], "evolve")]:
        for g in (a, b):
            for i in picks:
                g.click(i)
        b._settle()  # the student looked long enough for it to be bred
        ahead = b._ahead
        hit = ahead is not None and ahead[0].action == button and ahead[0].fits(b.evolution)
        hits.append(hit)
        if hit:  # its pictures too: the button only sends them
            calls = []
            b._cached = lambda cache, genomes, make, original=b._cached: original(cache, genomes, lambda todo: calls.append(todo) or make(todo))
        assert a.apply(button) == b.apply(button)
        if hit:
            assert calls == [] and len(ahead[2]) == 6 - len(picks)
            del b._cached
        assert _seen(a) == _seen(b)
    # ready whenever the button pressed is the last breeding button pressed (evolve at first)
    assert hits == [True, False, True, False, True, False, False]


def test_a_students_operator_runs_only_when_its_button_is_pressed():
    calls = []

    def mine(genome, rng):
        calls.append(genome)
        return O.substitution(genome, rng)

    g = Gallery(np.random.default_rng(3), n=4, size=8, genome_params=SMALL, mutations={"mine": mine})
    g.click(1)
    g._settle()
    assert calls == [] and g._ahead is None
    g.apply("mine")
    assert calls
    calls.clear()
    g.click(2)
    g._settle()
    assert calls == [] and g._ahead is None


@settings(max_examples=sized(classroom=25, ci=12), deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(st.lists(st.integers(0, 5), max_size=3),
                          st.sampled_from(["evolve", "transposition", "substitution", "crossover", "random_copy",
                                           "undo", "redo", "zoom in", "reset view", "new random"]),
                          st.booleans()), min_size=1, max_size=6))
def test_breeding_ahead_changes_nothing_but_the_wait(steps):
    """Any picks, any buttons, pressed at once or after the thread has finished: the session,
    its random state and the pictures are those of a gallery that breeds when pressed."""
    a = Gallery(np.random.default_rng(11), n=6, size=10, genome_params=SMALL, breed_ahead=False)
    b = Gallery(np.random.default_rng(11), n=6, size=10, genome_params=SMALL)
    for picks, button, pause in steps:
        for g in (a, b):
            for i in picks:
                g.click(i)
        if pause:
            b._settle()
        assert a.apply(button) == b.apply(button)
    assert _seen(a) == _seen(b)
