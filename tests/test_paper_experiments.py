"""The paper's section 4.1 experiments that ship with the kit (``coursekit/data/paper_experiments.json``,
made by ``benchmarks/data/paper_experiments.py``, loaded by :mod:`coursekit.creatures.experiments`):
every setting and seed is there, the numbers are finite and hang together, the final champions
score what the simulator scores them, and a quick run of the script writes a file that loads."""

import importlib.util
import json
import math
from pathlib import Path

import numpy as np
import pytest

from coursekit.creatures import evolution, simulate
from coursekit.creatures.audit import REFINE, body_length
from coursekit.creatures.experiments import paper_experiments

ROOT = Path(__file__).resolve().parent.parent
spec = importlib.util.spec_from_file_location("paper_experiments_script", ROOT / "benchmarks" / "data" / "paper_experiments.py")
script = importlib.util.module_from_spec(spec)
spec.loader.exec_module(script)


@pytest.fixture(scope="module")
def data():
    return paper_experiments()


def test_the_shipped_file_has_every_setting_and_seed_of_the_script(data):
    assert set(data.runs) == set(script.SETTINGS)
    assert data.groups == script.GROUPS
    for name, setting in script.SETTINGS.items():
        assert {k: v for k, v in data.settings[name].items() if k in setting} == setting
    seeds = data.sizes["seeds"]
    assert seeds >= 2, "one seed cannot show a spread"
    for name, runs in data.runs.items():
        assert [r.seed for r in runs] == list(range(seeds)), name
        for unit in ("ms", "bl"):
            curves = data.curves(name, unit)
            assert curves.shape == (seeds, data.sizes["generations"] + 1)
            assert np.all(np.isfinite(curves)) and np.all(curves >= 0)
    assert data.command.startswith("python benchmarks/data/paper_experiments.py")
    assert len(data.coursekit_commit.split("+")[0]) == 40


def test_elitism_keeps_every_best_curve_from_falling(data):
    # evolve_swimmers keeps the best fifth unchanged and does not score them again (ga.evolve
    # carries their fitness over), so the best of a generation is never below the one before
    source = Path(evolution.__file__).read_text()
    assert "elite = max(1, math.ceil(len(population) / 5))" in source
    for name, runs in data.runs.items():
        for r in runs:
            assert np.all(np.diff(r.best_ms) >= 0), (name, r.seed, r.best_ms)
            assert r.best_ms[-1] >= r.best_ms[0]
            # body lengths per second is the same creature's fitness over its length: zero together
            assert np.array_equal(r.best_ms > 0, r.best_bl > 0), (name, r.seed)


def test_the_final_champions_score_what_the_simulator_scores_them(data):
    runs = [r for rs in data.runs.values() for r in rs]
    champions = [r.champion() for r in runs]
    assert all(c.expand().body.n_parts == r.champion_parts for c, r in zip(champions, runs))
    seconds = data.sizes["seconds"]
    raw = simulate(champions, seconds).fitness
    fine = simulate(champions, seconds, substeps=REFINE).fitness  # the evaluation re-scores its best in 8 sub-steps
    # scored either as it swam, or (if it was among the best of its batch) the lower of the two
    off = np.array([min(abs(r.best_ms[-1] - a), abs(r.best_ms[-1] - min(a, b))) / a for r, a, b in zip(runs, raw, fine)])
    # The file was made on a machine with AVX-512: on one (an Intel Xeon) all 35 score its figures
    # to every digit. Elsewhere a rare one does not (on an AMD EPYC with AVX2 only, one by 3.8 %): numpy's
    # AVX2 and AVX-512 kernels of tan, exp, log and arctan differ in the last bit, and so does
    # OpenBLAS's solve on other processors (coursekit.creatures.champions). A change to the physics
    # moves them all, so the test asks for the bulk: with 1 % more drag, 86 % are within 2 %
    # (median 0.45 %, worst 38 %), and it fails.
    assert np.median(off) <= 0.005, np.round(off, 4)
    assert np.mean(off <= 0.02) >= 0.9, np.round(off, 4)
    assert np.all(off <= 0.2), np.round(off, 4)
    for r, c in zip(runs, champions):
        assert r.best_bl[-1] == pytest.approx(r.best_ms[-1] / body_length(c.expand().body), rel=1e-9)
        assert r.champion_bl == pytest.approx(r.champion_ms / body_length(c.expand().body), rel=1e-9)


def test_a_quick_run_of_the_script_writes_a_file_that_loads(tmp_path):
    out = tmp_path / "experiments.json"
    only = ["1-DOF revolute only", "multi-DOF joints"]
    assert script.main(["--quick", "--out", str(out), "--workers", "1", "--population", "4", "--seconds", "0.3",
                        "--seeds", "2", "--only", *only]) == 0
    got = paper_experiments(out)
    assert set(got.runs) == set(only) and got.groups == {"joint types": only}
    assert got.sizes == {**script.QUICK, "population": 4, "seconds": 0.3, "seeds": 2}
    assert "--quick" in got.command and got.settings["multi-DOF joints"]["joint_types"] == script.MULTI_DOF
    for name in only:
        curves = got.curves(name)
        assert curves.shape == (2, script.QUICK["generations"] + 1) and np.all(np.diff(curves, axis=1) >= 0)
        assert all(math.isfinite(r.champion_ms) for r in got.runs[name])
    # a broken file is refused, naming the place
    doc = json.loads(out.read_text())
    doc["results"]["multi-DOF joints"][1]["best_ms"][0] = float("nan")
    out.write_text(json.dumps(doc))
    with pytest.raises(ValueError, match=r"'multi-DOF joints', seed 1: field 'best_ms'"):
        paper_experiments(out)
    del doc["results"]["multi-DOF joints"][1]
    out.write_text(json.dumps(doc))
    with pytest.raises(ValueError, match=r"one run per seed"):
        paper_experiments(out)
