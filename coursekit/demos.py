"""Instructor demos: the whole thing, live, from one command (``coursekit demo NAME``).

- ``swimmers``: evolve a population of swimmers (paper section 2) in the batched simulator and
  write what a lecture wants to show: the best creature's genome, a picture of it, a GIF of it
  swimming, the fitness plot of the run, and its audit (:mod:`coursekit.creatures.audit`: does
  it swim, or exploit the simulator?).
- ``pictures``: breed genetic pictures (paper section 3) in the click-to-select gallery: the CLI
  opens ``demos/picture_breeding.ipynb`` in JupyterLab.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from coursekit.profile import sized


def swimmers(out="swimmers-demo", *, population: int | None = None, generations: int | None = None,
             seconds: float | None = None, seed: int = 0, progress: bool = True) -> dict:
    """Evolve swimmers and write ``best.json``, ``best.png``, ``best.gif`` and ``fitness.png`` to ``out``.

    Sizes default by profile (classroom: 60 creatures, 10 generations, 5 s swims; ci: tiny).

    Returns:
        A summary dict (also written as ``summary.json``).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from coursekit.creatures import evolve_swimmers, simulate
    from coursekit.creatures.audit import audit
    from coursekit.creatures.render import animate, render
    from coursekit.atomic import atomic_write

    population = population or sized(classroom=60, ci=6)
    generations = sized(classroom=10, ci=1) if generations is None else generations
    seconds = seconds or sized(classroom=5.0, ci=0.5)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    result = evolve_swimmers(generations=generations, rng=rng, population_size=population, seconds=seconds,
                             progress=progress, random_options=dict(max_parts=16))
    best = result.best
    atomic_write(out / "best.json", best.to_json())
    render(best, out / "best.png")
    replay = simulate([best], seconds, record_every=3)
    animate(best, replay.trajectory[0], out / "best.gif", fps=20)
    report = audit([best], seconds)[0]  # is it swimming, or exploiting the simulator?
    fig, ax = plt.subplots(figsize=(6, 3.5))
    result.history.plot(ax=ax)
    ax.set_ylabel("fitness: swimming speed (m/s)")
    ax.set_title(f"Swimmers: {population} creatures, {generations} generations")
    ax.annotate(f"champion: {report.speed:.3f} m/s = {report.body_lengths_per_second:.3f} body lengths/s\n"
                f"(body length {report.body_length:.2f} m)", xy=(0.02, 0.97), xycoords="axes fraction",
                va="top", fontsize=8, bbox=dict(boxstyle="round", fc="white", alpha=0.8))
    fig.tight_layout()
    fig.savefig(out / "fitness.png", dpi=100)
    plt.close(fig)
    summary = {
        "population": population, "generations": generations, "seconds": seconds, "seed": seed,
        "best_fitness": float(result.best_fitness), "best_parts": int(best.expand().body.n_bodies),
        "best_speed": report.speed, "best_body_length": report.body_length,
        "best_body_lengths_per_second": report.body_lengths_per_second,
        "audit": str(report), "audit_passed": report.passed,
        "history_best": [float(x) for x in result.history.best],
        "files": sorted(p.name for p in out.iterdir()),
    }
    atomic_write(out / "summary.json", json.dumps(summary, indent=2))
    return summary
