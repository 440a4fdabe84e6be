"""Evaluate a population of swimmers: settle, swim with brains in the loop, score (paper section 2.5).

``simulate`` packs the creatures into one :class:`~coursekit.creatures.physics.world.World`,
lets them settle passively in the water for ``settle`` seconds (effectors off, so that residual
motion from the initial pose does not count), resets the brains (so oscillator phase does not
depend on the settle length), then runs ``seconds`` of swimming. The brains tick twice per
physics step on the sensors (joint angles, wrapped to [-pi, pi) for revolute joints; joint
rates; per-face contact sensors) and the last tick's effector outputs become joint forces
``strength * clip(gain * e, -1, 1)``. The centre of mass of every creature is recorded after
every step and scored with :func:`coursekit.creatures.fitness.swimming_fitness`. Creatures are
validated again before they are expanded; one whose body was cut off at the part cap, or one with
a joint whose motion the step does not resolve (a step carried it beyond its limit by more than a
quarter of the range before it was put back), scores 0.
"""

from __future__ import annotations

import difflib
import inspect
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from coursekit.creatures.brain import BrainBatch
from coursekit.creatures.fitness import swimming_fitness
from coursekit.creatures.neural import is_real
from coursekit.creatures.physics import backend as bk
from coursekit.creatures.physics.limits import MAX_EXCESS
from coursekit.creatures.physics.model import as_trees, validated
from coursekit.creatures.physics.world import World


#: The default physics step (s).
DT = 1.0 / 60.0


@dataclass
class SimulationResult:
    """Outcome of :func:`simulate`.

    ``fitness`` (C,), ``com`` (C, T, 3) centre-of-mass trajectory of the evaluation phase,
    ``times`` (T,) its sample times (0 = end of settling), ``diverged`` (C,) flags,
    ``limit_excess`` (C,) the worst excess of any joint beyond its limits during the evaluation
    (share of the joint's range, 0 inside; with limits on, no state is beyond them and this is
    the worst overshoot a step put back; a creature past
    :data:`~coursekit.creatures.physics.limits.MAX_EXCESS` scores 0), the
    final ``qpos``/``qvel`` (lists, MuJoCo layout), and with ``record_every=k`` the ``trajectory``:
    per creature an (F, nq) array of ``qpos`` every k steps from the start of the evaluation
    (times ``frame_times``), for animations.
    """

    fitness: np.ndarray
    com: np.ndarray
    times: np.ndarray
    diverged: np.ndarray
    qpos: list
    qvel: list
    dt: float
    trajectory: list | None = None
    frame_times: np.ndarray | None = None
    limit_excess: np.ndarray | None = None


def _brains(creatures):
    """The creatures' expanded brains and bodies (brains None for bare body trees)."""
    seq = creatures if isinstance(creatures, (list, tuple)) else [creatures]
    if not all(hasattr(c, "expand") for c in seq):
        return None, as_trees(creatures)
    phenotypes = [validated(c, i).expand() for i, c in enumerate(seq)]
    return [p.brain for p in phenotypes], [p.body for p in phenotypes]


def _scores(fitness, com, times) -> np.ndarray:
    """A user's ``fitness(com, times)``, checked: one finite score >= 0 per creature."""
    name = getattr(fitness, "__name__", "fitness")
    if not callable(fitness):
        raise TypeError(f"fitness: must be a function fitness(com, times) -> (C,) scores, got {type(fitness).__name__}")
    scores = np.asarray(fitness(com, times), dtype=np.float64)
    if scores.shape != (com.shape[0],):
        raise ValueError(f"fitness: {name}(com, times) returned shape {scores.shape}; expected ({com.shape[0]},), one score per creature")
    if not np.all(np.isfinite(scores)) or np.any(scores < 0):
        raise ValueError(f"fitness: {name}(com, times) returned {scores.tolist()}; every score must be finite and >= 0")
    return scores


def simulate(
    creatures: Any,
    seconds: float = 10.0,
    *,
    dt: float = DT,
    settle: float = 0.5,
    controller: Any | None = None,
    initial_state: Any | None = None,
    progress: bool = False,
    record_every: int = 0,
    fitness: Callable | None = None,
    **options: Any,
) -> SimulationResult:
    """Simulate and score a population of swimmers together.

    Args:
        creatures: creatures (with ``.expand()``) or BodyTrees.
        seconds: evaluation time after settling (s).
        dt: physics step (s).
        settle: passive settling time before the evaluation (s).
        controller: object with ``step(joint_angle, joint_velocity, contact, dt) -> effector`` (and
            optionally ``reset()``), or such a callable; arrays are flat over all creatures in
            list order (joints = bodies 1..B-1, contact (total_bodies, 6), faces -x,+x,-y,+y,-z,+z).
            Default: the creatures' own brains (``BrainBatch``) when they have them, else none
            (passive bodies).
        initial_state: optional ``(qpos, qvel)`` in MuJoCo layout; default at rest at the origin.
        progress: show a tqdm progress bar.
        record_every: record every creature's ``qpos`` every this many steps (0: don't).
        fitness: optional ``fitness(com, times) -> (C,)`` scoring the centre-of-mass paths
            (exercise 08) in place of :func:`~coursekit.creatures.fitness.swimming_fitness`; it
            gets copies, and a creature the simulator flags (diverged, cut at the part cap, a
            joint the step could not hold) still scores 0.
        **options: passed to :class:`~coursekit.creatures.physics.world.World` (``backend``,
            ``device``, ``integrator``, ``drag_coefficient``, ``contacts``, ``hold_contacts``, caps ...).

    Returns:
        A :class:`SimulationResult`.
    """
    if not (is_real(seconds) and seconds > 0):
        raise ValueError(f"seconds: must be a positive number, got {seconds!r}")
    if not (is_real(settle) and settle >= 0):
        raise ValueError(f"settle: must be >= 0 seconds, got {settle!r}")
    if controller is not None and not callable(getattr(controller, "step", controller)):
        raise TypeError("controller: expected an object with step(joint_angle, joint_velocity, contact, dt) or such a "
                        f"function, got {type(controller).__name__}")
    if initial_state is not None and not (isinstance(initial_state, (tuple, list)) and len(initial_state) == 2):
        raise ValueError(f"initial_state: expected a (qpos, qvel) pair, got {type(initial_state).__name__}")
    check_options(options, "simulate", world_only=True)
    brains, bodies = _brains(creatures) if controller is None else (None, as_trees(creatures))
    world = World(bodies, dt=dt, **options)
    m = world.model
    # The creatures' own brains run on the world's backend and read its sensors where they are
    # (no trip to the host on torch); a controller passed in gets numpy arrays, as documented.
    native = brains is not None
    if native:
        controller = BrainBatch(brains, backend=m.backend, device=m.device, compiled=world.compiled)
    if initial_state is not None:
        world.set_state(*initial_state)
    tick = getattr(controller, "step", controller)
    if not (isinstance(record_every, (int, np.integer)) and record_every >= 0):
        raise ValueError(f"record_every: must be an integer >= 0 (steps), got {record_every!r}")
    n_settle = int(round(settle / dt))
    n_steps = int(round(seconds / dt))
    if n_steps < 11:
        raise ValueError(f"seconds: need at least 11 steps of dt={dt}, got {seconds} s")
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=n_settle + n_steps, desc="swimming", unit="step")
    world.set_effectors(np.zeros(m.n_joints))
    for _ in range(n_settle):
        world.step()
        if bar:
            bar.update()
    if controller is not None and hasattr(controller, "reset"):
        controller.reset()
    centres = [world.centre_of_mass(native=True)]  # on the world's device until the end: no wait per step
    frames = [world.get_state()[0]] if record_every else None
    # every joint's worst excess beyond its limits, as a share of its range (limits on or off)
    lo, hi = (bk.asarray(world.xp, m.limits_np[:, k], device=m.device) for k in (0, 1))
    worst = world.xp.zeros_like(world.state.q)
    for i in range(n_steps):
        if controller is not None:
            for _ in range(2):  # two brain ticks per physics step (Sims 1994 section 3)
                effector = tick(*world.sensors(native=native), dt / 2)
            world.set_effectors(effector if native else np.asarray(bk.to_numpy(effector), dtype=np.float64))
        world.step()
        q = world.state.q
        beyond = world.xp.maximum(q - hi, lo - q) if world.overshoot is None else world.overshoot
        worst = world.xp.maximum(worst, beyond / (hi - lo))
        centres.append(world.centre_of_mass(native=True))
        if record_every and (i + 1) % record_every == 0:
            frames.append(world.get_state()[0])
        if bar:
            bar.update()
    if bar:
        bar.close()
    com = np.asarray(bk.to_numpy(world.xp.stack(centres, axis=1)), dtype=np.float64)  # (C, steps + 1, 3)
    times = np.arange(n_steps + 1) * dt
    # a body cut off at the part cap is not the creature its genotype describes: it scores 0
    truncated = np.array([bool(b.meta.get("truncated", False)) for b in m.trees])
    excess = np.zeros(m.n_creatures)
    np.maximum.at(excess, m.joint_creature, bk.to_numpy(worst))
    broken = excess > MAX_EXCESS if world.limits is not None else np.zeros(m.n_creatures, dtype=bool)
    # a joint the step could not hold is no stroke: such a swim scores 0 too
    flagged = world.diverged | truncated | broken
    if fitness is None:
        fitness = swimming_fitness(com, times, flagged)
    else:
        fitness = np.where(flagged, 0.0, _scores(fitness, com.copy(), times.copy()))
    qpos, qvel = world.get_state()
    trajectory = frame_times = None
    if record_every:
        trajectory = [np.stack([f[c] for f in frames]) for c in range(m.n_creatures)]
        frame_times = np.arange(len(frames)) * record_every * dt
    return SimulationResult(fitness, com, times, world.diverged.copy(), qpos, qvel, dt, trajectory, frame_times, excess)


def check_options(options: dict, where: str, *, world_only: bool = False) -> None:
    """Raise ``TypeError`` naming the first of ``options`` that neither :func:`simulate` (unless
    ``world_only``) nor :class:`World` takes, with the closest allowed name and the whole list."""
    names = [p for p in inspect.signature(World.__init__).parameters if p not in ("self", "creatures")]
    if not world_only:
        names = list(dict.fromkeys([p for p in inspect.signature(simulate).parameters if p not in ("creatures", "seconds", "options")] + names))
    for key in options:
        if key not in names:
            near = difflib.get_close_matches(str(key), names, n=1)
            hint = f" (did you mean {near[0]!r}?)" if near else ""
            raise TypeError(f"{where}: unknown option {key!r}{hint}; allowed: {', '.join(names)}")
