"""Checks for exercise 08 (Sims' swimming fitness and his reproduction scheme).

The seed paper's swimmers are bred for speed (section 2.5: Sims 1994 section 5.1 for the
fitness, section 6 for survivors and offspring); exercise 08 has students write both halves,
which then drive the evolution of swimmers. The checks never compare with a reference output:

- ``swimming_fitness(com, times)`` is judged on centre-of-mass paths drawn here (the makers
  :func:`steady_swimmer`, :func:`one_push`, :func:`circling` and :func:`in_place`, which the
  exercise shows its students): a steady straight swimmer scores its speed in m/s, whatever the
  direction, the sample rate, the duration, the start time or the start position; one push and
  coasting, circling and wobbling in place score below a steady swimmer (Sims' two exploits, and
  noise); each creature is scored on its own; no fitness is negative (:func:`out_and_back`, a
  swimmer that comes back to its start, is below 0 by Sims' recipe before clipping). The resampled
  swims (30 and 120 Hz, 4 s, a late start) are the reference swim itself, sway included, so that
  only a duration measured wrongly tells them apart. The job comes first, as a gate: faster steady swimmers score
  higher, so a constant, a zero or a random fitness scores 0. The paths travel to the student's
  function as :class:`Paths`, a numpy array that the grader can compare before and after a call.
- ``reproduce(fitness, k, rng, survival=0.2)`` is judged on the parent indices it returns: only
  the best ``ceil(survival * n)`` reproduce (the gate, with more than one of them: a function
  that always picks the best, or any fixed index, scores 0), each survivor's number of offspring
  is its quota ``k * f_i / sum(f_survivors)`` rounded down or up, the counts do not depend on the
  seed while the order does (so that mates are random), an all-zero generation shares equally,
  and the survivor count is rounded up. Every expected count is computed here from the quota;
  coursekit's own :func:`~coursekit.ga.sims_select` is withheld, and so are Sims' counts under other
  names in the second run that grades ``reproduce``.
"""

from __future__ import annotations

import json
import math
from collections import Counter

import numpy as np

from coursekit.grading.checks import Check, exercise, register
from coursekit.grading.checks.properties import COPY_ARRAY, NEW_ARRAYS, RNG, array, deterministic, seeds, unmodified

__all__ = ["Paths", "circling", "in_place", "one_push", "out_and_back", "sample_times", "steady_swimmer"]

#: Hint ladders (formative ``hint(...)``): a nudge, where to look, a concrete pointer; never the answer.
HINTS = {
    "swimmers.fitness": (
        ("never negative", (
            "A creature that swims out and comes back towards its start has negative late window speeds.",
            "Sims' offspring counts are proportional to fitness: a negative fitness has no meaning there.",
            "Clip the result at 0: np.maximum(fitness, 0.0).")),
        ("faster steady swimmers score higher", (
            "Fitness measures how far the centre of mass gets, per unit of time.",
            "com[c, t] is creature c's centre of mass at times[t]: its distance from com[c, 0] says how far it got.",
            "np.linalg.norm(com - com[:, :1], axis=2) is every creature's distance from its start at every sample.")),
        ("a steady swimmer scores its speed in m/s", (
            "A creature swimming at 0.2 m/s for 10 s gets 2 m away: divide by the time, not by the number of samples.",
            "The time the swim lasted is times[-1] - times[0].")),
        ("time in seconds: any sample rate, duration and start", (
            "Use the times array for every duration: the samples need not be 1/60 s apart, nor start at 0.",
            "Window edges are times, not sample indices: np.interp(edges, times, x) reads a path at any time.")),
        ("any direction counts", (
            "Sims rewards the distance from the start, in any direction, not the progress along x.",)),
        ("the distance counts from where the creature starts", (
            "A creature need not start at the origin: where is it at times[0]?",
            "com[:, :1] is every creature's first position; measure from there.")),
        ("one push and coasting scores below a steady swimmer", (
            "Sims: a single initial push must not pay. Two creatures that end up equally far away should not score the "
            "same when one got there in the first second and then drifted.",
            "Cut the swim into windows and weight the speed of the later windows more heavily.",
            "The speed in a window is how much the distance from the start grew during it, divided by its length.")),
        ("circling scores below a steady swimmer", (
            "Sims: circling must not pay. The length of the path is not the distance from the start.",
            "Use the maximum distance from the initial centre of mass, as Sims did, not the distance travelled.")),
        ("wobbling in place scores about 0", (
            "A creature that flaps in place covers a long path and gets nowhere.",
            "Add up distances from the start, not the lengths of the steps between samples.")),
        ("each creature is scored on its own", (
            "One creature's fitness must not depend on which other creatures share its batch.",
            "Do not normalise by the batch (its maximum, its mean or its ranks): the evolution loop compares "
            "fitness values across generations.")),
    ),
    "swimmers.reproduce": (
        ("only the survivors reproduce", (
            "Sims: the best fifth survive, and only they have offspring.",
            "np.argsort(-fitness, kind='stable') ranks the creatures from the best; keep the first ceil(survival * n).",
            "Every survivor whose fitness earns it at least one offspring must have one: more than one parent appears.")),
        ("offspring in proportion to fitness", (
            "Survivor i's quota is k * f_i / (sum of the survivors' fitness).",
            "Round each quota down first (np.floor); then the counts sum to k or less.",
            "Give the offspring still missing, one each, to the survivors with the largest remainders (quota - floor).")),
        ("the same counts whatever the seed", (
            "Sims' counts are not drawn at random: the quota fixes them. Use the rng only to shuffle.",)),
        ("shuffled, so that mates are random", (
            "Whoever pairs neighbouring parents for crossover needs them in a random order: shuffle before you return.",
            "np.repeat(survivors, counts) lists each survivor counts times; rng.permutation(...) shuffles it.")),
        ("an all-zero generation shares equally", (
            "When every survivor has fitness 0 (a first generation where nothing swims), the quotas are 0/0.",
            "Give every survivor the same share, k / (number of survivors), and round as before.")),
        ("rounds the survivor count up", (
            "With 7 creatures and survival 0.2, 1.4 creatures survive: round up (math.ceil) to 2.",)),
    ),
}


# -- centre-of-mass paths ------------------------------------------------------------------------


def sample_times(seconds: float = 10.0, rate: float = 60.0, start: float = 0.0) -> np.ndarray:
    """``seconds * rate + 1`` sample times from ``start``, ``1 / rate`` apart (as ``simulate`` records them)."""
    return start + np.arange(int(round(seconds * rate)) + 1) / rate


def _unit(direction) -> np.ndarray:
    d = np.asarray(direction, dtype=np.float64)
    return d / np.linalg.norm(d)


def steady_swimmer(times, speed, direction=(1.0, 0.0, 0.0), wobble=0.02, frequency=1.3, phase=0.0) -> np.ndarray:
    """(T, 3) path of a creature swimming straight at ``speed`` (m/s), its body swaying sideways by
    ``wobble`` metres at ``frequency`` Hz (the centre of mass of an undulating swimmer)."""
    t = np.asarray(times, dtype=np.float64) - times[0]
    d = _unit(direction)
    side = np.cross(d, (0.0, 0.0, 1.0)) if abs(d[2]) < 0.9 else np.cross(d, (1.0, 0.0, 0.0))
    side /= np.linalg.norm(side)
    sway = wobble * (np.sin(2 * np.pi * frequency * t + phase) - np.sin(phase))
    return t[:, None] * speed * d + sway[:, None] * side


def one_push(times, distance, tau=0.5, direction=(1.0, 0.0, 0.0)) -> np.ndarray:
    """(T, 3) path of a creature that kicks once and coasts: it covers ``distance`` metres by the
    last sample, most of it in the first ``tau`` seconds (exponential decay of its speed)."""
    t = np.asarray(times, dtype=np.float64) - times[0]
    x = distance * (1 - np.exp(-t / tau)) / (1 - np.exp(-t[-1] / tau))
    return x[:, None] * _unit(direction)


def circling(times, radius, speed, phase=0.0) -> np.ndarray:
    """(T, 3) path of a creature swimming in circles of ``radius`` metres at ``speed`` m/s."""
    t = np.asarray(times, dtype=np.float64) - times[0]
    a = speed / radius * t + phase
    return np.stack([radius * (np.cos(a) - np.cos(phase)), radius * (np.sin(a) - np.sin(phase)), 0 * t], axis=1)


def out_and_back(times, distance, out=0.1, back=0.1, direction=(1.0, 0.0, 0.0)) -> np.ndarray:
    """(T, 3) path of a creature that swims ``distance`` metres out in the first ``out`` share of the
    time, stays there, and comes straight back to its start in the last ``back`` share: its late
    window speeds are negative, and Sims' recipe before clipping is below 0."""
    t = np.asarray(times, dtype=np.float64) - times[0]
    s = t / t[-1]
    x = distance * np.clip(np.minimum(s / out, (1 - s) / back), 0.0, 1.0)
    return x[:, None] * _unit(direction)


def in_place(times, amplitude=0.02, frequency=1.0, phase=0.0) -> np.ndarray:
    """(T, 3) path of a creature that flaps without getting anywhere: its centre of mass swings by
    ``amplitude`` metres (a figure of eight)."""
    t = np.asarray(times, dtype=np.float64) - times[0]
    w = 2 * np.pi * frequency
    return np.stack([amplitude * (np.sin(w * t + phase) - np.sin(phase)), amplitude / 2 * np.sin(2 * w * t), 0 * t], axis=1)


# -- the fitness function -------------------------------------------------------------------------

#: Accepted relative error of a steady swimmer's score against its speed (its sway moves the
#: centre of mass by up to 2 cm, 1 % of a 10 s swim at 0.2 m/s).
SPEED_TOLERANCE = 0.1
#: Agreement between the same swim sampled differently, or in another direction.
SAME_TOLERANCE = 0.05
#: Sims' exploits must score at most this share of the steady swimmer's fitness (the library's
#: fitness gives 0.55-0.65 for one push, at most 0.45 for circling).
EXPLOIT_SHARE = 0.9
#: A creature that gets nowhere scores at most this (m/s); the library's: under 0.002.
STILL = 0.01


def _random_direction(rng):
    d = rng.normal(size=3)
    return d / np.linalg.norm(d)


class Paths(np.ndarray):
    """Centre-of-mass paths ``(C, T, 3)`` as the checks send them: a numpy array in every respect.

    The grader tells whether a call changed an argument from the argument's plain-data form, which
    for an array argument is a flat list; these 3-D arrays travel as JSON instead
    (:meth:`from_json` / :meth:`to_json`, the form genomes and creatures travel in). Whatever a
    function computes from them (numpy functions, operators, methods) is a plain ``numpy.ndarray``.
    """

    FORMAT = "coursekit.paths/1"

    @classmethod
    def from_json(cls, text: str) -> "Paths":
        data = json.loads(text)
        if not (isinstance(data, dict) and data.get("format") == cls.FORMAT and "paths" in data):
            raise ValueError(f"Paths.from_json: expected a {cls.FORMAT!r} document")
        return np.asarray(data["paths"], dtype=np.float64).view(cls)

    def to_json(self) -> str:
        return _paths_json(self)

    def __array_ufunc__(self, ufunc, method, *inputs, **kwargs):
        out = kwargs.get("out")
        if out:
            kwargs["out"] = _plain(out)
        result = getattr(ufunc, method)(*_plain(inputs), **kwargs)
        return out[0] if out and len(out) == 1 and isinstance(out[0], Paths) else result  # x -= y keeps x

    def __array_function__(self, func, types, args, kwargs):
        return func(*_plain(args), **_plain(kwargs))


def _plain(x):
    """``x`` with every :class:`Paths` in it viewed as a plain ndarray (the same memory)."""
    if isinstance(x, Paths):
        return x.view(np.ndarray)
    if isinstance(x, (tuple, list)):
        return type(x)(_plain(v) for v in x)
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}
    return x


def _paths_json(paths) -> str:
    return json.dumps({"format": Paths.FORMAT, "paths": np.asarray(paths, dtype=np.float64).tolist()})


def _paths_case(cid, paths, times):
    text = _paths_json(np.stack(paths))
    com = {"object": f"{__name__}:Paths", "json": text}
    return {"id": cid, "args": [com, array(times)], "seeds": [0], "max_len": 2 * len(text) + len(times)}


def _fitness_cases(rng):
    t = sample_times()
    sway = lambda: dict(wobble=float(rng.uniform(0.005, 0.02)), frequency=float(rng.uniform(0.7, 1.6)),  # noqa: E731
                        phase=float(rng.uniform(0, 2 * np.pi)))
    speeds = np.sort(rng.uniform(0.02, 0.6, 5))
    ref = float(rng.uniform(0.15, 0.3))
    ref_sway = sway()
    ref_path = steady_swimmer(t, ref, **ref_sway)
    # one sway for all five speeds (drawn five times, as before): with a sway each, the path length ranked a slow
    # swimmer that swayed more above a faster one on some seeds and not on others (0 or 2.9 / 5 by the seed)
    speeds_sway = [sway() for _ in speeds][0]
    cases = [_paths_case("speeds", [steady_swimmer(t, v, **speeds_sway) for v in speeds], t), _paths_case("ref", [ref_path], t)]
    dirs = [(-1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, -1.0)] + [_random_direction(rng) for _ in range(2)]
    cases.append(_paths_case("directions", [steady_swimmer(t, ref, d, **sway()) for d in dirs], t))
    for cid, (seconds, rate, start) in {"rate30": (10.0, 30.0, 0.0), "rate120": (10.0, 120.0, 0.0),
                                        "short": (4.0, 60.0, 0.0), "late_start": (10.0, 60.0, 2.5)}.items():
        ts = sample_times(seconds, rate, start)
        sway()  # drawn as before, so that the other cases of a seed stay what they were; the swim is the reference's
        cases.append(_paths_case(cid, [steady_swimmer(ts, ref, **ref_sway)], ts))
    pushes = []
    for _ in range(3):  # a steady swimmer and a one-push creature that end up equally far away
        v, tau = float(rng.uniform(0.05, 0.4)), float(rng.uniform(0.2, 1.0))
        steady = steady_swimmer(t, v, wobble=0.0)
        pushes += [steady, one_push(t, float(np.linalg.norm(steady[-1])), tau)]
    cases.append(_paths_case("push", pushes, t))
    circles = [steady_swimmer(t, 0.1, **sway())]
    circles += [circling(t, float(rng.uniform(0.08, 0.3)), float(rng.uniform(0.4, 1.0)), float(rng.uniform(0, 2 * np.pi)))
                for _ in range(3)]
    cases.append(_paths_case("circle", circles, t))
    cases.append(_paths_case("still", [in_place(t, float(rng.uniform(0.01, 0.03)), float(rng.uniform(0.5, 2.0)),
                                                float(rng.uniform(0, 2 * np.pi))) for _ in range(3)], t))
    mixed = [steady_swimmer(t, float(rng.uniform(0.05, 0.5)), _random_direction(rng), **sway()),
             one_push(t, float(rng.uniform(0.5, 3.0)), float(rng.uniform(0.2, 1.0)), _random_direction(rng)),
             circling(t, 0.2, 0.7), in_place(t), steady_swimmer(t, 0.01, wobble=0.0),
             steady_swimmer(t, float(rng.uniform(0.5, 1.0)), **sway())]
    cases.append(_paths_case("batch", mixed, t))
    cases += [_paths_case(f"alone{i}", [p], t) for i, p in enumerate(mixed)]
    # drawn last (the other cases of a seed stay what they were): 4-8 m off the line the swim takes (+x), so
    # that the distance from the origin grows at another rate than the distance from the start
    side = rng.uniform(4, 8, size=2) * rng.choice((-1, 1), size=2)
    cases.append(_paths_case("moved", [ref_path + np.array([0.0, side[0], side[1]])], t))
    # drawn after those: swimmers that come back to their start in the last window or two (Sims' recipe
    # before clipping: -0.2 to -0.3 times distance / duration)
    cases.append(_paths_case("back", [out_and_back(t, float(rng.uniform(0.5, 2.0)), float(rng.uniform(0.05, 0.2)),
                                                   float(rng.uniform(0.05, 0.15)), _random_direction(rng))
                                      for _ in range(2)], t))
    return cases


def _paths(ctx, cid):
    return np.asarray(ctx.arg(cid, 0), dtype=np.float64)


def _scores(ctx, cid):
    return np.asarray(ctx.out(cid)[0], dtype=np.float64)


def _fitness_valid(ctx):
    for cid in ctx.cases:
        n = len(ctx.arg(cid, 0))
        out = ctx.out(cid)[0]
        if len(out) != n:
            return False, f"for {n} creatures it returned {len(out)} values; expected one fitness per creature (shape ({n},))"
        if not all(math.isfinite(f) for f in out):
            return False, f"returned {[f for f in out if not math.isfinite(f)][0]!r}; every fitness must be a finite number"
    return True, "one finite fitness per creature"


def _never_negative(ctx):
    for cid in ctx.cases:
        out = ctx.out(cid)[0]
        if min(out) < 0:
            what = ("a creature that swam out and came back to its start" if cid == "back" else
                    f"on test input {cid!r} a creature")
            return False, (f"{what} scored {min(out):.4g}; fitness must be >= 0 (Sims' offspring counts are "
                           "proportional to it): clip it at 0")
    return True, "every fitness >= 0, a creature that comes back to its start included"


def _faster_higher(ctx):
    speeds = [float(np.linalg.norm(p[-1] - p[0]) / 10.0) for p in _paths(ctx, "speeds")]
    f = _scores(ctx, "speeds")
    for i in range(len(f) - 1):
        if not f[i + 1] > f[i]:
            return False, (f"steady swimmers at {speeds[i]:.3f} and {speeds[i + 1]:.3f} m/s scored {f[i]:.4g} and "
                           f"{f[i + 1]:.4g}: the faster one must score higher. That is a fitness function's job. "
                           "Nothing else is judged until it does")
    return True, f"faster steady swimmers score higher ({len(f)} speeds from {speeds[0]:.2f} to {speeds[-1]:.2f} m/s)"


def _speed_of(path, times):
    return float(np.linalg.norm(path[-1] - path[0]) / (times[-1] - times[0]))


def _scores_speed(ctx):
    t = ctx.arg("speeds", 1)
    for p, f in zip(_paths(ctx, "speeds"), _scores(ctx, "speeds")):
        v = _speed_of(p, t)
        if abs(f - v) > SPEED_TOLERANCE * v:
            return False, (f"a creature swimming straight at {v:.3f} m/s for 10 s scored {f:.4g}; a steady swimmer "
                           f"should score its speed in m/s (within {SPEED_TOLERANCE:.0%}), so that fitness reads as a speed")
    return True, f"steady swimmers score their speed in m/s (within {SPEED_TOLERANCE:.0%})"


def _time_in_seconds(ctx):
    ref = _scores(ctx, "ref")[0]
    what = {"rate30": "sampled at 30 Hz", "rate120": "sampled at 120 Hz", "short": "over 4 s instead of 10 s",
            "late_start": "with times starting at 2.5 s"}
    for cid, how in what.items():
        f = _scores(ctx, cid)[0]
        if abs(f - ref) > SAME_TOLERANCE * ref:
            return False, (f"the same steady swim scored {ref:.4g} sampled at 60 Hz over 10 s, but {f:.4g} {how}: "
                           "measure durations with the times array, in seconds")
    return True, "the same swim scores the same at 30, 60 and 120 Hz, over 4 or 10 s, from any start time"


def _any_direction(ctx):
    ref = _scores(ctx, "ref")[0]
    for p, f in zip(_paths(ctx, "directions"), _scores(ctx, "directions")):
        if abs(f - ref) > SAME_TOLERANCE * ref:
            d = np.round((p[-1] - p[0]) / np.linalg.norm(p[-1] - p[0]), 2).tolist()
            return False, (f"a steady swimmer scored {ref:.4g} swimming along +x but {f:.4g} swimming along {d}: "
                           "Sims rewards the distance from the start in any direction")
    return True, "the same speed scores the same in any direction"


def _from_start(ctx):
    ref, f = _scores(ctx, "ref")[0], _scores(ctx, "moved")[0]
    if abs(f - ref) > SAME_TOLERANCE * ref:
        start = np.round(_paths(ctx, "moved")[0][0], 2).tolist()
        return False, (f"the same steady swim scored {ref:.4g} starting at the origin but {f:.4g} starting at {start}: "
                       "Sims measures the distance from where the creature starts, not from the origin")
    return True, "the distance counts from where the creature starts, wherever that is"


def _push_below(ctx):
    f = _scores(ctx, "push")
    paths = _paths(ctx, "push")
    for i in range(0, len(f), 2):
        d = float(np.linalg.norm(paths[i][-1]))
        if not f[i + 1] <= EXPLOIT_SHARE * f[i]:
            return False, (f"a creature that kicked once and coasted {d:.2f} m scored {f[i + 1]:.4g}, a steady swimmer "
                           f"that covered the same {d:.2f} m scored {f[i]:.4g}. Sims: a single initial push must not pay; "
                           f"it should score at most {EXPLOIT_SHARE:.0%} of the steady swimmer")
    return True, f"one push and coasting scores at most {EXPLOIT_SHARE:.0%} of a steady swimmer covering the same distance"


def _circle_below(ctx):
    f = _scores(ctx, "circle")
    for p, g in zip(_paths(ctx, "circle")[1:], f[1:]):
        r = float(np.max(np.linalg.norm(p - p[0], axis=1)) / 2)
        if not g <= EXPLOIT_SHARE * f[0]:
            return False, (f"a creature circling (radius {r:.2f} m) scored {g:.4g}, a steady swimmer at 0.1 m/s "
                           f"{f[0]:.4g}. Sims: circling must not pay; it should score at most {EXPLOIT_SHARE:.0%} of "
                           "the swimmer, however fast it circles")
    return True, f"circling scores at most {EXPLOIT_SHARE:.0%} of a steady swimmer at 0.1 m/s"


def _still(ctx):
    for f in _scores(ctx, "still"):
        if f > STILL:
            return False, (f"a creature that flaps in place (its centre of mass swings a few cm and comes back) scored "
                           f"{f:.4g} m/s; getting nowhere should score about 0 (at most {STILL} m/s)")
    return True, f"wobbling in place scores at most {STILL} m/s"


def _on_its_own(ctx):
    together = _scores(ctx, "batch")
    for i, f in enumerate(together):
        alone = _scores(ctx, f"alone{i}")[0]
        if not math.isclose(f, alone, rel_tol=1e-9, abs_tol=1e-12):
            return False, (f"creature {i} of a batch of {len(together)} scored {f:.6g}, and {alone:.6g} alone: a "
                           "creature's fitness must not depend on the rest of the batch")
    return True, f"each of {len(together)} creatures scores the same alone as in a batch"


register(Check(
    hints=HINTS["swimmers.fitness"],
    name="swimmers.fitness", function="swimming_fitness", params=("com", "times"), points=5.0,
    title="Sims' swimming fitness", output="array", cases=_fitness_cases, gates=2,
    reference=("coursekit.creatures.fitness:swimming_fitness",),
    props=(
        ("one fitness per creature", _fitness_valid),
        ("faster steady swimmers score higher", _faster_higher),
        ("never negative", _never_negative),
        ("a steady swimmer scores its speed in m/s", _scores_speed),
        ("time in seconds: any sample rate, duration and start", _time_in_seconds),
        ("any direction counts", _any_direction),
        ("the distance counts from where the creature starts", _from_start),
        ("one push and coasting scores below a steady swimmer", _push_below),
        ("circling scores below a steady swimmer", _circle_below),
        ("wobbling in place scores about 0", _still),
        ("each creature is scored on its own", _on_its_own),
        ("inputs unchanged", unmodified({0: "com", 1: "times"}, NEW_ARRAYS)),
    ),
    # Sims' late weighting (91 % before); the distance from the start (from the origin: 100 %, a student's walk)
    weights=(("one push and coasting scores below a steady swimmer", 4), ("the distance counts from where the creature starts", 2)),
))


# -- the reproduction scheme ----------------------------------------------------------------------


def survivors_of(fitness, survival=0.2) -> np.ndarray:
    """Indices of the best ``ceil(survival * n)`` (ties: the lower index), best first."""
    f = np.asarray(fitness, dtype=np.float64)
    return np.argsort(-f, kind="stable")[: math.ceil(survival * f.size - 1e-9)]


def quotas(fitness, k, survival=0.2) -> dict:
    """``{survivor: k * f_i / sum(f_survivors)}`` (equal shares when the survivors' fitness is all 0)."""
    f = np.asarray(fitness, dtype=np.float64)
    s = survivors_of(f, survival)
    total = float(f[s].sum())
    return {int(i): (k * float(f[i]) / total if total > 0 else k / len(s)) for i in s}


def _reproduce_cases(rng):
    def fitness(n, zeros=0):
        f = rng.uniform(0.0, 0.5, n) * rng.choice([0.1, 1.0], n)
        f[rng.choice(n, zeros, replace=False)] = 0.0
        return f

    def case(cid, f, survival=None, n_seeds=3, same=False):
        k = len(f) - math.ceil((survival or 0.2) * len(f))  # the offspring slots beside the kept survivors
        s = seeds(rng, 1) * n_seeds if same else seeds(rng, n_seeds)
        c = {"id": cid, "args": [array(f), int(k), RNG], "seeds": s, "max_len": 10 * len(f)}
        if survival is not None:
            c["kwargs"] = {"survival": survival}
        return c

    best_last = np.sort(fitness(20))  # index 0 is the worst: a constant index 0 picks a non-survivor
    cases = [case("n20", best_last), case("n30", fitness(30)), case("n50", fitness(50, zeros=5), n_seeds=4),
             case("half", fitness(16), survival=0.5), case("zeros", np.zeros(25)),
             # half survive, two of them with fitness 0: they get no offspring
             case("some_zero", rng.permutation(np.r_[rng.uniform(0.1, 0.5, 3), np.zeros(7)]), survival=0.5),
             case("seven", fitness(7) + 0.05), case("same", fitness(40), same=True),
             # drawn last: half survive and all of them earn about one offspring, so that the best fifth alone (the
             # survival argument ignored) gets twice its share or more (s25: 'half' let it pass on some seeds)
             case("half_even", rng.uniform(0.3, 0.5, 20), survival=0.5)]
    return cases


PROPORTIONAL = ("n20", "n30", "n50", "half", "some_zero", "same", "half_even")


def _indices_valid(ctx):
    for cid in ctx.cases:
        n, k = len(ctx.arg(cid, 0)), ctx.arg(cid, 1)
        for out in ctx.out(cid):
            if len(out) != k:
                return False, f"for k={k} it returned {len(out)} parents; expected k indices, one per child"
            bad = [i for i in out if not 0 <= i < n]
            if bad:
                return False, f"returned index {bad[0]}, out of range for a population of {n} (valid: 0..{n - 1})"
    return True, "returns k valid indices"


def _survival(ctx, cid):
    return ctx.kwarg(cid, "survival", 0.2)


def _only_survivors(ctx):
    for cid in ("n20", "n30", "n50", "half"):
        f = ctx.arg(cid, 0)
        allowed = set(survivors_of(f, _survival(ctx, cid)).tolist())
        for out in ctx.out(cid):
            outside = sorted(set(out) - allowed)
            if outside:
                i = outside[0]
                return False, (f"out of {len(f)} creatures, creature {i} (fitness {f[i]:.4g}, not among the best "
                               f"{len(allowed)}) got offspring; only the survivors (the best {_survival(ctx, cid):g} of "
                               "the population) reproduce. Nothing else is judged until they alone do")
            if len(set(out)) < 2:
                return False, (f"all {len(out)} children of a population of {len(f)} have the same parent: the "
                               f"{len(allowed)} survivors all reproduce. Nothing else is judged until they do")
    return True, "only the best fifth reproduce, and more than one of them"


def _proportional(ctx):
    for cid in PROPORTIONAL:
        f, k = ctx.arg(cid, 0), ctx.arg(cid, 1)
        q = quotas(f, k, _survival(ctx, cid))
        for out in ctx.out(cid):
            counts = Counter(out)
            for i, quota in q.items():
                if abs(counts.get(i, 0) - quota) >= 1:
                    survival = _survival(ctx, cid)
                    who = "" if survival == 0.2 else (f" With survival={survival:g} the best {len(q)} of {len(f)} "
                                                      "survive: use the survival argument.")
                    return False, (f"a survivor with fitness {f[i]:.4g} (the survivors' total is "
                                   f"{sum(f[j] for j in q):.4g}) got {counts.get(i, 0)} of the {k} offspring; its share "
                                   f"is {quota:.2f}, so it should get {math.floor(quota)} or {math.ceil(quota)}.{who}")
    return True, "each survivor's offspring are its share of k, rounded down or up"


def _same_counts(ctx):
    for cid in PROPORTIONAL:
        outs = [sorted(o) for o in ctx.out(cid)]
        if any(o != outs[0] for o in outs[1:]):
            return False, ("two calls with different seeds gave the survivors different numbers of offspring; Sims' "
                           "counts follow from the fitness alone (use the rng only to shuffle)")
    return True, "the counts follow from the fitness alone"


def _shuffled(ctx):
    for cid in ("n30", "n50"):
        outs = [tuple(o) for o in ctx.out(cid)]
        if len(set(outs)) == 1:
            return False, (f"{len(outs)} calls with different seeds returned the parents in the same order; shuffle "
                           "them with the rng, so that the loop pairs random mates for crossover")
    return True, "the order of the parents changes with the seed"


def _all_zero(ctx):
    f, k = ctx.arg("zeros", 0), ctx.arg("zeros", 1)
    n_surv = len(survivors_of(f))
    for out in ctx.out("zeros"):
        counts = Counter(out)
        got = [counts.get(i, 0) for i in range(len(f))]
        parents = [c for c in got if c]
        if len(parents) != n_surv or max(parents) - min(parents) > 1:
            return False, (f"when all {len(f)} creatures have fitness 0, {len(parents)} of them got offspring "
                           f"(between {min(parents) if parents else 0} and {max(parents) if parents else 0} each); the "
                           f"{n_surv} survivors should share the {k} offspring equally")
    return True, "an all-zero generation: the survivors share equally"


def _rounds_up(ctx):
    for out in ctx.out("seven"):
        if len(set(out)) != 2:
            return False, (f"with 7 creatures and survival 0.2, {len(set(out))} of them got offspring; 1.4 creatures "
                           "survive, rounded up to 2")
    return True, "rounds the survivor count up (7 creatures: 2 survivors)"


register(Check(
    hints=HINTS["swimmers.reproduce"],
    name="swimmers.reproduce", function="reproduce", params=("fitness", "k", "rng"), points=5.0,
    title="Sims' survivors and offspring", output="indices", cases=_reproduce_cases, gates=2,
    reference=("coursekit.ga.selection:sims_select", "coursekit.ga.selection:sims_offspring",
               "coursekit.grading.checks.ex08_fitness_and_reproduction:survivors_of",
               "coursekit.grading.checks.ex08_fitness_and_reproduction:quotas",
               # Sims' counts under other names (red team: ranking + n_survivors + largest_remainder, or ga.Variation as
               # the selector, 5/5): the library's evolution uses them, so a second run that grades reproduce withholds them
               "coursekit.ga.variation:largest_remainder", "coursekit.ga.selection:ranking", "coursekit.ga.selection:n_survivors"),
    library_uses=("coursekit.ga.variation:largest_remainder", "coursekit.ga.selection:ranking",
                  "coursekit.ga.selection:n_survivors"),
    props=(
        ("returns k valid indices", _indices_valid),
        ("only the survivors reproduce", _only_survivors),
        ("offspring in proportion to fitness", _proportional),
        ("the same counts whatever the seed", _same_counts),
        ("shuffled, so that mates are random", _shuffled),
        ("deterministic for a seed", deterministic("same")),
        ("an all-zero generation shares equally", _all_zero),
        ("rounds the survivor count up", _rounds_up),
        ("input unchanged", unmodified({0: "fitness"}, COPY_ARRAY)),
    ),
    # equal shares for every survivor kept 90 % (round 6); Sims' counts are the scheme's definition, half the
    # weight (s25: extra offspring all to the best, or the survival argument ignored, kept 69 %)
    weights=(("offspring in proportion to fitness", 9),),
))

exercise("08_fitness_and_reproduction", ["swimmers.fitness", "swimmers.reproduce"])
