"""Gallery driven headless through its widgets (ipywidgets without a kernel)."""

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
    assert len(gallery.images) == 6
    assert all(bytes(im.value).startswith(b"\x89PNG") for im in gallery.images)
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
    assert "transparent" in gallery.images[3].layout.border


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
    assert msg.startswith("generation 1") and msg in gallery.status.value
    assert [bytes(im.value) for im in gallery.images] != before  # the pictures on screen follow
    assert gallery.apply("undo") == "back to generation 0"
    assert [bytes(im.value) for im in gallery.images] == before
    with pytest.raises(ValueError, match="name: 'mutate'"):
        gallery.apply("mutate")


def test_buttons_need_a_selection(gallery):
    pop = list(gallery.state.population)
    gallery.buttons["transposition"].click()
    assert "select at least one" in gallery.status.value and gallery.state.population == pop
    gallery.toggles[0].value = True
    gallery.buttons["crossover"].click()
    assert "at least two" in gallery.status.value and gallery.state.population == pop


def test_undo_walks_back_through_history(gallery, tmp_path):
    generations = [list(gallery.state.population)]
    for _ in range(3):
        gallery.toggles[0].value = True
        gallery.buttons["next generation"].click()
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
        g.buttons["next generation"].click()
        return [x.to_json() for x in g.state.population]
    assert run() == run()


def test_foreign_session_file_is_refused(tmp_path):
    p = tmp_path / "x.json"
    p.write_text(json.dumps({"format": "coursekit.genome/1"}))
    with pytest.raises(ValueError, match="coursekit.gallery/1"):
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
