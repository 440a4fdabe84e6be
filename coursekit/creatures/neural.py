"""The control genotype: nested neural networks with relative identifiers (paper section 2.1.2).

Every morphology node carries a local network; one central network (the brain) is instantiated
once per creature. A network's nodes are numbered by a *control id*:

- a local network: ids ``0..7`` are the part's sensors (:data:`SENSORS`: joint angle, joint
  velocity, contact on the faces −x, +x, −y, +y, −z, +z), ids ``8..`` its neurons;
- the brain: ids ``0..`` are its neurons (it has no sensors of its own).

An :class:`Input` names its source by the paper's relative id ``(morph, ctrl)``:
``morph = −2`` the brain, ``−1`` the parent part's network, ``0`` the same network, ``m ≥ 1`` the
network of the m-th child of this part instance (children in expansion order, see
:mod:`coursekit.creatures.phenotype`), or ``morph = None`` for a constant 1. The brain's own
inputs may use ``−2``/``0`` (itself) and ``1`` (the root part's network). A reference that names
a part or node that an instance does not have (the root's parent, a child the expansion did not
produce, a neuron index the target network lacks) reads 0 — that is what keeps relative ids
valid when children change.

A neuron applies one of Sims' 23 functions (:data:`FUNCTIONS`) to 1..3 weighted inputs
``x = weight * source``. Unary functions act on ``s = sum(x)``; the others name their arguments
``a, b, c`` (missing ones take the defaults in :data:`FUNCTIONS`). Boolean results are ±1, like
the contact sensors. Exact definitions, with ``p`` the neuron's parameter, ``t`` the brain time
and ``dt`` the tick:

====================  ============================================================
sum                   ``s``
product               ``prod(x)``
divide                ``a / b`` (``b`` defaults to 1; 0 when ``|b| < 1e-6``)
sum_threshold         ``+1 if s > p else −1``
greater_than          ``+1 if a > b else −1`` (``b`` defaults to 0)
sign_of               ``sign(s)``
min, max              ``min(x)``, ``max(x)``
abs                   ``|s|``
if                    ``b if a > 0 else c`` (``b``, ``c`` default to 0)
interpolate           ``b + (c − b) * clip(a, 0, 1)`` (``b`` = 0, ``c`` = 1 by default)
sin, cos, atan        of ``s``
log                   ``log(max(|s|, 1e-6))``
expt                  ``exp(min(s, 20))``
sigmoid               ``1 / (1 + exp(−s))``
integrate             ``y ← y + dt * s`` (state)
differentiate         ``(s − s_prev) / dt``; 0 on the first tick after a reset (state)
smooth                ``y ← y + (1 − exp(−p * dt)) * (s − y)`` (state; ``p`` a rate in 1/s)
memory                ``y ← a if b > 0 else y`` (``b`` defaults to +1) (state)
oscillate_wave        ``sin(2π p t + s)`` (``p`` a frequency in Hz, ``s`` a phase)
oscillate_saw         ``2 * frac(p t + s / 2π) − 1``
====================  ============================================================

Every output is made finite and clipped to ``±OUTPUT_LIMIT``. Sims did not publish his
oscillator formulas or thresholds; these are ours. Sensors are per part and per joint DOF: ids
``0, 1`` are the angle and velocity of the joint's first DOF, and a multi-DOF joint's further DOFs
have ids from 16 on (:func:`dof_sensor`), after the largest neuron id, so a 1-DOF creature's ids
are the same as before multi-DOF joints existed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import array_api_compat
import numpy as np

#: Sensor names of one part's network, in control-id order (a multi-DOF joint's further DOFs: :func:`dof_sensor`).
SENSORS = ("joint_angle", "joint_velocity", "contact_-x", "contact_+x", "contact_-y", "contact_+y", "contact_-z", "contact_+z")
N_SENSORS = len(SENSORS)

#: name -> (defaults for the arguments a, b, c; None where the function is variadic/unary).
FUNCTIONS: dict[str, tuple | None] = {
    "sum": None,
    "product": None,
    "divide": (0.0, 1.0, 0.0),
    "sum_threshold": None,
    "greater_than": (0.0, 0.0, 0.0),
    "sign_of": None,
    "min": None,
    "max": None,
    "abs": None,
    "if": (0.0, 0.0, 0.0),
    "interpolate": (0.0, 0.0, 1.0),
    "sin": None,
    "cos": None,
    "atan": None,
    "log": None,
    "expt": None,
    "sigmoid": None,
    "integrate": None,
    "differentiate": None,
    "smooth": None,
    "memory": (0.0, 1.0, 0.0),
    "oscillate_wave": None,
    "oscillate_saw": None,
}
FUNCTION_NAMES = tuple(FUNCTIONS)
FUNCTION_CODE = {name: i for i, name in enumerate(FUNCTION_NAMES)}

#: Parameter range per function (random draws and mutation clamp to it); 0 where unused.
PARAM_RANGE = {"sum_threshold": (-1.0, 1.0), "smooth": (0.5, 20.0), "oscillate_wave": (0.2, 3.0), "oscillate_saw": (0.2, 3.0)}

MAX_INPUTS = 3
MAX_NEURONS = 8  #: neurons per local network (bloat cap)
MAX_BRAIN_NEURONS = 8
MAX_CHILD_REF = 8  #: largest child index ``m`` a relative id may name
MAX_JOINT_DOF = 3  #: the most DOFs a joint has (spherical), so the most DOF sensor ids a part has
#: The first control id of the sensors of a joint's second DOF (after every sensor and neuron id).
DOF_SENSOR_BASE = N_SENSORS + MAX_NEURONS
WEIGHT_LIMIT = 10.0
OUTPUT_LIMIT = 1.0e3


@dataclass
class Input:
    """One weighted input: relative id ``(morph, ctrl)`` or a constant (``morph is None``)."""

    morph: int | None
    ctrl: int
    weight: float

    def to_dict(self) -> dict:
        return {"morph": self.morph, "ctrl": self.ctrl, "weight": self.weight}

    @classmethod
    def from_dict(cls, d: dict, where: str) -> "Input":
        need_keys(d, ("morph", "ctrl", "weight"), where)
        return cls(d["morph"], d["ctrl"], d["weight"])


@dataclass
class Neuron:
    """A neuron: ``func`` (a name in :data:`FUNCTIONS`), 1..3 ``inputs`` and a parameter."""

    func: str
    inputs: list[Input] = field(default_factory=list)
    param: float = 0.0

    def to_dict(self) -> dict:
        return {"func": self.func, "param": self.param, "inputs": [i.to_dict() for i in self.inputs]}

    @classmethod
    def from_dict(cls, d: dict, where: str) -> "Neuron":
        need_keys(d, ("func", "param", "inputs"), where)
        if not isinstance(d["inputs"], list):
            raise TypeError(f"{where}.inputs: expected a list, got {type(d['inputs']).__name__}")
        return cls(d["func"], [Input.from_dict(x, f"{where}.inputs[{k}]") for k, x in enumerate(d["inputs"])], d["param"])


def need_keys(d, keys, where: str) -> None:
    if not isinstance(d, dict):
        raise TypeError(f"{where}: expected a JSON object, got {type(d).__name__}")
    missing = [k for k in keys if k not in d]
    if missing:
        raise ValueError(f"{where}: missing field(s) {missing}")


def is_int(v: object) -> bool:
    return isinstance(v, (int, np.integer)) and not isinstance(v, bool)


def is_real(v: object) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool) and math.isfinite(v)


def dof_sensor(dof: int, which: int) -> int:
    """The control id of the angle (``which = 0``) or velocity (``1``) sensor of DOF ``dof`` of a
    part's joint: ``0, 1`` for the first DOF (as :data:`SENSORS`), ``16, 17`` for the second,
    ``18, 19`` for the third.

    >>> [dof_sensor(d, w) for d in range(3) for w in (0, 1)]
    [0, 1, 16, 17, 18, 19]
    """
    if not (is_int(dof) and 0 <= dof < MAX_JOINT_DOF and which in (0, 1)):
        raise ValueError(f"dof_sensor: need dof in [0, {MAX_JOINT_DOF}) and which 0 (angle) or 1 (velocity), got {dof!r}, {which!r}")
    return which if dof == 0 else DOF_SENSOR_BASE + 2 * (dof - 1) + which


def sensor_dof(ctrl: int) -> tuple[int, int] | None:
    """``(dof, which)`` of a joint sensor's control id (inverse of :func:`dof_sensor`), else None."""
    if ctrl in (0, 1):
        return 0, ctrl
    k = ctrl - DOF_SENSOR_BASE
    return (1 + k // 2, k % 2) if 0 <= k < 2 * (MAX_JOINT_DOF - 1) else None


def validate_input(inp: Input, where: str, *, brain: bool, n_local: int, n_brain: int, dof: int = 1) -> None:
    """Check one input of a local network (``brain=False``) or of the brain.

    Args:
        n_local: number of control ids of the network itself (sensors + neurons).
        n_brain: number of brain neurons.
        dof: the DOFs of the network's own joint (its further DOFs' sensors, :func:`dof_sensor`).
    """
    if not isinstance(inp, Input):
        raise TypeError(f"{where}: expected an Input, got {type(inp).__name__}")
    if not is_real(inp.weight) or abs(inp.weight) > WEIGHT_LIMIT:
        raise ValueError(f"{where}.weight: must be finite with |weight| <= {WEIGHT_LIMIT}, got {inp.weight!r}")
    if not is_int(inp.ctrl) or inp.ctrl < 0:
        raise ValueError(f"{where}.ctrl: must be an int >= 0, got {inp.ctrl!r}")
    m = inp.morph
    if m is None:
        return
    allowed = (-2, 0, 1) if brain else tuple(range(-2, MAX_CHILD_REF + 1))
    if not is_int(m) or m not in allowed:
        raise ValueError(f"{where}.morph: must be None (constant) or one of {list(allowed)}, got {m!r}")
    if m == -2 or (brain and m == 0):
        if inp.ctrl >= n_brain:
            raise ValueError(f"{where}.ctrl: brain has {n_brain} neurons, got ctrl={inp.ctrl}")
    elif m == 0:
        if inp.ctrl >= n_local and not DOF_SENSOR_BASE <= inp.ctrl < DOF_SENSOR_BASE + 2 * (dof - 1):
            extra = f" or a sensor of its further DOFs in [{DOF_SENSOR_BASE}, {DOF_SENSOR_BASE + 2 * (dof - 1)})" if dof > 1 else ""
            raise ValueError(f"{where}.ctrl: this network has {n_local} nodes (8 sensors + neurons){extra}, got ctrl={inp.ctrl}")
    elif inp.ctrl >= DOF_SENSOR_BASE + 2 * (MAX_JOINT_DOF - 1):
        raise ValueError(f"{where}.ctrl: a part network has at most {N_SENSORS + MAX_NEURONS} nodes and "
                         f"{2 * (MAX_JOINT_DOF - 1)} further DOF sensors, got ctrl={inp.ctrl}")


def validate_neuron(n: Neuron, where: str, *, brain: bool, n_local: int, n_brain: int, dof: int = 1) -> None:
    """Check a neuron's function, parameter and inputs (see :func:`validate_input`)."""
    if not isinstance(n, Neuron):
        raise TypeError(f"{where}: expected a Neuron, got {type(n).__name__}")
    if not isinstance(n.func, str) or n.func not in FUNCTIONS:
        raise ValueError(f"{where}.func: unknown neuron function {n.func!r}; allowed: {', '.join(FUNCTION_NAMES)}")
    if not is_real(n.param):
        raise ValueError(f"{where}.param: must be a finite number, got {n.param!r}")
    lo, hi = PARAM_RANGE.get(n.func, (-np.inf, np.inf))
    if not lo <= n.param <= hi:
        raise ValueError(f"{where}.param: {n.func} needs a parameter in [{lo}, {hi}], got {n.param}")
    if not isinstance(n.inputs, list) or not 1 <= len(n.inputs) <= MAX_INPUTS:
        raise ValueError(f"{where}.inputs: a neuron needs 1..{MAX_INPUTS} inputs, got {n.inputs!r}")
    for k, inp in enumerate(n.inputs):
        validate_input(inp, f"{where}.inputs[{k}]", brain=brain, n_local=n_local, n_brain=n_brain, dof=dof)


# ---------------------------------------------------------------------------------- random


def random_param(func: str, rng: np.random.Generator) -> float:
    """A random parameter for ``func`` (0 where the function has none)."""
    if func not in PARAM_RANGE:
        return 0.0
    lo, hi = PARAM_RANGE[func]
    return float(rng.uniform(lo, hi))


def random_input(rng: np.random.Generator, *, brain: bool, n_local: int, n_brain: int, n_children: int,
                 dof: int = 1) -> Input:
    """A random valid input for a local network or the brain.

    Args:
        n_local: control ids available in the same network (sensors + neurons).
        n_brain: brain neurons.
        n_children: expected child count of the part (bounds ``m``; at least 1 is tried).
        dof: the DOFs of the network's joint: a same-network input may also read the sensors
            of its further DOFs (:func:`dof_sensor`; for 1 DOF the draws are as before).
    """
    w = float(np.round(rng.uniform(-2.0, 2.0), 3))
    kinds = ["const", "self"]
    if n_brain and not brain:
        kinds.append("brain")
    if not brain:
        kinds += ["parent", "child"]
    else:
        kinds.append("child")
    kind = kinds[int(rng.integers(len(kinds)))]
    if kind == "const":
        return Input(None, 0, w)
    if kind == "self":
        if brain:
            return Input(0, int(rng.integers(n_brain)), w) if n_brain else Input(None, 0, w)
        k = int(rng.integers(n_local + 2 * (dof - 1)))
        return Input(0, k if k < n_local else DOF_SENSOR_BASE + k - n_local, w)
    if kind == "brain":
        return Input(-2, int(rng.integers(n_brain)), w)
    if kind == "parent":
        return Input(-1, int(rng.integers(N_SENSORS + 2)), w)
    m = 1 if brain else int(rng.integers(1, max(1, min(n_children, MAX_CHILD_REF)) + 1))
    return Input(m, int(rng.integers(N_SENSORS + 2)), w)


def random_neuron(rng: np.random.Generator, *, brain: bool, n_local: int, n_brain: int, n_children: int,
                  dof: int = 1) -> Neuron:
    """A random neuron with 1..3 random inputs (see :func:`random_input`)."""
    func = FUNCTION_NAMES[int(rng.integers(len(FUNCTION_NAMES)))]
    k = int(rng.integers(1, MAX_INPUTS + 1))
    inputs = [random_input(rng, brain=brain, n_local=n_local, n_brain=n_brain, n_children=n_children, dof=dof) for _ in range(k)]
    return Neuron(func, inputs, random_param(func, rng))


# -------------------------------------------------------------------------- the functions


def function_groups(code: np.ndarray) -> list[tuple[int, np.ndarray]]:
    """``(function code, neuron indices)`` for every function present (computed once per batch)."""
    return [(int(c), np.nonzero(code == c)[0]) for c in np.unique(code)]


def evaluate(code: np.ndarray, x: Any, n_inputs: Any, param: Any, y_prev: Any, s_prev: Any, first: bool,
             t: float, dt: float, groups=None, xp: Any = np) -> tuple[Any, Any]:
    """Evaluate many neurons at once; one vectorised branch per function present.

    Args:
        code: (N,) function codes (:data:`FUNCTION_CODE`), a numpy array.
        x: (N, 3) weighted inputs (unused slots ignored).
        n_inputs: (N,) number of inputs, 1..3.
        param: (N,) parameters.
        y_prev: (N,) outputs of the previous tick (state of integrate, smooth, memory).
        s_prev: (N,) input sums of the previous tick (state of differentiate).
        first: True on the first tick after a reset.
        t: brain time of this tick; dt: tick length (> 0).
        groups: :func:`function_groups` of ``code`` (computed here when omitted), its indices
            arrays of ``xp``.
        xp: the array namespace of ``x`` and the other arrays (numpy, or the simulator's torch
            namespace, :func:`coursekit.creatures.physics.backend.namespace`): the brain runs
            where the physics does.

    Returns:
        (outputs (N,), input sums (N,)) — the sums are the next call's ``s_prev``.
    """
    mask = xp.arange(MAX_INPUTS, device=array_api_compat.device(x))[None, :] < n_inputs[:, None]
    xm = xp.where(mask, x, 0.0)
    s = xp.sum(xm, axis=1)
    out = xp.zeros_like(s)
    for c, i in function_groups(code) if groups is None else groups:
        name = FUNCTION_NAMES[c]
        si, p = s[i], param[i]
        defaults = FUNCTIONS[name]
        if defaults is not None:
            xi, ni = x[i], n_inputs[i]
            a = xi[:, 0]
            b = xp.where(ni >= 2, xi[:, 1], defaults[1])
            cc = xp.where(ni >= 3, xi[:, 2], defaults[2])
        with np.errstate(all="ignore"):
            if name == "sum":
                y = si
            elif name == "product":
                y = xp.prod(xp.where(mask[i], x[i], 1.0), axis=1)
            elif name == "divide":
                y = xp.where(xp.abs(b) < 1e-6, 0.0, a / xp.where(xp.abs(b) < 1e-6, 1.0, b))
            elif name == "sum_threshold":
                y = xp.where(si > p, 1.0, -xp.ones_like(si))  # one array operand: its dtype (float64 on torch too)
            elif name == "greater_than":
                y = xp.where(a > b, 1.0, -xp.ones_like(a))
            elif name == "sign_of":
                y = xp.sign(si)
            elif name == "min":
                y = xp.min(xp.where(mask[i], x[i], math.inf), axis=1)
            elif name == "max":
                y = xp.max(xp.where(mask[i], x[i], -math.inf), axis=1)
            elif name == "abs":
                y = xp.abs(si)
            elif name == "if":
                y = xp.where(a > 0, b, cc)
            elif name == "interpolate":
                y = b + (cc - b) * xp.clip(a, 0.0, 1.0)
            elif name == "sin":
                y = xp.sin(si)
            elif name == "cos":
                y = xp.cos(si)
            elif name == "atan":
                y = xp.atan(si)
            elif name == "log":
                y = xp.log(xp.clip(xp.abs(si), 1e-6, None))  # clip: a number, not a tensor made of it (a GPU upload)
            elif name == "expt":
                y = xp.exp(xp.clip(si, None, 20.0))
            elif name == "sigmoid":
                y = 1.0 / (1.0 + xp.exp(-si))
            elif name == "integrate":
                y = y_prev[i] + dt * si
            elif name == "differentiate":
                y = xp.zeros_like(si) if first else (si - s_prev[i]) / dt
            elif name == "smooth":
                y = y_prev[i] + (1.0 - xp.exp(-p * dt)) * (si - y_prev[i])
            elif name == "memory":
                y = xp.where(b > 0, a, y_prev[i])
            elif name == "oscillate_wave":
                y = xp.sin(2.0 * math.pi * p * t + si)
            elif name == "oscillate_saw":
                y = 2.0 * xp.remainder(p * t + si / (2.0 * math.pi), 1.0) - 1.0
            else:  # pragma: no cover - FUNCTIONS and this table are kept in step by the tests
                raise AssertionError(name)
        out[i] = y
    out = xp.where(xp.isnan(out), 0.0, out)  # NaN -> 0; +-inf and beyond are clipped to the limit
    out = xp.clip(out, -OUTPUT_LIMIT, OUTPUT_LIMIT)
    return out, s
