"""Exercise 07 checks (box drag, RKN step) and the simulator's plug-in points, without kernels.

Two independent correct implementations of each function pass every property; one known-wrong
implementation per property fails exactly that property. The grader's own references are
cross-checked against physics: the face quadrature against the library's closed form, the exact
ODE solutions against their differential equations, and student functions plugged into
``World`` against the library's own simulation.
"""


import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from coursekit.creatures.physics import World, odes, random_body_tree, random_state
from coursekit.creatures.physics.water import drag_diagonal
from coursekit.grading import evaluate
from coursekit.grading.checks import for_notebook
from coursekit.grading.checks.ex07_swimming_physics import face_integral_drag
from solution_cells import solution_functions



SOL = solution_functions("07_swimming_physics.ipynb", {"np": np})


# -- independent second implementations ---------------------------------------------------------


def box_drag_loops(half_extents, k):
    """Face pair by face pair: each pair resists sliding along its normal with 2 k A and turning
    about the two in-plane axes with 2 k A (third half extent)^2 / 3."""
    h = [float(x) for x in half_extents]
    d = [0.0] * 6
    for i in range(3):
        j, l = [a for a in range(3) if a != i]
        area = 4 * h[j] * h[l]
        d[3 + i] += 2 * k * area
        d[j] += 2 * k * area * h[l] ** 2 / 3  # turning about j sweeps the face along l
        d[l] += 2 * k * area * h[j] ** 2 / 3
    return np.array(d)


# Nystrom's tableau: stage times c, stage-position matrix A (times h^2), weights bbar (y) and b (v).
C = np.array([0.0, 0.5, 0.5, 1.0])
A = np.array([[0, 0, 0, 0], [1 / 8, 0, 0, 0], [1 / 8, 0, 0, 0], [0, 0, 1 / 2, 0]])
AV = np.array([[0, 0, 0, 0], [1 / 2, 0, 0, 0], [0, 1 / 2, 0, 0], [0, 0, 1, 0]])
BBAR = np.array([1 / 6, 1 / 6, 1 / 6, 0])
B = np.array([1 / 6, 1 / 3, 1 / 3, 1 / 6])


def rkn_tableau(f, t, y, v, h):
    a = []
    for s in range(4):
        ys = y + C[s] * h * v + h * h * sum(A[s, r] * a[r] for r in range(s))
        vs = v + h * sum(AV[s, r] * a[r] for r in range(s))
        a.append(np.asarray(f(t + C[s] * h, ys, vs), dtype=float))
    return y + h * v + h * h * sum(BBAR[s] * a[s] for s in range(4)), v + h * sum(B[s] * a[s] for s in range(4))


def rk4_first_order(f, t, y, v, h):
    """Classic RK4 on the first-order system (y, v)' = (v, f): a different method of the same order."""
    k1y, k1v = v, f(t, y, v)
    k2y, k2v = v + h / 2 * k1v, f(t + h / 2, y + h / 2 * k1y, v + h / 2 * k1v)
    k3y, k3v = v + h / 2 * k2v, f(t + h / 2, y + h / 2 * k2y, v + h / 2 * k2v)
    k4y, k4v = v + h * k3v, f(t + h, y + h * k3y, v + h * k3v)
    return y + h / 6 * (k1y + 2 * k2y + 2 * k3y + k4y), v + h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)


@pytest.mark.parametrize("name, others", [("physics.box_drag", [box_drag_loops]), ("physics.rkn_step", [rkn_tableau])])
@pytest.mark.parametrize("seed", [0, 1])
def test_correct_implementations_get_full_marks(name, others, seed):
    for fn in [SOL[name.split(".")[1]], *others]:
        j = evaluate(name, fn, seed=seed)
        assert j.passed and j.score == j.check.points, [v for v in j.verdicts if not v.passed]


def test_exercise_registers_both_checks():
    assert [c.name for c in for_notebook("07_swimming_physics")] == ["physics.box_drag", "physics.rkn_step"]
    assert sum(c.points for c in for_notebook("07_swimming_physics")) == 10.0


# -- known-wrong implementations fail exactly the property they violate --------------------------

box_drag = SOL["box_drag"]


def drag_three_values(h, k):
    return box_drag(h, k)[3:]


def drag_one_face_sliding(h, k):  # counts only one face of each pair for sliding
    d = box_drag(h, k)
    d[3:] /= 2
    return d


def drag_face_centres(h, k):  # face-centre velocities only: no turning resistance at all
    d = box_drag(h, k)
    d[:3] = 0.0
    return d


def drag_constant(h, k):  # red team, round 6: no physics, but non-zero, positive and proportional to k (2.18 / 4)
    return k * np.ones(6)


def drag_ignores_k(h, k):
    return box_drag(h, 1.0)


def drag_force_sign(h, k):  # returns the force coefficients -D
    return -box_drag(h, k)


def drag_in_place(h, k):
    h *= 2.0  # "full extents", then undone in the formula
    return box_drag(h / 2, k)


rkn_step = SOL["rkn_step"]


def rkn_flat(f, t, y, v, h):
    return np.concatenate(rkn_step(f, t, y, v, h)), np.zeros(0)


def rkn_no_time_offsets(f, t, y, v, h):
    return rkn_step(lambda _t, yy, vv: f(t, yy, vv), t, y, v, h)


def rkn_stage_position_without_a1(f, t, y, v, h):
    a1 = f(t, y, v)
    y2 = y + h / 2 * v
    a2 = f(t + h / 2, y2, v + h / 2 * a1)
    a3 = f(t + h / 2, y2, v + h / 2 * a2)
    a4 = f(t + h, y + h * v + h * h / 2 * a3, v + h * a3)
    return y + h * v + h * h / 6 * (a1 + a2 + a3), v + h / 6 * (a1 + 2 * a2 + 2 * a3 + a4)


def rkn_stage3_uses_a1(f, t, y, v, h):
    a1 = f(t, y, v)
    y2 = y + h / 2 * v + h * h / 8 * a1
    a2 = f(t + h / 2, y2, v + h / 2 * a1)
    a3 = f(t + h / 2, y2, v + h / 2 * a1)
    a4 = f(t + h, y + h * v + h * h / 2 * a3, v + h * a3)
    return y + h * v + h * h / 6 * (a1 + a2 + a3), v + h / 6 * (a1 + 2 * a2 + 2 * a3 + a4)


def rkn_five_calls(f, t, y, v, h):
    y1, v1 = rkn_step(f, t, y, v, h)
    f(t + h, y1, v1)  # an extra evaluation "for the next step", thrown away
    return y1, v1


def rkn_in_place(f, t, y, v, h):
    y1, v1 = rkn_step(f, t, y, v, h)
    y[:] = y1  # updates the caller's array
    return y.copy(), v1


WRONG = [
    ("physics.box_drag", drag_three_values, "returns the 6 diagonal entries"),
    ("physics.box_drag", drag_one_face_sliding, "sliding drag matches the face integral (k = 1)"),
    ("physics.box_drag", drag_face_centres, "turning drag matches the face integral (k = 1)"),
    ("physics.box_drag", drag_constant, "the water resists sliding, face first most"),
    ("physics.box_drag", drag_ignores_k, "proportional to k"),
    ("physics.box_drag", drag_in_place, "inputs unchanged"),
    ("physics.rkn_step", rkn_flat, "returns (y_next, v_next) shaped like y and v"),
    ("physics.rkn_step", rkn_no_time_offsets, "exact for forces that depend only on time"),
    ("physics.rkn_step", rkn_stage_position_without_a1, "fourth order for position-dependent forces"),
    ("physics.rkn_step", rkn_stage3_uses_a1, "fourth order for velocity-dependent forces"),
    ("physics.rkn_step", rkn_five_calls, "evaluates f 4 times per step"),
    ("physics.rkn_step", rkn_in_place, "inputs unchanged"),
]


#: Steps that evaluate f away from Nystrom's stages fail that property too.
OFF_STAGE = {rkn_no_time_offsets, rkn_stage_position_without_a1, rkn_stage3_uses_a1}


@pytest.mark.parametrize("name, fn, prop", WRONG, ids=[w[1].__name__ for w in WRONG])
def test_known_wrong_fails_exactly_its_property(name, fn, prop):
    j = evaluate(name, fn, seed=3)
    failed = [v.prop for v in j.verdicts if not v.passed]
    if prop in [p for p, _ in j.check.props[:j.check.gates]]:  # a gate (validity, the job) fails everything after it
        assert failed[0] == prop and j.score == 0.0, failed
    else:
        also = ["evaluates f at Nystrom's stages", "combines the stages with Nystrom's weights"] if fn in OFF_STAGE else []
        assert failed == [prop] + also, [(v.prop, v.message) for v in j.verdicts if not v.passed]
    msg = next(v.message for v in j.verdicts if v.prop == prop)
    assert "BEGIN SOLUTION" not in msg and "2 * k" not in msg and "h**2/6" not in msg


def test_the_force_coefficients_minus_d_fail_the_values_and_the_sign():
    """-D is the wrench's factor, not the drag matrix: the values are compared signed (s25: by
    magnitude, -D kept 91 %), and they are the function's definition, half of its weight."""
    j = evaluate("physics.box_drag", drag_force_sign, seed=3)
    assert [v.prop for v in j.verdicts if not v.passed] == ["sliding drag matches the face integral (k = 1)",
                                                             "turning drag matches the face integral (k = 1)",
                                                             "never adds energy"]
    assert j.score <= 0.5 * j.check.points, j.score
    assert "opposite sign" in next(v.message for v in j.verdicts if not v.passed)


@pytest.mark.parametrize("fn", [rkn_stage_position_without_a1, rkn_stage3_uses_a1])
def test_a_wrong_tableau_entry_keeps_less_than_half(fn):
    """A wrong coefficient gives a method of lower order that is not Nystrom's: less than half the
    points (s25: a typo h^2/2 for h^2/8, or a3 copy-pasted from a2, kept 54 %)."""
    j = evaluate("physics.rkn_step", fn, seed=3)
    assert j.score < 0.5 * j.check.points, j.score


@pytest.mark.parametrize("seed", [0, 3])
def test_classic_rk4_is_fourth_order_but_not_nystroms_method(seed):
    """RK4 on (y, v) passes every accuracy property (the same order) and fails only Nystrom's own:
    its stages and their weights."""
    j = evaluate("physics.rkn_step", rk4_first_order, seed=seed)
    assert [v.prop for v in j.verdicts if not v.passed] == ["evaluates f at Nystrom's stages",
                                                             "combines the stages with Nystrom's weights"]
    msg = next(v.message for v in j.verdicts if not v.passed)
    assert "evaluation 2" in msg and "h^2/8 a1" in msg
    assert j.score <= 0.5 * j.check.points, j.score  # Nystrom's stages and weights are half the check (s25: 61 %)


def rkn_faked_order(f, t, y, v, h):
    """Red team, round 5: an accurate integrator of another kind (SciPy's DOP853) plus a made-up
    error of order h^5 where the force is not a function of time alone, evaluating a counting
    force only at Nystrom's stages (4.36/6 before the weights were judged)."""
    from scipy.integrate import solve_ivp

    from coursekit.creatures.physics import odes

    y, v = np.asarray(y, dtype=float), np.asarray(v, dtype=float)
    rhs = odes.ODES[f.ode] if isinstance(f, odes.CountingODE) else f
    n = len(y)
    sol = solve_ivp(lambda s, z: np.r_[z[n:], rhs(s, z[:n], z[n:])], (t, t + h), np.r_[y, v], method="DOP853",
                    rtol=1e-13, atol=1e-13)
    end = sol.y[:, -1]
    fake = 0.0 if np.allclose(rhs(t, y, v), rhs(t, y + 1, v + 1)) else 1e-2 * h**5
    a1 = f(t, y, v)  # where Nystrom's step evaluates, as the stage message tells
    a2 = f(t + h / 2, y + h / 2 * v + h * h / 8 * a1, v + h / 2 * a1)
    a3 = f(t + h / 2, y + h / 2 * v + h * h / 8 * a1, v + h / 2 * a2)
    f(t + h, y + h * v + h * h / 2 * a3, v + h * a3)
    return end[:n] + fake, end[n:] + fake


def test_an_integrator_with_a_made_up_error_of_fourth_order_is_not_nystroms_step():
    j = evaluate("physics.rkn_step", rkn_faked_order, seed=7)
    failed = [v.prop for v in j.verdicts if not v.passed]
    assert failed == ["combines the stages with Nystrom's weights"], failed  # the ratios and stages are right, by design
    assert j.score <= 0.85 * j.check.points, j.score


def test_messages_are_specific():
    msg = {v.prop: v.message for v in evaluate("physics.rkn_step", rkn_stage_position_without_a1).verdicts}
    assert "shrink" in msg["fourth order for position-dependent forces"] and "32" in msg["fourth order for position-dependent forces"]
    msg = {v.prop: v.message for v in evaluate("physics.box_drag", drag_face_centres).verdicts}
    assert "spinning about" in msg["turning drag matches the face integral (k = 1)"]
    msg = {v.prop: v.message for v in evaluate("physics.rkn_step", rkn_five_calls).verdicts}
    assert "5 times" in msg["evaluates f 4 times per step"]


# -- the grader's references are right ----------------------------------------------------------

half_extent = st.floats(0.01, 2.0)


@settings(max_examples=60, deadline=None)
@given(st.tuples(half_extent, half_extent, half_extent), st.floats(0.0, 50.0))
def test_face_quadrature_is_the_library_closed_form_and_diagonal(h, k):
    D = face_integral_drag(np.array(h), k)
    scale = max(1e-300, np.abs(D).max())
    assert np.abs(D - np.diag(np.diag(D))).max() <= 1e-13 * scale  # a centred box: no coupling
    np.testing.assert_allclose(np.diag(D), drag_diagonal(np.array([h]), k)[0], rtol=1e-12, atol=1e-14 * scale)


def test_face_quadrature_obeys_the_scaling_laws():
    h, s = np.array([0.3, 0.1, 0.05]), 1.7
    D, Ds = np.diag(face_integral_drag(h, 2.0)), np.diag(face_integral_drag(s * h, 2.0))
    np.testing.assert_allclose(Ds[3:], s**2 * D[3:], rtol=1e-12)  # force ~ area
    np.testing.assert_allclose(Ds[:3], s**4 * D[:3], rtol=1e-12)  # torque ~ area * lever arm^2
    np.testing.assert_allclose(np.diag(face_integral_drag(h, 5.0)), 2.5 * D, rtol=1e-12)


@pytest.mark.parametrize("name", list(odes.ODES))
def test_exact_solutions_solve_their_equations(name):
    rng = np.random.default_rng(5)
    n = 3 if name == "time_forcing" else 2
    t0, y0, v0 = 0.4, rng.normal(size=n), rng.normal(size=n)
    y, v = odes.solution(name, t0, y0, v0, 0.0)
    np.testing.assert_allclose(np.r_[y, v], np.r_[y0, v0], atol=1e-15)
    for h in (0.3, 1.2):
        e = 1e-4
        (yp, vp), (ym, vm), (y, v) = (odes.solution(name, t0, y0, v0, h + d) for d in (e, -e, 0.0))
        np.testing.assert_allclose((yp - ym) / (2 * e), v, atol=1e-7)  # y' = v
        np.testing.assert_allclose((vp - vm) / (2 * e), odes.ODES[name](t0 + h, y, v), atol=1e-7)  # v' = f
        # the flow property: two half steps = one step
        y2, v2 = odes.solution(name, t0 + h / 2, *odes.solution(name, t0, y0, v0, h / 2), h / 2)
        np.testing.assert_allclose(np.r_[y2, v2], np.r_[y, v], rtol=1e-12, atol=1e-13)


def test_rkn_agrees_with_rk4_to_fifth_order_and_exactly_without_position_forces():
    rng = np.random.default_rng(2)
    y0, v0 = rng.normal(size=2), rng.normal(size=2)
    diffs = []
    for h in (0.2, 0.1, 0.05):
        a, b = rkn_step(odes.damped, 0.3, y0, v0, h), rk4_first_order(odes.damped, 0.3, y0, v0, h)
        diffs.append(np.linalg.norm(np.r_[a[0] - b[0], a[1] - b[1]]))
    assert all(20 < r < 48 for r in np.divide(diffs[:-1], diffs[1:]))  # difference O(h^5)
    for ode in ("drag", "time_forcing"):  # f independent of y: the two methods coincide
        n = 3 if ode == "time_forcing" else 2
        y0, v0 = rng.normal(size=n), rng.normal(size=n)
        a, b = rkn_step(odes.ODES[ode], 0.1, y0, v0, 0.5), rk4_first_order(odes.ODES[ode], 0.1, y0, v0, 0.5)
        np.testing.assert_allclose(np.r_[a[0], a[1]], np.r_[b[0], b[1]], rtol=1e-14, atol=1e-15)


def test_global_error_of_rkn_is_fourth_order_on_the_damped_oscillator():
    y0, v0 = np.array([1.0, -0.5]), np.array([0.0, 2.0])
    errors = []
    for n in (20, 40, 80):
        h, y, v = 2.0 / n, y0, v0
        for i in range(n):
            y, v = rkn_step(odes.damped, i * h, y, v, h)
        ye, ve = odes.solution("damped", 0.0, y0, v0, 2.0)
        errors.append(np.linalg.norm(np.r_[y - ye, v - ve]))
    ratios = np.divide(errors[:-1], errors[1:])
    assert np.all((ratios > 13) & (ratios < 19)), ratios  # 2^4 = 16


def test_counting_ode_round_trip_and_refuses_foreign_text():
    f = odes.CountingODE("drag")
    f(0.0, np.zeros(2), np.ones(2))
    g = odes.CountingODE.from_json(f.to_json())
    assert (g.ode, g.calls) == ("drag", 1)
    for bad in ('{"format": "other/1", "ode": "drag", "calls": 0, "points": []}', '{"format": "coursekit.counting_ode/2"', "[]",
                '{"format": "coursekit.counting_ode/2", "ode": "nope", "calls": 0, "points": []}',
                '{"format": "coursekit.counting_ode/2", "ode": "drag", "calls": 0}'):
        with pytest.raises(ValueError, match="CountingODE|ode"):
            odes.CountingODE.from_json(bad)
    with pytest.raises(ValueError, match="y: expected shape"):
        odes.harmonic(0.0, np.zeros(3), np.zeros(2))


# -- plug-in points: the student's functions drive the simulator ----------------------------------


@pytest.fixture(scope="module")
def swimmers():
    rng = np.random.default_rng(11)
    trees = [random_body_tree(rng, (4, 8)) for _ in range(3)]
    return trees, [random_state(rng, t, speed=1.0, inside=0.3) for t in trees]


def run_world(swimmers, n=30, **options):
    trees, start = swimmers
    w = World(trees, **options)
    w.set_state([s[0] for s in start], [s[1] for s in start])
    for i in range(n):
        w.set_effectors(np.sin(0.2 * i + np.arange(w.model.n_joints)))
        w.step()
    return np.concatenate(w.get_state()[0] + w.get_state()[1]), w


@pytest.mark.parametrize("options", [dict(drag=box_drag_loops), dict(integrator=rkn_tableau),
                                     # a coarse step with sub-steps, joint limits off: at dt = 1/15 the joints overshoot their
                                     # limits within steps and are put back, and a put-back joint's path is not smooth in the
                                     # rounding of what led to it (1e-16 grew to 4e-7 in three steps), so the plug-ins are
                                     # compared where the dynamics is smooth
                                     dict(drag=box_drag_loops, integrator=rkn_tableau, dt=1 / 15, limits=False),
                                     dict(drag=box_drag_loops, integrator=rkn_step, backend="torch")])
def test_student_functions_reproduce_the_library_simulation(swimmers, options):
    lib, w_lib = run_world(swimmers, dt=options.get("dt", 1 / 60), limits=options.get("limits", True))
    mine, w = run_world(swimmers, **options)
    assert w.substeps == w_lib.substeps and (options.get("dt") is None or w.substeps > 1)
    np.testing.assert_allclose(mine, lib, rtol=0, atol=1e-11 * np.abs(lib).max())


def test_plugged_classic_rk4_reproduces_the_library_rk4(swimmers):
    lib_rk4, _ = run_world(swimmers, n=10, integrator="rk4")
    lib_rkn, _ = run_world(swimmers, n=10)
    mine, _ = run_world(swimmers, n=10, integrator=rk4_first_order)
    np.testing.assert_allclose(mine, lib_rk4, rtol=0, atol=1e-11 * np.abs(lib_rk4).max())
    assert np.abs(mine - lib_rkn).max() > 1e-9  # a different method: the plug-in is really used


def test_plug_in_points_refuse_bad_functions(swimmers):
    trees, _ = swimmers
    with pytest.raises(ValueError, match="drag: .*expected 6 finite numbers >= 0"):
        World(trees, drag=lambda h, k: -box_drag_loops(h, k))
    with pytest.raises(ValueError, match="drag: .*expected 6 finite numbers"):
        World(trees, drag=lambda h, k: box_drag_loops(h, k)[:3])
    with pytest.raises(TypeError, match="drag: must be True, False or a function"):
        World(trees, drag="yes")
    with pytest.raises(ValueError, match="integrator: got 'euler'"):
        World(trees, integrator="euler")
    w = World(trees, integrator=lambda f, t, y, v, h: (y, v[:-1]))
    with pytest.raises(ValueError, match="integrator: .*v_next of shape"):
        w.step()
    w = World(trees, integrator=lambda f, t, y, v, h: (f(t, y[:3], v), v))
    with pytest.raises(ValueError, match="integrator: .*called f with y of shape \\(3,\\)"):
        w.step()
