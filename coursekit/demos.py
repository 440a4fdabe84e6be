"""Instructor demos: the whole thing, live, from one command (``coursekit demo [NAME]``).

- ``coursekit demo`` (no name): :func:`both` -- the swimmers and the pictures into one folder,
  with an ``index.html`` that opens them all: the live run's champion swimming (MP4, GIF), its
  key frames (the paper's Figure 3), the fitness plot, the shipped champions beside it, and the
  gallery of a scripted breeding session.
- ``swimmers``: :func:`swimmers` -- evolve a population of swimmers (paper section 2), on every
  core, and write what a lecture wants to show: the best creature's genome, a picture of it, a
  film of it swimming, its key frames, the fitness plot of the run, and its audit
  (:mod:`coursekit.creatures.audit`: does it swim, or exploit the simulator?).
- ``pictures``: breed genetic pictures (paper section 3) in the click-to-select gallery: the CLI
  opens ``demos/picture_breeding.ipynb`` in JupyterLab. :func:`pictures` is the same loop with
  no one to click (for :func:`both`): the script picks the most colourful pictures.
"""

from __future__ import annotations

import html
import json
import os
import re
import time
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor
from multiprocessing import get_context
from pathlib import Path

import numpy as np

from coursekit.atomic import atomic_write
from coursekit.profile import sized

#: The swimmer films' frame size and rate (even sizes: H.264 needs them).
FILM_SIZE, FILM_FPS = (480, 360), 20
KEY_FRAMES, KEY_FRAME_SIZE = 4, (320, 240)


def _film(creature, trajectory, frame_times, folder: Path, stem: str, progress: bool | None = None) -> dict:
    """Write ``stem.mp4``, ``stem.gif`` (one pass) and ``stem-keyframes.png`` of a recorded swim."""
    from coursekit.creatures.render import animate, keyframes

    names = _names(stem)
    animate(creature, trajectory, [folder / names["mp4"], folder / names["gif"]], fps=FILM_FPS, size=FILM_SIZE,
            frame_times=frame_times, progress=progress)
    keyframes(creature, trajectory, folder / names["keyframes"], n=KEY_FRAMES, size=KEY_FRAME_SIZE, frame_times=frame_times)
    return names


def _names(stem: str) -> dict:
    return {"mp4": f"{stem}.mp4", "gif": f"{stem}.gif", "keyframes": f"{stem}-keyframes.png"}


def _films(creatures, seconds: float, folder: str, stems, progress: bool | None = None) -> list[dict]:
    """Swim ``creatures`` in one batch (the same swims as alone) and film each as ``stems[k]``
    (``progress``: the films' bars, see :func:`~coursekit.creatures.render.animate`)."""
    from coursekit.creatures import simulate

    if not creatures:
        return []
    replay = simulate(list(creatures), seconds, record_every=3)  # 20 frames per simulated second at dt = 1/60
    return [_film(c, replay.trajectory[k], replay.frame_times, Path(folder), stem, progress)
            for k, (c, stem) in enumerate(zip(creatures, stems))]


def _lowest_priority() -> None:
    """Run this process at the lowest priority, where the system has one (``os.nice``)."""
    if hasattr(os, "nice"):
        os.nice(19)


class _Budget:
    """An :func:`~coursekit.creatures.evolve_swimmers` callback that stops the run before a
    generation that, taking as long as the last one did, would end more than ``seconds`` after
    ``start`` (0: never stops it). What runs is the same run, generation by generation: only where
    it ends depends on the machine's speed."""

    def __init__(self, seconds: float, start: float):
        self.seconds, self.start, self.last = seconds, start, start
        self.stopped = False

    def __call__(self, result) -> bool:
        now = time.perf_counter()
        took, self.last = now - self.last, now
        self.stopped = 0 < self.seconds < now - self.start + took
        return self.stopped


def swimmer_sizes(population: int | None = None, generations: int | None = None, seconds: float | None = None,
                  workers: int | None = None, budget: float | None = None) -> tuple:
    """The swimmer demo's ``(population, generations, seconds, workers, budget)``: the given ones,
    checked (a ``ValueError`` names the one that is not allowed), the others by profile."""
    from coursekit.creatures.neural import is_int

    population = sized(classroom=100, ci=6) if population is None else population
    generations = sized(classroom=40, ci=1) if generations is None else generations
    seconds = sized(classroom=10.0, ci=0.5) if seconds is None else seconds
    if not (isinstance(seconds, (int, float)) and not isinstance(seconds, bool) and 0 < seconds < float("inf")):
        raise ValueError(f"seconds: must be a number of seconds > 0, got {seconds!r}")
    if not (is_int(population) and population >= 2):
        raise ValueError(f"population: must be an integer >= 2, got {population!r}")
    if workers is None:
        workers = min(os.cpu_count() or 1, population)
    elif not (is_int(workers) and 1 <= workers <= population):  # a process per creature at most
        raise ValueError(f"workers: must be an integer from 1 to the population ({population}), got {workers!r}")
    budget = sized(classroom=75.0, ci=0.0) if budget is None else budget
    if not (isinstance(budget, (int, float)) and budget >= 0):
        raise ValueError(f"budget: must be a number of seconds >= 0 (0: no limit), got {budget!r}")
    return population, generations, seconds, workers, budget


def swimmers(out: str | os.PathLike[str] = "swimmers-demo", *, population: int | None = None,
             generations: int | None = None, seconds: float | None = None, seed: int = 0, workers: int | None = None,
             budget: float | None = None, rhythm: float | None = None, progress: bool = True) -> dict:
    """Evolve swimmers and write the champion's files and the run's fitness plot to ``out``.

    Files: ``best.json``, ``best.png``, ``best.mp4`` and ``best.gif`` (the champion swimming, the
    camera following it), ``best-keyframes.png`` (Figure 3), ``fitness.png``, ``summary.json``,
    and for every shipped champion (:func:`coursekit.creatures.champions.hall_of_fame`) ``champion-K.*``
    films and key frames (a champion that is this run's best -- the demo's own run at its
    defaults ships as one -- is shown with the best's films, not filmed twice).

    Sizes default by profile (classroom: 100 creatures, 40 generations, 10 s swims, Sims' own
    evaluation time -- in 5 s swims evolution bred creatures that unfold once and stop after the
    5 s; ci: tiny). Randomly wired first swimmers (``rhythm=0``) bred 0.065 to 0.38 body lengths/s
    over five seeds within the 75 s budget on 2 cores, where 40 creatures bred 0.02 to 0.18; with
    rhythm, all 40 generations of seeds 0-2 bred 0.19 to 0.70, against 0.09 to 0.38 without
    (``benchmarks/NOTES.md``, "Rhythm").

    Args:
        budget: seconds the live evolution may take, so that the demo fits a lecture's break on
            any laptop: no generation is begun that, taking as long as the last one, would end
            after them (default by profile: classroom 75 s -- with the films and the audit after
            it, 1 to 1.5 minutes in all on 2 cores; ci and 0: no limit). The run is the same run
            either way, cut short: ``generations`` in the summary is what was bred, and
            ``--budget 0`` breeds them all.
        rhythm: the first generation's share of effectors driven by oscillators
            (``Creature.random``'s ``rhythm``; default :data:`~coursekit.creatures.generation.RHYTHM`;
            0: random creatures as the kit drew them before, as the shipped demo champion was bred).
        workers: processes the population swims in, at most one per creature (default: one per
            core; 1: this process).
            The run is bit for bit the same either way. With more than one, the shipped
            champions are filmed while evolution runs (in a process at the lowest priority) and
            the audit's five runs are spread over the workers.

    Returns:
        A summary dict (also written as ``summary.json``), with the wall times of its parts.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from coursekit.creatures import evolve_swimmers
    from coursekit.creatures.audit import audit
    from coursekit.creatures.champions import hall_of_fame
    from coursekit.creatures.generation import RHYTHM
    from coursekit.creatures.render import render

    population, generations, seconds, workers, budget = swimmer_sizes(population, generations, seconds, workers, budget)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    wall, t0 = {}, time.perf_counter()
    t = t0
    rng = np.random.default_rng(seed)
    fame = hall_of_fame()
    champions = [c.creature for c in fame]
    pool = ProcessPoolExecutor(workers) if workers > 1 else None
    auditor = None
    # The shipped champions are filmed while evolution runs, in a process of their own at the
    # lowest priority: it takes the core evolution leaves idle while it refines its best in this
    # process, not the workers' time. One of them may turn out to be the run's best, whose films
    # are then the best's.
    filming = (ProcessPoolExecutor(1, mp_context=get_context("spawn"), initializer=_lowest_priority)
               if pool is not None and champions else None)
    try:
        shot = (filming.submit(_films, champions, seconds, str(out), [f"champion-{k}" for k in range(len(champions))],
                               progress=False) if filming is not None else None)  # no bars under evolution's
        clock = _Budget(budget, t)
        result = evolve_swimmers(generations=generations, rng=rng, population_size=population, seconds=seconds,
                                 progress=progress, random_options=dict(max_parts=16, rhythm=RHYTHM if rhythm is None else rhythm),
                                 executor=pool, callback=clock)
        wall["evolution"] = time.perf_counter() - t
        best = result.best
        t = time.perf_counter()
        # The audit (is it swimming, or exploiting the simulator?) runs in the workers, its five
        # simulations spread over them, while this process films.
        auditor = ThreadPoolExecutor(1)
        auditing = auditor.submit(audit, [best], seconds, executor=pool)
        atomic_write(out / "best.json", best.to_json())
        render(best, out / "best.png")
        text = best.to_json()
        own = next((k for k, c in enumerate(champions) if c.to_json() == text), None)  # the run's best shipped
        if shot is not None:
            if own is None:  # filmed here while the champions' films end in their process
                films = _films([best], seconds, str(out), ["best"])[0]
            names = shot.result()
            if own is not None:  # already filmed as that champion: its files become the best's
                films = _names("best")
                for kind, name in names[own].items():
                    os.replace(out / name, out / films[kind])
                names[own] = films
        else:
            others = [k for k in range(len(champions)) if k != own]
            made = _films([best] + [champions[k] for k in others], seconds, str(out),
                          ["best"] + [f"champion-{k}" for k in others])
            films, names = made[0], dict(zip(others, made[1:]))
            if own is not None:
                names[own] = films
        shown = [{"name": c.name, "parts": int(c.creature.expand().body.n_bodies), "speed": c.speed,
                  "body_lengths_per_second": c.body_lengths_per_second, "command": c.command, **names[k]}
                 for k, c in enumerate(fame)]
        wall["films"] = time.perf_counter() - t
        report = auditing.result()[0]
        wall["films and audit"] = time.perf_counter() - t
    finally:
        for executor in (auditor, pool, filming):
            if executor is not None:
                executor.shutdown(cancel_futures=True)
    fig, ax = plt.subplots(figsize=(6, 3.5))
    result.history.plot(ax=ax)
    ax.set_ylabel("fitness: swimming speed (m/s)")
    bred = f"{result.generation} of {generations} generations (the {budget:g} s budget)" if clock.stopped else f"{generations} generations"
    ax.set_title(f"Swimmers: {population} creatures, {bred}")
    ax.annotate(f"champion: {report.speed:.3f} m/s = {report.body_lengths_per_second:.3f} body lengths/s\n"
                f"(body length {report.body_length:.2f} m)", xy=(0.02, 0.97), xycoords="axes fraction",
                va="top", fontsize=8, bbox=dict(boxstyle="round", fc="white", alpha=0.8))
    fig.tight_layout()
    fig.savefig(out / "fitness.png", dpi=100)
    plt.close(fig)
    wall["total"] = time.perf_counter() - t0
    summary = {
        "population": population, "generations": result.generation, "generations_planned": generations,
        "budget": budget, "stopped_by_budget": clock.stopped, "seconds": seconds, "seed": seed, "workers": workers,
        "rhythm": RHYTHM if rhythm is None else rhythm, "best_fitness": float(result.best_fitness), "best_parts": int(best.expand().body.n_bodies),
        "best_speed": report.speed, "best_body_length": report.body_length,
        "best_body_lengths_per_second": report.body_lengths_per_second,
        "audit": str(report), "audit_passed": report.passed,
        "history_best": [float(x) for x in result.history.best],
        "films": films, "champions": shown, "wall_seconds": {k: round(v, 2) for k, v in wall.items()},
    }
    summary["files"] = sorted({p.name for p in out.iterdir() if not p.name.startswith(".")} | {"summary.json"})
    atomic_write(out / "summary.json", json.dumps(summary, indent=2))
    return summary


def _colourful(images: np.ndarray) -> np.ndarray:
    """Hasler and Suesstrunk's colourfulness of ``(N, H, W, 3)`` images in [0, 1] (the script's taste)."""
    rg = images[..., 0] - images[..., 1]
    yb = 0.5 * (images[..., 0] + images[..., 1]) - images[..., 2]
    std = np.hypot(rg.std(axis=(1, 2)), yb.std(axis=(1, 2)))
    mean = np.hypot(rg.mean(axis=(1, 2)), yb.mean(axis=(1, 2)))
    return std + 0.3 * mean


def _sheet(images: np.ndarray, columns: int, picked, gap: int = 6) -> np.ndarray:
    """The gallery's grid as one uint8 picture; the picks framed in orange."""
    n, h, w, _ = images.shape
    rows = -(-n // columns)
    sheet = np.full((rows * (h + gap) + gap, columns * (w + gap) + gap, 3), 255, dtype=np.uint8)
    for i, img in enumerate(images):
        y, x = gap + (i // columns) * (h + gap), gap + (i % columns) * (w + gap)
        if i in picked:
            sheet[y - gap // 2: y + h + gap // 2, x - gap // 2: x + w + gap // 2] = (230, 85, 13)
        sheet[y: y + h, x: x + w] = np.clip(img * 255 + 0.5, 0, 255).astype(np.uint8)
    return sheet


def pictures(out: str | os.PathLike[str] = "pictures-demo", *, generations: int | None = None, size: int | None = None,
             picks: int = 2, seed: int = 0) -> dict:
    """A breeding session (paper section 3) with the script as the audience, written to ``out``.

    Sims' 4 x 5 gallery of random pictures; in every generation the script picks the ``picks``
    most colourful pictures (Hasler and Suesstrunk's measure: the script's taste, where a room
    would click) and breeds the next generation from them (:meth:`Evolution.next_generation`:
    the paper's seven operators at random). Files: ``gallery-G.png`` (generation G, the picks
    framed), ``favourite-K.png`` (the last picks, with their genomes inside:
    :func:`~coursekit.pictures.load_genome`), ``gallery_session.json`` (``Gallery.load`` goes
    on breeding from it in a notebook) and ``summary.json``.

    Sizes default by profile (classroom: 3 generations of 128-pixel pictures; ci: 1 of 32).
    """
    from coursekit.creatures.film import write_png
    from coursekit.pictures import render, save_image
    from coursekit.pictures.session import Evolution, GalleryState
    from coursekit.pictures.variety import random_population

    generations = sized(classroom=3, ci=1) if generations is None else generations
    size = size or sized(classroom=128, ci=32)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    rng = np.random.default_rng(seed)
    evo = Evolution(GalleryState(random_population(rng, 20)), rng, autosave=out / "gallery_session.json")
    sheets, chosen = [], []
    for g in range(generations + 1):
        images = render(evo.state.population, size)
        chosen = [int(i) for i in np.argsort(-_colourful(images), kind="stable")[:picks]]
        sheets.append(f"gallery-{g}.png")
        write_png(_sheet(images, 5, chosen), out / sheets[-1])
        for i in chosen:
            evo.select(i, True)
        if g < generations:
            evo.next_generation()
    favourites = []
    for k, i in enumerate(chosen):
        favourites.append(f"favourite-{k}.png")
        save_image(out / favourites[-1], evo.state.population[i], size=sized(classroom=512, ci=64))
    summary = {"generations": generations, "size": size, "picks": picks, "seed": seed, "sheets": sheets,
               "favourites": favourites, "expressions": [evo.state.population[i].expression() for i in chosen],
               "wall_seconds": round(time.perf_counter() - t0, 2)}
    atomic_write(out / "summary.json", json.dumps(summary, indent=2))
    return summary


_PAGE = """<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>coursekit demo</title>
<style>
body {{ font-family: system-ui, sans-serif; max-width: 1400px; margin: 2em auto; padding: 0 1em; color: #222; }}
h1, h2 {{ font-weight: 600; }} img, video {{ max-width: 100%; }} figure {{ margin: 1em 0; }}
figcaption {{ color: #555; font-size: 0.9em; }} .row {{ display: flex; flex-wrap: wrap; gap: 1.5em; align-items: flex-start; }}
code {{ background: #f3f3f3; padding: 0 0.2em; }}
</style></head><body>
<h1>coursekit: evolved swimmers and bred pictures</h1>
<p>Made by <code>coursekit demo</code> in {total:.0f} s. After <em>On Artificial Intelligence and Motivation in
Computer Graphics Education</em> and Karl Sims' <em>Evolving Virtual Creatures</em> (1994) and
<em>Artificial Evolution for Computer Graphics</em> (1991).</p>
<h2>Swimmers: a live run</h2>
<p>{population} random creatures, {generations}, {seconds:g} s of swimming each
({evolution:.0f} s on {workers} processes). The champion swims {speed:.3f} m/s =
{blps:.3f} body lengths per second. Audit: {audit}</p>
<div class="row">
<figure><video src="{mp4}" autoplay loop muted controls playsinline width="{fw}" height="{fh}"></video>
<figcaption>The champion swimming (the camera follows it; orange: its centre of mass's path;
the grid stays put in the water). Also as a <a href="{gif}">GIF</a>; its genome: <a href="{json}">best.json</a>.</figcaption></figure>
<figure><img src="{fitness}" alt="fitness per generation"><figcaption>Best, mean and median fitness per generation.</figcaption></figure>
</div>
<figure><img src="{keyframes}" alt="key frames"><figcaption>Key frames, time increasing from left to right (the paper's Figure 3); after the first, the panels
show the stroke at successive phases of one cycle.</figcaption></figure>
<h2>Shipped champions</h2>
<p>The same recipe, given time. A lecture break's run breeds a first swimmer on a lucky seed and a
creature that paddles in place on another; the champions below were bred by the commands under them,
the fastest by Karl Sims' full experiment (300 creatures, 100 generations, 10 s each), and swim with a
steady stroke.</p>
{champions}
<h2>Pictures: a breeding session</h2>
<p>Sims' gallery of 20 random pictures. With no room to click, the script picked the {picks} most colourful
(framed in orange) and bred each next generation from them with the paper's seven operators.
Breed your own: <code>coursekit demo pictures</code> (the session goes on from
<a href="{session}">gallery_session.json</a> with <code>Gallery.load</code>).</p>
{sheets}
<div class="row">{favourites}</div>
</body></html>
"""


def _bred(summary: dict) -> str:
    """How many generations a run bred, and why no more."""
    bred = f"{summary['generations']} generations of Sims' recipe"
    if summary["stopped_by_budget"]:
        bred += f" (of {summary['generations_planned']}: the next would have ended after the {summary['budget']:g} s budget)"
    return bred


def _links(page: str) -> list[str]:
    return re.findall(r'(?:src|href)="([^"]+)"', page)


def both(out: str | os.PathLike[str] = "coursekit-demo", *, population: int | None = None,
         generations: int | None = None, seconds: float | None = None, seed: int = 0, workers: int | None = None,
         budget: float | None = None, rhythm: float | None = None, progress: bool = True) -> dict:
    """Both demos into ``out`` (``swimmers/``, ``pictures/``) and an ``index.html`` that opens them
    (the options are :func:`swimmers`').

    Returns:
        ``{"swimmers": ..., "pictures": ..., "index": path, "wall_seconds": ...}``; every file the
        page links to exists (checked before the page is written).
    """
    out = Path(out)
    t0 = time.perf_counter()
    sw = swimmers(out / "swimmers", population=population, generations=generations, seconds=seconds, seed=seed,
                  workers=workers, budget=budget, rhythm=rhythm, progress=progress)
    pi = pictures(out / "pictures", seed=seed)
    total = time.perf_counter() - t0
    esc = html.escape
    champions = "\n".join(
        f'<figure><video src="swimmers/{c["mp4"]}" autoplay loop muted controls playsinline width="{FILM_SIZE[0]}" '
        f'height="{FILM_SIZE[1]}"></video><img src="swimmers/{c["keyframes"]}" alt="key frames">'
        f'<figcaption>{esc(c["name"])} ({c["parts"]} parts): {c["speed"]:.3f} m/s = {c["body_lengths_per_second"]:.2f} '
        f'body lengths/s over 10 s; evolved by <code>{esc(c["command"])}</code>; <a href="swimmers/{c["gif"]}">GIF</a>.'
        f'</figcaption></figure>' for c in sw["champions"])
    champions = f'<div class="row">{champions}</div>'
    sheets = "\n".join(f'<figure><img src="pictures/{s}" alt="generation {g}"><figcaption>Generation {g}'
                       f'{" (random)" if g == 0 else ""}.</figcaption></figure>' for g, s in enumerate(pi["sheets"]))
    favourites = "\n".join(f'<figure><img src="pictures/{f}" alt="favourite {k}" width="256"><figcaption><code>'
                           f'{esc(e[:120])}{"..." if len(e) > 120 else ""}</code></figcaption></figure>'
                           for k, (f, e) in enumerate(zip(pi["favourites"], pi["expressions"])))
    page = _PAGE.format(
        total=total, population=sw["population"], generations=_bred(sw), seconds=sw["seconds"],
        evolution=sw["wall_seconds"]["evolution"], workers=sw["workers"], speed=sw["best_speed"],
        blps=sw["best_body_lengths_per_second"], audit=esc(sw["audit"]), fw=FILM_SIZE[0], fh=FILM_SIZE[1],
        mp4=f"swimmers/{sw['films']['mp4']}", gif=f"swimmers/{sw['films']['gif']}", json="swimmers/best.json",
        fitness="swimmers/fitness.png", keyframes=f"swimmers/{sw['films']['keyframes']}", champions=champions,
        picks=pi["picks"], session="pictures/gallery_session.json", sheets=sheets, favourites=favourites)
    missing = [link for link in _links(page) if not (out / link).is_file()]
    if missing:
        raise RuntimeError(f"index.html would link to files the demo did not write: {missing}")
    atomic_write(out / "index.html", page)
    return {"swimmers": sw, "pictures": pi, "index": out / "index.html", "wall_seconds": round(total, 2)}
