"""Joint-limit and contact springs never create energy or momentum (the exploit evolution found first).

A 3-box, 41 g creature with two narrow prismatic joints (tests/data/limit_exploit_creature.json,
bred by `coursekit demo swimmers` before the fix) "swam" 8.7 m/s -- with the water switched off
it still travelled 42 m in 5 s: limit dampers tuned to the parts' own inertias were explicitly
unstable for a joint whose effective inertia in the free-floating body was 6x smaller.
"""

from pathlib import Path

import mujoco  # in the [test] extra: the cross-check must run, never skip
import numpy as np
from hypothesis import example, given, settings
from hypothesis import strategies as st

from coursekit.creatures import Creature, simulate, to_mjcf
from coursekit.creatures.physics.limits import effective_inertia
from coursekit.creatures.physics.model import Model
from coursekit.creatures.physics.world import World

EXPLOIT = Creature.from_json((Path(__file__).parent / "data" / "limit_exploit_creature.json").read_text())


def test_effective_inertia_is_the_inverse_diagonal_of_mujocos_inverse_mass_matrix():
    rng = np.random.default_rng(4)
    creatures = [EXPLOIT] + [Creature.random(rng, max_parts=12) for _ in range(12)]
    model = Model([c.expand().body for c in creatures])
    ours = effective_inertia(model)
    for c, creature in enumerate(creatures):
        m = mujoco.MjModel.from_xml_string(to_mjcf(creature))
        d = mujoco.MjData(m)
        d.qpos[:7] = [0, 0, 0, 1, 0, 0, 0]
        mujoco.mj_forward(m, d)
        Minv = np.zeros((m.nv, m.nv))
        mujoco.mj_solveM(m, d, Minv, np.eye(m.nv))  # rows of M^-1 (symmetric)
        expect = 1.0 / np.diag(Minv)[6:]
        first = int(np.sum(model.joints_per_creature[:c]))
        rows = np.asarray(model.joint_order)[first:first + m.nv - 6]
        np.testing.assert_allclose(ours[rows], expect, rtol=1e-9)


def test_the_exploit_creature_goes_nowhere_without_water():
    r = simulate([EXPLOIT], 5.0, drag_coefficient=0.0, contacts=False)
    assert not r.diverged[0]
    assert np.linalg.norm(r.com[0, -1] - r.com[0, 0]) < 1e-3
    swim = simulate([EXPLOIT], 5.0)
    assert swim.fitness[0] < 0.05  # it was 8.7 m/s


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**32 - 1), st.booleans())
@example(11845, False)  # zeta = 1 dampers: one creature's energy grew 67x in 2 s
@example(11, True)  # contact forces held over the step / fused overlaps: +16 %
@example(1064, True)  # contacts anchored anew every step / loaded at detection: +0.5 %
@example(1041, False)  # a whip: a 0.1 kg tip of a 100 kg chain passes the 100 rad/s joint-speed cap
def test_passive_creatures_thrown_against_their_limits_and_themselves_never_gain_energy(seed, contacts):
    rng = np.random.default_rng(seed)
    creatures = [Creature.random(rng, max_parts=12) for _ in range(6)]
    world = World([c.expand().body for c in creatures], dt=1 / 60, drag=False, contacts=contacts)
    qpos, qvel = world.get_state()
    qvel = [np.r_[rng.normal(size=6) * 0.2, rng.normal(size=len(v) - 6) * 3.0] for v in qvel]  # fast: limits get hit
    world.set_state(qpos, qvel)
    e0 = world.kinetic_energy() + world.potential_energy()
    worst = np.zeros_like(e0)
    for _ in range(120):
        world.step()
        # a creature past a speed cap is flagged and frozen (it scores zero): its energy counts
        # up to the flag; the energy of a light part whipped by a heavy chain is no energy gain
        alive = ~world.diverged
        worst = np.where(alive, np.maximum(worst, world.kinetic_energy() + world.potential_energy()), worst)
    # RK4/RKN truncation may wobble the energy by ~1e-6 relative (more around contact onsets);
    # the unstable limit dampers grew it 250x, contact forces held over each step up to 16 %
    assert np.all(worst <= e0 * (1 + 1e-3) + 1e-12)
