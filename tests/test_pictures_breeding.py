"""Every slot a new picture, even when the parents have few children to give (paper section 3.4).

A student's walk: click a picture, mutate it, pick two of its children and cross them. Two
siblings differ at one or two chromosomes, so their crossings are mostly themselves: before,
2-4 of the 20 pictures were distinct and the status line said only "crossover of 2 parents".
"""

import numpy as np
import pytest

from coursekit.pictures import Genome, operators as O, variety
from coursekit.pictures.genome import Chromosome as C, ChromosomeString
from coursekit.pictures.session import Evolution, GalleryState
from coursekit.pictures.variety import SAME, distinct_children, preview, random_population


def nearest(pics):
    """Per picture, the mean absolute difference to the nearest other picture."""
    d = np.abs(pics[:, None] - pics[None]).mean(axis=(2, 3, 4))
    np.fill_diagonal(d, np.inf)
    return d.min(axis=1)


def siblings(seed):
    """A session whose selection is two children of one substitution click."""
    rng = np.random.default_rng(seed)
    ev = Evolution(GalleryState(random_population(rng, 20)), rng)
    ev.select(0, True)
    assert ev.mutate("substitution").startswith("generation 1")
    a, b = (int(v) for v in np.random.default_rng(seed).choice(np.arange(1, 20), 2, replace=False))
    ev.select(a, True)
    ev.select(b, True)
    return ev, (a, b)


def rescued(ev, action):
    """Children whose origin says they were mutated once more after ``action``."""
    return [o for o in ev.state.origins if o.operator.startswith(action + "+")]


@pytest.mark.parametrize("action", ["crossover", "random_interpolation"])
@pytest.mark.parametrize("seed", range(5))
def test_recombining_two_siblings_fills_every_slot_with_a_new_picture(seed, action):
    # measured over 30 sessions: before, 0 of 540 crossings and 73 of 540 interpolations were unlike
    # every other picture of their generation; after, all 1080
    ev, (a, b) = siblings(seed)
    msg = ev.recombine(action)
    pics = preview(ev.state.population)
    assert nearest(pics)[2:].min() >= SAME, msg  # every child unlike its parents and its siblings
    assert len({O.coding(g) for g in ev.state.population}) == 20
    # the status line tells how many were mutated once more, as their origins do
    extra = rescued(ev, action)
    if extra:
        assert f"; {len(extra)} of 18 children mutated once more: the parents differ too little" in msg
    else:
        assert msg == f"generation 2: {action} of 2 parents"
    # every child still descends from the two parents it was bred from
    assert all(set(o.parents) == {a, b} for o in ev.state.origins[2:])
    for o in extra:  # mutated once by one of the library's mutations
        made, mutation = o.operator.split("+")
        assert made == action and mutation in O.MUTATIONS


def test_the_siblings_of_the_walk_needed_mutations_and_the_lineage_names_them():
    ev, (a, b) = siblings(3)  # both children of picture 0 differ from it in one place
    msg = ev.recombine("crossover")
    extra = rescued(ev, "crossover")
    assert len(extra) >= 9, msg
    i = next(j for j, o in enumerate(ev.state.origins) if o.operator.startswith("crossover+"))
    newest = ev.lineage(i)[0]
    assert newest.operator == ev.state.origins[i].operator and set(newest.parents) == {a, b}
    assert {x.index for x in ev.lineage(i) if x.generation == 1} == {a, b}


def test_a_recombination_of_siblings_is_bred_the_same_way_from_the_same_seed():
    def run():
        ev, _ = siblings(4)
        msg = ev.recombine("crossover")
        return msg, [g.to_json() for g in ev.state.population], ev.state.origins
    assert run() == run()


@pytest.mark.parametrize("action", sorted(O.MUTATIONS))
def test_a_mutation_of_a_tiny_coding_part_fills_every_slot_with_a_new_picture(action):
    # (hsv-to-rgb (plus x y)): a transposition or rotation has two or three distinct results
    tiny = Genome((ChromosomeString(2, (C("hsv-to-rgb"), C("plus"), C("x"), C("y"), C("radius"))),))
    rng = np.random.default_rng(1)
    ev = Evolution(GalleryState([tiny] + random_population(rng, 19)), rng)
    ev.select(0, True)
    msg = ev.mutate(action)
    assert nearest(preview(ev.state.population))[1:].min() >= SAME, msg
    extra = rescued(ev, action)
    assert (f"; {len(extra)} of 19 children mutated once more: the parent has too few distinct" in msg) == bool(extra)
    assert all(o.parents == (0,) for o in ev.state.origins[1:])


def test_a_students_other_operator_is_not_run_to_fill_slots():
    # a crossover click runs the library's mutations to fill slots, never a student's (that runs
    # only when its own button, or evolve, is pressed)
    def broken(genome, rng):
        raise AssertionError("a student's operator ran")
    mutations = {"mine": broken, "substitution": O.substitution}
    ev, _ = siblings(3)
    ev = Evolution(ev.state, ev.rng, mutations=mutations)
    msg = ev.recombine("crossover")
    assert "mutated once more" in msg and {o.operator for o in rescued(ev, "crossover")} == {"crossover+substitution"}


def test_distinct_children_goes_on_to_mutate_at_once_when_its_iterator_only_repeats():
    rng = np.random.default_rng(4)
    parent = random_population(rng, 1)[0]
    drawn = []

    def copies():
        while True:
            drawn.append(1)
            yield parent
    mutated = []

    def mutate(c):
        mutated.append(O.substitution(c, rng))
        return mutated[-1]
    kids = distinct_children([parent], copies(), 6, mutate=mutate, draws=3)
    assert nearest(preview([parent] + kids)).min() >= SAME
    assert all(any(k is m for m in mutated) for k in kids)
    assert len(drawn) == 6 * 3  # one batch of draws per slot, all copies: then mutations
    # with nothing to go on to, the slots keep their copies (bounded, as before)
    assert distinct_children([parent], copies(), 2, tries=1, draws=2) == [parent] * 2


def test_dark_children_of_a_lively_parent_are_drawn_again():
    # the first generation has no dark picture; nor have the children of its pictures
    rng = np.random.default_rng(7)
    ev = Evolution(GalleryState(random_population(rng, 20)), rng)
    dark = 0
    for i in range(4):
        ev.select(i, True)
        ev.next_generation()
        dark += int(variety.dark(preview(ev.state.population[1:])).sum())
        ev.undo()
        ev.state.selected.clear()
    assert not variety.dark(preview(ev.state.population)).any()
    assert dark == 0


def test_genomes_a_mutation_does_not_fit_still_get_their_slots_filled():
    # one string with a head of one chromosome: no root transposition fits it (it raises), so
    # the children are mutated once more by the others
    rng = np.random.default_rng(2)
    ev = Evolution(GalleryState(random_population(rng, 20, n_strings=1, head_length=1)), rng)
    ev.select(0, True)
    assert ev.mutate("substitution").startswith("generation 1")
    ev.select(1, True)
    ev.select(2, True)
    msg = ev.recombine("crossover")
    assert msg.startswith("generation 2: crossover of 2 parents; "), msg
    assert all(o.operator != "crossover+root_transposition" for o in ev.state.origins)
    for k in range(6):  # evolve draws root transposition a quarter of the time: it gives way too
        for i in list(ev.state.selected):
            ev.select(i, False)
        ev.select(k, True)
        msg = ev.next_generation()
        assert msg.startswith(f"generation {3 + k}: "), msg
        assert all("root_transposition" not in o.operator for o in ev.state.origins)
