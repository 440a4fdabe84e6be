"""The phenotype's neural system as flat arrays, evaluated in one batch (paper section 2.3).

The paper keeps the expanded network "as a list together with a map storing the state of each
element". Here a :class:`Brain` holds, for one creature, every neuron instance (each part's copy
of its node's local neurons in body order, then the central brain's neurons) with its function
code, parameter and up to three ``(source slot, weight)`` inputs, plus one effector per joint DOF
(per body of the body tree: a multi-DOF joint's massless frames carry its further DOFs).
Relative ids are resolved once, at expansion (see :mod:`coursekit.creatures.neural` for their
meaning; unresolvable ones read the constant-0 slot).

Slots of one creature's value vector: ``0`` the constant 0, ``1`` the constant 1, ``2 + 8 b + k``
sensor ``k`` of body ``b`` (:data:`~coursekit.creatures.neural.SENSORS`; a massless frame uses only its
joint's angle and velocity), then ``2 + 8 B + j``
neuron ``j``. :class:`BrainBatch` concatenates many brains into one vector and evaluates them
together: synchronous update (every neuron reads the previous tick's values and this tick's
sensors), then every effector reads its source's new value times its weight. Physics calls
:meth:`BrainBatch.step` twice per physics step (Sims: two brain ticks per step).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from .neural import FUNCTION_CODE, FUNCTION_NAMES, MAX_INPUTS, MAX_NEURONS, N_SENSORS, OUTPUT_LIMIT, SENSORS, evaluate, function_groups, sensor_dof
from .physics import backend as bk
from .physics import kernels

if TYPE_CHECKING:
    from .phenotype import Phenotype

ZERO, ONE = 0, 1
N_CONST = 2


@dataclass
class Brain:
    """One creature's expanded neural system (see the module docstring for the slot layout)."""

    n_bodies: int
    func: np.ndarray  # (N,) function codes
    param: np.ndarray  # (N,)
    src: np.ndarray  # (N, 3) slots
    weight: np.ndarray  # (N, 3)
    n_inputs: np.ndarray  # (N,) 1..3
    effector_src: np.ndarray  # (B,) slot (row 0, the root, is unused)
    effector_weight: np.ndarray  # (B,)
    neuron_body: np.ndarray  # (N,) part of each neuron, -1 for the central brain
    neuron_index: np.ndarray  # (N,) index within its network's neurons

    @property
    def n_neurons(self) -> int:
        return len(self.func)

    @property
    def n_slots(self) -> int:
        return N_CONST + N_SENSORS * self.n_bodies + self.n_neurons

    def slot_labels(self) -> list[str]:
        """The state map: a readable name for every slot (``"part3.neuron1:sin"``, ...)."""
        out = ["zero", "one"]
        out += [f"part{b}.{s}" for b in range(self.n_bodies) for s in SENSORS]
        for j in range(self.n_neurons):
            b = self.neuron_body[j]
            net = "brain" if b < 0 else f"part{b}"
            out.append(f"{net}.neuron{self.neuron_index[j]}:{FUNCTION_NAMES[self.func[j]]}")
        return out


def build_brain(creature, node_of: list[int], parent_of: list[int], children: list[list[int]],
                dof_bodies: list[list[int]] | None = None, massless: list[bool] | None = None) -> Brain:
    """Resolve the relative ids of ``creature``'s networks over an expanded body tree.

    Args:
        creature: the genotype.
        node_of, parent_of: genotype node and parent part of every body (pre-order).
        children: children[b], part indices in relative-id order.
        dof_bodies: dof_bodies[b], the bodies whose joints are the DOFs of part ``b``'s joint, in
            DOF order (default ``[b]``: 1-DOF joints). Their angle and velocity are the part's
            joint sensors (:func:`~coursekit.creatures.neural.dof_sensor`), and each DOF's
            effector drives its body's joint.
        massless: massless[b], body ``b`` is a massless frame of a multi-DOF joint (no network
            of its own; default none).
    """
    B = len(node_of)
    nodes = creature.nodes
    massless = [False] * B if massless is None else list(massless)
    dof_bodies = [[b] for b in range(B)] if dof_bodies is None else dof_bodies
    first = np.zeros(B + 1, dtype=np.int64)  # first neuron index of each part; the brain last
    for b in range(B):
        first[b + 1] = first[b] + (0 if massless[b] else len(nodes[node_of[b]].neurons))
    brain_first = int(first[B])
    N = brain_first + len(creature.brain)
    neuron_base = N_CONST + N_SENSORS * B

    def network_slot(part: int, ctrl: int) -> int:
        """Slot of control id ``ctrl`` of part ``part``'s network (-1: the brain)."""
        if part == -1:
            return neuron_base + brain_first + ctrl if ctrl < len(creature.brain) else ZERO
        joint = sensor_dof(ctrl)
        if joint is not None:
            d, which = joint
            return N_CONST + N_SENSORS * dof_bodies[part][d] + which if d < len(dof_bodies[part]) else ZERO
        if ctrl < N_SENSORS:
            return N_CONST + N_SENSORS * part + ctrl
        k = ctrl - N_SENSORS
        if k >= MAX_NEURONS:
            return ZERO
        return neuron_base + first[part] + k if k < len(nodes[node_of[part]].neurons) else ZERO

    def resolve(inp, part: int) -> tuple[int, float]:
        if inp is None:
            return ZERO, 0.0
        m = inp.morph
        if m is None:
            return ONE, inp.weight
        if part == -1:  # the brain: -2 and 0 mean itself, 1 the root part
            target = -1 if m in (-2, 0) else (0 if m == 1 else None)
        elif m == -2:
            target = -1
        elif m == -1:
            target = parent_of[part] if parent_of[part] >= 0 else None
        elif m == 0:
            target = part
        else:
            target = children[part][m - 1] if m <= len(children[part]) else None
        if target is None:
            return ZERO, inp.weight
        return network_slot(target, inp.ctrl), inp.weight

    func = np.zeros(N, dtype=np.int64)
    param = np.zeros(N)
    src = np.zeros((N, MAX_INPUTS), dtype=np.int64)
    weight = np.zeros((N, MAX_INPUTS))
    n_inputs = np.zeros(N, dtype=np.int64)
    neuron_body = np.full(N, -1, dtype=np.int64)
    neuron_index = np.zeros(N, dtype=np.int64)
    eff_src = np.zeros(B, dtype=np.int64)
    eff_w = np.zeros(B)

    def fill(j: int, neuron, part: int, k: int) -> None:
        func[j] = FUNCTION_CODE[neuron.func]
        param[j] = neuron.param
        n_inputs[j] = len(neuron.inputs)
        neuron_body[j] = part
        neuron_index[j] = k
        for s, inp in enumerate(neuron.inputs):
            src[j, s], weight[j, s] = resolve(inp, part)

    for b in range(B):
        if massless[b]:
            continue
        node = nodes[node_of[b]]
        for k, neuron in enumerate(node.neurons):
            fill(int(first[b]) + k, neuron, b, k)
        for d, j in enumerate(dof_bodies[b]):
            eff_src[j], eff_w[j] = resolve(node.effectors[d], b)
    for k, neuron in enumerate(creature.brain):
        fill(brain_first + k, neuron, -1, k)
    return Brain(B, func, param, src, weight, n_inputs, eff_src, eff_w, neuron_body, neuron_index)


class BrainBatch:
    """Many creatures' brains evaluated together, on the simulator's array backend.

    Args:
        brains: :class:`Brain` objects (or phenotypes with ``.brain``), in creature order.
        backend: ``"numpy"`` or ``"torch"`` (:func:`coursekit.creatures.physics.backend.namespace`):
            the brain's arrays live there, so a torch simulation's sensors and effectors never
            travel to the host and back.
        device: torch device (ignored for numpy).
        compiled: evaluate the neurons with the compiled kernel
            (:func:`coursekit.creatures.physics.kernels.neurons`, numpy backend): the same outputs
            to rounding. ``None`` (default): wherever it can run.

    ``step`` takes the joints of all creatures concatenated (within a creature, joints are parts
    1..B-1 in body order) and the parts of all creatures concatenated, and returns the effector
    outputs per joint, before gain and strength clamping, as arrays of the backend.
    """

    def __init__(self, brains: Sequence[Brain | Phenotype], backend: str = "numpy", device: Any | None = None,
                 compiled: bool | None = None) -> None:
        if isinstance(brains, (str, bytes)) or not hasattr(brains, "__iter__"):
            raise TypeError(f"BrainBatch.brains: expected a non-empty list of Brain (or Phenotype) objects, got {type(brains).__name__}")
        brains = [getattr(b, "brain", b) for b in brains]
        if not brains or not all(isinstance(b, Brain) for b in brains):
            raise TypeError("BrainBatch.brains: expected a non-empty list of Brain (or Phenotype) objects")
        self.brains = brains
        self.backend = backend
        self.xp = xp = bk.namespace(backend)
        if compiled is None:
            compiled = bk.is_numpy(xp) and kernels.available()
        if compiled and not (bk.is_numpy(xp) and kernels.available()):
            raise ValueError(f"BrainBatch.compiled: the compiled neurons need the numpy backend and numba, got backend={backend!r}")
        self.compiled = bool(compiled)
        self.device = device
        nb = np.array([b.n_bodies for b in brains], dtype=np.int64)
        nn = np.array([b.n_neurons for b in brains], dtype=np.int64)
        self.body_offset = np.concatenate([[0], np.cumsum(nb)])
        self.neuron_offset = np.concatenate([[0], np.cumsum(nn)])
        TB, TN = int(self.body_offset[-1]), int(self.neuron_offset[-1])
        self.total_bodies, self.total_neurons = TB, TN
        self.total_joints = TB - len(brains)
        base = N_CONST + N_SENSORS * TB

        def remap(local: np.ndarray, c: int) -> np.ndarray:
            B = brains[c].n_bodies
            out = local.copy()
            sens = (local >= N_CONST) & (local < N_CONST + N_SENSORS * B)
            neur = local >= N_CONST + N_SENSORS * B
            out[sens] = local[sens] + N_SENSORS * self.body_offset[c]
            out[neur] = local[neur] - (N_CONST + N_SENSORS * B) + base + self.neuron_offset[c]
            return out

        cat = lambda f: np.concatenate([f(c, b) for c, b in enumerate(brains)])  # noqa: E731
        real = lambda a: bk.asarray(xp, a, device=device)  # noqa: E731
        index = lambda a: bk.index(xp, a, device=device)  # noqa: E731
        self.func = cat(lambda c, b: b.func)  # the function codes stay on the host: they pick the branches
        self.param = real(cat(lambda c, b: b.param))
        self.src = index(cat(lambda c, b: remap(b.src, c).reshape(-1, MAX_INPUTS)))
        self.weight = real(cat(lambda c, b: b.weight.reshape(-1, MAX_INPUTS)))
        self.n_inputs = index(cat(lambda c, b: b.n_inputs))
        self.groups = [(c, index(i)) for c, i in function_groups(self.func)]
        joint_rows = np.ones(TB, dtype=bool)
        joint_rows[self.body_offset[:-1]] = False  # drop every root
        self.joint_body = index(np.nonzero(joint_rows)[0])  # global part index of every joint
        self.effector_src = index(cat(lambda c, b: remap(b.effector_src, c))[joint_rows])
        self.effector_weight = real(cat(lambda c, b: b.effector_weight)[joint_rows])
        self._sensors = slice(N_CONST, base)
        self._neurons = slice(base, base + TN)
        self.values = real(np.zeros(base + TN))
        self.values[ONE] = 1.0
        self.reset()

    def __getstate__(self) -> dict:
        """Copies and pickles name the array backend instead of holding its module."""
        state = dict(self.__dict__)
        del state["xp"]
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state, xp=bk.namespace(state["backend"]))

    def reset(self) -> None:
        """Zero every neuron's output and state and the brain time."""
        self.values[N_CONST:] = 0.0
        self._s_prev = bk.asarray(self.xp, np.zeros(self.total_neurons), device=self.device)
        self._first = True
        self.time = 0.0

    def step(self, joint_angle: ArrayLike, joint_velocity: ArrayLike, contact: ArrayLike, dt: float) -> Any:
        """One brain tick.

        Args:
            joint_angle, joint_velocity: (total_joints,) float arrays (numpy, or of the backend).
            contact: (total_bodies, 6) in {-1, +1}, faces -x, +x, -y, +y, -z, +z.
            dt: tick length in seconds (> 0).

        Returns:
            (total_joints,) effector outputs, an array of the backend.
        """
        J, TB, xp = self.total_joints, self.total_bodies, self.xp
        ja, jv, ct = (bk.asarray(xp, a, device=self.device) for a in (joint_angle, joint_velocity, contact))
        if tuple(ja.shape) != (J,) or tuple(jv.shape) != (J,):
            raise ValueError(f"BrainBatch.step: joint_angle and joint_velocity must be shaped ({J},), "
                             f"got {tuple(ja.shape)}, {tuple(jv.shape)}")
        if tuple(ct.shape) != (TB, 6):
            raise ValueError(f"BrainBatch.step.contact: must be shaped ({TB}, 6), got {tuple(ct.shape)}")
        if not dt > 0:
            raise ValueError(f"BrainBatch.step.dt: must be > 0, got {dt!r}")
        v = self.values
        sens = xp.reshape(v[self._sensors], (TB, N_SENSORS))  # a view: writing it writes the values
        sens[self.joint_body, 0] = ja
        sens[self.joint_body, 1] = jv
        sens[:, 2:] = ct
        x = v[self.src] * self.weight
        y_prev = v[self._neurons]
        if self.compiled:
            out, sums = np.empty(self.total_neurons), np.empty(self.total_neurons)
            kernels.neurons(self.func, x, self.n_inputs, self.param, y_prev, self._s_prev, self._first, self.time, dt,
                            OUTPUT_LIMIT, out, sums)
            self._s_prev = sums
        else:
            out, self._s_prev = evaluate(self.func, x, self.n_inputs, self.param, y_prev, self._s_prev, self._first,
                                         self.time, dt, self.groups, xp=xp)
        v[self._neurons] = out
        self._first = False
        self.time += dt
        return self.effector_weight * v[self.effector_src]

    def neuron_outputs(self) -> Any:
        """(total_neurons,) current neuron outputs (a view; copy to keep)."""
        return self.values[self._neurons]
