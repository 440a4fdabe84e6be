"""Checks for exercise 06 (wiring a brain by relative ids: the seed paper's nested networks).

Seed paper section 2.1.2: every node of the morphology graph carries a local network, and a
connection names its source by a *relative id* ``(morphId, controlId)`` that expansion resolves
on each part instance (section 2.3; :mod:`coursekit.creatures.neural`, :mod:`.brain`). Exercise 06
has students resolve relative ids themselves and then wire the Figure 1 snake so that it swims.

- ``brains.resolve(morph, part, parent, children)``: which network a relative id names, read
  from part ``part`` of an expanded tree (``parent[b]``, ``children[b]`` in relative-id order):
  the part index, ``"brain"`` for ``-2``, or ``None`` where the instance has no such relative (it
  reads 0). The trees are expansions of the library's random creatures and of the snake; the
  expected answers follow the four rules of the lesson's table, computed here. The job, a gate:
  -1 names the parent or m >= 1 names the children (a constant answer scores 0). Then each rule
  of the table is a property of its own (parent and children count double), so one wrong rule --
  the root's parent as -1, an off-by-one child, an IndexError on a missing child -- costs its
  share, not the check.
- ``brains.wire_snake(snake)``: the snake's body without networks in, the same body with
  neurons and effectors out. The grader swims the result in its own process
  (:func:`~coursekit.creatures.simulate.simulate`, :data:`SECONDS` s) for 3, 4 and 5
  segments. Gates: a valid creature, the body kept, and the job -- the 4-segment snake swims at
  least :data:`SWIM_MIN` body lengths per second (the unwired body, or one beating every
  segment in phase, scores 0: measured 0.00 and 0.01, the paper's travelling wave 0.26). Then: a
  wave travels along the spine, the one genotype swims at every length (relative ids, not
  per-part wiring), the legs swing, the input is left alone. The wave is judged on what the
  wiring sends the spine's muscles (recorded as the simulator runs the creature's brain), not on
  the joints' motion: the water bends the joints with phase shifts of its own (a snake driven in
  phase moves its neighbouring joints nearly in opposition, one driven with steps of -0.5 rad
  shows no steady step), so the motion cannot tell the student's wave from none. Each joint's
  drive must lag its neighbour's by one steady step modulo 2 pi, at least :data:`WAVE_LAG` rad
  either way and short of a half turn: every step the exercise's sweep tries (-3 .. -0.5, and
  +0.3 .. +3.1 the other way) is a wave; in-phase, exact opposition and uneven steps are not.
"""

from __future__ import annotations

import functools
import json

import numpy as np

from coursekit.grading.checks import Check, NotRun, exercise, register

CREATURE = "coursekit.creatures.genotype:Creature"
SECONDS = 4.0  #: swim time of the wired snakes (after the simulator's settling)
SWIM_MIN = 0.05  #: body lengths per second that count as swimming
WAVE_LAG = 0.25  #: rad: smallest phase step between neighbouring spine joints' drives that counts as a wave
WAVE_SPREAD = 0.25  #: rad: how far a phase step along the spine may stray from their mean and still be one steady step
STANDING_GAP = 0.02  #: rad: a step this close to a half turn is a standing wave (neighbours in opposition)
SETTLE_OUT = 0.25  #: s: the start of the swim left out when measuring phases (the phase chain starts up)
LEG_SWING = 0.2  #: rad: smallest range of motion of a leg joint that counts as a swing
SEGMENTS = (4, 3, 5)


def _creature_cls():
    from coursekit.creatures.genotype import Creature

    return Creature


# ============================================================================ resolve


def _tree(creature):
    pheno = creature.expand()
    return [int(p) for p in pheno.body.parent], [[int(c) for c in kids] for kids in pheno.children]


def expected_target(morph, part, parent, children):
    """The rule of the lesson's table: the part index, ``"brain"`` or ``None`` (reads 0)."""
    if morph == -2:
        return "brain"
    if morph == -1:
        return parent[part] if parent[part] >= 0 else None
    if morph == 0:
        return part
    return children[part][morph - 1] if morph <= len(children[part]) else None


def _resolve_cases(rng):
    Creature = _creature_cls()
    trees = [_tree(Creature.figure1_snake(segments=4))]
    while len(trees) < 4:
        c = Creature.random(np.random.default_rng(int(rng.integers(2**31))), n_nodes=(2, 5))
        parent, children = _tree(c)
        if len(parent) >= 4 and any(len(k) >= 2 for k in children):
            trees.append((parent, children))
    cases = []

    def add(kind, morph, part, t):
        parent, children = trees[t]
        cases.append({"id": f"{kind}{sum(c['id'].startswith(kind) for c in cases)}",
                      "args": [int(morph), int(part), parent, children], "seeds": [0], "max_len": 100})

    for t, (parent, children) in enumerate(trees):
        n = len(parent)
        inner = [b for b in range(n) if children[b]]
        leaves = [b for b in range(n) if not children[b]]
        add("self", 0, rng.integers(n), t)
        add("parent", -1, rng.integers(1, n), t)
        add("parent", -1, rng.integers(1, n), t)
        add("root", -1, 0, t)
        b = inner[rng.integers(len(inner))]
        add("child", rng.integers(1, len(children[b]) + 1), b, t)
        wide = [b for b in inner if len(children[b]) >= 2] or inner
        b = wide[rng.integers(len(wide))]
        add("child", len(children[b]), b, t)
        add("missing", 1, leaves[rng.integers(len(leaves))], t)
        b = inner[rng.integers(len(inner))]
        add("missing", len(children[b]) + 1 + rng.integers(3), b, t)
        add("brain", -2, rng.integers(n), t)
    return cases


def _answer(ctx, cid):
    return json.loads(ctx.out(cid)[0])


def _where(ctx, cid):
    morph, part = ctx.arg(cid, 0), ctx.arg(cid, 1)
    return f"resolve(morph={morph}, part={part}, ...)"


def _describe(value):
    return "None" if value is None else repr(value)


def _ran(ctx):
    return [c for c in ctx.cases if (ctx.records.get(c) or {}).get("status") == "ok"]


def _resolve_valid(ctx):
    ran = _ran(ctx)
    if not ran:
        return False, "not checked: no test input ran"
    for cid in ran:
        got = _answer(ctx, cid)
        if not (got is None or got == "brain" or type(got) is int):
            return False, (f"{_where(ctx, cid)} returned {got!r}; expected a part index (an int), the string 'brain', "
                           "or None")
    return True, "every answer is a part index, 'brain' or None"


def _resolve_group(prefixes, title, meaning):
    def prop(ctx):
        cids = [c for c in ctx.cases if c.startswith(prefixes)]
        for cid in cids:
            parent, children = ctx.arg(cid, 2), ctx.arg(cid, 3)
            morph, part = ctx.arg(cid, 0), ctx.arg(cid, 1)
            want = expected_target(morph, part, parent, children)
            got = _answer(ctx, cid)
            if got != want:
                return False, (f"{_where(ctx, cid)} on a tree where part {part} has parent {parent[part]} and children "
                               f"{children[part]} returned {_describe(got)}; {meaning(morph)}")
        return True, f"{title} on {len(cids)} test inputs"

    return prop


_PARENT = _resolve_group(("parent",), "-1 names the parent", lambda m: "-1 names the parent part's network")
_CHILD = _resolve_group(("child",), "m >= 1 names child m",
                        lambda m: f"{m} names child number {m} of this part (1 is the first child in the list)")


def _resolve_job(ctx):
    """The gate: the answers follow the tree at all (the parent or the children are named); a constant answer
    (None, the part itself) names neither."""
    results = []
    for rule in (_PARENT, _CHILD):
        try:
            results.append(rule(ctx))
        except NotRun:
            results.append((False, ""))
    if any(ok for ok, _ in results):
        return True, "relative ids name relatives in the tree"
    return False, (f"{results[0][1] or results[1][1] or 'the parent and child ids did not run'}. Neither -1 (the parent) "
                   "nor m >= 1 (the children) names the right part. Nothing else is judged until one of them does")


register(Check(
    name="brains.resolve", function="resolve", params=("morph", "part", "parent", "children"), points=3.0,
    title="resolving relative ids", output="json", cases=_resolve_cases, gates=2,
    # the library resolves ids inside build_brain (a closure; red team: build_brain on a one-neuron creature as an
    # oracle, 3/3): kept for expansion, withheld in a second run that grades resolve; and the grader's own rule
    reference=("coursekit.grading.checks.ex06_wire_a_brain:expected_target", "coursekit.creatures.brain:build_brain"),
    library_uses=("coursekit.creatures.brain:build_brain",),
    props=(
        ("returns a part index, 'brain' or None", _resolve_valid),
        ("ids name relatives in the tree", _resolve_job),
        ("-1 names the parent", _PARENT),
        ("m >= 1 names child m", _CHILD),
        ("0 names the part's own network", _resolve_group(("self",), "0 names the part itself",
                                                          lambda m: "0 names the part's own network")),
        ("-2 names the brain", _resolve_group(("brain",), "-2 names 'brain'", lambda m: "-2 names the brain, 'brain'")),
        ("the root's parent reads nothing", _resolve_group(("root",), "the root's parent is None",
                                                            lambda m: "the root has no parent: the id reads nothing (None)")),
        ("a missing child reads nothing", _resolve_group(("missing",), "children a part lacks are None",
                                                          lambda m: f"this part has no child number {m}: the id reads nothing (None)")),
    ),
    # one wrong rule of the table costs its share, not the whole check; parent and children are the
    # core of relative ids and count double (honest-student study s25: a root answering -1, an
    # off-by-one child or an IndexError on a missing child scored 0/3)
    weights=(("-1 names the parent", 2), ("m >= 1 names child m", 2)),
))


# ============================================================================ wire the snake


def unwired_snake(segments):
    """The Figure 1 snake's body with every network removed: what ``wire_snake`` receives."""
    return _creature_cls().figure1_snake(segments=segments).unwired()


def _wire_cases(rng):
    return [{"id": f"segments{n}", "args": [{"object": CREATURE, "json": unwired_snake(n).to_json()}], "seeds": [0],
             "max_len": 200_000, "check_inputs": n == SEGMENTS[0]} for n in SEGMENTS]


WIRE_CASES = [f"segments{n}" for n in SEGMENTS]


def _body_only(d):
    return [{k: v for k, v in node.items() if k not in ("neurons", "effectors")} for node in d["nodes"]]


def _parse(text):
    return _creature_cls().from_json(text)


def _wire_valid(ctx):
    for cid in WIRE_CASES:
        try:
            _parse(ctx.out(cid)[0])
        except (ValueError, TypeError) as exc:
            return False, f"for the snake of {cid[len('segments'):]} segments it returned an invalid creature: {exc}"
    return True, "every result is a valid Creature"


def _wire_body(ctx):
    for cid in WIRE_CASES:
        got = json.loads(ctx.out(cid)[0])
        want = json.loads(ctx.case(cid)["args"][0]["json"])
        if len(got["nodes"]) != len(want["nodes"]):
            return False, (f"the snake of {cid[len('segments'):]} segments came back with {len(got['nodes'])} nodes instead "
                           f"of {len(want['nodes'])}; wire its networks, keep its body")
        if _body_only(got) != _body_only(want):
            return False, (f"the body of the snake of {cid[len('segments'):]} segments was changed (sizes, joints or "
                           "links); only add neurons, effectors and brain neurons")
    return True, "the body is the one given"


class _Recorder:
    """The creatures' own brains as the simulator's controller, keeping each physics step's effector outputs."""

    def __init__(self, brains):
        from coursekit.creatures.brain import BrainBatch

        self.batch, self.outputs, self._ticks = BrainBatch(brains), [], 0

    def reset(self):
        self.batch.reset()
        self.outputs, self._ticks = [], 0

    def step(self, joint_angle, joint_velocity, contact, dt):
        e = self.batch.step(joint_angle, joint_velocity, contact, dt)
        self._ticks += 1
        if self._ticks % 2 == 0:  # the second of the two ticks per physics step drives the joints
            self.outputs.append(np.array(e, dtype=np.float64))
        return e


@functools.lru_cache(maxsize=8)
def swim(texts):
    """Simulate the creatures (JSON texts) for :data:`SECONDS`; per creature a dict of measurements.

    ``spine``/``legs``: the joint angles over time; ``drive``: what the wiring sends each spine
    joint's muscle, ``clip(gain * e, -1, 1)`` of its effector output ``e`` (the simulator's own
    brains, recorded as they run)."""
    from coursekit.creatures.audit import body_length
    from coursekit.creatures.simulate import simulate

    creatures = [_parse(t) for t in texts]
    phenotypes = [c.expand() for c in creatures]
    recorder = _Recorder([p.brain for p in phenotypes])
    result = simulate(creatures, SECONDS, record_every=1, controller=recorder)
    effectors = np.asarray(recorder.outputs)
    first = np.concatenate([[0], np.cumsum([p.body.n_bodies - 1 for p in phenotypes])])
    out = []
    for i, (p, speed, traj) in enumerate(zip(phenotypes, result.fitness, result.trajectory)):
        body = p.body
        q = np.asarray(traj)[:, 7:]
        node = np.asarray(body.node_id)[1:]
        drive = np.clip(np.asarray(body.gain)[1:] * effectors[:, first[i]:first[i + 1]], -1.0, 1.0)
        out.append({"speed": float(speed), "bl": float(speed) / body_length(body),
                    "spine": q[:, node == 0], "legs": q[:, node == 1], "drive": drive[:, node == 0],
                    "dt": float(result.dt)})
    return out


def _swims(ctx):
    return swim(tuple(ctx.out(cid)[0] for cid in WIRE_CASES))


def _swim_text(m):
    return f"{m['speed']:.3f} m/s = {m['bl']:.3f} body lengths/s"


def _wave_fault(drive):
    """Why the spine's drive (steps x joints) is no travelling wave, or None when it is one.

    A wave: every joint's muscle beats with the first one's rhythm, and each lags its neighbour
    by the same phase step (within :data:`WAVE_SPREAD`, modulo 2 pi), a step of at least
    :data:`WAVE_LAG` rad either way and not a half turn (neighbours in exact opposition are a
    standing wave; a step of 3.1 rad is still a wave)."""
    lags, amplitude = phase_lags(drive)
    if amplitude.size < 2 or not np.all(amplitude >= 0.1 * max(amplitude.max(), 1e-9)):
        return "some spine joints get no oscillating signal", lags
    step = float(np.angle(np.mean(np.exp(1j * lags))))
    spread = np.abs(np.angle(np.exp(1j * (lags - step))))
    if np.any(spread > WAVE_SPREAD):
        return "the phase differences of neighbours are not one steady step", lags
    if abs(step) < WAVE_LAG:
        return "neighbours beat in step", lags
    if abs(step) > np.pi - STANDING_GAP:
        return "neighbours beat in exact opposition, a standing wave", lags
    return None, lags


def _rounded(lags):
    return np.round(lags, 2).tolist()


def _wire_swims(ctx):
    m = _swims(ctx)[0]
    if m["bl"] < SWIM_MIN:
        fault, lags = _wave_fault(m["drive"])
        if fault is None:
            why = (f"Its spine's muscles beat as a travelling wave (phase steps {_rounded(lags)} rad), but too slowly or "
                   "in an unlucky rhythm for this body: try another phase step or frequency (-1.5 rad at 3 Hz swims).")
        elif fault.startswith("some"):
            why = "Does every segment's joint get a signal that oscillates?"
        else:
            why = (f"Its joints move, but no wave travels along the body: {fault} (phase differences {_rounded(lags)} "
                   "rad), and a body that bends in place gets nowhere. Let each segment's oscillator lag its parent's by a "
                   "phase step.")
        return False, (f"the snake of {SEGMENTS[0]} segments swims {_swim_text(m)} in {SECONDS:g} s; it must reach "
                       f"{SWIM_MIN} body lengths/s. {why} Nothing else is judged until it swims")
    return True, f"the snake of {SEGMENTS[0]} segments swims {_swim_text(m)}"


def phase_lags(signals):
    """Phase of each column's oscillation relative to the previous column's (rad, in (-pi, pi]) and the amplitudes.

    Both at the first column's main frequency (a Hann-windowed, zero-padded spectrum), by a least-squares fit of
    a sinusoid to each column over all but the first :data:`SETTLE_OUT` s (the phase chain's start-up)."""
    x = np.asarray(signals, dtype=np.float64)
    x = x[int(len(x) * SETTLE_OUT / SECONDS):]
    if x.ndim != 2 or x.shape[1] == 0 or len(x) < 8:
        return np.zeros(0), np.zeros(0)
    x = x - x.mean(axis=0)
    pad = 16 * len(x)
    spectrum = np.abs(np.fft.rfft(x[:, 0] * np.hanning(len(x)), n=pad))
    k = int(np.argmax(spectrum[1:])) + 1  # cycles per pad samples
    t = np.arange(len(x)) * 2 * np.pi * k / pad
    basis = np.stack([np.ones_like(t), np.cos(t), np.sin(t)], axis=1)
    coef = np.linalg.lstsq(basis, x, rcond=None)[0]
    a = coef[1] - 1j * coef[2]  # x = Re(a exp(i t))
    lags = np.angle(a[1:] * np.conj(a[:-1]))
    return lags, np.abs(a)


def _wire_wave(ctx):
    m = _swims(ctx)[0]
    fault, lags = _wave_fault(m["drive"])
    if fault is not None:
        return False, (f"the muscles of neighbouring spine joints beat with phase differences {_rounded(lags)} rad: "
                       f"{fault}, so no wave travels along the body (each should lag the previous one by the same step, "
                       f"at least {WAVE_LAG} rad either way). Let each segment's oscillator read a phase from its parent's "
                       "network")
    return True, f"a wave travels along the spine (phase steps {_rounded(lags)} rad)"


def _wire_any_length(ctx):
    for n, m in zip(SEGMENTS, _swims(ctx)):
        if m["bl"] < SWIM_MIN:
            return False, (f"the snake of {n} segments swims only {_swim_text(m)}; the same wiring should swim at any "
                           "length. Use relative ids (parent, self, brain) rather than wiring particular parts")
    return True, f"swims at {', '.join(str(n) for n in sorted(SEGMENTS))} segments"


def _wire_legs(ctx):
    m = _swims(ctx)[0]
    swing = np.ptp(m["legs"], axis=0) if m["legs"].size else np.zeros(0)
    if swing.size == 0 or np.any(swing < LEG_SWING):
        return False, (f"the legs swing through {np.round(swing, 2).tolist()} rad; each should swing at least {LEG_SWING} "
                       "rad. Give the leg node an effector (the brain's oscillator is a good source)")
    return True, f"the legs swing ({np.round(swing, 2).tolist()} rad)"


def _wire_unmodified(ctx):
    cid = WIRE_CASES[0]
    after = ctx.record(cid).get("inputs_after") or []
    if not after or not isinstance(after[0], dict) or \
            json.loads(after[0]["json"]) != json.loads(ctx.case(cid)["args"][0]["json"]):
        return False, "the snake you were given was modified; wire a copy (snake.copy())"
    return True, "input left unchanged"


register(Check(
    name="brains.wire_snake", function="wire_snake", params=("snake",), points=5.0,
    title="wiring the snake's brain", output="json", cases=_wire_cases, gates=3,
    reference=("coursekit.creatures.genotype:Creature.figure1_snake",),
    props=(
        ("returns a valid creature", _wire_valid),
        ("keeps the body", _wire_body),
        ("the snake swims", _wire_swims),
        ("a wave travels along the spine", _wire_wave),
        ("swims at every length", _wire_any_length),
        ("the legs swing", _wire_legs),
        ("input unchanged", _wire_unmodified),
    ),
))

exercise("06_wire_a_brain", ["brains.resolve", "brains.wire_snake"])
