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

import itertools
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
    y = (state.pos, xp.zeros_like(state.omega), state.q)
    yd = (state.lin, state.omega, state.qd)
    # the chart coordinates and their rates, each packed into one flat vector (the integrators'
    # linear combinations are then one array operation per term)
    shapes = [tuple(a.shape) for a in y]
    cut = list(itertools.accumulate((math.prod(s) for s in shapes), initial=0))
    pack = lambda parts: xp.concat([xp.reshape(a, (-1,)) for a in parts])  # noqa: E731
    unpack = lambda flat: tuple(xp.reshape(flat[cut[i] : cut[i + 1]], shapes[i]) for i in range(3))  # noqa: E731

    # what depends on the positions alone, for the last y seen: stages that share positions (RKN
    # 2 and 3) share the unpacked arrays (the same q lets the world reuse its inertias), the root
    # rotation and the chart's matrices (spatial.chart_maps)
    last = [None, None, None, None]
    R0 = sp.quat_to_mat(xp, quat0)

    def f(y_flat, yd_flat, start=False):
        if start:  # theta = 0: the chart is the identity map there (and the state's own arrays)
            return pack(accel(state.pos, R0, state.q, state.lin, state.omega, state.qd))
        if y_flat is not last[0]:
            y = unpack(y_flat)
            maps = sp.chart_maps(xp, y[1])
            last[:] = y_flat, y, xp.matmul(R0, maps[0]), maps  # R = R0 exp(theta)
        (pos, theta, q), R, maps = last[1:]
        lin, theta_d, qd = unpack(yd_flat)
        omega, curvature = sp.chart_rates_at(xp, theta, theta_d, maps)
        la, wd, qdd = accel(pos, R, q, lin, omega, qd)
        return pack((la, sp.mv(maps[2], wd - curvature), qdd))  # dexp_inv

    if callable(method):
        y_new, yd_new = _plugged_step(method, f, t, pack(y), pack(yd), h)
    else:
        y_new, yd_new = (_nystrom if method == "rkn" else _rk4)(f, pack(y), pack(yd), h)
    (pos, theta, q), (lin_v, theta_d, qd) = unpack(y_new), unpack(yd_new)
    quat = sp.quat_canonical(xp, sp.quat_mul(xp, quat0, sp.quat_exp(xp, theta)))
    return State(pos, quat, q, lin_v, sp.dexp(xp, theta, theta_d), qd)


def _nystrom(f, y, yd, h):
    a1 = f(y, yd, start=True)
    y2 = y + (h / 2) * yd + (h * h / 8) * a1
    a2 = f(y2, yd + (h / 2) * a1)
    a3 = f(y2, yd + (h / 2) * a2)
    a4 = f(y + h * yd + (h * h / 2) * a3, yd + h * a3)
    y_new = y + h * yd + (h * h / 6) * (a1 + a2 + a3)
    return y_new, yd + (h / 6) * (a1 + a4) + (h / 3) * (a2 + a3)


def _rk4(f, y, yd, h):
    a1 = f(y, yd, start=True)
    yd2 = yd + (h / 2) * a1
    a2 = f(y + (h / 2) * yd, yd2)
    yd3 = yd + (h / 2) * a2
    a3 = f(y + (h / 2) * yd2, yd3)
    yd4 = yd + h * a3
    a4 = f(y + h * yd3, yd4)
    y_new = y + (h / 6) * (yd + yd4) + (h / 3) * (yd2 + yd3)
    return y_new, yd + (h / 6) * (a1 + a4) + (h / 3) * (a2 + a3)


def _plugged_step(rkn_step, f, t, y, yd, h):
    """Apply a user's ``rkn_step(f, t, y, v, h)`` to the packed chart coordinates."""
    n = y.shape[0]

    def g(_t, y_flat, v_flat):
        for name, a in (("y", y_flat), ("v", v_flat)):
            if tuple(getattr(a, "shape", ())) != (n,):
                raise ValueError(f"integrator: {_name(rkn_step)} called f with {name} of shape "
                                 f"{tuple(getattr(a, 'shape', ()))}; expected ({n},), like the y and v it was given")
        return f(y_flat, v_flat)

    out = rkn_step(g, float(t), y, yd, float(h))
    if not (isinstance(out, (tuple, list)) and len(out) == 2):
        raise ValueError(f"integrator: {_name(rkn_step)} returned {type(out).__name__}; expected a pair (y_next, v_next)")
    for name, a in zip(("y_next", "v_next"), out):
        if tuple(getattr(a, "shape", ())) != (n,):
            raise ValueError(f"integrator: {_name(rkn_step)} returned {name} of shape {tuple(getattr(a, 'shape', ()))}; expected ({n},)")
    return out[0], out[1]


def _name(fn):
    return getattr(fn, "__name__", "rkn_step")
