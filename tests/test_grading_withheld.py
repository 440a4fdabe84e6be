"""The library as the grading sandbox shows it: each graded function's body withheld, the rest intact.

End to end (a notebook that takes over the harvest, or loads the library's compiled code, scores
nothing for those functions): tests/test_grading_integrity.py, hijacks_harvest and reads_git.
"""

import importlib.util
import inspect

import numpy as np
import pytest

import coursekit.ga.selection as selection
from coursekit.grading import checks as registry
from coursekit.grading.withheld import withhold


def _load(path, name):
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_every_graded_function_can_be_withheld(tmp_path):
    """The grader refuses to grade when a reference cannot be withheld, so every check's must be."""
    registry._load()
    references = sorted({r for c in registry.REGISTRY.values() for r in c.reference})
    assert len(references) >= 20
    replacements, _ = withhold(references, tmp_path)
    modules = {r.partition(":")[0] for r in references}
    assert len(replacements) == len(modules)
    for copy, origin in replacements:
        compile(copy.read_text(), origin, "exec")
        assert copy.stat().st_mode & 0o044 == 0o044  # readable by the sandbox's user


def test_a_withheld_function_raises_and_its_neighbours_still_work(tmp_path):
    (copy, origin), = withhold(["coursekit.ga.selection:tournament"], tmp_path)[0]
    assert origin == selection.__file__
    fresh = _load(copy, "withheld_selection")
    fitness = np.arange(10.0)
    with pytest.raises(RuntimeError, match="coursekit's own tournament is withheld"):
        fresh.tournament(fitness, 4, np.random.default_rng(0))
    assert np.array_equal(fresh.truncation(fitness, 6, np.random.default_rng(1)),
                          selection.truncation(fitness, 6, np.random.default_rng(1)))
    # only the body's lines change: what comes before the function keeps its line numbers (tracebacks)
    first = inspect.getsourcelines(selection.tournament)[1]
    original = open(origin).read().splitlines()
    assert copy.read_text().splitlines()[:first] == original[:first]
    assert "np.argmax" not in inspect.getsource(fresh.tournament)


def test_a_method_is_found_by_its_qualified_name(tmp_path):
    (copy, _), = withhold(["coursekit.creatures.genotype:Creature.expand"], tmp_path)[0]
    text = copy.read_text()
    assert "coursekit's own Creature.expand is withheld" in text
    assert "def figure1_snake" in text or "def random" in text  # the class's other methods stay


@pytest.mark.parametrize("path, what", [("numpy:sum", "expected 'coursekit.module:function'"),
                                        ("coursekit.ga.selection", "expected 'coursekit.module:function'"),
                                        ("coursekit.ga.selection:no_such", "no such function"),
                                        ("coursekit.ga.selection:np", "no such function")])
def test_a_reference_that_names_no_library_function_is_an_error(tmp_path, path, what):
    with pytest.raises(ValueError, match=what):
        withhold([path], tmp_path)


def test_what_the_library_itself_needs_is_refused_but_not_withheld():
    """Exercise 02's decode is graded beside the picture operators, which decode genomes with the
    library's karva: the sandbox keeps it (refused only while decode runs), and withholds the rest."""
    from coursekit.grading.withheld import of

    checks = registry.for_notebook("02_picture_mutations")
    withheld = of(checks)
    assert "coursekit.pictures.genome:karva" not in withheld
    assert "coursekit.grading.checks.ex02_picture_mutations:karva" in withheld  # the check's own oracle
    assert "coursekit.pictures.operators:transposition" in withheld
    assert "coursekit.grading.checks.ex07_swimming_physics:face_integral_drag" in of(registry.for_notebook("07_swimming_physics"))


@pytest.mark.parametrize("stem, second", [("01_selection", {"truncation", "roulette"}), ("02_picture_mutations", {"decode"}),
                                          ("06_wire_a_brain", {"resolve"}), ("08_fitness_and_reproduction", {"reproduce"}),
                                          ("03_picture_recombination", set()), ("05_creature_operators", set()),
                                          ("07_swimming_physics", set())])
def test_what_the_library_needs_elsewhere_is_withheld_in_a_second_run(stem, second):
    """A function the library needs while some checks are graded (karva for the picture operators)
    answers another (decode): that one is graded in a second run of the notebook whose sandbox
    withholds every reference of the notebook's checks; every check is graded exactly once, in a
    sandbox without any of its own references."""
    from coursekit.grading.withheld import helpers, runs

    checks = registry.for_notebook(stem)
    groups = runs(checks)
    assert sorted(c.name for g, _ in groups for c in g) == sorted(c.name for c in checks)
    assert [{c.function for c in g} for g, _ in groups[1:]] == ([second] if second else [])
    for group, held in groups:
        for c in group:
            assert helpers(set(c.reference)) <= set(held), c.name
    if second:
        uses = {r for c in checks for r in c.library_uses}
        assert uses <= set(groups[1][1]) and not uses & set(groups[0][1])


def test_a_graded_functions_own_helpers_are_withheld_with_it():
    """A public operator that hands its work to a private one, or a constructor to the builder
    behind it, would leave the answer one call away: what only withheld functions use goes too,
    what the rest of the library uses stays."""
    from coursekit.grading.withheld import helpers, of, refused

    mutations = of(registry.for_notebook("02_picture_mutations"))
    for helper in ("_mutated", "_transposition", "_root_transposition", "_head_tail_rotation"):
        assert f"coursekit.pictures.operators:{helper}" in mutations
    assert "coursekit.pictures.genome:karva" not in mutations  # the operators decode with it
    assert "coursekit.pictures.genome:Genome.copy" not in mutations
    assert "coursekit.creatures.generation:figure1_snake" in of(registry.for_notebook("06_wire_a_brain"))
    assert "coursekit.creatures.generation:paddle_turtle" not in of(registry.for_notebook("06_wire_a_brain"))
    physics = registry.for_notebook("07_swimming_physics")
    assert "coursekit.creatures.physics.integrate:_rk4" in of(physics)
    assert "coursekit.creatures.physics.odes:solution" in of(physics)  # the notebook's reference is SciPy's
    reproduce, fitness = registry.get("swimmers.reproduce"), registry.for_notebook("08_fitness_and_reproduction")
    assert "coursekit.ga.variation:largest_remainder" in refused(reproduce, of(fitness))  # evolution needs it:
    assert "coursekit.ga.variation:largest_remainder" not in of(fitness)                  # kept in the first run
    # a helper shared with a function that is not withheld stays
    assert helpers({"coursekit.pictures.operators:transposition"}) >= {"coursekit.pictures.operators:_transposition"}
    assert "coursekit.pictures.operators:_mutated" not in helpers({"coursekit.pictures.operators:transposition"})


def test_the_call_graph_sees_uses_through_re_exports_and_module_level_tables():
    from coursekit.grading.withheld import _users

    users, containers = _users()
    # evolution.py imports simulate through the package (from coursekit.creatures import ...): still a use
    assert "coursekit.creatures.evolution:_swim" in users["coursekit.creatures.simulate:simulate"]
    # a module-level table of functions is a node of its own, used by what reads it
    assert "coursekit.creatures.operators:MODIFY_STEPS" in containers
    assert users["coursekit.creatures.operators:_mutate_size"] == {"coursekit.creatures.operators:MODIFY_STEPS"}
    assert "coursekit.creatures.operators:mutate" in users["coursekit.creatures.operators:MODIFY_STEPS"]
