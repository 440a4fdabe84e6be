"""evolve_swimmers: the paper's GA on creatures, fitness from the batched simulator."""

import numpy as np
import pytest

from coursekit.creatures import Creature, audit, operators
from coursekit.creatures.evolution import Mated, evolve_swimmers
from coursekit.creatures.simulate import simulate

SMALL = dict(population_size=8, seconds=0.5, settle=0.1, progress=False, random_options=dict(max_parts=8))


def test_evolution_is_deterministic_elitist_and_scores_what_the_simulator_scores():
    a = evolve_swimmers(generations=2, rng=np.random.default_rng(3), **SMALL)
    b = evolve_swimmers(generations=2, rng=np.random.default_rng(3), **SMALL)
    assert [c.to_json() for c in a.population] == [c.to_json() for c in b.population]
    assert a.history.to_json() == b.history.to_json()
    best = a.history.best
    assert len(best) == 3 and all(x <= y + 1e-12 for x, y in zip(best, best[1:]))  # survivors are kept
    # the recorded fitness is exactly the simulator's score of the final population, except that
    # the fittest are re-scored with the physics in the audit's eight sub-steps and keep the lower
    # score, or 0 where the finer step takes more than the audit allows
    again = simulate(a.population, 0.5, settle=0.1).fitness
    fine = simulate(a.population, 0.5, settle=0.1, substeps=audit.REFINE).fitness
    floor = np.array([audit.NEGLIGIBLE * audit.body_length(c.expand().body) for c in a.population]) / 0.5
    exploit = (fine < audit.FINE_SPEED_SHARE * again) & (again - fine > floor)
    refined = a.fitness != again
    assert refined.sum() <= 3 * 3  # at most the top three of each of the 3 batches
    np.testing.assert_array_equal(a.fitness[refined], np.where(exploit, 0.0, np.minimum(again, fine))[refined])
    assert np.all(a.fitness <= again)


def test_a_speed_that_comes_from_the_time_step_does_not_survive_selection():
    from coursekit.creatures.evolution import SwimmerFitness

    snake = Creature.figure1_snake()
    coarse = simulate([snake], 2.0, dt=1 / 20).fitness[0]
    fine = simulate([snake], 2.0, dt=1 / 20, substeps=audit.REFINE).fitness[0]
    scored = SwimmerFitness(2.0, {"dt": 1 / 20}, refine=1)(None, [snake])[0]
    assert scored == min(coarse, fine) and coarse != fine and fine >= audit.FINE_SPEED_SHARE * coarse


def test_a_creature_that_swims_on_the_time_step_scores_nothing():
    # a random creature that swims 0.028 m/s at the step, 0.0003 in eight sub-steps and 0.00003 in
    # 32 (with its self-contacts off it swims 0.046 m/s at both): its speed is integration error
    from coursekit.creatures.evolution import SwimmerFitness
    from coursekit.data import creature

    cheat = creature("time_step_creature")
    coarse, fine = (simulate([cheat], 10.0, substeps=k).fitness[0] for k in (1, audit.REFINE))
    assert fine < 0.1 * coarse and coarse > 0.01
    assert SwimmerFitness(10.0, refine=1)(None, [cheat]) == [0.0]


def test_a_creature_that_swims_through_itself_scores_nothing():
    # in eight sub-steps its parts sit sunk in each other in three frames of four and it keeps 95 %
    # of its speed; in 24 they never sink over 4 % and it swims a tenth as fast
    from coursekit.creatures.evolution import SwimmerFitness
    from coursekit.data import creature

    cheat = creature("step_exploit_creature")
    fine, deep = (simulate([cheat], 10.0, substeps=k, record_every=audit.FRAME) for k in (audit.REFINE, audit.DEEP_REFINE))
    assert audit.sunk_share([cheat], fine.trajectory)[0] > audit.SUNK_SHARE and audit.sunk_share([cheat], deep.trajectory)[0] == 0.0
    assert deep.fitness[0] < 0.25 * fine.fitness[0]
    assert SwimmerFitness(10.0, refine=1)(None, [cheat]) == [0.0]


def test_student_operators_plug_in():
    calls = {"mutate": 0, "cross": 0}

    def my_mutate(c, rng):  # no rate parameter, as a student might write it
        calls["mutate"] += 1
        return operators.mutate(c, rng)

    def my_crossover(a, b, rng):
        calls["cross"] += 1
        return operators.crossover(a, b, rng)

    r = evolve_swimmers(generations=1, rng=np.random.default_rng(0), mutate=my_mutate, crossover=my_crossover, graft=None,
                        ratios=(0.5, 0.5, 0.0), **SMALL)
    assert calls["mutate"] > 0 and calls["cross"] > 0
    assert all(isinstance(c, Creature) for c in r.population)


def test_mated_children_are_valid_and_inputs_untouched():
    rng = np.random.default_rng(1)
    a, b = Creature.random(rng), Creature.random(rng)
    ja, jb = a.to_json(), b.to_json()
    c1, c2 = Mated(operators.crossover)(a, b, rng)
    for c in (c1, c2):
        c.validate()
        c.expand().body.validate()
    assert (a.to_json(), b.to_json()) == (ja, jb)


def test_bad_arguments_are_named():
    with pytest.raises(ValueError, match="population_size"):
        evolve_swimmers(generations=1, rng=np.random.default_rng(0), population_size=1)
    with pytest.raises(ValueError, match="ratios"):
        evolve_swimmers(generations=1, rng=np.random.default_rng(0), ratios=(1, -1, 0), **SMALL)
    for ratios in (None, 5, ("a", 1, 1)):
        with pytest.raises(ValueError, match="ratios: need three shares >= 0"):
            evolve_swimmers(generations=1, rng=np.random.default_rng(0), ratios=ratios, **SMALL)
    with pytest.raises(TypeError, match="crossover: must be a function or None, got int"):
        evolve_swimmers(generations=1, rng=np.random.default_rng(0), crossover=5, **SMALL)
    with pytest.raises(TypeError, match="graft: must be a function or None, got str"):
        evolve_swimmers(generations=1, rng=np.random.default_rng(0), graft="graft", **SMALL)
    with pytest.raises(TypeError, match="mutate: must be a function, got NoneType"):
        evolve_swimmers(generations=1, rng=np.random.default_rng(0), mutate=None, **SMALL)
    with pytest.raises(TypeError, match="population: expected a list of creatures, got int"):
        evolve_swimmers(5, generations=1, rng=np.random.default_rng(0))
    with pytest.raises(TypeError, match="random_options: expected a dict of Creature.random options, got int"):
        evolve_swimmers(generations=1, rng=np.random.default_rng(0), population_size=4, random_options=5)


def test_a_run_on_worker_processes_or_dask_equals_the_serial_run_bit_for_bit():
    # the generation is dealt into one batch per worker; a creature's trajectory does not depend
    # on its batch, so every back end breeds the very same creatures
    from concurrent.futures import ProcessPoolExecutor

    from distributed import Client, LocalCluster

    def run(executor=None):
        r = evolve_swimmers(generations=2, rng=np.random.default_rng(5), population_size=7, seconds=0.5,
                            progress=False, random_options=dict(max_parts=6), executor=executor)
        return r.history, [c.to_json() for c in r.population]

    serial = run()
    with ProcessPoolExecutor(2) as pool:
        assert run(pool) == serial
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, Client(cluster) as client:
        assert run(client) == serial
    assert serial[0].best[-1] > 0


def test_a_run_stopped_after_a_generation_resumes_to_the_uninterrupted_result(tmp_path):
    from coursekit.creatures import resume_swimmers

    options = dict(population_size=6, seconds=0.5, progress=False, random_options=dict(max_parts=6))
    whole = evolve_swimmers(generations=2, rng=np.random.default_rng(9), **options)
    evolve_swimmers(generations=1, rng=np.random.default_rng(9), checkpoint=tmp_path / "run.ckpt", **options)
    resumed = resume_swimmers(tmp_path / "run.ckpt", generations=2, seconds=0.5, progress=False)
    assert resumed.history == whole.history
    assert [c.to_json() for c in resumed.population] == [c.to_json() for c in whole.population]
