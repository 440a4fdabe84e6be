"""Benchmark: how long does a click on Evolve (or an operator) take to put a new generation on screen?

A :class:`~coursekit.pictures.gallery.Gallery` of 20 pictures at 128 x 128 (Sims' 4 x 5, the
issue's case) is driven from code as a student drives it: two pictures clicked, then one
button, cycling through evolve and the seven operators. Each click is timed from the button to
the last thumbnail handed to its widget: breeding (operators, the previews that redraw children
looking like a parent or a sibling), rendering the new pictures and encoding the thumbnails.
What the browser adds (messages, decoding) is measured by ``tests/test_gallery_browser.py``.

Prints the median, 95th percentile and largest wall-clock time per click and the CPU time of
this process (per click on average, and its 95th percentile over the clicks), for the renders in this process (``workers=1``) and split over worker processes
(the default), after a few warm-up clicks (the worker pool starts once per session). On a
machine shared with other work the wall-clock times are upper bounds: the load average is
printed with them, and the CPU times (what the click itself costs, whoever else runs) are the
steadier comparison. The script runs the ``coursekit`` it imports: put another checkout first
on ``PYTHONPATH`` to time that one with the same clicks.

Usage: ``python benchmarks/gallery_click.py [--clicks 60] [--size 128] [--n 20] [--buttons evolve ...]``
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from coursekit.cli import number
from coursekit.pictures import operators as O
from coursekit.pictures.gallery import Gallery

BUTTONS = ["evolve", *O.MUTATIONS, *O.RECOMBINATIONS]


def clicks(gallery: Gallery, count: int, seed: int = 0, buttons: list[str] = BUTTONS,
           think: float = 0.0) -> tuple[np.ndarray, float, np.ndarray]:
    """Wall-clock seconds of ``count`` button clicks (two pictures selected before each, then
    ``think`` seconds before the press), the CPU seconds of this process over them (pauses
    included), and its CPU seconds per click."""
    rng = np.random.default_rng(seed)
    times, cpus = [], []
    cpu = time.process_time()
    for k in range(count):
        for i in rng.choice(gallery.evolution.size, size=2, replace=False):
            gallery.click(int(i))
        if think:
            time.sleep(think)
        start, start_cpu = time.perf_counter(), time.process_time()
        msg = gallery.apply(buttons[k % len(buttons)])
        times.append(time.perf_counter() - start)
        cpus.append(time.process_time() - start_cpu)
        assert msg.startswith("generation"), msg
    return np.array(times), time.process_time() - cpu, np.array(cpus)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--clicks", type=number(int, 1), default=60)
    ap.add_argument("--size", type=number(int, 1), default=128)
    ap.add_argument("--n", type=number(int, 2), default=20)
    ap.add_argument("--warmup", type=number(int, 0), default=8)
    ap.add_argument("--think", type=number(float, 0), default=0.5,
                    help="seconds between the last pick and the press in the breeding-ahead rows (a student's pause)")
    ap.add_argument("--buttons", nargs="+", choices=BUTTONS, default=BUTTONS,
                    help="the buttons clicked in turn (default: evolve and the seven operators; "
                         "'--buttons evolve' times the issue's Evolve click alone)")
    args = ap.parse_args(argv)
    print(f"{args.n} pictures at {args.size}^2, {args.clicks} clicks of {', '.join(args.buttons)} after {args.warmup} warm-up clicks; "
          f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}")
    print(f"{'renders':18s} {'breeding':34s} {'p50 ms':>8s} {'p95 ms':>8s} {'max ms':>8s} {'CPU ms/click':>13s} "
          f"{'CPU p95 ms':>11s}")
    rows = (("when pressed", False, 0.0), ("ahead, pressed at once", True, 0.0),
            (f"ahead, pressed {args.think:g} s after the pick", True, args.think))
    for label, options in (("in this process", {"workers": 1}), ("worker processes", {})):
        for breeding, ahead, think in rows:
            gallery = Gallery(np.random.default_rng(1991), n=args.n, size=args.size, render_options=options,
                              breed_ahead=ahead)
            clicks(gallery, args.warmup, seed=1, buttons=args.buttons, think=think)
            t, cpu, per_click = clicks(gallery, args.clicks, buttons=args.buttons, think=think)
            p50, p95 = np.percentile(t, [50, 95]) * 1000
            print(f"{label:18s} {breeding:34s} {p50:8.1f} {p95:8.1f} {t.max() * 1000:8.1f} "
                  f"{cpu / args.clicks * 1000:13.1f} {np.percentile(per_click, 95) * 1000:11.1f}")


if __name__ == "__main__":
    main()
