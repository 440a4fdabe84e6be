"""The compiled ABA of ``benchmarks/compiled_aba.py`` (what a compiled step would buy, issue #11)
computes the textbook ABA's accelerations, so that its timings measure the same work."""

import importlib.util
import subprocess
import sys
from pathlib import Path

import numpy as np
from hypothesis import given, settings, strategies as st

from coursekit.creatures import Creature
from coursekit.creatures.physics import reference
from coursekit.creatures.physics.water import DRAG_COEFFICIENT, drag_diagonal

SCRIPT = Path(__file__).parents[1] / "benchmarks" / "compiled_aba.py"
_spec = importlib.util.spec_from_file_location("compiled_aba", SCRIPT)
bench = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(bench)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 4), speed=st.floats(0.0, 3.0))
def test_the_compiled_aba_equals_the_textbook_one_on_random_creatures(seed, n, speed):
    rng = np.random.default_rng(seed)
    trees = [Creature.random(rng, joint_types=["revolute", "prismatic"]).expand().body for _ in range(n)]
    joints = [t.n_bodies - 1 for t in trees]
    q = rng.uniform(-1.0, 1.0, sum(joints))
    qd, tau = rng.normal(0.0, speed, sum(joints)), rng.normal(0.0, 0.5, sum(joints))
    v0 = rng.normal(0.0, speed, (n, 6))
    a0, qdd = bench.compiled_aba(bench.pack(trees), q, qd, v0, tau)
    at = 0
    for k, t in enumerate(trees):
        js = slice(at, at + joints[k])
        a0r, qddr, _ = reference.aba(t, q[js], qd[js], v0[k], tau[js], damping=drag_diagonal(t.half_extents, DRAG_COEFFICIENT))
        scale = 1.0 + max(np.abs(a0r).max(), np.abs(qddr).max(initial=0.0))
        assert np.abs(a0[k] - a0r).max() <= 1e-10 * scale
        assert np.abs(qdd[js] - qddr).max(initial=0.0) <= 1e-10 * scale
        at += joints[k]


def test_the_benchmark_checks_then_times_both_abas():
    run = subprocess.run([sys.executable, "-m", "coursekit", "bench", "compiled_aba", "--quick"], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    rows = [line.split() for line in run.stdout.splitlines() if line.strip()[:1].isdigit()]
    assert [r[0] for r in rows] == ["1", "3"]
    assert all(float(r[-1]) <= 1e-10 and float(r[2]) > 0 and float(r[3]) > 0 for r in rows), run.stdout
