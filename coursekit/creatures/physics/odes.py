"""Second-order test ODEs ``y'' = f(t, y, y')`` with exact solutions (paper section 2.4, integration).

The swimmers' equations of motion are integrated with a Runge-Kutta-Nystrom step (see
:mod:`~coursekit.creatures.physics.integrate`). To check such a step on its own -- in exercise
07 and its grader, which can only hand library functions to a student's code -- here are small
ODEs whose solutions are known in closed form, each probing one way the right-hand side can
depend on its arguments:

- :func:`time_forcing`: ``y'' = P(t)`` with quadratic polynomials ``P`` (so ``y`` is a quartic in
  ``t``, which a fourth-order step integrates exactly);
- :func:`harmonic`: ``y'' = -omega^2 y`` (position only);
- :func:`drag`: ``y'' = -c y'`` (velocity only: Sims' linear water drag on a single body);
- :func:`damped`: ``y'' = -omega^2 y - 2 zeta omega y'`` (both).

:class:`CountingODE` wraps one of them, counts its calls and notes their arguments; its JSON form
carries both, so the grader can see how many times a step evaluated ``f``, and where.
"""

from __future__ import annotations

import json

import numpy as np

#: Row ``i``: coefficients ``(c0, c1, c2)`` of component ``i`` of ``time_forcing``'s ``P(t)``.
FORCING = np.array([[1.0, -2.0, 0.0], [0.0, 0.0, 3.0], [0.5, 1.5, -1.0]])
#: Angular frequencies of the two components of :func:`harmonic` (rad/s).
OMEGA = np.array([1.0, 2.5])
#: Drag rates of the two components of :func:`drag` (1/s).
DRAG = np.array([0.7, 3.0])
#: Frequency (rad/s) and damping ratio of :func:`damped`.
DAMPED_OMEGA, DAMPED_ZETA = 2.0, 0.15


def _vector(name, value, n=None):
    a = np.asarray(value, dtype=np.float64)
    if a.ndim != 1 or (n is not None and a.shape != (n,)):
        want = f"({n},)" if n is not None else "a 1-D array"
        raise ValueError(f"{name}: expected shape {want}, got shape {a.shape}")
    return a


def time_forcing(t, y, v):
    """``y'' = P(t)`` componentwise, ``P_i(t) = FORCING[i] . (1, t, t^2)``; ``y``, ``v`` of shape (3,)."""
    _vector("y", y, 3), _vector("v", v, 3)
    t = float(t)
    return FORCING @ np.array([1.0, t, t * t])


def harmonic(t, y, v):
    """``y'' = -OMEGA^2 y`` (two independent oscillators); ``y``, ``v`` of shape (2,)."""
    _vector("v", v, 2)
    return -(OMEGA**2) * _vector("y", y, 2)


def drag(t, y, v):
    """``y'' = -DRAG * y'`` (a body coasting through viscous water); ``y``, ``v`` of shape (2,)."""
    _vector("y", y, 2)
    return -DRAG * _vector("v", v, 2)


def damped(t, y, v):
    """``y'' = -omega^2 y - 2 zeta omega y'`` (an under-damped oscillator); any 1-D shape."""
    y = _vector("y", y)
    v = _vector("v", v, y.size)
    return -(DAMPED_OMEGA**2) * y - 2 * DAMPED_ZETA * DAMPED_OMEGA * v


ODES = {"time_forcing": time_forcing, "harmonic": harmonic, "drag": drag, "damped": damped}


def solution(name: str, t0: float, y0, v0, h: float):
    """Exact ``(y, y')`` at ``t0 + h`` of ODE ``name`` started from ``(y0, v0)`` at ``t0``.

    Args:
        name: one of :data:`ODES`.
        t0: start time; y0, v0: start position and velocity (1-D arrays); h: elapsed time.
    Returns:
        (y, v) as float64 arrays.
    """
    y0, v0 = np.asarray(y0, dtype=np.float64), np.asarray(v0, dtype=np.float64)
    if name == "time_forcing":
        P = np.polynomial.Polynomial
        y, v = np.empty(3), np.empty(3)
        for i, c in enumerate(FORCING):
            Q = P(c).integ(2)  # Q'' = P_i; y = y0 + v0 s + Q(t) - Q(t0) - Q'(t0) s with s = t - t0
            y[i] = y0[i] + v0[i] * h + Q(t0 + h) - Q(t0) - Q.deriv()(t0) * h
            v[i] = v0[i] + Q.deriv()(t0 + h) - Q.deriv()(t0)
        return y, v
    if name == "harmonic":
        c, s = np.cos(OMEGA * h), np.sin(OMEGA * h)
        return y0 * c + v0 / OMEGA * s, -y0 * OMEGA * s + v0 * c
    if name == "drag":
        e = np.exp(-DRAG * h)
        return y0 + v0 * (1 - e) / DRAG, v0 * e
    if name == "damped":
        w, z = DAMPED_OMEGA, DAMPED_ZETA
        wd, sigma = w * np.sqrt(1 - z * z), z * w
        A, B = y0, (v0 + sigma * y0) / wd  # y = e^{-sigma t} (A cos wd t + B sin wd t)
        e, c, s = np.exp(-sigma * h), np.cos(wd * h), np.sin(wd * h)
        return e * (A * c + B * s), e * ((B * wd - sigma * A) * c - (A * wd + sigma * B) * s)
    raise ValueError(f"ode: got {name!r}; allowed: {', '.join(ODES)}")


class CountingODE:
    """The right-hand side of a named ODE (see :data:`ODES`) that counts its calls and notes where
    it was evaluated.

    Args:
        ode: the ODE's name.
        calls: the count to start from.
        points: ``[t, y, v]`` of the calls so far (``y`` and ``v`` as lists), in call order.
    """

    FORMAT = "coursekit.counting_ode/2"

    def __init__(self, ode: str = "harmonic", calls: int = 0, points: list | None = None):
        if ode not in ODES:
            raise ValueError(f"ode: got {ode!r}; allowed: {', '.join(ODES)}")
        if type(calls) is not int or calls < 0:
            raise ValueError(f"calls: must be an integer >= 0, got {calls!r}")
        self.ode, self.calls, self.points = ode, calls, list(points or [])

    def __call__(self, t, y, v):
        self.calls += 1
        a = ODES[self.ode](t, y, v)
        self.points.append([float(t), np.asarray(y, dtype=np.float64).tolist(), np.asarray(v, dtype=np.float64).tolist()])
        return a

    def to_json(self) -> str:
        return json.dumps({"format": self.FORMAT, "ode": self.ode, "calls": self.calls, "points": self.points})

    @classmethod
    def from_json(cls, text: str) -> "CountingODE":
        """Rebuild from :meth:`to_json` text; foreign or truncated text raises ``ValueError``."""
        try:
            data = json.loads(text)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"CountingODE.from_json: not valid JSON ({exc})") from None
        if not isinstance(data, dict) or data.get("format") != cls.FORMAT:
            got = data.get("format") if isinstance(data, dict) else type(data).__name__
            raise ValueError(f"CountingODE.from_json: format must be {cls.FORMAT!r}, got {got!r}")
        if set(data) != {"format", "ode", "calls", "points"} or not isinstance(data["points"], list):
            raise ValueError(f"CountingODE.from_json: expected fields format, ode, calls, points (a list); got {sorted(data)}")
        return cls(data["ode"], data["calls"], data["points"])
