"""Runge-Kutta-Nyström and classic RK4 steps of the floating-base system (paper section 2.4).

The system is second order, ``y'' = f(y, y')``, with ``y = (root position, root orientation,
joint coordinates)``. The orientation lives on SO(3); each step works in the chart
``R = R_n exp(theta)`` around the step's start (``theta = 0``, ``theta' = omega_n``), where the
equations are ordinary ODEs:

``omega = dexp(theta) theta'`` and ``theta'' = dexp(theta)^-1 (omega' - d/dt[dexp(theta)] theta')``

(``dexp`` is the right Jacobian of SO(3), in closed form). Both integrators are then applied to
``(y, y')`` unchanged, so both are genuinely fourth order also for tumbling roots, and the new
orientation is ``q_n * exp(theta_{n+1})`` (unit quaternion through the exponential map,
re-normalised and sign-canonicalised).

4-stage Nyström (Kreyszig)::

    a1 = f(y, y')
    a2 = f(y + h/2 y' + h^2/8 a1, y' + h/2 a1)
    a3 = f(y + h/2 y' + h^2/8 a1, y' + h/2 a2)
    a4 = f(y + h y' + h^2/2 a3,   y' + h a3)
    y  += h y' + h^2/6 (a1 + a2 + a3);   y' += h/6 (a1 + 2 a2 + 2 a3 + a4)

RK4 uses the same velocity update and the classic stage positions ``y + c h y'_stage``.

Plug-in point: ``method`` may also be a function ``rkn_step(f, t, y, v, h) -> (y_next, v_next)``
for ``y'' = f(t, y, y')`` on flat 1-D arrays (exercise 07 has students write one). The chart
coordinates ``(root position, theta, joint coordinates)`` and their rates are then packed into
one vector each and the function is applied to them unchanged, so a correct Nyström step gives
the library's own result to round-off.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from . import spatial as sp

INTEGRATORS = ("rkn", "rk4")


@dataclass
class State:
    """Internal state of a packed batch (backend arrays).

    ``pos`` (C, 3) root position, ``quat`` (C, 4) root orientation (w, x, y, z), ``q`` (M,)
    joint coordinates, ``lin`` (C, 3) root velocity (world), ``omega`` (C, 3) root angular
    velocity (root frame), ``qd`` (M,) joint rates; joints in the model's internal order.
    """

    pos: object
    quat: object
    q: object
    lin: object
    omega: object
    qd: object

    def copy(self) -> "State":
        c = lambda a: a.clone() if hasattr(a, "clone") else a.copy()  # noqa: E731
        return State(*(c(a) for a in (self.pos, self.quat, self.q, self.lin, self.omega, self.qd)))


def step(xp, state: State, h: float, accel, method="rkn", t: float = 0.0) -> State:
    """Advance ``state`` by ``h``.

    Args:
        xp: array namespace.
        state: current :class:`State`.
        h: step (s).
        accel: ``accel(pos, R, q, lin, omega, qd) -> (lin_acc, omega_dot, qdd)``, with ``R`` the
            (C, 3, 3) root rotation.
        method: "rkn" (4-stage Nyström), "rk4", or a function ``rkn_step(f, t, y, v, h)``.
        t: time at the start of the step (only passed on to a ``method`` function; the
            accelerations do not depend on it).

    Returns:
        The new :class:`State`.
    """
    if not callable(method) and method not in INTEGRATORS:
        raise ValueError(f"integrator: got {method!r}; allowed: {', '.join(INTEGRATORS)} or a function rkn_step(f, t, y, v, h)")
    quat0 = state.quat
    theta0 = xp.zeros_like(state.omega)

    def f(y, yd):
        pos, theta, q = y
        lin, theta_d, qd = yd
        if theta is theta0:  # the step's start, where the chart is the identity map
            return accel(pos, sp.quat_to_mat(xp, quat0), q, lin, theta_d, qd)
        R = sp.quat_to_mat(xp, sp.quat_mul(xp, quat0, sp.quat_exp(xp, theta)))
        omega, curvature, gamma = sp.chart_rates(xp, theta, theta_d)
        la, wd, qdd = accel(pos, R, q, lin, omega, qd)
        return (la, sp.dexp_inv(xp, theta, wd - curvature, gamma), qdd)

    y = (state.pos, theta0, state.q)
    yd = (state.lin, state.omega, state.qd)

    if callable(method):
        y_new, yd_new = _plugged_step(xp, method, f, t, y, yd, h)
    else:
        y_new, yd_new = _builtin_step(f, y, yd, h, method)
    pos, theta, q = y_new
    lin_v, theta_d, qd = yd_new
    quat = sp.quat_canonical(xp, sp.quat_mul(xp, quat0, sp.quat_exp(xp, theta)))
    return State(pos, quat, q, lin_v, sp.dexp(xp, theta, theta_d), qd)


def _builtin_step(f, y, yd, h, method):
    lin = lambda *terms: tuple(sum(c * t[i] for c, t in terms) for i in range(3))  # noqa: E731
    a1 = f(y, yd)
    if method == "rkn":
        y2 = lin((1, y), (h / 2, yd), (h * h / 8, a1))
        yd2 = lin((1, yd), (h / 2, a1))
        a2 = f(y2, yd2)
        yd3 = lin((1, yd), (h / 2, a2))
        a3 = f(y2, yd3)
        y4 = lin((1, y), (h, yd), (h * h / 2, a3))
        yd4 = lin((1, yd), (h, a3))
        a4 = f(y4, yd4)
        y_new = lin((1, y), (h, yd), (h * h / 6, a1), (h * h / 6, a2), (h * h / 6, a3))
    else:
        yd2 = lin((1, yd), (h / 2, a1))
        a2 = f(lin((1, y), (h / 2, yd)), yd2)
        yd3 = lin((1, yd), (h / 2, a2))
        a3 = f(lin((1, y), (h / 2, yd2)), yd3)
        yd4 = lin((1, yd), (h, a3))
        a4 = f(lin((1, y), (h, yd3)), yd4)
        y_new = lin((1, y), (h / 6, yd), (h / 3, yd2), (h / 3, yd3), (h / 6, yd4))
    yd_new = lin((1, yd), (h / 6, a1), (h / 3, a2), (h / 3, a3), (h / 6, a4))
    return y_new, yd_new


def _plugged_step(xp, rkn_step, f, t, y, yd, h):
    """Apply a user's ``rkn_step(f, t, y, v, h)`` to the chart coordinates packed into flat vectors."""
    shapes = [tuple(a.shape) for a in y]
    sizes = [math.prod(s) for s in shapes]
    cut = [0, sizes[0], sizes[0] + sizes[1], sum(sizes)]
    pack = lambda parts: xp.concat([xp.reshape(a, (-1,)) for a in parts])  # noqa: E731
    unpack = lambda flat: tuple(xp.reshape(flat[cut[i]:cut[i + 1]], shapes[i]) for i in range(3))  # noqa: E731

    def g(_t, y_flat, v_flat):
        for name, a in (("y", y_flat), ("v", v_flat)):
            if tuple(getattr(a, "shape", ())) != (cut[3],):
                raise ValueError(f"integrator: {_name(rkn_step)} called f with {name} of shape "
                                 f"{tuple(getattr(a, 'shape', ()))}; expected ({cut[3]},), like the y and v it was given")
        return pack(f(unpack(y_flat), unpack(v_flat)))

    out = rkn_step(g, float(t), pack(y), pack(yd), float(h))
    if not (isinstance(out, (tuple, list)) and len(out) == 2):
        raise ValueError(f"integrator: {_name(rkn_step)} returned {type(out).__name__}; expected a pair (y_next, v_next)")
    for name, a in zip(("y_next", "v_next"), out):
        if tuple(getattr(a, "shape", ())) != (cut[3],):
            raise ValueError(f"integrator: {_name(rkn_step)} returned {name} of shape {tuple(getattr(a, 'shape', ()))}; expected ({cut[3]},)")
    return unpack(out[0]), unpack(out[1])


def _name(fn):
    return getattr(fn, "__name__", "rkn_step")
