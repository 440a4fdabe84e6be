"""The simulator's kernels compiled once per grader, each sandboxed notebook given a copy (coursekit.grading.warm)."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from coursekit.grading import sandbox, warm

ROOT = Path(__file__).resolve().parent.parent
HAVE = sandbox.available() is None

# Counts, in this process, the kernels numba loaded from its cache and those it had to compile.
COUNT = """
import numba
from coursekit.creatures import simulate
from coursekit.creatures.champions import champions
from coursekit.creatures.physics import compiled, kernels
simulate(champions()[:2], 0.5)
stats = [f.stats for m in (compiled, kernels) for f in vars(m).values()
         if isinstance(f, numba.core.registry.CPUDispatcher) and f.signatures]
print(sum(sum(s.cache_hits.values()) for s in stats), sum(sum(s.cache_misses.values()) for s in stats))
"""


@pytest.mark.skipif(not HAVE, reason=f"no sandbox here: {sandbox.available()}")
def test_a_sandboxed_notebook_loads_the_compiled_kernels_instead_of_compiling_them(tmp_path):
    box = tmp_path / "box"
    (box / "work").mkdir(parents=True)
    (box / "home").mkdir()
    kernels = warm.copy_into(box / "numba")
    assert kernels is not None and any(kernels.rglob("*.nbc"))
    env = {"PATH": "/usr/bin:/bin", "PYTHONPATH": str(ROOT), "HOME": str(box / "home"), "PYTHONNOUSERSITE": "1",
           "NUMBA_CACHE_DIR": str(kernels)}
    run = subprocess.run(sandbox.command(box, show=[ROOT / "coursekit"]) + [sys.executable, "-c", COUNT], env=env,
                         capture_output=True, text=True, timeout=600, stdin=subprocess.DEVNULL)
    assert run.returncode == 0, run.stderr[-2000:]
    hits, misses = map(int, run.stdout.split()[-2:])
    assert hits > 0 and misses == 0, (hits, misses)  # every kernel the swim called was loaded, none compiled


def test_a_notebook_gets_its_own_copy_without_the_code_of_withheld_modules(tmp_path, monkeypatch):
    grader = tmp_path / "grader" / "physics_0123abcd"
    grader.mkdir(parents=True)
    names = ["kernels.rkn-210.py311.nbi", "kernels.rkn-210.py311.1.nbc", "integrate.rkn_step-40.py311.nbi",
             "integrate.rkn_step-40.py311.1.nbc"]
    for name in names:
        (grader / name).write_bytes(b"machine code")
    monkeypatch.setattr(warm, "cache", lambda: grader.parent)
    copy = warm.copy_into(tmp_path / "box" / "numba", withheld=["/somewhere/coursekit/creatures/physics/integrate.py"])
    assert sorted(p.name for p in copy.rglob("*") if p.is_file()) == sorted(names[:2])
    (copy / "physics_0123abcd" / names[0]).write_bytes(b"a notebook's own")  # what a notebook writes stays in its box
    assert (grader / names[0]).read_bytes() == b"machine code"


def test_without_a_cache_the_notebook_compiles_the_kernels_itself(tmp_path, monkeypatch):
    monkeypatch.setattr(warm, "_READY", {})
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "not-a-folder"))
    (tmp_path / "not-a-folder").write_text("a file where the cache folder would be")
    assert warm.cache() is None and warm.copy_into(tmp_path / "box") is None
    assert not (tmp_path / "box").exists()


@pytest.mark.skipif(not HAVE, reason=f"no sandbox here: {sandbox.available()}")
def test_coursekit_grade_says_when_it_compiles_the_simulator_and_does_so_once(tmp_path):
    bad = tmp_path / "01_selection.ipynb"
    bad.write_text('{"cells": [')  # unreadable: graded at once (0 points), no kernel started
    env = {**os.environ, "XDG_CACHE_HOME": str(tmp_path / "cache"), "PYTHONPATH": str(ROOT)}
    runs = [subprocess.run([sys.executable, "-m", "coursekit", "grade", str(bad), "--json", str(tmp_path / "r.json")],
                           cwd=tmp_path, capture_output=True, text=True, env=env, timeout=600) for _ in range(2)]
    assert [r.returncode for r in runs] == [0, 0], runs[0].stderr[-2000:]  # graded at once: 0 points
    said = "coursekit grade: compiling the simulator once"
    assert said in runs[0].stderr and said not in runs[1].stderr  # the second run loads what the first compiled
    assert any((tmp_path / "cache" / "coursekit" / "numba").rglob("*.nbc"))
