"""Swimmer simulator throughput vs MuJoCo, same creatures, same step, same run (issue #5).

For batches of random creatures (10-20 boxes each) this prints body-steps and creature-steps per
second of our batched simulator (numpy, torch CPU, torch CUDA when present) next to MuJoCo
stepping the very same exported creatures (``to_mjcf``, all creatures in one model) with its RK4
integrator, the same step and one thread, and the ratio. Ours runs the full swimmer physics
(water drag, joint limits as constraints; self-collisions in a separate row, and a row with
the joint limits off, which measures their share of a step); MuJoCo runs the
exported articulated bodies (joint limits as constraints, no fluid, no contacts). Times are the best
window of process CPU time, the engines taking turns window by window (see ``_timed``), so other
jobs on a shared machine disturb them little and disturb all engines alike.

Every engine first simulates ``--warmup`` seconds (default 2 s, 120 steps) untimed. The random
creatures start inside their joint limits, and MuJoCo's step cost grows as they reach them and
its constraint count rises (at batch 300, about 6 ms per step over the first 20 steps, 10 ms from
about step 60 on, 255 -> 1,200 active constraints by step 240); ours costs a little more with
more joints locked at their limits (each locked leaf adds its inertia to its parent). Timing
from the first step would measure MuJoCo on that transient only (the best window is an early
one); ``--warmup 0`` does so.

Our numpy step is bound by memory traffic and per-call overhead (see the notes in
``coursekit/creatures/physics/aba.py``); part of it is stacked 6x6 products, which a forced
``OPENBLAS_CORETYPE`` (set on some machines to dodge bugs of old OpenBLAS builds) slows down in
current numpy; the header prints it. To measure the library as users get it there, run
``env -u OPENBLAS_CORETYPE -u OPENBLAS_L2_SIZE python benchmarks/swimmers.py``.

It also counts the computing tensor operations of one step: on a GPU each is a kernel launch,
which bounds the speed there, so the count tells on any machine what a GPU will pay. On a GPU,
``--cuda-batches`` (default 4096 and 16384) are timed on CUDA alone.

    python benchmarks/swimmers.py [--batches 1 30 300] [--seconds 2] [--warmup 2] [--cuda-batches 4096 16384]
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from coursekit.creatures.mjcf import mujoco_model  # noqa: E402
from coursekit.creatures.physics import random_body_tree, random_state  # noqa: E402
from coursekit.creatures.physics.world import World  # noqa: E402

DT = 1.0 / 60.0


def _population(n: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    trees = [random_body_tree(rng, (10, 20)) for _ in range(n)]
    states = [random_state(rng, t, speed=0.5, inside=0.5) for t in trees]
    return trees, states


def _timed(steps: dict, seconds: float, window: float = 0.25, clock=time.process_time) -> dict:
    """Seconds per call of every function in ``steps``: the best of repeated windows of about
    ``window`` seconds, the engines taking turns window by window (about ``seconds`` each).

    CPU engines are timed by this process's CPU time (every engine runs on one thread): with the
    best window, and all engines measured in the same stretches of time, the ratios are robust to
    other jobs sharing the machine. CUDA runs use wall time with a synchronisation after every step.
    """
    reps = {}
    for name, step in steps.items():
        step()  # warm up
        t0 = clock()
        step()
        reps[name] = max(1, round(window / max(clock() - t0, 1e-6)))
    best = dict.fromkeys(steps, float("inf"))
    start = clock()
    while float("inf") in best.values() or clock() - start < seconds * len(steps):
        for name, step in steps.items():
            t0 = clock()
            for _ in range(reps[name]):
                step()
            best[name] = min(best[name], (clock() - t0) / reps[name])
    return best


def ours(trees, states, backend, device=None, contacts=False, limits=True):
    """One step of our simulator on the population (a function to time)."""
    w = World(trees, dt=DT, backend=backend, device=device, contacts=contacts, limits=limits)
    w.set_state([s[0] for s in states], [s[1] for s in states])
    if device is not None and "cuda" in str(device):
        import torch

        def step():
            w.step()
            torch.cuda.synchronize()

        return step
    return w.step


def mujoco_step(trees, states):
    """One RK4 step of MuJoCo on the same creatures, exported into one model (a function to time)."""
    import mujoco

    model = mujoco_model(trees, timestep=DT, integrator="RK4")
    data = mujoco.MjData(model)
    data.qpos[:] = np.concatenate([s[0] for s in states])
    data.qvel[:] = np.concatenate([s[1] for s in states])
    return lambda: mujoco.mj_step(model, data)


def _on_cuda(trees, states, warm: int, seconds: float) -> float:
    """Wall seconds per step of our torch simulator on CUDA (after ``warm`` untimed steps)."""
    step = ours(trees, states, "torch", device="cuda")
    for _ in range(warm):
        step()
    return _timed({"cuda": step}, seconds, clock=time.perf_counter)["cuda"]


def operations_per_step(trees, states, contacts: bool) -> int:
    """Computing tensor operations in one step (torch backend): kernel launches on a GPU."""
    from coursekit.operations import CountOperations

    step = ours(trees, states, "torch", device="cpu", contacts=contacts)
    step()
    with CountOperations() as ops:
        step()
    return ops.count


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batches", type=int, nargs="+", default=[1, 30, 300])
    ap.add_argument("--seconds", type=float, default=2.0, help="CPU time per engine and batch")
    ap.add_argument("--warmup", type=float, default=2.0, help="simulated seconds every engine runs untimed first")
    ap.add_argument("--cuda-batches", type=int, nargs="*", default=[4096, 16384],
                    help="batches timed on CUDA only, when a GPU is present (the GPU target is at >= 4096)")
    args = ap.parse_args(argv)
    import torch

    torch.set_num_threads(1)
    cuda = torch.cuda.is_available()
    warm = round(args.warmup / DT)
    rows = []
    for batch in args.batches:
        trees, states = _population(batch)
        bodies = sum(t.n_bodies for t in trees)
        steps = {"mujoco RK4 (1 thread)": mujoco_step(trees, states)}
        for backend, device, contacts, limits in [("numpy", None, False, True), ("numpy", None, False, False),
                                                  ("numpy", None, True, True), ("torch", "cpu", False, True)]:
            name = f"ours {backend}{'/' + device if device else ''} RKN{' +collisions' if contacts else ''}{' -limits' if not limits else ''}"
            steps[name] = ours(trees, states, backend, device=device, contacts=contacts, limits=limits)
        for step in steps.values():
            for _ in range(warm):
                step()
        times = _timed(steps, args.seconds)
        if cuda:
            times["ours torch/cuda RKN"] = _on_cuda(trees, states, warm, args.seconds)
        ref = times["mujoco RK4 (1 thread)"]
        rows += [(batch, bodies, name, t, ref) for name, t in times.items()]
    for batch in args.cuda_batches if cuda else []:
        trees, states = _population(batch)
        rows.append((batch, sum(t.n_bodies for t in trees), "ours torch/cuda RKN",
                     _on_cuda(trees, states, warm, args.seconds), None))
    print(f"step dt = {DT:.5f} s, random creatures of 10-20 boxes; ratio = our body-steps/s over MuJoCo's")
    print(f"numpy {np.__version__}, OPENBLAS_CORETYPE={os.environ.get('OPENBLAS_CORETYPE', '(unset)')}; best-window CPU time per step "
          f"after {args.warmup:g} s simulated untimed")
    trees, states = _population(max(args.batches))
    print(f"computing tensor operations per step at batch {max(args.batches)} (kernel launches on a GPU; they grow with the depth of the trees, not with the batch): "
          f"{operations_per_step(trees, states, False)}, with collisions {operations_per_step(trees, states, True)}\n")
    print(f"{'batch':>5} {'bodies':>6}  {'engine':<34} {'ms/step':>9} {'body-steps/s':>13} {'creature-steps/s':>17} {'ratio':>6}")
    for batch, bodies, name, t, ref in rows:
        ratio = f"{ref / t:>6.2f}" if ref else f"{'-':>6}"
        print(f"{batch:>5} {bodies:>6}  {name:<34} {t * 1e3:>9.3f} {bodies / t:>13,.0f} {batch / t:>17,.0f} {ratio}")


if __name__ == "__main__":
    main()
