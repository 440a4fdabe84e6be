"""Creature rendering: pictures and film frames per second, one reused plotter vs a new one each time.

Run: ``coursekit bench render [--quick]`` (or ``PYTHONPATH=. python benchmarks/render.py``). Prints a
side-by-side table measured in the same run:

- pictures: ``render()`` of random creatures through the module's one off-screen plotter, next to
  a new plotter (a new GL context) per picture, which is what ``render()`` did before;
- clips: short swims filmed by :class:`~coursekit.creatures.render.Clip` (follow camera, trail,
  grid), through the shared plotter and through a new plotter per clip, and the cost of the GIF
  and MP4 writers on top of the frames.

Frames are 480 x 360 (the default size) unless ``--size W H``. Mesa's llvmpipe renders on the CPU,
so the figures depend on the machine and its load (printed).
"""

import argparse
import importlib
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from coursekit.cli import number
from coursekit.creatures import Creature, simulate

R = importlib.import_module("coursekit.creatures.render")  # (coursekit.creatures.render is the function)


def _fresh(size):
    import pyvista as pv

    return pv.Plotter(off_screen=True, window_size=list(size))


def pictures(creatures, size, fresh: bool) -> float:
    """Seconds per picture."""
    t = time.perf_counter()
    for c in creatures:
        scene = R._framed_scene(c, size, None, True, "white", 30.0, 25.0, plotter=_fresh(size) if fresh else None)
        try:
            scene.image()
        finally:
            scene.close()
    return (time.perf_counter() - t) / len(creatures)


def clips(creatures, trajectories, times, size, fresh: bool) -> float:
    """Frames per second over all clips (the clip set-up included)."""
    n, t = 0, time.perf_counter()
    for c, traj in zip(creatures, trajectories):
        clip = R.Clip(c, traj, frame_times=times, size=size)
        if fresh:  # what one plotter per clip costs: a new one for the framing pass and the film
            real = R._shared_plotter
            R._shared_plotter = lambda size, background: _fresh(size)
            try:
                n += sum(1 for _ in clip.film())
            finally:
                R._shared_plotter = real
        else:
            n += sum(1 for _ in clip.film())
    return n / (time.perf_counter() - t)


def files(creature, trajectory, times, size, out: Path) -> dict:
    """Frames per second of animate() writing a GIF, an MP4, and both from one pass."""
    fps = {}
    for name, paths in (("gif", [out / "a.gif"]), ("mp4", [out / "a.mp4"]), ("gif+mp4", [out / "b.gif", out / "b.mp4"])):
        t = time.perf_counter()
        R.animate(creature, trajectory, paths, frame_times=times, size=size, progress=False)  # the timing only
        fps[name] = len(trajectory) / (time.perf_counter() - t)
    return fps


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="a few pictures and one short clip (CI)")
    p.add_argument("--size", type=number(int, 16), nargs=2, default=(480, 360), metavar=("W", "H"))
    p.add_argument("--seed", type=number(int, 0), default=0)
    a = p.parse_args(argv)
    size = tuple(a.size)
    rng = np.random.default_rng(a.seed)
    n_pictures, n_clips, seconds = (4, 2, 0.5) if a.quick else (20, 4, 3.0)
    creatures = [Creature.random(rng, max_parts=16) for _ in range(max(n_pictures, n_clips))]
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores; frames {size[0]} x {size[1]}")
    R.render(creatures[0], size=size)  # the shared plotter made (its one-off cost is not in the table)

    shared = pictures(creatures[:n_pictures], size, fresh=False)
    fresh = pictures(creatures[:n_pictures], size, fresh=True)
    print(f"\n{'pictures (render)':<28} {'shared plotter':>15} {'new plotter each':>17} {'speed-up':>9}")
    print(f"{f'{n_pictures} random creatures':<28} {1 / shared:>10.1f} /s   {1 / fresh:>12.1f} /s   {fresh / shared:>7.2f}x")

    sim = simulate(creatures[:n_clips], seconds, record_every=3)
    n_frames = sum(len(t) for t in sim.trajectory)
    shared = clips(creatures[:n_clips], sim.trajectory, sim.frame_times, size, fresh=False)
    fresh = clips(creatures[:n_clips], sim.trajectory, sim.frame_times, size, fresh=True)
    print(f"\n{'film frames (Clip)':<28} {'shared plotter':>15} {'new plotter each':>17} {'speed-up':>9}")
    print(f"{f'{n_clips} clips, {n_frames} frames':<28} {shared:>10.1f} /s   {fresh:>12.1f} /s   {shared / fresh:>7.2f}x")

    with tempfile.TemporaryDirectory() as d:
        fps = files(creatures[0], sim.trajectory[0], sim.frame_times, size, Path(d))
    print(f"\n{'animate(), one clip':<28} {'frames/s':>10}")
    for name, v in fps.items():
        print(f"{name:<28} {v:>10.1f}")


if __name__ == "__main__":
    main()
