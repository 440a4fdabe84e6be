"""Swimmer simulator throughput vs MuJoCo, same creatures, same step, same run (issue #5).

For batches of random creatures (10-20 boxes each) this prints body-steps and creature-steps per
second of our simulator -- its default step compiled with numba
(:mod:`coursekit.creatures.physics.compiled`) and the batched array step (numpy, torch CPU, torch
CUDA when present) -- next to MuJoCo
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

Our numpy step is bound by memory traffic and per-call overhead (see
``benchmarks/NOTES.md``); part of it is stacked 6x6 products, which a forced
``OPENBLAS_CORETYPE`` (set on some machines to dodge bugs of old OpenBLAS builds) slows down in
current numpy; the header prints it. To measure the library as users get it there, run
``env -u OPENBLAS_CORETYPE -u OPENBLAS_L2_SIZE python benchmarks/swimmers.py``.

A second table times what evolution pays for: the population of ``benchmarks/data/evolved_swimmers.json``
(the last generation of a real run, 60 creatures of 3-30 parts, written by
``python benchmarks/data/evolved_swimmers.py``: ``coursekit demo swimmers`` settings, seed 0),
repeated to ``--evolved-batches`` creatures (default 300), and at batch 1 its champion alone,
the size a lesson swims. Self-collisions are on in both engines: ours as in evolution (every pair
but parent and child and those fused at rest), MuJoCo's own (``to_mjcf(contacts=True)``: every
pair of boxes but parent and child, its default, so it also pushes apart the parts that overlap at
rest; its default solver). All engines start from one mid-swim state (our simulator settles 0.5 s
and swims ``--warmup`` s with the brains first). Rows with ``+brains`` tick the creatures' brains
twice per step on the sensors and drive the joints with them, as ``simulate`` does (MuJoCo's with
the contact sensors off); the rows without hold the joint forces of that state. The brains'
share is also timed alone (two ticks and the sensors, on a fixed state, with numpy's neurons), and
the compiled step with the springs alone (``World(hold_contacts=False)``: the nearest pairs not held
apart) shows what holding them costs.
``ours compiled`` rows swim with the compiled step and, with brains, the compiled neurons.

It also counts the computing tensor operations of one step: on a GPU each is a kernel launch,
which bounds the speed there, so the count tells on any machine what a GPU will pay. On a GPU,
``--cuda-batches`` (default 4096 and 16384) are timed on CUDA alone, eager and with the
graph-ready step captured as a CUDA graph (``World(graph=True)``). Measured on an NVIDIA H200
(2026-12-04, eager; ``benchmarks/gpu.py`` has the whole GPU run): 44.1 ms per step at batch 4,096
(93,000 creature-steps/s) and 52.5 ms at 16,384 (312,000), without collisions; the graph rows have
not run on a GPU yet.

    python benchmarks/swimmers.py [--batches 1 30 300] [--evolved-batches 1 300] [--seconds 2] [--warmup 2]
                                  [--cuda-batches 4096 16384]
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import argparse  # noqa: E402
import copy  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from coursekit.creatures import BrainBatch, Creature  # noqa: E402
from coursekit.creatures.body import REVOLUTE  # noqa: E402
from coursekit.creatures.mjcf import mujoco_model  # noqa: E402
from coursekit.creatures.physics import random_body_tree, random_state  # noqa: E402
from coursekit.creatures.physics.world import World  # noqa: E402

DT = 1.0 / 60.0
#: The evolved population (``python benchmarks/data/evolved_swimmers.py`` writes it).
EVOLVED = Path(__file__).parent / "data" / "evolved_swimmers.json"


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


def ours(trees, states, backend, device=None, contacts=False, limits=True, graph=False, compiled=False):
    """One step of our simulator on the population (a function to time); ``compiled``: the
    numba-compiled step (``World(compiled=True)``) instead of the numpy one."""
    w = World(trees, dt=DT, backend=backend, device=device, contacts=contacts, limits=limits, graph=graph, compiled=compiled)
    w.set_state([s[0] for s in states], [s[1] for s in states])
    if device is not None and "cuda" in str(device):
        import torch

        def step():
            w.step()
            torch.cuda.synchronize()

        return step
    return w.step


def mujoco_step(trees, states, contacts=False, ctrl=None, brain=None):
    """One RK4 step of MuJoCo on the same creatures, exported into one model (a function to time).

    With ``contacts`` the boxes collide (MuJoCo's default filter: all pairs but parent and child)
    and every creature is moved by its root's place in the model (``to_mjcf`` spaces them apart).
    ``ctrl`` (one per joint) is held; a ``brain`` (:class:`BrainBatch`) instead drives the motors,
    ticking twice per step on MuJoCo's joint angles and rates (contact sensors all off, -1).
    """
    import mujoco

    model = mujoco_model(trees, timestep=DT, integrator="RK4", contacts=contacts)
    data = mujoco.MjData(model)
    data.qpos[:] = np.concatenate([s[0] for s in states])
    data.qvel[:] = np.concatenate([s[1] for s in states])
    if contacts:
        free = model.jnt_qposadr[model.jnt_type == mujoco.mjtJoint.mjJNT_FREE]
        for k in range(3):
            data.qpos[free + k] += model.qpos0[free + k]
    if ctrl is not None:
        data.ctrl[:] = ctrl
    if brain is None:
        return lambda: mujoco.mj_step(model, data)
    joint = model.jnt_type != mujoco.mjtJoint.mjJNT_FREE
    qadr, vadr = model.jnt_qposadr[joint], model.jnt_dofadr[joint]
    revolute = model.jnt_type[joint] == mujoco.mjtJoint.mjJNT_HINGE
    contact = -np.ones((brain.total_bodies, 6))

    def step():
        q = data.qpos[qadr]
        q = np.where(revolute, np.mod(q + np.pi, 2 * np.pi) - np.pi, q)
        for _ in range(2):
            e = brain.step(q, data.qvel[vadr], contact, DT / 2)
        data.ctrl[:] = e
        mujoco.mj_step(model, data)

    return step


class Swim:
    """Our simulator swimming creatures with their brains in the loop, as ``simulate`` does it.

    Each physics step, the brains tick twice on the sensors (joint angles wrapped to (-pi, pi],
    joint rates, per-face contact sensors) and their outputs drive the joints.
    """

    def __init__(self, creatures, contacts=True, compiled=False, hold=True):
        phenotypes = [c.expand() for c in creatures]
        self.brain = BrainBatch(phenotypes, compiled=compiled)
        self.world = World([p.body for p in phenotypes], dt=DT, contacts=contacts, compiled=compiled, hold_contacts=hold)
        m = self.world.model
        self.revolute = m.joint_type_np[m.joint_order] == REVOLUTE
        self.effector = np.zeros(m.n_joints)

    def think(self) -> np.ndarray:
        """Two brain ticks on the current sensors; the effector outputs (user joint order)."""
        w, m = self.world, self.world.model
        s = w.state
        q = s.q[m.joint_order]
        q = np.where(self.revolute, np.mod(q + np.pi, 2 * np.pi) - np.pi, q)
        contact = -np.ones((m.n_bodies, 6))
        if w.contact_sensors is not None:
            contact[m.order] = w.contact_sensors
        for _ in range(2):
            e = self.brain.step(q, s.qd[m.joint_order], contact, DT / 2)
        return e

    def swim(self) -> None:
        """One physics step with the brains in the loop."""
        self.effector = self.think()
        self.world.set_effectors(self.effector)
        self.world.step()


def evolved_population(batch: int, path=EVOLVED) -> list:
    """``batch`` creatures of the saved evolved population: its champion alone at batch 1 (what a
    lesson swims), else the population repeated (elites first) to ``batch`` creatures."""
    import json

    doc = json.loads(Path(path).read_text(encoding="utf-8"))
    if doc.get("format") != "coursekit.population/1":
        raise ValueError(f"{path}: format must be 'coursekit.population/1', got {doc.get('format')!r}")
    creatures = [Creature.from_dict(c) for c in doc["creatures"]]
    if batch == 1:
        return [creatures[int(np.argmax(doc["fitness"]))]]
    return [creatures[i % len(creatures)] for i in range(batch)]


def evolved_engines(creatures, warmup: float) -> tuple[dict, int]:
    """The functions to time on an evolved population, all from one mid-swim state: our
    simulator settles 0.5 s (as ``simulate`` does) and swims ``warmup`` s with brains first.
    Without brains, both engines hold the joint forces of that state's last brain output."""
    start = Swim(creatures)
    w = start.world
    for _ in range(round(0.5 / DT)):
        w.step()
    start.brain.reset()
    for _ in range(round(warmup / DT)):
        start.swim()
    qpos, qvel = w.get_state()
    states = list(zip(qpos, qvel))
    trees = [t for t in w.model.trees]
    # the same joint forces in MuJoCo: its motor gives gear * ctrl (gear = our gain), capped at the strength
    tau, gain = w.tau[w.model.joint_order], w.gain[w.model.joint_order]
    ctrl = np.clip(np.divide(tau, gain, out=np.zeros_like(tau), where=gain != 0), -1.0, 1.0)

    def ours(compiled=False, hold=True):
        s = Swim(creatures, compiled=compiled, hold=hold)
        s.world.set_state(qpos, qvel)
        s.brain = copy.deepcopy(start.brain)
        s.world.set_effectors(start.effector)
        return s

    return {
        "mujoco RK4 +collisions (1 thread)": mujoco_step(trees, states, contacts=True, ctrl=ctrl),
        "mujoco RK4 +collisions +brains": mujoco_step(trees, states, contacts=True, brain=copy.deepcopy(start.brain)),
        "ours numpy RKN +collisions": ours().world.step,
        "ours numpy RKN +collisions +brains": ours().swim,
        "ours compiled RKN +collisions": ours(True).world.step,
        "ours compiled RKN +collisions +brains": ours(True).swim,
        "ours compiled RKN +springs only +brains": ours(True, hold=False).swim,  # the self-contacts not held
        "our brains alone (2 ticks + sensors)": ours().think,
    }, sum(t.n_bodies for t in trees)


def _on_cuda(trees, states, warm: int, seconds: float, graph: bool = False) -> float:
    """Wall seconds per step of our torch simulator on CUDA (after ``warm`` untimed steps; with
    ``graph`` the graph-ready step, captured in the first of them)."""
    step = ours(trees, states, "torch", device="cuda", graph=graph)
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
    ap.add_argument("--batches", type=int, nargs="*", default=[1, 30, 300], help="batches of random creatures")
    ap.add_argument("--evolved-batches", type=int, nargs="*", default=[1, 300],
                    help="batches of the evolved population (1: its champion alone)")
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
        for backend, device, contacts, limits, compiled in [
                ("numpy", None, False, True, False), ("numpy", None, False, False, False), ("numpy", None, True, True, False),
                ("numpy", None, False, True, True), ("numpy", None, True, True, True), ("torch", "cpu", False, True, False)]:
            engine = "compiled" if compiled else f"{backend}{'/' + device if device else ''}"
            name = f"ours {engine} RKN{' +collisions' if contacts else ''}{' -limits' if not limits else ''}"
            steps[name] = ours(trees, states, backend, device=device, contacts=contacts, limits=limits, compiled=compiled)
        for step in steps.values():
            for _ in range(warm):
                step()
        times = _timed(steps, args.seconds)
        if cuda:
            times["ours torch/cuda RKN"] = _on_cuda(trees, states, warm, args.seconds)
            times["ours torch/cuda RKN, CUDA graph"] = _on_cuda(trees, states, warm, args.seconds, graph=True)
        ref = times["mujoco RK4 (1 thread)"]
        rows += [(batch, bodies, name, t, ref) for name, t in times.items()]
    for batch in args.cuda_batches if cuda else []:
        trees, states = _population(batch)
        for graph in (False, True):
            rows.append((batch, sum(t.n_bodies for t in trees), f"ours torch/cuda RKN{', CUDA graph' if graph else ''}",
                         _on_cuda(trees, states, warm, args.seconds, graph), None))
    evolved = []
    if args.evolved_batches and not EVOLVED.exists():  # a copy of the scripts without their data folder
        print(f"no {EVOLVED}: the evolved-population table needs the checkout's benchmarks/data/ "
              f"(python benchmarks/data/evolved_swimmers.py writes it)")
        args.evolved_batches = []
    for batch in args.evolved_batches:
        steps, bodies = evolved_engines(evolved_population(batch), args.warmup)
        times = _timed(steps, args.seconds)
        mj, mj_brains = times["mujoco RK4 +collisions (1 thread)"], times["mujoco RK4 +collisions +brains"]
        evolved += [(batch, bodies, name, t, None if "alone" in name else mj_brains if "brains" in name else mj)
                    for name, t in times.items()]
    print(f"numpy {np.__version__}, OPENBLAS_CORETYPE={os.environ.get('OPENBLAS_CORETYPE', '(unset)')}; best-window CPU time per step "
          f"after {args.warmup:g} s simulated untimed")
    if rows:
        print(f"step dt = {DT:.5f} s, random creatures of 10-20 boxes; ratio = our body-steps/s over MuJoCo's")
        trees, states = _population(max(args.batches))
        print(f"computing tensor operations per step at batch {max(args.batches)} (kernel launches on a GPU; they grow with the depth of the trees, not with the batch): "
              f"{operations_per_step(trees, states, False)}, with collisions {operations_per_step(trees, states, True)}\n")
        _table(rows)
    if evolved:
        print(f"\nstep dt = {DT:.5f} s, the evolved population ({EVOLVED.name}; batch 1: its champion), self-collisions on, "
              f"from a mid-swim state; ratio = ours over MuJoCo with collisions, with brains over MuJoCo with the same brains\n")
        _table(evolved)


def _table(rows) -> None:
    width = max(34, *(len(r[2]) for r in rows))
    print(f"{'batch':>5} {'bodies':>6}  {'engine':<{width}} {'ms/step':>9} {'body-steps/s':>13} {'creature-steps/s':>17} {'ratio':>6}")
    for batch, bodies, name, t, ref in rows:
        ratio = f"{ref / t:>6.2f}" if ref else f"{'-':>6}"
        print(f"{batch:>5} {bodies:>6}  {name:<{width}} {t * 1e3:>9.3f} {bodies / t:>13,.0f} {batch / t:>17,.0f} {ratio}")


if __name__ == "__main__":
    main()
