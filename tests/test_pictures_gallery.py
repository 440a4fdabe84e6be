"""Gallery driven headless through its widgets (ipywidgets without a kernel): what a student
sees and does -- pictures, buttons, undo and redo, the lineage, zoom, keys and the status line.
Session files, what a click writes and sends, and breeding ahead: ``test_pictures_gallery_sessions.py``."""

import json

import numpy as np
import pytest

from coursekit.pictures import operators as O
from coursekit.pictures.gallery import Gallery, GalleryState
from tests.test_pictures_genome import assert_valid

SMALL = {"n_strings": 2, "head_length": 3}


@pytest.fixture
def gallery(tmp_path):
    return Gallery(np.random.default_rng(0), n=6, columns=3, size=12, genome_params=SMALL,
                   autosave=tmp_path / "session.json")


def saved(tmp_path):
    return GalleryState.from_dict(json.loads((tmp_path / "session.json").read_text()))


def test_widgets_mirror_the_state(gallery):
    import base64
    import io

    from PIL import Image

    assert len(gallery.images) == 6
    for im in gallery.images:  # JPEG thumbnails of the gallery's size, as data: URLs the page shows as they come
        assert im.format == "url" and bytes(im.value).startswith(b"data:image/jpeg;base64,")
        jpeg = base64.b64decode(bytes(im.value).split(b",", 1)[1], validate=True)
        assert jpeg.startswith(b"\xff\xd8\xff") and Image.open(io.BytesIO(jpeg)).size == (12, 12)
    gallery.toggles[2].value = True
    gallery.toggles[4].value = True
    assert gallery.state.selected == [2, 4]
    gallery.toggles[2].value = False
    assert gallery.state.selected == [4]
    assert "1 selected" in gallery.status.value


def test_clicking_a_picture_selects_it(gallery):
    """A browser click on a thumbnail reaches the gallery as an ipyevents DOM-event message."""
    def browser_click(i):
        gallery._clicks[i]._handle_mouse_msg(None, {"event": "click", "type": "click"}, [])

    browser_click(3)
    browser_click(0)
    assert gallery.state.selected == [3, 0]  # click order is kept: it is the parents' order
    assert gallery.toggles[3].value and "2 selected" in gallery.status.value
    assert "2e7d32" in gallery.images[3].layout.border and "transparent" in gallery.images[1].layout.border
    browser_click(3)
    assert gallery.state.selected == [0]
    assert "2e7d32" not in gallery.images[3].layout.border  # unselected (the keyboard cursor stays on it)


def test_each_operator_button_breeds_from_the_selection(gallery, tmp_path):
    for name in O.MUTATIONS:
        parent = gallery.state.population[1]
        gallery.toggles[1].value = True
        before = [bytes(im.value) for im in gallery.images]
        gallery.buttons[name].click()
        pop = gallery.state.population
        assert pop[0] == parent and len(pop) == 6 and gallery.state.selected == []
        for g in pop:
            assert_valid(g)
        assert [bytes(im.value) for im in gallery.images] != before  # thumbnails follow the state
        assert not any(t.value for t in gallery.toggles)
    for name in O.RECOMBINATIONS:
        parents = [gallery.state.population[i] for i in (0, 3)]
        gallery.toggles[0].value = True
        gallery.toggles[3].value = True
        gallery.buttons[name].click()
        assert gallery.state.population[:2] == parents
        for g in gallery.state.population:
            assert_valid(g)
    assert gallery.state.generation == 7
    assert saved(tmp_path).population == gallery.state.population  # autosaved


def test_apply_from_code_breeds_and_redraws_like_the_buttons(gallery):
    gallery.click(2)
    before = [bytes(im.value) for im in gallery.images]
    msg = gallery.apply("substitution")
    assert msg.startswith("generation 1") and msg.split(": ")[1] in gallery.status.value
    assert [bytes(im.value) for im in gallery.images] != before  # the pictures on screen follow
    assert gallery.apply("undo") == "back to generation 0"
    assert [bytes(im.value) for im in gallery.images] == before
    with pytest.raises(ValueError, match="name: 'mutate'"):
        gallery.apply("mutate")
    for label in ("head tail rotation", "head/tail rotation"):  # what the button says, and what the lessons call it
        assert gallery.apply(label).startswith("generation 1")
        assert gallery.state.generation == 1 and gallery.apply("undo") == "back to generation 0"


def test_buttons_need_a_selection(gallery):
    pop = list(gallery.state.population)
    gallery.buttons["transposition"].click()
    assert "select a picture" in gallery.status.value and gallery.state.population == pop
    gallery.toggles[0].value = True
    gallery.buttons["crossover"].click()
    assert "1 more picture to recombine" in gallery.status.value and gallery.state.population == pop


def test_undo_walks_back_through_history(gallery, tmp_path):
    generations = [list(gallery.state.population)]
    for _ in range(3):
        gallery.toggles[0].value = True
        gallery.buttons["evolve"].click()
        generations.append(list(gallery.state.population))
    for k in (2, 1, 0):
        gallery.buttons["undo"].click()
        assert gallery.state.population == generations[k]
        assert gallery.state.generation == k
    gallery.buttons["undo"].click()
    assert "nothing to undo" in gallery.status.value
    assert saved(tmp_path).population == generations[0]


def test_session_resumes_from_autosave(gallery, tmp_path):
    gallery.toggles[0].value = True
    gallery.buttons["substitution"].click()
    gallery.toggles[5].value = True
    resumed = Gallery.load(tmp_path / "session.json", np.random.default_rng(1), size=12)
    assert resumed.state.population == gallery.state.population
    assert resumed.state.selected == [5] and resumed.toggles[5].value
    resumed.buttons["undo"].click()
    assert resumed.state.generation == 0


def test_students_operators_plug_in(tmp_path):
    calls = []

    def my_transposition(genome, rng):
        child = O.transposition(genome, rng)
        calls.append((genome, child))
        return child

    def broken(genome, rng):
        return "not a genome"

    g = Gallery(np.random.default_rng(3), n=4, size=8, genome_params=SMALL,
                mutations={"transposition": my_transposition, "broken": broken})
    assert set(g.buttons) >= {"transposition", "broken", "crossover"}
    g.toggles[2].value = True
    g.buttons["transposition"].click()
    # the first three calls breed from the parent; a child that looks like its parent or a
    # sibling is bred again, so there may be more calls, but every child is one of their results
    parent = g.state.population[0]
    assert len(calls) >= 3 and all(given == parent for given, _ in calls[:3])
    assert all(any(child is out for _, out in calls) for child in g.state.population[1:])
    g.toggles[1].value = True
    pop = list(g.state.population)
    g.buttons["broken"].click()
    assert "not a Genome" in g.status.value and g.state.population == pop


def test_same_seed_same_session():
    def run():
        g = Gallery(np.random.default_rng(9), n=4, size=8, genome_params=SMALL)
        g.toggles[1].value = True
        g.toggles[2].value = True
        g.buttons["evolve"].click()
        return [x.to_json() for x in g.state.population]
    assert run() == run()


def test_foreign_session_file_is_refused(tmp_path):
    p = tmp_path / "x.json"
    p.write_text(json.dumps({"format": "coursekit.genome/1"}))
    with pytest.raises(ValueError, match="coursekit.gallery/2"):
        Gallery.load(p, np.random.default_rng(0))
    p.write_text("{truncated")
    with pytest.raises(ValueError, match="not a gallery session"):
        Gallery.load(p, np.random.default_rng(0))


def test_export_saves_a_picture_that_can_be_bred_again(gallery, tmp_path):
    from coursekit.pictures import load_genome

    path = gallery.export(3, tmp_path / "keep.png", size=24)
    assert load_genome(path) == gallery.state.population[3]
    with pytest.raises(ValueError, match="not a picture index"):
        gallery.export(6, tmp_path / "nope.png")


# ---- redo, lineage, branching ---------------------------------------------------------------

def test_redo_goes_forward_again_until_a_new_action(gallery, tmp_path):
    assert gallery.buttons["redo"].disabled and gallery.buttons["undo"].disabled
    gallery.click(1)
    gallery.apply("substitution")
    bred = list(gallery.state.population)
    shown = [bytes(im.value) for im in gallery.images]
    assert gallery.apply("undo") == "back to generation 0"
    assert not gallery.buttons["redo"].disabled
    assert gallery.redo() == "forward to generation 1"
    assert gallery.state.population == bred and [bytes(im.value) for im in gallery.images] == shown
    assert saved(tmp_path).population == bred and gallery.buttons["redo"].disabled
    gallery.apply("undo")
    gallery.click(4)
    gallery.apply("transposition")  # a new action forgets the undone generation
    assert gallery.state.future == [] and gallery.redo() == "nothing to redo"


def test_lineage_names_the_picks_and_operators_that_made_a_picture(gallery):
    start = list(gallery.state.population)
    gallery.click(2)
    gallery.apply("substitution")           # generation 1: #0 is start #2, the rest its mutants
    gen1 = list(gallery.state.population)
    gallery.click(3)
    gallery.click(0)
    gallery.apply("crossover")              # generation 2: #0, #1 are gen-1 #3, #0; the rest their crosses
    child = gallery.lineage(4)
    assert (child[0].generation, child[0].index) == (2, 4)
    # a crossing of a picture and its own mutant, maybe mutated once more (it says by what)
    made, *more = child[0].operator.split("+")
    assert made == "crossover" and all(m in O.MUTATIONS for m in more)
    assert child[0].genome == gallery.state.population[4] and set(child[0].parents) <= {0, 3}
    by_place = {(a.generation, a.index): a for a in child}
    for a in child:
        assert a.genome == ([start, gen1, gallery.state.population][a.generation][a.index])
        for p in a.parents:  # every parent named is in the lineage, one generation earlier
            assert (a.generation - 1, p) in by_place or by_place.get((a.generation - 1, p)) is None
    assert by_place[(0, 2)].operator == "start"
    if (1, 3) in by_place:
        assert by_place[(1, 3)].operator == "substitution" and by_place[(1, 3)].parents == (2,)
    kept = gallery.lineage(1)               # gen-1 #0 was kept twice: it is start #2
    assert [(a.generation, a.index, a.operator) for a in kept] == [(0, 2, "start")]


def test_clicking_an_ancestor_in_the_lineage_view_branches_from_it(gallery, tmp_path):
    gallery.click(2)
    gallery.apply("root_transposition")
    gallery.click(5)
    gallery.apply("evolve")
    latest = list(gallery.state.population)
    gallery.show_lineage(5)
    assert gallery.lineage_box.children and gallery.lineage_tiles
    generation, index, button = next(t for t in gallery.lineage_tiles if t[0] == 1)
    button.click()
    assert gallery.state.generation == 1 and gallery.state.selected == [index]
    assert saved(tmp_path).selected == [index]
    gallery.apply("transposition")          # the new branch grows from the ancestor
    assert gallery.state.population[0] == gallery.state.history[-1].population[index]
    assert gallery.state.population != latest and gallery.state.future == []


# ---- zoom, keys, the evolve button, the status line -------------------------------------------

def test_zoom_and_pan_re_evaluate_the_genomes_and_reset_comes_back(gallery, tmp_path):
    from coursekit.pictures import render
    from coursekit.pictures.files import load_render_settings
    from coursekit.pictures.gallery import thumbnail_url

    home = [bytes(im.value) for im in gallery.images]
    gallery.apply("zoom in")
    assert gallery.window == (0.25, 0.25, 0.75, 0.75)
    want = render(gallery.state.population, 12, window=gallery.window)
    assert [bytes(im.value) for im in gallery.images] == [thumbnail_url(p) for p in want]
    gallery.key("ArrowRight", shift=True)   # shift + arrow pans a quarter of the view
    assert gallery.window == (0.375, 0.25, 0.875, 0.75) and "view 2x" in gallery.status_text()
    path = gallery.export(0, tmp_path / "zoomed.png", size=16)
    assert load_render_settings(path)["window"] == list(gallery.window)
    gallery.key("0")
    assert gallery.window == (0.0, 0.0, 1.0, 1.0) and [bytes(im.value) for im in gallery.images] == home
    assert "x at (" not in gallery.status_text()


def test_bad_arguments_are_named_and_leave_the_gallery_as_it_was(gallery):
    window = gallery.window
    for bad in (float("nan"), float("inf"), None, "1"):
        with pytest.raises(ValueError, match="dx: .* must be a finite number"):
            gallery.pan(bad, 0)
    assert gallery.window == window  # a nan pan once stuck in the view: every later render refused it
    assert gallery.pan(1e308, 0) == "the view cannot pan further" and gallery.window == window
    for bad in (6, -1, "a", None):
        with pytest.raises(ValueError, match=r"i: .* is not a picture index \(0..5\)"):
            gallery.click(bad)
    assert gallery.state.selected == []
    for name, bad in (("columns", 0), ("size", "96"), ("lineage_size", -1)):
        with pytest.raises(ValueError, match=f"{name}: .* must be an integer >= 1"):
            Gallery(np.random.default_rng(0), gallery.state.population, **{"size": 12, name: bad})
    with pytest.raises(TypeError, match=r"mutations\['mine'\]: expected an operator function, got int"):
        Gallery(np.random.default_rng(0), gallery.state.population, size=12, mutations={"mine": 5})
    for option, bad, error, message in (
            ("mutations", [O.MUTATIONS["transposition"]], TypeError, r"mutations: expected a dict of \{name: operator\}, got list"),
            ("recombinations", 5, TypeError, r"recombinations: expected a dict of \{name: operator\}, got int"),
            ("genome_params", 5, TypeError, "genome_params: expected a dict of Genome.random options, got int"),
            ("render_options", "fast", TypeError, "render_options: expected a dict of render options"),
            ("render_options", {"window": "abc"}, ValueError, r"window: 'abc' must be \(x0, y0, x1, y1\)"),
            ("autosave", 5, TypeError, "autosave: expected the path of a JSON file, got int"),
            ("breed_ahead", "no", TypeError, "breed_ahead: expected True or False, got 'no'"),
            ("population", 5, TypeError, "gallery: population must be a non-empty list of genomes, got int")):
        with pytest.raises(error, match=message):
            Gallery(np.random.default_rng(0), **{"population": gallery.state.population, "size": 12, option: bad})


def test_keys_move_a_cursor_select_evolve_undo_and_redo(gallery):
    def press(key, shift=False):  # a keydown over the gallery, as ipyevents delivers it
        gallery._keys._handle_mouse_msg(None, {"event": "keydown", "type": "keydown", "key": key,
                                               "shiftKey": shift}, [])
    press("ArrowRight")
    press("ArrowDown")                      # 3 columns: #1 -> #4
    press(" ")
    press("ArrowLeft")
    press("Enter")
    assert gallery.state.selected == [4, 3] and gallery.cursor == 3
    assert "dashed" in gallery.images[3].layout.border
    press("e")
    assert gallery.state.generation == 1 and gallery.state.population[:2] == gallery.state.history[-1].population[4:2:-1]
    press("u")
    assert gallery.state.generation == 0 and gallery.state.selected == [4, 3]
    press("y")
    assert gallery.state.generation == 1
    press("ArrowRight")
    press(" ")
    press("Escape")
    assert gallery.state.selected == []
    press("+")
    assert gallery.window == (0.25, 0.25, 0.75, 0.75)


def test_evolve_is_disabled_with_its_reason_until_the_selection_fits(gallery):
    rec, mut = gallery.buttons["crossover"], gallery.buttons["substitution"]
    assert gallery.buttons["evolve"].disabled and mut.disabled and rec.disabled
    assert "select a picture" in gallery.hint.value and "select a picture" in gallery.buttons["evolve"].tooltip
    gallery.click(0)
    assert not gallery.buttons["evolve"].disabled and not mut.disabled and rec.disabled
    assert "select 1 more picture to recombine" in gallery.hint.value and "1 more" in rec.tooltip
    gallery.click(1)
    assert not rec.disabled and "ready" in gallery.hint.value
    for i in range(2, 6):
        gallery.click(i)
    assert gallery.buttons["evolve"].disabled and rec.disabled
    assert "leaves no room for children" in gallery.hint.value
    pop = list(gallery.state.population)
    assert "no room" in gallery.apply("evolve") and gallery.state.population == pop  # code is refused too


def test_the_status_line_says_each_thing_once(gallery):
    gallery.click(2)
    gallery.click(4)
    text = gallery.status_text()
    assert text.startswith("generation 0 · 2 selected (#2, #4) · ") and text.count("selected") == 1, text
    gallery.apply("random_interpolation")
    assert gallery.status_text().count("generation 1") == 1
    assert all(b.layout.width == "auto" for name, b in gallery.buttons.items())  # labels are never cut
    gallery.apply("zoom in")
    assert gallery.status_text().count("2x") == 1, gallery.status_text()
