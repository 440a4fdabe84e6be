"""Is a swimmer swimming, or exploiting the simulator? The checks a fast creature must pass.

Sims warned that "energy leaks from non-conservation, or even round-off errors, will inevitably be
discovered and exploited". A creature's speed is only worth celebrating when it comes from
pushing against the water. :func:`audit` simulates each creature under conditions in which
nothing can swim and reports what it finds:

- ``passive_drift``: centre-of-mass displacement with its effectors off, in water (m): a body
  settling, not swimming, should barely move;
- ``vacuum_drift``: displacement with the water switched off, at the simulation step and with
  the physics integrated in eight sub-steps per step (m): internal forces conserve momentum, so
  nothing swims in a vacuum; what is left is integration error, which shrinks with the step
  (order 4) -- a creature whose speed depends on it is exploiting the step, not the water;
- ``fine_speed``: the distance swum per second with the physics in eight sub-steps per step
  (m/s), against ``speed`` at the step itself: a speed that disappears when the same system is
  integrated more finely was integration error. Only the physics is refined: the brain ticks and
  the effectors change at the same times (a brain is a discrete-time system whose behaviour
  depends on its tick, as in Sims' creatures, so a finer *step* changes the controller, not only
  the integration: a demo champion kept half its speed at dt/8 and all of it in eight sub-steps);
- ``sunk``: the share of the fine run's frames (one every :data:`FRAME` steps) in which two of
  its parts sit more than :data:`SUNK_DEPTH` of the thinner one's thickness inside each other
  (:func:`overlaps`). Held contacts (:mod:`~coursekit.creatures.physics.contact_forces`) keep
  parts apart, but a fast limb that sweeps through another part within a step can end up inside
  it and stay there, pressed in by its muscle; a creature evolution bred swam 1.26 m/s so, 1.19
  in eight sub-steps and 0.13 in 24, where its parts never sank over 4 %. A creature sunk in
  more than :data:`SUNK_SHARE` of its frames swims once more with the physics in
  :data:`DEEP_REFINE` sub-steps per step: ``deep_speed`` (m/s; ``None`` when not sunk);
- ``limit_excess``: the worst overshoot of any joint beyond its limits within a step (put back at
  the step's end; :mod:`~coursekit.creatures.physics.limits`), as a fraction of its range;
- ``diverged``: the speed-cap or non-finite guard fired (the creature scores 0);
- ``energy``: the work its effectors did (J), ``sum(tau * qd) dt``; ``cost_of_transport`` =
  energy / (mass * distance) (J / (kg m)).

``passed`` is False, with ``reasons``, when the drift in a vacuum in the fine run or the drift
with the effectors off is over :data:`VACUUM_TOLERANCE` of the distance swum, when the fine-step
speed or the deep one is below :data:`FINE_SPEED_SHARE` of the speed, when a limit is passed by
more than :data:`LIMIT_TOLERANCE` of its range, or when the creature diverged. Distances under
:data:`NEGLIGIBLE` body lengths are not judged.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from .physics.limits import MAX_EXCESS

if TYPE_CHECKING:
    from .body import BodyTree

#: Largest vacuum drift in the fine run, as a share of the distance swum in water.
VACUUM_TOLERANCE = 0.05
#: Smallest share of its speed a creature must keep when the step is refined eightfold.
FINE_SPEED_SHARE = 0.75
#: Largest joint-limit excess, as a share of the joint's range (the simulator's own bound).
LIMIT_TOLERANCE = MAX_EXCESS
#: How many sub-steps per step the "fine" runs integrate the physics in.
REFINE = 8
#: Distances below this many body lengths are not judged (a creature that hardly moves).
NEGLIGIBLE = 0.05
#: Two parts whose overlap exceeds this share of the thinner one's thickness are sunk into each other.
SUNK_DEPTH = 0.25
#: A creature sunk in more than this share of its fine run's frames is refined again, deeper.
SUNK_SHARE = 0.25
#: How many sub-steps per step the run of a sunk creature integrates the physics in.
DEEP_REFINE = 3 * REFINE
#: The fine run is measured for overlaps every this many steps (0.1 s at 60 steps a second).
FRAME = 6


@dataclass
class AuditReport:
    """What :func:`audit` found for one creature (see the module docstring for the fields)."""

    speed: float
    body_length: float
    fine_speed: float
    passive_drift: float
    vacuum_drift: float
    vacuum_drift_fine: float
    limit_excess: float
    diverged: bool
    energy: float
    cost_of_transport: float
    sunk: float = 0.0
    deep_speed: float | None = None
    reasons: list = field(default_factory=list)

    @property
    def passed(self) -> bool:
        return not self.reasons

    @property
    def body_lengths_per_second(self) -> float:
        return self.speed / self.body_length

    def __str__(self) -> str:
        verdict = "passed" if self.passed else "FAILED: " + "; ".join(self.reasons)
        return (f"{self.speed:.3f} m/s = {self.body_lengths_per_second:.3f} body lengths/s "
                f"(in {REFINE} sub-steps: {self.fine_speed:.3f} m/s); drift with effectors off {self.passive_drift:.3f} m, "
                f"in a vacuum in {REFINE} sub-steps {self.vacuum_drift_fine:.4f} m (at the step itself {self.vacuum_drift:.3f} m, "
                f"not judged: with no water to slow them the limbs move far faster than when swimming); "
                f"parts sunk into each other in {self.sunk:.0%} of the frames"
                + ("" if self.deep_speed is None else f" ({self.deep_speed:.3f} m/s in {DEEP_REFINE} sub-steps)")
                + f"; worst limit excess {100 * self.limit_excess:.1f} % of range; energy {self.energy:.3g} J; {verdict}")


def body_length(body: BodyTree) -> float:
    """The creature's largest extent at rest (m): its length, the unit of "body lengths per second"."""
    from .render import box_corners

    pts = box_corners(body).reshape(-1, 3)
    return float(np.max(np.ptp(pts, axis=0)))


def overlaps(creatures: Any, trajectory: list) -> tuple[np.ndarray, np.ndarray]:
    """How deep each creature's parts sit in each other, frame by frame: ``(share, metres)``, both
    (F, C) -- at each recorded frame of ``trajectory`` (:func:`~coursekit.creatures.simulate`'s,
    one ``(F, nq)`` array per creature; creatures or BodyTrees), the deepest overlap of any candidate pair of the
    creature's parts (not joined directly, not fused at rest), as a share of the thinner part's
    thickness (1: the thinner part is wholly inside the other) and in metres; 0 without contact."""
    from .physics.world import World

    world = World(creatures)
    m = world.model
    thin = 2.0 * m.half_extents_np.min(axis=1)
    frames = len(trajectory[0]) if trajectory else 0
    share, metres = np.zeros((frames, m.n_creatures)), np.zeros((frames, m.n_creatures))
    if world.contacts is None or world.contacts.n_pairs == 0:
        return share, metres
    at_rest = [np.zeros(f.shape[1] - 1) for f in trajectory]  # qvel: one fewer than qpos (quaternion)
    for k in range(frames):
        world.set_state([f[k] for f in trajectory], at_rest)
        _, a, b, _, depth, _ = world.contacts.detect(*world.body_poses())
        owner = m.creature[np.asarray(a, dtype=np.int64)]
        np.maximum.at(share[k], owner, depth / np.minimum(thin[a], thin[b]))
        np.maximum.at(metres[k], owner, depth)
    return share, metres


def sunk_share(creatures: Any, trajectory: list) -> np.ndarray:
    """(C,) the share of the frames of ``trajectory`` in which some two of each creature's parts sit
    more than :data:`SUNK_DEPTH` of the thinner one's thickness inside each other (:func:`overlaps`)."""
    return (overlaps(creatures, trajectory)[0] > SUNK_DEPTH).mean(axis=0)


class _Silent:
    """A controller whose effectors are all off."""

    def __init__(self, n):
        self.n = n

    def step(self, q, qd, contact, dt):
        return np.zeros(self.n)


#: The audit's runs, the two in eight sub-steps first (each costs as much as the other three).
RUNS = ("fine", "vacuum_fine", "swim", "passive", "vacuum")


@dataclass
class _Run:
    """What the audit keeps of one run: the centre of mass at its start and end, the worst limit
    excess, the guards' flags and the effectors' work (the metered swim only)."""

    ends: np.ndarray
    limit_excess: np.ndarray
    diverged: np.ndarray
    work: np.ndarray | None = None
    sunk: np.ndarray | None = None

    def distance(self, i: int) -> float:
        return float(np.linalg.norm(self.ends[i, 1] - self.ends[i, 0]))


def _run(job) -> _Run:
    """One of the audit's :data:`RUNS` ``(run, creatures, seconds, dt, options)``, one thread."""
    from threadpoolctl import threadpool_limits

    from .simulate import simulate

    run, creatures, seconds, dt, options = job
    substeps = options.pop("substeps", 1)
    if run.startswith("vacuum"):
        options["drag_coefficient"] = 0.0
    if run.endswith("fine"):
        options["substeps"] = REFINE * substeps
    if run == "deep":
        options["substeps"] = DEEP_REFINE * substeps
    if run == "fine":
        options["record_every"] = FRAME
    meter = _Metered(creatures) if run == "swim" else None
    if meter is not None:
        options["controller"] = meter
    elif run == "passive":
        options["controller"] = _Silent(sum(c.expand().body.n_joints for c in creatures))
    with threadpool_limits(1):
        r = simulate(creatures, seconds, dt=dt, **options)
    sunk = None if r.trajectory is None else sunk_share(creatures, r.trajectory)
    return _Run(r.com[:, [0, -1]], r.limit_excess, r.diverged, None if meter is None else meter.work, sunk)


def audit(creatures: Any, seconds: float = 10.0, *, dt: float = 1.0 / 60.0, executor: Any | None = None,
          **options: Any) -> list[AuditReport]:
    """Audit creatures for exploits (module docstring); one :class:`AuditReport` each.

    Args:
        creatures: creatures (with brains) to audit, simulated together.
        seconds: swimming time of every run (s).
        dt: the simulation step to audit.
        executor: a ``concurrent.futures`` pool or a Dask client the five runs (:data:`RUNS`)
            are spread over; the reports are the same as without one.
        **options: further :func:`~coursekit.creatures.simulate.simulate` options.
    """
    from coursekit.ga.evaluation import parallel_map

    creatures = list(creatures)
    bodies = [c.expand().body for c in creatures]
    jobs = [(run, creatures, seconds, dt, dict(options)) for run in RUNS]
    runs = parallel_map(_run, jobs, executor) if executor is not None else [_run(job) for job in jobs]
    fine, vacuum_fine, swim, passive, vacuum = runs
    energy = swim.work
    sunk = np.flatnonzero(fine.sunk > SUNK_SHARE)  # swum once more, in DEEP_REFINE sub-steps
    deep_speed, deep_diverged = [None] * len(creatures), np.zeros(len(creatures), dtype=bool)
    if len(sunk):
        deep = _run(("deep", [creatures[i] for i in sunk], seconds, dt, dict(options)))
        for k, i in enumerate(sunk):
            deep_speed[i] = deep.distance(k) / seconds
        deep_diverged[sunk] = deep.diverged
    reports = []
    for i, b in enumerate(bodies):
        d = swim.distance(i)
        mass = float(b.mass.sum())
        rep = AuditReport(
            speed=d / seconds, body_length=body_length(b), fine_speed=fine.distance(i) / seconds,
            passive_drift=passive.distance(i), vacuum_drift=vacuum.distance(i), vacuum_drift_fine=vacuum_fine.distance(i),
            limit_excess=float(swim.limit_excess[i]), diverged=bool(swim.diverged[i] or fine.diverged[i] or deep_diverged[i]),
            energy=energy[i], cost_of_transport=energy[i] / (mass * d) if d > 0 else float("inf"),
            sunk=float(fine.sunk[i]), deep_speed=deep_speed[i],
        )
        if rep.diverged:
            rep.reasons.append("diverged (speed cap or non-finite state)")
        floor = NEGLIGIBLE * rep.body_length  # below this, no one would call it swimming either way
        if rep.vacuum_drift_fine > max(VACUUM_TOLERANCE * d, floor):
            rep.reasons.append(f"moves {rep.vacuum_drift_fine:.3g} m in a vacuum in {REFINE} sub-steps")
        if rep.passive_drift > max(VACUUM_TOLERANCE * d, floor):
            rep.reasons.append(f"drifts {rep.passive_drift:.3g} m with its effectors off")
        if rep.fine_speed < FINE_SPEED_SHARE * rep.speed and (rep.speed - rep.fine_speed) * seconds > floor:
            rep.reasons.append(f"keeps only {rep.fine_speed / max(rep.speed, 1e-12):.0%} of its speed in {REFINE} sub-steps")
        if rep.deep_speed is not None and rep.deep_speed < FINE_SPEED_SHARE * rep.speed and (rep.speed - rep.deep_speed) * seconds > floor:
            rep.reasons.append(f"keeps only {rep.deep_speed / max(rep.speed, 1e-12):.0%} of its speed in {DEEP_REFINE} sub-steps, "
                               f"its parts sunk into each other in {rep.sunk:.0%} of the frames in {REFINE}")
        if rep.limit_excess > LIMIT_TOLERANCE:
            rep.reasons.append(f"passes a joint limit by {100 * rep.limit_excess:.0f} % of its range")
        reports.append(rep)
    return reports


class _Metered:
    """The creatures' own brains as the controller, metering the effectors' work ``|tau . qd| dt``."""

    def __init__(self, creatures):
        from .brain import BrainBatch

        phenotypes = [c.expand() for c in creatures]
        self.brains = BrainBatch([p.brain for p in phenotypes])
        self.strength = np.concatenate([p.body.strength[1:] for p in phenotypes])
        self.gain = np.concatenate([p.body.gain[1:] for p in phenotypes])
        self.owner = np.concatenate([np.full(p.body.n_joints, i) for i, p in enumerate(phenotypes)])
        self.work = np.zeros(len(phenotypes))

    def reset(self):
        self.brains.reset()

    def step(self, q, qd, contact, h):
        e = np.asarray(self.brains.step(q, qd, contact, h), dtype=np.float64)
        tau = self.strength * np.clip(self.gain * np.where(np.isfinite(e), e, 0.0), -1.0, 1.0)  # as World.set_effectors
        self.work += np.bincount(self.owner, weights=np.abs(tau * qd) * h, minlength=len(self.work))
        return e
