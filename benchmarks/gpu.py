"""Both engines on a CUDA GPU, in one run (issue #16): correctness against the CPU, host
synchronisations, and throughput.

What it prints, each part on its own (a part, or one configuration of it, that fails prints its
error and the run goes on), the results also in ``--out``/gpu.json after every part:

- the GPU, torch and CUDA versions;
- **swimmers, the CUDA graph against CPU torch**: the same random creatures (limits, water,
  without and with collisions) stepped 100 times on the CPU's ordinary step and on the captured
  graph-ready one (``World(graph=True)``), random effectors each step and the state set anew at
  step 50 (a new capture); the largest relative difference of the state, and whether the contact
  sensors agreed at every step;
- **host synchronisations** of one swimmer step (ordinary and graph-ready, run eagerly) and one
  render of 256 genomes at 256^2, counted by torch's own CUDA sync debugging
  (``torch.cuda.set_sync_debug_mode("warn")``: a warning per synchronising call, with the
  source lines that made them) and by :class:`coursekit.operations.CountHostSyncs` (the count
  the CPU tests keep at 0);
- **swimmer throughput** at ``--batches`` (default 4,096 and 16,384 random creatures of 10-20
  boxes), without and with self-collisions, eager and as a CUDA graph: creature-steps and
  body-steps per second, timed with CUDA events over ``--steps`` steps after 10 (the capture's);
- **picture throughput**: 256 random genomes at 256^2 (genome by genome and in waves) and 20
  gallery children at 128^2, pictures per second (CUDA events), and the render to numpy as the
  gallery takes it; a torch profile of the waves;
- **swimming with brains**: ``simulate`` of the evolved population (``benchmarks/data``), the
  fitness on CUDA (eager and graph) against the CPU, then 300 and 2,048 creatures for 10 s, the
  brains ticking on the device: a generation of Sims' experiment, timed.

    python benchmarks/gpu.py [--batches 4096 16384] [--steps 30] [--out DIR]

It needs a CUDA GPU; without one it says so and exits 1.

Measured on an NVIDIA H200 (torch 2.11.0+cu130), 2026-12-04, before the graph-ready step (the
run of this script's first version; the graph rows have not run on a GPU yet):

======  =======  ==========  =========  ================  ============
batch   bodies   collisions  ms/step    creature-steps/s  body-steps/s
======  =======  ==========  =========  ================  ============
4,096    61,345  off            44.07            92,949     1,392,073
4,096    61,345  on             62.81            65,216       976,731
16,384  245,822  off            52.52           311,931     4,680,153
16,384  245,822  on             66.69           245,665     3,685,900
======  =======  ==========  =========  ================  ============

Eager CUDA equalled CPU torch to 3.4e-15 (collisions off) and 5.1e-14 (on) over 100 steps.
Host synchronisations per step 15 (collisions off) and 30 (on), per render of 256 genomes
3,106 genome by genome and 978 in waves. Pictures: 120 per second at 256^2 genome by genome,
353 in waves; 20 children at 128^2 in 20 ms (waves) and 26 ms (genome by genome).
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import itertools
import json
import platform
import sys
import time
import traceback
import warnings
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))

RESULTS: dict = {}
OUT: list = []  # the folder the results go to, rewritten after every part


def part(name):
    """Run one part; print and record its failure instead of stopping the run."""
    def wrap(fn):
        def run(*a, **k):
            t = time.perf_counter()
            print(f"\n== {name}", flush=True)
            try:
                RESULTS[name] = fn(*a, **k)
            except Exception as e:  # noqa: BLE001 -- a report, not a library
                traceback.print_exc()
                RESULTS[name] = {"error": f"{type(e).__name__}: {e}"}
            print(f"   ({time.perf_counter() - t:.1f} s)", flush=True)
            for out in OUT:
                (out / "gpu.json").write_text(json.dumps(RESULTS, indent=1, default=str))
        return run
    return wrap


def event_time(fn, repeats: int) -> float:
    """Median seconds of ``fn`` over ``repeats`` calls, timed with CUDA events."""
    times = []
    for _ in range(repeats):
        a, b = torch.cuda.Event(enable_timing=True), torch.cuda.Event(enable_timing=True)
        a.record()
        fn()
        b.record()
        b.synchronize()
        times.append(a.elapsed_time(b) / 1e3)
    return float(np.median(times))


@functools.lru_cache(maxsize=4)
def _population_once(batch, seed):
    from swimmers import _population

    return _population(batch, seed)


def world(batch, device, contacts=True, seed=0, model=None, **options):
    """A world of ``batch`` random creatures (10-20 boxes) in their mid-swim random state."""
    from coursekit.creatures.physics.model import Model
    from coursekit.creatures.physics.world import World
    from swimmers import DT

    trees, states = _population_once(batch, seed)
    w = World(model or Model(trees, backend="torch", device=device), dt=DT, contacts=contacts, **options)
    w.set_state([s[0] for s in states], [s[1] for s in states])
    return w, sum(t.n_bodies for t in trees)


def _rel(a, b) -> dict:
    return {f: float((getattr(a, f).cpu() - getattr(b, f).cpu()).abs().max() / getattr(a, f).abs().max().clamp_min(1e-300))
            for f in ("pos", "quat", "q", "lin", "omega", "qd")}


@part("swimmers: the CUDA graph against CPU torch, 100 steps (random effectors each step, the state set anew at step 50)")
def swimmers_equal(batch=32, steps=100):
    """The captured step against the CPU's ordinary one (eager CUDA against the CPU: 5e-14 in the
    first run, benchmarks/NOTES.md)."""
    out = {}
    for contacts in (False, True):
        with each(f"collisions {contacts}"):
            out[f"collisions {'on' if contacts else 'off'}"] = _equal(batch, steps, contacts)
    return out


def _equal(batch, steps, contacts) -> dict:
    ref, w = world(batch, "cpu", contacts=contacts)[0], world(batch, "cuda", contacts=contacts, graph=True)[0]
    rng = np.random.default_rng(1)
    sensors_equal = True
    for i in range(steps):
        if i == 50:
            qpos, qvel = ref.get_state()
            ref.set_state(qpos, qvel)
            w.set_state(qpos, qvel)
        e = rng.uniform(-1.0, 1.0, ref.model.n_joints)
        ref.set_effectors(e)
        w.set_effectors(e)
        ref.step()
        w.step()
        sensors_equal &= bool(np.array_equal(ref.sensors()[2], w.sensors()[2]))
    rel = _rel(ref.state, w.state)
    row = {"max_rel": max(rel.values()), "fields": rel, "contact_sensors_equal": sensors_equal,
           "diverged_equal": bool((ref.diverged == w.diverged).all()), "captured": w._graph is not None,
           "capture_failed": w._graph_failed}
    print(f"   collisions {'on ' if contacts else 'off'}: largest relative difference {row['max_rel']:.2e}, contact sensors "
          f"equal every step: {sensors_equal}, captured: {row['captured']}"
          + (f" (the capture failed: {w._graph_failed})" if w._graph_failed else ""), flush=True)
    return row


@contextlib.contextmanager
def each(name):
    """One configuration of a part: its failure is printed and the part goes on."""
    try:
        yield
    except Exception:  # noqa: BLE001 -- a report, not a library
        print(f"   {name}: FAILED")
        traceback.print_exc(limit=-6)
        RESULTS.setdefault("failures", []).append(f"{name}: {traceback.format_exc(limit=-3)}")


def sync_sites(fn, top=6) -> tuple[int, list]:
    """:func:`cuda_syncs` with the source lines that synchronised, most frequent first."""
    torch.cuda.synchronize()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        torch.cuda.set_sync_debug_mode("warn")
        try:
            fn()
        finally:
            torch.cuda.set_sync_debug_mode("default")
    hits = [w for w in caught if "synchroniz" in str(w.message)]
    sites: dict = {}
    for w in hits:
        k = f"{Path(w.filename).name}:{w.lineno}"
        sites[k] = sites.get(k, 0) + 1
    return len(hits), sorted(sites.items(), key=lambda kv: -kv[1])[:top]


@part("host synchronisations (torch's CUDA sync debug mode; CountHostSyncs)")
def syncs():
    from coursekit.operations import CountHostSyncs
    from coursekit.pictures import render
    from pictures import population

    out = {}
    for contacts in (False, True):
        for graph in (False, True):
            w, _ = world(256, "cuda", contacts=contacts, graph=graph)
            for _ in range(5):
                w._advance()
            with CountHostSyncs() as c:
                w._advance()
            n, sites = sync_sites(w._advance)
            out[f"swimmer step, collisions {contacts}, graph-ready {graph}"] = {"cuda_debug": n, "counted": c.count, "sites": sites}
    genomes = population(256, seed=7)
    for group in (False, True):
        f = lambda: render(genomes, 256, device="cuda", group=group, as_tensor=True)  # noqa: E731
        f()
        with CountHostSyncs() as c:
            f()
        n, sites = sync_sites(f)
        out[f"render 256 genomes 256^2, group {group}"] = {"cuda_debug": n, "counted": c.count, "sites": sites}
    for k, v in out.items():
        print(f"   {k}: {v['cuda_debug']} (CUDA sync debug), {v['counted']} (CountHostSyncs); {v['sites']}")
    return out


@part("swimmer throughput on CUDA (eager and CUDA graph)")
def swimmer_speed(batches, steps):
    from coursekit.creatures.physics.model import Model

    rows = []
    for batch in batches:
        model = Model(_population_once(batch, 0)[0], backend="torch", device="cuda")
        for contacts, graph in itertools.product((False, True), (False, True)):
            with each(f"batch {batch}, collisions {contacts}, graph {graph}"):
                rows.append(_speed(batch, model, contacts, graph, steps))
    return rows


def _speed(batch, model, contacts, graph, steps) -> dict:
    w, bodies = world(batch, "cuda", contacts=contacts, graph=graph, model=model)
    t0 = time.perf_counter()
    for _ in range(10):
        w.step()
    torch.cuda.synchronize()
    warm = time.perf_counter() - t0
    t = event_time(w.step, steps)
    if graph and w._graph is None:  # a graph row that did not capture says so
        print(f"   batch {batch}: no CUDA graph ({w._graph_failed})")
        graph = False
    print(f"   batch {batch:>6} bodies {bodies:>7} collisions {'on ' if contacts else 'off'} {'graph' if graph else 'eager'}: "
          f"{t * 1e3:8.3f} ms/step {batch / t:>12,.0f} creature-steps/s {bodies / t:>13,.0f} body-steps/s "
          f"(first 10 steps, capture included: {warm:.2f} s)", flush=True)
    return {"batch": batch, "bodies": bodies, "collisions": contacts, "graph": graph, "s_per_step": t,
            "creature_steps_per_s": batch / t, "body_steps_per_s": bodies / t, "first_10_steps_s": warm}


@part("swimming with brains on CUDA: simulate() of the evolved population, fitness against the CPU")
def swims(batches=(300, 2048), seconds=10.0):
    from coursekit.creatures import simulate
    from swimmers import evolved_population

    out = []
    creatures = evolved_population(60)
    ref = simulate(creatures, seconds=2.0, backend="torch", device="cpu")
    for graph in (False, True):
        with each(f"simulate 60, graph {graph}"):
            r = simulate(creatures, seconds=2.0, backend="torch", device="cuda", graph=graph)
            rel = float(np.max(np.abs(r.fitness - ref.fitness)) / max(np.max(np.abs(ref.fitness)), 1e-300))
            print(f"   60 evolved creatures, 2 s, {'graph' if graph else 'eager'}: fitness largest relative difference "
                  f"to the CPU {rel:.2e}", flush=True)
            out.append({"batch": 60, "graph": graph, "fitness_max_rel": rel})
    for batch in batches:
        with each(f"simulate {batch}"):
            creatures = evolved_population(batch)
            t = time.perf_counter()
            r = simulate(creatures, seconds=seconds, backend="torch", device="cuda", graph=True)
            wall = time.perf_counter() - t
            steps = len(r.times) + round(0.5 / r.dt)
            out.append({"batch": batch, "seconds": seconds, "wall_s": wall, "creature_s_per_s": batch * seconds / wall,
                        "ms_per_step": wall / steps * 1e3})
            print(f"   {batch:>5} evolved creatures x {seconds:g} s (settle 0.5 s), graph: {wall:6.2f} s wall, "
                  f"{wall / steps * 1e3:6.2f} ms per step with brains, {batch * seconds / wall:8.1f} creature-seconds per second",
                  flush=True)
    return out


@part("picture throughput on CUDA")
def picture_speed(repeats=5):
    from coursekit.pictures import render
    from pictures import children, population

    rows = []
    big = population(256, seed=7)
    kids = children(population(1)[0], 20)
    for genomes, size, group, name in ((big, 256, False, "256 genomes 256^2, genome by genome"),
                                       (big, 256, True, "256 genomes 256^2, in waves"),
                                       (kids, 128, True, "20 children 128^2, in waves"),
                                       (kids, 128, False, "20 children 128^2, genome by genome")):
        f = lambda: render(genomes, size, device="cuda", group=group, as_tensor=True)  # noqa: E731
        f()
        t = event_time(f, repeats)
        t0 = time.perf_counter()
        render(genomes, size, device="cuda", group=group)  # to numpy, as the gallery takes it
        host = time.perf_counter() - t0
        rows.append({"name": name, "s": t, "pictures_per_s": len(genomes) / t, "to_numpy_s": host})
        print(f"   {name:40} {t * 1e3:8.2f} ms  {len(genomes) / t:>9,.0f} pictures/s  (to numpy: {host * 1e3:.1f} ms)", flush=True)
    from torch.profiler import ProfilerActivity, profile

    with profile(activities=[ProfilerActivity.CPU, ProfilerActivity.CUDA]) as prof:
        render(big, 256, device="cuda", group=True, as_tensor=True)
        torch.cuda.synchronize()
    table = prof.key_averages().table(sort_by="self_cuda_time_total", row_limit=12)
    print(table)
    RESULTS["picture profile"] = table
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batches", type=int, nargs="*", default=[4096, 16384])
    ap.add_argument("--steps", type=int, default=30)
    ap.add_argument("--out", type=Path)
    args = ap.parse_args(argv)
    if not torch.cuda.is_available():
        print("no CUDA GPU: benchmarks/gpu.py measures the CUDA paths only")
        return 1
    p = torch.cuda.get_device_properties(0)
    RESULTS["device"] = {"gpu": torch.cuda.get_device_name(), "sms": p.multi_processor_count,
                         "torch": torch.__version__, "cuda": torch.version.cuda, "python": platform.python_version()}
    print(RESULTS["device"])
    if args.out:
        args.out.mkdir(parents=True, exist_ok=True)
        OUT.append(args.out)
    swimmers_equal()
    syncs()
    swimmer_speed(args.batches, args.steps)
    picture_speed()
    swims()
    return 0


if __name__ == "__main__":
    sys.exit(main())
