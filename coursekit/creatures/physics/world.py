"""A population of swimmers stepping together: water, limits, effectors, guards (paper section 2.4).

:class:`World` owns a packed :class:`~coursekit.creatures.physics.model.Model` and its
:class:`~coursekit.creatures.physics.integrate.State`. Each :meth:`World.step` advances every
creature by ``dt`` with the chosen integrator (sub-stepped when the water would be too stiff, see
:mod:`~coursekit.creatures.physics.water`). Joint forces from effectors are held constant over a
step; self-collisions are detected at the step's start and their forces (the springs of :mod:`~.contact`
and the constraint forces of :mod:`~.contact_forces` that hold each creature's nearest pairs apart),
like drag, are evaluated at every stage. Joints at their limits are locked for the step (:mod:`~.limits`):
the articulated-body algorithm prescribes their accelerations and the rest of the body responds.

Guards: after each step a creature whose state is not finite or whose root speed, root spin or
any joint rate exceeds its cap is flagged ``diverged`` and frozen at its last good state with zero
velocity (and no forces); the rest of the batch goes on unaffected -- creatures never share
arrays rows, so NaNs cannot leak between them.

On a GPU the host waits for the device at every value Python reads and every output whose size
depends on the data; ``World(graph=True)`` steps without either, so that a CUDA graph can record a
step once and replay it (:meth:`World._graph_step`; :class:`~coursekit.operations.CountHostSyncs`
counts the waits on any machine; :mod:`~coursekit.creatures.physics.graph` records it).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from coursekit.creatures.body import REVOLUTE

from . import backend as bk
from . import spatial as sp
from .aba import aba, articulated_inertias, body_velocities, impulse
from .jcalc import forward_kinematics, joint_transform_matrices, joint_transforms, pose_stacks, poses_rows
from .compiled import Dynamics, available
from .graph import CudaGraph
from .contact import Contacts
from .contact_forces import ContactForces
from .dynamics import flatten_layout, split_layout, join_velocity_layout
from .integrate import INTEGRATORS, State, step
from .limits import Limits
from .model import Model
from .water import DRAG_COEFFICIENT, STABLE_DRAG_STEP, drag_matrix, max_drag_rate

#: Default guard caps: root speed (m/s), root spin (rad/s), joint rate (rad/s or m/s).
MAX_SPEED = 20.0
MAX_ANGULAR_SPEED = 100.0
MAX_JOINT_SPEED = 100.0


class World:
    """A batch of creatures in water.

    Args:
        creatures: BodyTrees / creatures, or a packed :class:`Model`.
        dt: physics step (s).
        backend: "numpy" or "torch"; device: torch device.
        integrator: "rkn" (default), "rk4", or a function ``rkn_step(f, t, y, v, h) -> (y_next,
            v_next)`` that then advances the state (see :mod:`integrate`; exercise 07).
        drag: water on/off, or a function ``box_drag(half_extents, k) -> (6,)`` giving one box's
            drag diagonal, used for every box instead of the library's (see :mod:`water`);
            drag_coefficient: ``k`` of :mod:`water`.
        limits: joint limits on/off (one-sided constraints, see :mod:`limits`).
        contacts: self-collisions on/off: penalty springs (:mod:`contact`) and, with ``hold_contacts``,
            forces that hold each creature's nearest pairs apart (:mod:`contact_forces`).
        substeps: integrate in this many times the sub-steps the water needs (default 1). The
            model stays the same -- effectors held over ``dt``, the contact springs of the
            water's own sub-step -- so more sub-steps integrate the same system more finely: the
            audit's test that a speed is not integration error (:mod:`~coursekit.creatures.audit`).
        max_speed, max_angular_speed, max_joint_speed: divergence caps.
        graph: the graph-ready step: static shapes and no read on the host -- the guards' flags
            stay on the device (:attr:`diverged` reads them), every candidate pair of boxes is
            tested and followed with a mask for those in contact, locked joints are masks, the
            root's solve is an elimination. On CUDA the step is captured as a
            ``torch.cuda.CUDAGraph`` after a few eager steps and replayed (a custom integrator then
            sees the time of the capture; the forces do not depend on time); elsewhere it runs as
            it is. The motion is the ordinary step's up to rounding.
        compiled: the step compiled with numba (:mod:`~coursekit.creatures.physics.compiled`;
            numpy backend, not ``graph``): the same physics up to rounding, 3 to 29 times faster
            (``benchmarks/swimmers.py``).
            ``None`` (default): compiled wherever it can run; ``False``: the numpy step.
    """

    def __init__(
        self,
        creatures: Any,
        *,
        dt: float = 1.0 / 60.0,
        backend: str = "numpy",
        device: Any | None = None,
        integrator: str | Callable = "rkn",
        drag: bool | Callable = True,
        drag_coefficient: float = DRAG_COEFFICIENT,
        limits: bool = True,
        contacts: bool = True,
        hold_contacts: bool = True,
        contact_stiffness: float | None = None,
        max_speed: float = MAX_SPEED,
        max_angular_speed: float = MAX_ANGULAR_SPEED,
        max_joint_speed: float = MAX_JOINT_SPEED,
        substeps: int = 1,
        graph: bool = False,
        compiled: bool | None = None,
    ):
        if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0):
            raise ValueError(f"dt: must be a positive number of seconds, got {dt!r}")
        if not callable(integrator) and integrator not in INTEGRATORS:
            raise ValueError(f"integrator: got {integrator!r}; allowed: {', '.join(INTEGRATORS)} or a function rkn_step(f, t, y, v, h)")
        if not (isinstance(drag, (bool, np.bool_)) or callable(drag)):
            raise TypeError(f"drag: must be True, False or a function box_drag(half_extents, k), got {type(drag).__name__}")
        for name, flag in (("graph", graph), ("limits", limits), ("contacts", contacts), ("hold_contacts", hold_contacts), ("compiled", compiled)):
            if not isinstance(flag, (bool, np.bool_)) and not (name == "compiled" and flag is None):
                raise TypeError(f"{name}: must be True or False{' (or None)' if name == 'compiled' else ''}, got {type(flag).__name__}")
        if not (isinstance(substeps, (int, np.integer)) and not isinstance(substeps, bool) and substeps >= 1):
            raise ValueError(f"substeps: must be an integer >= 1, got {substeps!r}")
        for name, cap in (("max_speed", max_speed), ("max_angular_speed", max_angular_speed), ("max_joint_speed", max_joint_speed)):
            if not (cap > 0):
                raise ValueError(f"{name}: must be > 0, got {cap}")
        self.model = m = creatures if isinstance(creatures, Model) else Model(creatures, backend=backend, device=device)
        self.xp = xp = m.xp
        self.graph = bool(graph)
        self.dt = float(dt)
        self.integrator = integrator
        box_drag = drag if callable(drag) else None
        self.damping = drag_matrix(m, drag_coefficient, box_drag) if drag else None
        if compiled is None:
            compiled = bk.is_numpy(xp) and not graph and available()
        if compiled and (not bk.is_numpy(xp) or graph):
            raise ValueError(f"compiled: the compiled step runs on the numpy backend without graph, got backend={m.backend!r}, graph={graph!r}")
        self._compiled = Dynamics(m, self.damping) if compiled else None
        self.compiled = bool(compiled)  # the step compiled (the creatures' brains follow it in simulate)
        rate = max_drag_rate(m, drag_coefficient, box_drag) if drag else 0.0
        water_steps = max(1, math.ceil(self.dt * rate / STABLE_DRAG_STEP))  # what the water needs
        self.substeps = water_steps * int(substeps)
        self.h = self.dt / self.substeps
        self.limits = Limits(m, self.h) if limits else None
        self._lock = None
        self.overshoot = None  # (M,) how far the last step carried each joint beyond its limits before they were put back
        f = lambda a: bk.asarray(xp, a, device=m.device)  # noqa: E731
        self.strength = f(m.strength_np)
        self.gain = f(m.gain_np)
        self.contacts = self.contact_forces = None
        if contacts:
            self.contacts = Contacts(m, stiffness=contact_stiffness, dt=self.dt / water_steps, static=self.graph)
            if self._compiled is not None:
                self.contacts.compiled = self._compiled.begin(self.contacts)
            self.contact_forces = ContactForces(self.contacts) if hold_contacts else None
        self.caps = (float(max_speed), float(max_angular_speed), float(max_joint_speed))
        self._graph = None  # the captured CUDA graph and its buffers (graph=True on CUDA)
        self._graph_failed = None  # why the step could not be captured (it then runs eagerly)
        self._eager_steps = 0  # graph-ready steps run eagerly (the warm-up before a capture)
        self._diverged = np.zeros(m.n_creatures, dtype=bool)
        if self.graph:
            self._diverged = bk.asarray(xp, self._diverged, dtype=xp.bool, device=m.device)
        self._eye3 = bk.asarray(xp, np.eye(3), device=m.device)[:, :, None]
        self.time = 0.0
        C, M = m.n_creatures, m.n_joints
        z = lambda *s: xp.zeros(s, dtype=xp.float64, device=m.device)  # noqa: E731
        quat = z(C, 4)
        quat[:, 0] = 1.0
        self.state = State(z(C, 3), quat, z(M), z(C, 3), z(C, 3), z(M))
        self.tau = z(M)
        self.active_contacts = self._held = None
        self._inertia_q = self._inertia = self._poses_q = self._poses = None
        self.contact_sensors = None
        self._sensed = None  # (user joint order, which of them are hinges), on the first sensors()
        self._user_order = None  # the joints' user order on the device, on the first set_effectors()
        self._joint_creature = bk.index(xp, m.joint_creature, device=m.device)
        self._total_mass = f(m.total_mass[:, None])

    # ------------------------------------------------------------------ state in MuJoCo layout
    def set_state(self, qpos: ArrayLike, qvel: ArrayLike) -> None:
        """Set every creature's state from MuJoCo-layout ``qpos``/``qvel`` (see ``forward_dynamics``)."""
        m, xp = self.model, self.xp
        qp, _ = flatten_layout(qpos, m.nq, "qpos")
        qv, _ = flatten_layout(qvel, m.nv, "qvel")
        pos, quat, q, lin, omega, qd = split_layout(m, qp, qv)
        f = lambda a: bk.asarray(xp, a, device=m.device)  # noqa: E731
        self.state = State(f(pos), sp.quat_canonical(xp, f(quat)), f(q), f(lin), f(omega), f(qd))
        if self.contacts is not None:
            self.contacts.reset()
        if self.limits is not None:
            self.limits.reset(m)
            self._lock = None
        self._graph = None  # the captured step reads the buffers the old state lived in

    def get_state(self) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """``(qpos, qvel)`` as lists of per-creature numpy vectors (MuJoCo layout)."""
        m, s = self.model, self.state
        n = bk.to_numpy
        qpos = join_velocity_layout(m, n(s.pos), n(s.quat), n(s.q))  # same packing, 3 + 4 + joints
        qvel = join_velocity_layout(m, n(s.lin), n(s.omega), n(s.qd))
        oq = np.r_[0, np.cumsum(m.nq)]
        ov = np.r_[0, np.cumsum(m.nv)]
        return [qpos[oq[i] : oq[i + 1]] for i in range(m.n_creatures)], [qvel[ov[i] : ov[i + 1]] for i in range(m.n_creatures)]

    # ------------------------------------------------------------------ dynamics
    def _accel(self, pos, R, q, lin, omega, qd):
        xp, m = self.xp, self.model
        vb = sp.mv(R.mT, lin)
        tau = self.tau
        if q is not self._inertia_q:  # RKN stages 2 and 3 share positions, hence inertias
            self._inertia_q, self._inertia = q, self._inertias(q)
        if self._compiled is not None:
            lin_acc, ang_acc, qdd, need = self._compiled.accel(self._inertia, R, qd, lin, omega, tau, self._lock, self.active_contacts, self._held)
            self._force = lambda: need
            return lin_acc, ang_acc, qdd
        f_ext = v = None
        if self.active_contacts is not None:  # the step's contacts, followed through this stage
            if q is not self._poses_q:  # stages 2 and 3 share positions, hence poses
                self._poses_q, self._poses = q, forward_kinematics(m, R, pos, q)
            v = body_velocities(m, self._inertia[0], xp.concat([omega, vb], axis=1), qd)  # [0]: Xup
            f_ext = self.contacts.wrench(self.active_contacts, *self._poses, v)
        if self._lock is None:
            a0, qdd, _ = aba(m, q, qd, xp.concat([omega, vb], axis=1), tau, f_ext=f_ext, damping=self.damping, inertias=self._inertia, v=v, static=self.graph)
        else:
            a0, qdd, _, force = aba(m, q, qd, xp.concat([omega, vb], axis=1), tau, f_ext=f_ext, damping=self.damping,
                                    inertias=self._inertia, v=v, lock=self._lock, static=self.graph)  # locked joints keep their rates
            self._force = force  # the step's last evaluation is what the limits remember
        if self._held is not None:  # the contacts held in every stage, at the stage's poses
            a0, qdd = self.contact_forces.force(self, self._held, a0, qdd, forward_kinematics(m, R, pos, q))
        lin_acc = sp.mv(R, a0[:, 3:] + sp.cross3(xp, omega, vb))
        return lin_acc, a0[:, :3], qdd

    def _integrate(self, s: State, t: float) -> State:
        """One (sub-)step of the integrator from ``s`` (compiled whole with ``compiled`` and RKN)."""
        if self._compiled is None or self.integrator != "rkn":
            return step(self.xp, s, self.h, self._accel, self.integrator, t)
        held = self._inertia if self._inertia_q is s.q else None
        new, need = self._compiled.step(s, self.h, self.tau, self._lock, self.active_contacts, held, self._held)
        self._force, self._inertia_q = (lambda: need), None
        return new

    def _rotations(self, quat):
        """(C, 3, 3) the roots' rotation matrices (numpy's or the compiled ones)."""
        return sp.quat_to_mat(self.xp, quat) if self._compiled is None else self._compiled.rotations(quat)

    def _inertias(self, q):
        """The articulated inertias at ``q`` with the current locks (numpy's or the compiled ones)."""
        if self._compiled is not None:
            return self._compiled.inertias(q, self._lock)
        return articulated_inertias(self.model, q, self._lock, self.graph)

    def _rows(self, R0, p0, q):
        """Every body's world pose, component-major (:func:`~.jcalc.poses_rows`)."""
        return poses_rows(self.model, R0, p0, q) if self._compiled is None else self._compiled.poses_rows(R0, p0, q)

    def _impulse(self, change, wrench=None, forces=False):
        """The response to ``change`` of the locked joints' rates and to the bodies' impulses ``wrench``, from rest."""
        if self._compiled is not None:
            return self._compiled.impulse(self._inertia, self._lock, change, wrench, forces)
        return impulse(self.model, self._inertia, self._lock, change, self.graph, wrench, forces)

    def sensors(self, native: bool = False) -> tuple[Any, Any, Any]:
        """What the creatures' sensors read now, in the layout controllers take.

        Returns ``(joint_angle, joint_velocity, contact)``: angles (M,) in user joint order, a
        hinge's wrapped to [-pi, pi); joint rates (M,); contact (total_bodies, 6) in {-1, +1} per
        box face -x, +x, -y, +y, -z, +z, as the last step's contact pass saw them (-1 everywhere
        with contacts off or before the first step). numpy arrays; with ``native`` arrays of the
        world's backend, left on its device (what the creatures' own brains read on torch).
        """
        xp, m, s = self.xp, self.model, self.state
        if self._sensed is None:
            revolute = m.joint_type_np[m.joint_order] == REVOLUTE
            self._sensed = (bk.index(xp, m.joint_order, device=m.device), bk.index(xp, m.order, device=m.device),
                            bk.asarray(xp, revolute, dtype=xp.bool, device=m.device))
        user, order, revolute = self._sensed
        q = s.q[user]
        q = xp.where(revolute, xp.remainder(q + math.pi, 2 * math.pi) - math.pi, q)
        contact = xp.full((m.n_bodies, 6), -1.0, dtype=xp.float64, device=m.device)
        if self.contact_sensors is not None:
            contact[order] = self.contact_sensors
        sensed = (q, s.qd[user], contact)
        return sensed if native else tuple(bk.to_numpy(a) for a in sensed)

    def set_effectors(self, effector: ArrayLike) -> None:
        """Joint forces from effector outputs (M,) in user joint order: ``strength * clip(gain * e, -1, 1)``.

        ``gain * e`` is the muscle's activation: at +-1 and beyond the effector pulls with its full
        strength (:func:`~coursekit.creatures.body.effector_strength`).
        """
        xp, m = self.xp, self.model
        e = bk.asarray(xp, effector, device=m.device)
        if tuple(e.shape) != (m.n_joints,):
            raise ValueError(f"effector: expected shape ({m.n_joints},), got {tuple(e.shape)}")
        e_int = xp.zeros_like(e)
        if self._user_order is None:
            self._user_order = bk.index(xp, m.joint_order, device=m.device)
        e_int[self._user_order] = e
        e_int = xp.where(xp.isfinite(e_int), e_int, xp.zeros_like(e_int))
        self.tau = self.strength * xp.clip(self.gain * e_int, -1.0, 1.0)

    @property
    def diverged(self) -> np.ndarray:
        """(C,) bool: the creatures the guards froze (numpy; with ``graph`` read from the device)."""
        return bk.to_numpy(self._diverged) if self.graph else self._diverged

    def step(self) -> None:
        """Advance the whole batch by ``dt``."""
        if self.graph and self._graph_failed is None and self.GRAPH.applies(self):
            self._graph_step()
        else:
            self._advance()
        self.time += self.dt

    def _advance(self) -> None:
        xp, m = self.xp, self.model
        if self.graph:  # frozen creatures feel no joint forces
            self.tau = xp.where(xp.take(self._diverged, self._joint_creature, axis=0), 0.0, self.tau)
        elif self._diverged.any():
            jfrozen = xp.take(bk.asarray(xp, self._diverged, dtype=xp.bool, device=m.device), self._joint_creature, axis=0)
            self.tau = xp.where(jfrozen, xp.zeros_like(self.tau), self.tau)
        for i in range(self.substeps):
            if self.limits is not None and m.n_joints and self._lock is None:  # the first step, or a state set from outside
                self.state = self._stop_at_limits(self.state)
            if self.contacts is not None:
                s = self.state
                rows = self._rows(self._rotations(s.quat), s.pos, s.q) if self.contacts.n_pairs else None
                self.active_contacts, self.contact_sensors = self.contacts.begin(s, rows)
                if self.active_contacts is not None and self._compiled is None:  # the first stage's poses (it passes s.q on)
                    self._poses_q, self._poses = s.q, pose_stacks(xp, rows)
                self._held = self.contact_forces.hold(self, s, rows) if self.contact_forces and self.contacts.n_pairs else None
            prev = self.state
            new = self._guard(prev, self._integrate(prev, self.time + i * self.h))
            if self._lock is not None:
                self.limits.end(self._force(), self.tau)
                new = self._stop_at_limits(new)
                over = self.limits.beyond if i == 0 else xp.maximum(over, self.limits.beyond)
            self.state = new
        if self._lock is not None:
            self.overshoot = over

    # ------------------------------------------------------------------ the step as a CUDA graph
    #: Graph-ready steps run eagerly, on a side stream, before the capture (as torch asks).
    GRAPH_WARMUP = 3
    #: The recorder of graph-ready steps (a test puts an emulation of graph semantics in its place).
    GRAPH = CudaGraph

    def _carried(self) -> list:
        """What a step hands the next, as ``(get, set)`` pairs: the state, the joint forces, the
        guards' flags, the locks and what the limits remember, the inertias the next step reuses."""
        slot = lambda owner, name: (lambda: getattr(owner, name), lambda v: setattr(owner, name, v))  # noqa: E731
        slots = [slot(self.state, f) for f in ("pos", "quat", "q", "lin", "omega", "qd")]
        slots += [slot(self, name) for name in ("tau", "_diverged", "_lock", "overshoot", "contact_sensors")]
        if self.contacts is not None:  # the contacts held, with their anchors
            slots += [(lambda k=k: self.contacts.anchor[k], lambda v, k=k: self.contacts.anchor.__setitem__(k, v))
                      for k in ("on", "depth", "xa", "xb", "n")]
        if self.limits is not None:  # with limits the next step's first stage reuses the inertias
            slots += [slot(self.limits, name) for name in ("push", "lock", "target", "beyond", "up")]
            slots += [(lambda k=k: self._inertia[k], lambda v, k=k: setattr(self, "_inertia", self._inertia[:k] + (v,) + self._inertia[k + 1 :]))
                      for k, v in enumerate(self._inertia) if v is not None]
        return [(get, put) for get, put in slots if get() is not None]

    def _graph_step(self) -> None:
        """One graph-ready step through a recorded graph (:attr:`GRAPH`): a few eager steps
        first, then one capture, replayed; its inputs and outputs are fixed buffers.

        Before each replay, a buffer whose attribute was set from outside (``set_effectors``
        gives ``tau`` a new tensor) takes the new value; the captured step copies what it hands
        the next step back into the buffers it read them from. A capture the device refuses (an
        operation CUDA cannot record) is undone: the world warns and steps eagerly from then on
        (``_graph_failed`` says why), with the same results.
        """
        if self._graph is not None:
            graph, slots, buffers = self._graph
            for (get, put), buf in zip(slots, buffers):
                value = get()
                if value is not buf:
                    buf.copy_(value)
                    put(buf)
            graph.replay()
            return
        limits = self.limits is not None
        if self._eager_steps < self.GRAPH_WARMUP or (limits and (self._lock is None or self.state.q is not self._inertia_q)):
            self.GRAPH.warm(self, self._advance)
            self._eager_steps += 1
            return
        slots = self._carried()
        owners = [o for o in (self, self.limits, self.contacts) if o is not None]
        before = [(o, dict(vars(o))) for o in owners]  # to undo a capture that fails
        originals = [get() for get, _ in slots]
        buffers = [t.clone() for t in originals]  # fresh buffers: no carried tensor may alias a constant
        for (_, put), buf in zip(slots, buffers):
            put(buf)
        self._inertia_q = self.state.q if limits else None  # without limits the first stage computes them

        def record():
            self._advance()
            outs = [get() for get, _ in self._carried()]
            mine = {id(b) for b in buffers}
            outs = [o.clone() if id(o) in mine and o is not b else o for o, b in zip(outs, buffers)]
            for o, b in zip(outs, buffers):
                if o is not b:
                    b.copy_(o)

        graph = self.GRAPH(self)
        try:
            graph.capture(record)
        except RuntimeError as e:  # an operation the device would not record: step eagerly from now on
            for o, attributes in before:  # the capture's Python ran part of a step that never happened
                vars(o).clear()
                vars(o).update(attributes)
            for (_, put), t in zip(slots, originals):
                put(t)
            self._graph_failed = f"{type(e).__name__}: {e}"
            warnings.warn(f"graph: the step could not be captured as a CUDA graph ({self._graph_failed}); "
                          "it runs eagerly, with the same results", RuntimeWarning, stacklevel=3)
            self._advance()
            return
        slots = self._carried()  # the capture bound the attributes to its own outputs: back to the buffers
        for (_, put), buf in zip(slots, buffers):
            put(buf)
        self._inertia_q = self.state.q if limits else None
        self._graph = (graph, slots, buffers)
        graph.replay()  # a capture records the step without running it

    def _stop_at_limits(self, s: State) -> State:
        """Lock the joints at their limits for the next step, stop them there (a lock whose stop
        does work is released, :meth:`~.limits.Limits.release`), and put those the step carried beyond
        their limits back on them (:meth:`_put_back`; :mod:`~coursekit.creatures.physics.limits`).

        Both are impulses through the articulated inertia (:func:`~.aba.impulse`): the locked
        joints change as prescribed and the root and the free joints respond. The stop is a
        velocity change (exactly momentum-conserving), the projection a displacement. The
        inertias, at the pose it ends in, are those the next step's first stage reuses.
        """
        xp = self.xp
        if self._compiled is not None:
            self._lock, at, rate = self._compiled.limits(self.limits, s.q, s.qd, self.tau)
        else:
            self._lock, at = self.limits.begin(s.q, s.qd, self.tau)
            rate = self.limits.rate(at, s.qd)
        for k in range(self.limits.ROUNDS):  # the stops, solved again while a lock does work (the last round keeps them)
            self._inertia = self._inertias(s.q)
            dv0, dqd, force = self._impulse(rate - s.qd, forces=True)
            released = self.limits.release(force, s.qd, rate) if k + 1 < self.limits.ROUNDS else None
            if released is None or not (self.graph or released.any()):  # graph-ready: every round, no look at the host
                break
            self._lock = self.limits.lock
        R = self._rotations(s.quat)
        new = State(s.pos, s.quat, s.q, s.lin + sp.mv(R, dv0[:, 3:]), s.omega + dv0[:, :3], xp.where(self._lock, rate, s.qd + dqd))
        if self.graph or bool(xp.any(at != s.q)):  # a joint to put back; with none the sweep would move nothing, bit for bit
            new = self._put_back(s, R, at, new)
            self._inertia = self._inertias(new.q)  # the next step starts from the pose put back
        self._inertia_q = new.q
        return new

    def _put_back(self, s: State, R, at, stopped: State) -> State:
        """The projection: the joints beyond their limits are put back ``at`` them, the root and
        the free joints move as that impulse would move them, and the creatures that moved keep
        their centre of mass and their momentum exactly. The impulse keeps the centre of mass to
        first order only, and the rates of ``stopped`` (the stop's, at the pose before) carry
        another momentum at the pose after: both rests are drifts a creature could swim on in a
        vacuum (evolution found them), so the root takes them back -- a shift, and a rigid velocity
        of the whole body that restores the linear and the angular momentum. Only the creatures
        that had a joint to put back change: a creature's motion does not depend on its batch.
        """
        xp = self.xp
        dx0, dq = self._impulse(at - s.q)
        q = xp.where(self._lock, at, self.limits.within(s.q, s.q + dq))
        pos, quat = s.pos + sp.mv(R, dx0[:, 3:]), sp.quat_mul(xp, s.quat, sp.quat_exp(xp, dx0[:, :3]))  # the next step normalises
        R1 = self._rotations(quat)
        com, h0, _ = self._mass_properties(R, s.pos, s.q, s.lin, s.omega, s.qd, None if self._compiled else self._inertia[0])
        com1, h1, Ic = self._mass_properties(R1, pos, q, stopped.lin, stopped.omega, stopped.qd)
        shift = com - com1  # the whole body moves by it: the linear momentum stays, the angular one about the origin gains shift x P
        pos = pos + shift
        h1 = xp.concat([h1[:, :3], h1[:, 3:] + sp.cross3(xp, shift, h1[:, :3])], axis=1)
        # a rigid velocity (w, u) about the centre of mass adds (M u, Ic w) to the momentum about it
        dh = h0 - h1
        dP = dh[:, :3]
        dL = dh[:, 3:] - sp.cross3(xp, com, dP)  # about the centre of mass (com is the same before and after)
        w = bk.solve(xp, Ic, dL, self.graph)
        lin = stopped.lin + dP / self._total_mass + sp.cross3(xp, w, pos - com)
        omega = stopped.omega + sp.mv(R1.mT, w)
        moved = self._per_creature_any(at != s.q)
        keep = lambda a, b: xp.where(moved[:, None] if a.ndim > 1 else xp.take(moved, self._joint_creature, axis=0), a, b)  # noqa: E731
        return State(keep(pos, s.pos), keep(quat, s.quat), keep(q, s.q), keep(lin, stopped.lin), keep(omega, stopped.omega), stopped.qd)

    def _per_creature_any(self, joint_mask):
        """(C,) bool: does any of a creature's joints have ``joint_mask`` set (backend array)."""
        xp, m = self.xp, self.model
        if bk.is_torch(xp):
            n = xp.zeros((m.n_creatures,), dtype=xp.float64, device=m.device)
            bk.scatter_add(xp, n, self._joint_creature, joint_mask.to(xp.float64))
            return n > 0
        return np.bincount(m.joint_creature, weights=joint_mask, minlength=m.n_creatures) > 0

    def _guard(self, prev: State, new: State) -> State:
        xp, m = self.xp, self.model
        if self._compiled is not None:
            badC = self._compiled.diverged(new, self.caps)
        else:
            vmax, wmax, qmax = self.caps
            # a NaN or infinite speed fails its cap (every comparison with NaN is false): only the
            # positions need their own finiteness test
            ok = xp.all(xp.isfinite(xp.concat([new.pos, new.quat], axis=1)), axis=1)
            ok = ok & (xp.sum(new.lin * new.lin, axis=1) <= vmax**2) & (xp.sum(new.omega * new.omega, axis=1) <= wmax**2)
            jbad = ~(xp.isfinite(new.q) & (xp.abs(new.qd) <= qmax))
            if m.n_joints:
                ok = ok & ~self._per_creature_any(jbad)
            badC = ~ok
        if self.graph:  # no look at the host: the picks below keep the good creatures' rows as they are
            self._diverged = self._diverged | badC
        else:
            bad = bk.to_numpy(badC)
            if not bad.any():
                return new
            self._diverged |= bad
        badJ = badC[self._joint_creature]
        pick = lambda mask, a, b: xp.where(mask[:, None] if a.ndim > 1 else mask, b, a)  # noqa: E731
        zc, zj = xp.zeros_like(new.lin), xp.zeros_like(new.qd)
        return State(
            pick(badC, new.pos, prev.pos),
            pick(badC, new.quat, prev.quat),
            pick(badJ, new.q, prev.q),
            pick(badC, new.lin, zc),
            pick(badC, new.omega, zc),
            pick(badJ, new.qd, zj),
        )

    # ------------------------------------------------------------------ observables
    def body_poses(self) -> tuple[Any, Any]:
        """World rotations (N, 3, 3) and positions (N, 3) of all bodies (internal order)."""
        s = self.state
        return forward_kinematics(self.model, self._rotations(s.quat), s.pos, s.q)

    def body_velocities(self) -> Any:
        """Body-frame spatial velocities (N, 6) of all bodies (internal order)."""
        xp, m, s = self.xp, self.model, self.state
        R0 = self._rotations(s.quat)
        E, r = joint_transforms(m, s.q)
        return body_velocities(m, sp.transform_matrix(xp, E, r), xp.concat([s.omega, sp.mv(R0.mT, s.lin)], axis=1), s.qd)

    def centre_of_mass(self, native: bool = False) -> Any:
        """(C, 3) centre of mass of every creature (numpy; with ``native`` an array of the
        world's backend, left on its device)."""
        s = self.state
        com = self._com(self._rotations(s.quat), s.pos, s.q)
        return com if native else bk.to_numpy(com)

    def _com(self, R0, p0, q):
        """(C, 3) centre of mass of every creature at root pose ``(R0, p0)`` and joints ``q`` (backend array)."""
        return self._com_rows(self._rows(R0, p0, q))

    def _com_rows(self, rows):
        """(C, 3) centres of mass from the component-major poses of :func:`~.jcalc.poses_rows`."""
        m = self.model
        return m.segment_sum((rows[1] * m.mass).T) / self._total_mass

    def _mass_properties(self, R0, p0, q, lin, omega, qd, X=None):
        """``(com (C, 3), h (C, 6), Ic (C, 3, 3))``: every creature's centre of mass, momentum
        (:meth:`_momentum`) and rotational inertia about its centre of mass at this pose and
        these rates (``X``: the joint transforms at ``q``, if known)."""
        if self._compiled is not None:
            return self._compiled.mass_properties(R0, p0, q, lin, omega, qd)
        rows = self._rows(R0, p0, q)
        com = self._com_rows(rows)
        X = joint_transform_matrices(self.model, q) if X is None else X
        return com, self._momentum(rows, X, R0, lin, omega, qd), self._composite_inertia(rows, com)

    def _momentum(self, rows, X, R0, lin, omega, qd):
        """(C, 6) world linear momentum and angular momentum about the world origin, at the poses
        ``rows`` (:func:`~.jcalc.poses_rows`) with joint transforms ``X`` and the given rates."""
        xp, m = self.xp, self.model
        v = body_velocities(m, X, xp.concat([omega, sp.mv(R0.mT, lin)], axis=1), qd)
        vt, I = v.T, m.inertia_diag.T
        R, p = rows
        P = xp.sum(R * (I[3:] * vt[3:])[None], axis=1)  # (3, N) world: R (m u)
        L = xp.sum(R * (I[:3] * vt[:3])[None], axis=1) + sp.cross3(xp, p, P, axis=0)
        return m.segment_sum(xp.concat([P, L], axis=0).T)

    def _composite_inertia(self, rows, com):
        """(C, 3, 3) rotational inertia of every creature about its centre of mass ``com`` (world)."""
        xp, m = self.xp, self.model
        R, p = rows
        d = p - xp.take(com, m.body_creature, axis=0).T  # (3, N)
        RI = R * m.inertia_diag.T[:3][None]  # R diag(I)
        Ib = xp.sum(RI[:, None] * R[None], axis=2)  # (3, 3, N): R diag(I) R'
        Ib = Ib + m.mass * (xp.sum(d * d, axis=0) * self._eye3 - d[:, None] * d[None])  # parallel axes
        return xp.reshape(m.segment_sum(xp.reshape(Ib, (9, -1)).T), (-1, 3, 3))

    def kinetic_energy(self) -> np.ndarray:
        """(C,) kinetic energy of every creature (numpy)."""
        v = self.body_velocities()
        return bk.to_numpy(self.model.segment_sum(0.5 * self.xp.sum(v * v * self.model.inertia_diag, axis=1)))

    def momentum(self) -> tuple[np.ndarray, np.ndarray]:
        """(C, 3) world linear momentum and (C, 3) angular momentum about the world origin (numpy)."""
        xp, m = self.xp, self.model
        R, p = self.body_poses()
        v = self.body_velocities()
        I = m.inertia_diag
        lin = sp.mv(R, I[:, 3:] * v[:, 3:])
        ang = sp.mv(R, I[:, :3] * v[:, :3]) + sp.cross3(xp, p, lin)
        return bk.to_numpy(m.segment_sum(lin)), bk.to_numpy(m.segment_sum(ang))
