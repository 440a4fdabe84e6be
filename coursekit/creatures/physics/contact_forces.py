"""Self-contacts held as constraints: contact forces through the articulated inertia in every stage.

The penalty springs of :mod:`~coursekit.creatures.physics.contact` are smooth and internal, but an
explicit spring can only be as stiff as the step allows, and Sims-strength muscles beat it:
random creatures held their parts half inside each other (``benchmarks/contacts.py``). Here each
creature's nearest pairs are also held as constraints, like Sims' impulses for fast collisions but
inside the integrator (Featherstone 2008, chapter 11; the speculative contacts of game engines):

1. *Pairs found before they touch.* At the start of every (sub-)step the separating-axis test of
   :class:`~.contact.Contacts` runs with a margin: half the thinner part's thickness, or what the
   parts' speeds close in 1.5 steps (a paddle closes 50 mm in one step at 60 steps a second).
   Each creature's :data:`CAP` pairs that their speeds would bring deepest by the step's end take
   its *slots*.
2. *Responses.* Each slot's unit force -- B pushed along the normal ``n`` at the contact point, A
   pulled back -- swept through the articulated inertia with the step's locks (the joints held at
   their limits pass it on whole) gives the creature's acceleration per unit force, and its effect
   on every held pair's normal acceleration: the Delassus matrix ``D = J M^-1 J'`` (C, K, K). One
   sweep per slot, over the creatures holding that many pairs.
3. *Forces in every stage.* Each stage of the integrator solves ``f >= 0`` with ``J a + D f >=
   -(gap + v_n h) / h^2`` and ``f . (J a + D f + ...) = 0`` (a linear complementarity problem,
   projected Gauss-Seidel): at the step's end a pair approaches no faster than would close its gap
   in a step (the velocity-level speculative contact, inelastic). A pair arriving faster ends the
   step at rest against the other, at most half its overshoot inside it. (Asking for the gap closed
   exactly by the step's end -- a bias twice as large -- bounces it back as fast as it came:
   passive creatures thrown into themselves gained up to 5 % energy in 2 s.) The forces act at the
   stage's own poses, equal and opposite on the two parts at one point, so they are internal there
   and the creature's momentum is kept (forces made for the step's start but applied at a later
   stage's poses are not: a creature drifted in a vacuum and swam on it). A stage's forces are
   swept through that stage's inertias.
4. *Bounds.* A contact its creature cannot open (its ``D`` under :data:`FLOOR` of its parts' free
   inverse mass: parts held rigidly together) takes no force, and no contact takes a force that
   would change a joint's rate by more than :data:`RATE` within a step: a light part pressed in a
   nearly singular pose would otherwise be given enormous forces and spin the creature apart.

What the constraints leave -- pairs beyond the cap, contacts that cannot open, depth a bound let
through -- the springs push apart as before, and the springs' contacts are the touch sensors.
Hand-written because the contacts must act through the reduced-coordinate articulated inertia the
simulator steps with: the physics libraries that solve contact LCPs (MuJoCo, Bullet) bring their
own dynamics. :mod:`~.contact_kernels` is the same, compiled; ``benchmarks/NOTES.md`` ("Self-contacts
as constraints", "Self-contacts held") has the designs tried and what each taught.
"""

from __future__ import annotations

import numpy as np

from . import backend as bk
from . import spatial as sp
from .aba import body_velocities
from .integrate import State
from .jcalc import pose_stacks

#: Pairs held per creature (one sweep through the batch each, over the creatures holding that many).
CAP = 8
#: Pairs closer than this share of the thinner part's thickness are found before they touch.
SPECULATIVE = 0.5
#: A contact whose inverse effective mass is under this share of its parts' free one cannot open.
FLOOR = 1e-2
#: The most one contact's force changes a joint's (or a root's) rate within a step (rad/s).
RATE = 10.0
#: Projected Gauss-Seidel sweeps over a creature's contacts.
ITERATIONS = 5


def pgs(xp, D, b, floor, hi, iterations: int = ITERATIONS):
    """``0 <= f <= hi`` with ``w = D f + b >= 0`` where ``f < hi``, and ``f . w = 0``, batched:
    ``D`` (C, K, K) symmetric positive semi-definite, ``b``, ``floor`` and ``hi`` (C, K). A slot
    whose diagonal is not above ``floor`` keeps ``f = 0``: an empty slot (adding exact zeros, so a
    creature's result does not depend on its batch's ``K``), or a contact its creature cannot open."""
    K = b.shape[1]
    diag = xp.stack([D[:, k, k] for k in range(K)], axis=1) if K else b
    live = diag > floor
    inv = xp.where(live, 1.0 / xp.where(live, diag, xp.ones_like(diag)), xp.zeros_like(diag))
    f, w = xp.zeros_like(b), b
    for _ in range(iterations):
        for k in range(K):
            new = xp.minimum(xp.clip(f[:, k] - w[:, k] * inv[:, k], 0.0, None), hi[:, k])
            delta = new - f[:, k]
            f[:, k] = new
            w = w + D[:, :, k] * delta[:, None]
    return f


class ContactForces:
    """The forces that hold one batch's self-contacts in every stage of a step (module docstring).

    Args:
        contacts: the world's :class:`~.contact.Contacts` (its candidate pairs and detection;
            ``static`` for the graph-ready step: every creature then takes :data:`CAP` slots).
    """

    def __init__(self, contacts, cap: int = CAP):
        self.contacts = contacts
        m = self.model = contacts.model
        xp = self.xp = m.xp
        self.cap = int(cap)
        a, b = bk.to_numpy(contacts.a).astype(np.int64), bk.to_numpy(contacts.b).astype(np.int64)
        owner = m.creature[a]
        thin = 2.0 * np.minimum(m.half_extents_np[a].min(axis=1), m.half_extents_np[b].min(axis=1))
        self.owner = bk.index(xp, owner, device=m.device)
        self.thin = bk.asarray(xp, thin, device=m.device)
        self.margin = bk.asarray(xp, SPECULATIVE * thin, device=m.device)
        self.radius = bk.asarray(xp, np.linalg.norm(m.half_extents_np, axis=1), device=m.device)
        self.floor = bk.asarray(xp, FLOOR * (1.0 / m.mass_np[a] + 1.0 / m.mass_np[b]), device=m.device)
        # each pair's creature's first pair (the static step's slots are running counts from there)
        self.first = bk.index(xp, np.searchsorted(owner, owner, side="left"), device=m.device)

    def reach(self, h, v):
        """(P,) how close a pair must be to be found: half the thinner part's thickness, or what the
        parts' speeds (body velocities ``v``) can close in 1.5 (sub-)steps ``h``, the larger."""
        xp = self.xp
        speed = xp.sqrt(xp.sum(v[:, 3:] ** 2, axis=1)) + xp.sqrt(xp.sum(v[:, :3] ** 2, axis=1)) * self.radius
        close = 1.5 * h * (xp.take(speed, self.contacts.a, axis=0) + xp.take(speed, self.contacts.b, axis=0))
        return xp.maximum(self.margin, close)

    def _found(self, rows, R, p, v, h):
        """The pairs at the poses ``rows`` (the same as ``R, p``) within their reach (bodies'
        velocities ``v``) with their slots: ``(hits, K)``, or ``(None, 0)``."""
        xp, m, c = self.xp, self.model, self.contacts
        pair, a, b, n, depth, x = c._detect_rows(xp.reshape(rows[0], (9, m.n_bodies)), rows[1], self.reach(h, v))
        hits = {"a": a, "b": b, "n": n, "x": x}
        vn = self._normal_speed(hits, R, p, v)
        ahead = depth - h * vn  # how deep the pair would be at the step's end
        if c.static:  # every candidate pair, those not found masked
            on, owner, thin, floor, K = pair, self.owner, self.thin, self.floor, self.cap
            depth, ahead, vn = xp.where(on, depth, 0.0), xp.where(on, ahead, 0.0), xp.where(on, vn, 0.0)
            n, x = xp.where(on[:, None], n, 0.0), xp.where(on[:, None], x, 0.0)
            first = self.first
        else:
            if pair.shape[0] == 0:
                return None, 0
            on = xp.ones(pair.shape, dtype=xp.bool, device=m.device)
            owner = xp.take(self.owner, pair, axis=0)
            thin, floor = xp.take(self.thin, pair, axis=0), xp.take(self.floor, pair, axis=0)
            first = bk.index(xp, np.searchsorted(bk.to_numpy(owner), bk.to_numpy(owner), side="left"), device=m.device)
        # a creature's CAP pairs deepest at the step's end (relative to the thinner part) take the
        # slots, ties in the order of the pairs
        key = xp.astype(owner, depth.dtype) * 1e6 + xp.where(on, xp.clip(-ahead / thin, -1e5, 1e5), 2e5)
        order = xp.argsort(key, stable=True) if bk.is_torch(xp) else np.argsort(key, kind="stable")
        deep = xp.zeros_like(on)
        deep[order] = (xp.arange(order.shape[0], device=m.device) if bk.is_torch(xp) else np.arange(order.shape[0])) - xp.take(first, order, axis=0) < self.cap
        taken = xp.astype(on & deep, xp.int64)
        before = xp.cumsum(taken, axis=0) - taken  # taken pairs before each
        slot = before - xp.take(before, first, axis=0)
        if not c.static:
            K = int(bk.to_numpy(slot).max()) + 1
        slot = xp.where(taken > 0, slot, K)
        hits.update(n=n, x=x, depth=depth, vn=vn, owner=owner, slot=slot, floor=floor)
        return hits, K

    def _per_slot(self, hits, K, value):
        """(C, K) ``value`` (H,) of each creature's contact in each slot (0 in empty slots)."""
        xp, C = self.xp, self.model.n_creatures
        out = xp.zeros((C * (K + 1),) + tuple(value.shape[1:]), dtype=value.dtype, device=self.model.device)
        bk.scatter_add(xp, out, hits["owner"] * (K + 1) + hits["slot"], value)
        return xp.reshape(out, (C, K + 1) + tuple(value.shape[1:]))[:, :K]

    def _per_creature_max(self, world, x):
        """(C,) the largest of each creature's joints' ``x`` (M,) (0 for a creature without joints)."""
        xp, C = self.xp, self.model.n_creatures
        if bk.is_torch(xp):
            out = xp.zeros((C,), dtype=x.dtype, device=self.model.device)
            return out.scatter_reduce(0, world._joint_creature, x, reduce="amax")
        out = np.zeros(C)
        np.maximum.at(out, world._joint_creature, x)
        return out

    def _normal_speed(self, hits, R, p, v):
        """(H,) the speed ``n . (v_B - v_A)`` at every contact point, bodies' velocities ``v`` (N, 6)."""
        xp = self.xp

        def at(body):
            Rb, vb = xp.take(R, body, axis=0), xp.take(v, body, axis=0)
            local = sp.mtv(Rb, hits["x"] - xp.take(p, body, axis=0))
            return sp.mv(Rb, vb[:, 3:] + sp.cross3(xp, vb[:, :3], local))

        return xp.vecdot(hits["n"], at(hits["b"]) - at(hits["a"]))

    def _unit_forces(self, hits, R, p):
        """``(bodies, rows)``: the body-frame wrenches (2H, 6) of every contact's unit force, B
        pushed along ``n`` at the contact point and A pulled back, and the bodies they act on."""
        xp = self.xp
        body = xp.concat([hits["b"], hits["a"]])
        F = xp.concat([hits["n"], -hits["n"]])
        Rb = xp.take(R, body, axis=0)
        moment = sp.cross3(xp, xp.concat([hits["x"], hits["x"]]) - xp.take(p, body, axis=0), F)
        return body, xp.concat([sp.mtv(Rb, moment), sp.mtv(Rb, F)], axis=1)

    def hold(self, world, s: State, rows):
        """What the step from ``s`` (its poses ``rows``, :meth:`World._rows`) needs to hold its contacts in every stage (steps 1, 2 and 4 of
        the module docstring): the pairs found with their slots, ``D``, the gap allowance and the
        bounds; ``None`` when no pair is near."""
        xp, m, h = self.xp, self.model, world.h
        R0 = world._rotations(s.quat)
        if world._inertia_q is not s.q:
            world._inertia, world._inertia_q = world._inertias(s.q), s.q
        if world._compiled is not None:
            return world._compiled.hold(self, R0, s, world._inertia, world._lock, h)
        X = world._inertia[0]
        R, p = pose_stacks(xp, rows)
        hits, K = self._found(rows, R, p, body_velocities(m, X, xp.concat([s.omega, sp.mv(R0.mT, s.lin)], axis=1), s.qd), h)
        if hits is None:
            return None
        body, unit = self._unit_forces(hits, R, p)
        columns, rate = [], []
        for k in range(K):
            f = xp.zeros((m.n_bodies, 6), dtype=unit.dtype, device=m.device)
            in_slot = xp.astype(hits["slot"] == k, unit.dtype)
            bk.scatter_add(xp, f, body, unit * xp.concat([in_slot, in_slot])[:, None])
            dv0, dqd = world._impulse(xp.zeros_like(s.qd), f)
            columns.append(self._normal_speed(hits, R, p, body_velocities(m, X, dv0, dqd)))
            rate.append(xp.maximum(xp.max(xp.abs(dv0[:, :3]), axis=1), self._per_creature_max(world, xp.abs(dqd))))
        D = xp.stack([self._per_slot(hits, K, col) for col in columns], axis=2)  # D[c, j, k]: slot j's acceleration per slot k's force
        rate = xp.stack(rate, axis=1) if K else xp.zeros((m.n_creatures, 0), dtype=unit.dtype, device=m.device)
        ahead = xp.clip(-hits["depth"], 0.0, None) + hits["vn"] * h  # v_n at the step's end closes at most the gap in a step
        Ra, Rb = xp.take(R, hits["a"], axis=0), xp.take(R, hits["b"], axis=0)
        return {"hits": hits, "K": K, "R": R, "p": p, "X": X, "D": D, "floor": self._per_slot(hits, K, hits["floor"]),
                "hi": xp.where(rate > 0, RATE / (h * xp.where(rate > 0, rate, 1.0)), float("inf")),
                "bias": self._per_slot(hits, K, ahead / h**2),
                "n_a": sp.mtv(Ra, hits["n"]), "x_b": sp.mtv(Rb, hits["x"] - xp.take(p, hits["b"], axis=0))}

    def force(self, world, held, a0, qdd, poses):
        """A stage's accelerations ``(a0, qdd)`` with the contact forces that keep the held pairs
        from closing more than their gaps (step 3 of the module docstring); ``poses``: the stage's."""
        xp, m = self.xp, self.model
        hits, K = held["hits"], held["K"]
        alpha = self._per_slot(hits, K, self._normal_speed(hits, held["R"], held["p"], body_velocities(m, held["X"], a0, qdd)))
        f = pgs(xp, held["D"], alpha + held["bias"], held["floor"], held["hi"])
        # the forces act at the stage's own poses: B pushed along n (turning with A) at B's material
        # point, A pulled back along the same line -- internal there, so the momentum is kept
        C = f.shape[0]
        f_hit = xp.take(xp.reshape(xp.concat([f, xp.zeros_like(f[:, :1])], axis=1), (C * (K + 1),)), hits["owner"] * (K + 1) + hits["slot"], axis=0)
        R, p = poses
        a, b = hits["a"], hits["b"]
        Ra, Rb = xp.take(R, a, axis=0), xp.take(R, b, axis=0)
        n = sp.mv(Ra, held["n_a"])
        x = sp.mv(Rb, held["x_b"]) + xp.take(p, b, axis=0)
        F = f_hit[:, None] * n
        body = xp.concat([b, a])
        Rw, Fw = xp.concat([Rb, Ra]), xp.concat([F, -F])
        moment = sp.cross3(xp, xp.concat([x, x]) - xp.take(p, body, axis=0), Fw)
        wrench = xp.zeros((m.n_bodies, 6), dtype=F.dtype, device=m.device)
        bk.scatter_add(xp, wrench, body, xp.concat([sp.mtv(Rw, moment), sp.mtv(Rw, Fw)], axis=1))
        da0, dqd = world._impulse(xp.zeros_like(qdd), wrench)
        return a0 + da0, qdd + dqd
