"""Self-collisions: oriented-bounding-box separating-axis tests, penalty forces, contact sensors.

Paper section 2.4 (Sims 1994 section 4 and 3.1). Every pair of boxes of the same creature that
are not joined directly (not parent and child) and do not already overlap in the creature's rest
pose (those are fused; see :class:`Contacts`) is tested: first their bounding spheres (broad
phase), then the 15 separating axes of two oriented boxes (3 + 3 face normals and 9 edge-edge
cross products). A pair whose projections overlap on every axis is in contact; the axis of least
overlap gives the contact normal ``n`` (pointing from box A to box B) and the penetration depth
``delta``. The contact point is the midpoint of A's deepest vertex along ``n`` and B's deepest
vertex along ``-n`` (exact for vertex-face contacts; for an edge or a face, whose points are
equally deep, the centre of that edge or face is used).

Response is a penalty spring-damper along ``n``, ``f = max(0, k delta - c v_n)``, pushing B along
``+n`` and A along ``-n``; ``k = m_red w^2`` and ``c = 2 m_red w`` (critical)
use the pair's reduced mass; the spring's depth is capped at :data:`DEPTH_CAP` of the thinner
box's smallest half extent, so the force stays bounded; and ``w = CONTACT_STIFFNESS_PER_STEP / dt``.
Pairs are detected once per step; a contact is anchored when first found (its spring relaxed
there: ``delta`` is the penetration since first touch) and followed through the integrator's
stages and the following steps until it releases (:meth:`Contacts.begin`,
:meth:`Contacts.wrench`), so the force is a smooth function of the state, the gradient of one
spring energy per contact, and a contact can only take energy. Holding the start-of-step force
over the step instead (an explicit, first-order treatment) let passive creatures thrown into
themselves gain up to 16 % energy in 3 s -- an energy leak evolution would find (Sims'
"clacking" exploit). The springs are soft enough for an explicit step, too soft to stop a fast
part: each creature's nearest pairs are also held as constraints
(:mod:`~coursekit.creatures.physics.contact_forces`, which finds pairs with this module's test and a
margin). Sensors: a face is touching (+1) when it is the face of its box whose
outward normal is closest to the contact direction, otherwise -1 (Sims' per-face contact
sensors).
"""

from __future__ import annotations

import numpy as np

from . import backend as bk
from . import spatial as sp
from .jcalc import forward_kinematics, pose_stacks, poses_rows

#: Default ``dt * w`` of the contact springs (see the module docstring).
CONTACT_STIFFNESS_PER_STEP = 0.1


def _sign(xp, x, tol=1e-9):
    """Sign with a dead band: a box axis (nearly) perpendicular to the normal gives the face centre."""
    return xp.where(xp.abs(x) < tol, xp.zeros_like(x), xp.sign(x))


def _face(xp, R, direction):
    """The face of each box (rotations ``R``) whose outward normal is closest to ``direction``
    (world): 0-5 for -x, +x, -y, +y, -z, +z (the contact sensors)."""
    dl = sp.mtv(R, direction)  # the direction in the box frame
    k = xp.argmax(xp.abs(dl), axis=1)
    return 2 * k + xp.astype(xp.take_along_axis(dl, k[:, None], axis=1)[:, 0] > 0, k.dtype)


#: Overlaps (m) this close count as equal when choosing the contact's axis: the first of them, in the
#: order A's faces, B's faces, edge pairs, so that backends that round differently find one normal.
TIE = 1e-12

#: The spring stretches at most this fraction of the thinner box's smallest half extent: parts
#: that start deeply interpenetrated (overlapping siblings) are pushed apart with bounded force.
DEPTH_CAP = 0.5


class Contacts:
    """Self-collision detection and response for a packed model.

    Args:
        model: packed :class:`~coursekit.creatures.physics.model.Model`.
        stiffness: contact frequency ``w`` (rad/s); default ``CONTACT_STIFFNESS_PER_STEP / dt``.
        dt: the (sub)step the forces are held over.
        static: the graph-ready formulation (:class:`~coursekit.creatures.physics.world.World`
            with ``graph=True``): every candidate pair is tested and followed every step, with a
            mask for those in contact, instead of the list of touching pairs, whose length is
            data read on the host. The same contacts and forces, up to the order in which a
            body's contact forces are summed.
    """

    def __init__(self, model, *, stiffness: float | None = None, dt: float = 1.0 / 60.0, static: bool = False):
        self.model = m = model
        self.static = static
        xp = self.xp = m.xp
        w = CONTACT_STIFFNESS_PER_STEP / dt if stiffness is None else float(stiffness)
        if not (np.isfinite(w) and w > 0):
            raise ValueError(f"contact_stiffness: must be a positive frequency (rad/s), got {stiffness}")
        a_list, b_list = [], []
        par = m.part_parent_np  # parts joined by a joint (through a multi-DOF joint's massless frames) never collide
        for c in range(m.n_creatures):
            idx = np.flatnonzero((m.creature == c) & ~m.massless_np)  # massless frames touch nothing
            if len(idx) < 3:
                continue
            ia, ib = np.triu_indices(len(idx), k=1)
            a, b = idx[ia], idx[ib]
            adjacent = (par[a] == b) | (par[b] == a)
            a_list.append(a[~adjacent])
            b_list.append(b[~adjacent])
        a = np.concatenate(a_list) if a_list else np.zeros(0, np.int64)
        b = np.concatenate(b_list) if b_list else np.zeros(0, np.int64)
        self.half_extents = m.half_extents
        self.half_t = bk.asarray(xp, m.half_extents_np.T, device=m.device)  # (3, N)
        # rows of the edge-edge axes (i, j) = (k // 3, k % 3), i1 = i + 1, i2 = i + 2 (mod 3)
        I, J = np.repeat(np.arange(3), 3), np.tile(np.arange(3), 3)
        I1, I2, J1, J2 = (I + 1) % 3, (I + 2) % 3, (J + 1) % 3, (J + 2) % 3
        rows = (3 * I1 + J, 3 * I2 + J, 3 * I + J1, 3 * I + J2, I1, I2, J1, J2)
        self._edge_rows = tuple(bk.index(xp, k, device=m.device) for k in rows)
        self.held = None  # contacts touching at the end of the last step, with their anchors
        self.anchor = None  # static: every pair's anchors and whether it touches (``on``)
        self.compiled = None  # the compiled step's begin(R, p, held) -> (found, sensors), if set
        self._set_pairs(a, b, w)
        # Parts that interpenetrate in the creature's own rest pose are fused, not colliding: a
        # deep overlap has no meaningful normal (the axis of least overlap flips as the parts
        # move), so its penalty force is not conservative and pumps energy into the creature.
        if len(a):
            C = m.n_creatures
            eye = xp.zeros((C, 3, 3), dtype=xp.float64, device=m.device) + bk.asarray(xp, np.eye(3), device=m.device)
            R, p = forward_kinematics(m, eye, xp.zeros((C, 3), dtype=xp.float64, device=m.device),
                                      xp.zeros((m.n_joints,), dtype=xp.float64, device=m.device))
            fused = np.zeros(len(a), dtype=bool)
            fused[bk.to_numpy(self.detect(R, p)[0])] = True
            self.n_fused = int(fused.sum())
            self._set_pairs(a[~fused], b[~fused], w)
        else:
            self.n_fused = 0
        self.reset()

    def _set_pairs(self, a, b, w):
        """Candidate pairs ``(a, b)`` (numpy body indices) and their spring gains at frequency ``w``."""
        xp, m = self.xp, self.model
        self.n_pairs = len(a)
        self.a, self.b = bk.index(xp, a, device=m.device), bk.index(xp, b, device=m.device)
        mass = m.mass_np
        m_red = mass[a] * mass[b] / (mass[a] + mass[b]) if len(a) else np.zeros(0)
        self.k = bk.asarray(xp, m_red * w * w, device=m.device)
        self.c = bk.asarray(xp, 2.0 * m_red * w, device=m.device)
        h_min = m.half_extents_np.min(axis=1)
        self.depth_cap = bk.asarray(xp, DEPTH_CAP * np.minimum(h_min[a], h_min[b]), device=m.device)
        radius = np.linalg.norm(m.half_extents_np, axis=1)
        self.reach2 = bk.asarray(xp, (radius[a] + radius[b]) ** 2, device=m.device)  # bounding spheres

    def detect(self, R, p):
        """Colliding pairs among the candidates.

        Args:
            R, p: (N, 3, 3) world rotations and (N, 3) positions of all bodies.

        Returns:
            ``(pair, a, b, normal, depth, point)``: candidate-pair index, body indices, unit
            normals from A to B (world), penetration depths and contact points (world) of the
            pairs in contact.
        """
        xp = self.xp
        N = p.shape[0]
        return self._detect_rows(bk.contiguous(xp, xp.reshape(R, (N, 9)).T), bk.contiguous(xp, p.T))

    def _detect_rows(self, Rt, pt, margin=None):
        """:meth:`detect` on component-major poses: ``Rt`` (9, N), ``Rt[3k + i]`` = component k of
        box axis i (``R[:, k, i]``), and ``pt`` (3, N). Component-major (k, n) rows throughout:
        numpy gathers and multiplies contiguous rows fast.

        ``static``: every candidate pair, returned with a mask of those in contact (``pair`` is
        then that (P,) bool mask); the others' normals, depths and points are left as they come.
        """
        xp = self.xp
        a, b = self.a, self.b
        d = xp.take(pt, b, axis=1) - xp.take(pt, a, axis=1)
        gap = 0.0 if margin is None else margin  # (P,): pairs this close count (speculative contacts, depth > -gap)
        spheres = xp.sum(d * d, axis=0) < (self.reach2 if margin is None else (xp.sqrt(self.reach2) + margin) ** 2)
        if self.static:
            sel = None
        else:
            sel = xp.nonzero(spheres)[0]
            a, b, d = a[sel], b[sel], xp.take(d, sel, axis=1)
            if margin is not None:
                gap = xp.take(margin, sel, axis=0)
        n = a.shape[0]
        A, B = xp.reshape(xp.take(Rt, a, axis=1), (3, 3, n)), xp.reshape(xp.take(Rt, b, axis=1), (3, 3, n))  # [component, axis]
        # the 15 axes in A's frame (Gottschalk et al. 1996): Rm[3i + j] = A_i . B_j, t = d in A's frame
        Rm = xp.reshape(xp.sum(A[:, :, None] * B[:, None], axis=0), (9, n))
        Am = xp.abs(Rm)
        t = xp.sum(A * d[:, None], axis=0)
        hA, hB = xp.take(self.half_t, a, axis=1), xp.take(self.half_t, b, axis=1)
        A3, R3 = xp.reshape(Am, (3, 3, n)), xp.reshape(Rm, (3, 3, n))
        faces = xp.concat([hA + xp.sum(A3 * hB[None], axis=1) - xp.abs(t),
                           xp.sum(A3 * hA[:, None], axis=0) + hB - xp.abs(xp.sum(R3 * t[:, None], axis=0))], axis=0)
        # a face axis separates most pairs whose spheres overlap (about 3 in 4 in an evolved
        # population): the 9 edge axes, the dearer part, are tested on the others only
        if not self.static:
            near = xp.nonzero(xp.min(faces, axis=0) > -gap)[0]
            a, b, sel = a[near], b[near], sel[near]
            if margin is not None:
                gap = xp.take(gap, near, axis=0)
            d, A, B, Rm, Am, t, hA, hB, faces = (xp.take(x, near, axis=-1) for x in (d, A, B, Rm, Am, t, hA, hB, faces))
        i1j, i2j, ij1, ij2, I1, I2, J1, J2 = self._edge_rows
        len_e = xp.sqrt(xp.clip(1.0 - Rm * Rm, 0.0, None))  # |A_i x B_j|
        valid = len_e > 1e-6  # parallel edges: the face axes already decide
        over_e = (
            hA[I1] * Am[i2j] + hA[I2] * Am[i1j] + hB[J1] * Am[ij2] + hB[J2] * Am[ij1]
            - xp.abs(t[I2] * Rm[i1j] - t[I1] * Rm[i2j])
        ) / xp.where(valid, len_e, xp.ones_like(len_e))
        overlap = xp.concat([faces, xp.where(valid, over_e, xp.full_like(over_e, float("inf")))], axis=0)
        depth = xp.min(overlap, axis=0)
        # the first axis of least overlap, ties within TIE included (an order that round-off does not decide)
        first = xp.astype(overlap <= depth[None] + TIE, xp.float64)
        if self.static:
            hit = spheres & (depth > -gap)
            best = xp.argmax(first, axis=0)
        else:
            hit = xp.nonzero(depth > -gap)[0]
            best = xp.argmax(xp.take(first, hit, axis=1), axis=0)
            a, b, d, depth = a[hit], b[hit], xp.take(d, hit, axis=1), depth[hit]
            A, B, hA, hB = (xp.take(x, hit, axis=-1) for x in (A, B, hA, hB))
        # the normal: A's axis best (< 3), B's axis best - 3 (< 6) or A_i x B_j (best = 6 + 3i + j)
        zero = xp.zeros_like(best)
        h = best.shape[0]
        rows = xp.arange(h, device=self.model.device) if bk.is_torch(xp) else np.arange(h)
        a_ax = xp.take(xp.reshape(A, (3, 3 * h)), h * xp.where(best < 3, best, xp.where(best < 6, zero, (best - 6) // 3)) + rows, axis=1)
        b_ax = xp.take(xp.reshape(B, (3, 3 * h)), h * xp.where(best < 3, zero, xp.where(best < 6, best - 3, (best - 6) % 3)) + rows, axis=1)
        nrm = xp.where(best < 3, a_ax, xp.where(best < 6, b_ax, sp.cross3(xp, a_ax, b_ax, axis=0)))
        nrm = nrm / xp.sqrt(xp.sum(nrm * nrm, axis=0))
        nrm = xp.where(xp.sum(nrm * d, axis=0) < 0, -nrm, nrm)
        # deepest vertices: of A along +n, of B along -n
        vA = xp.take(pt, a, axis=1) + xp.sum(A * (hA * _sign(xp, xp.sum(A * nrm[:, None], axis=0)))[None], axis=1)
        vB = xp.take(pt, b, axis=1) - xp.sum(B * (hB * _sign(xp, xp.sum(B * nrm[:, None], axis=0)))[None], axis=1)
        return hit if self.static else sel[hit], a, b, bk.contiguous(xp, nrm.T), depth, bk.contiguous(xp, (0.5 * (vA + vB)).T)

    def begin(self, state, rows=None):
        """Detect the contacts of a step at its start and freeze their geometry.

        A pair still touching since the last step keeps its anchors (contact points as material
        points of each box, normal as a direction in A), so the spring of one contact is one
        potential, ``k depth^2 / 2``, from first touch to release, and it is relaxed at first touch:
        ``depth`` counts the penetration since then. Two ways of giving energy for nothing are so
        ruled out (hypothesis found both, in passive creatures thrown against themselves):
        anchoring anew every step changed the potential while the spring was loaded (+0.5 % over
        40 steps of a resting contact), and a spring loaded with the overlap found at detection
        (up to one step's approach, or more where a held contact had slid) released that energy
        (+0.15 %). The price: boxes may stay interpenetrated by the overlap they were found with.

        Args:
            state: the step's start.
            rows: optional :func:`~coursekit.creatures.physics.jcalc.poses_rows` at ``state`` (reused).

        Returns:
            ``(active, sensors)``: the frozen contact set for :meth:`wrench` (``None`` when no pair
            touches) and the (N, 6) face sensors in {-1, +1}.
        """
        xp, m = self.xp, self.model
        sensors = -xp.ones((m.n_bodies, 6), dtype=xp.float64, device=m.device)
        if self.n_pairs == 0:
            return None, sensors
        Rr, pr = poses_rows(m, sp.quat_to_mat(xp, state.quat), state.pos, state.q) if rows is None else rows
        R, p = pose_stacks(xp, (Rr, pr))
        if self.compiled is not None and not self.static:
            return self._active(*self.compiled(R, p, self.held))
        pair, a, b, n, depth, x = self._detect_rows(xp.reshape(Rr, (9, m.n_bodies)), pr)
        if self.static:
            return self._begin_static(pair, n, x, R, p, sensors)
        # a new contact's spring is relaxed at first touch (depth 0 there): the overlap it is found
        # with (at most what one step's approach covers) stays, and no energy comes from nowhere
        found = {"pair": pair, "depth": xp.zeros_like(depth), "xa": sp.mtv(R[a], x - p[a]),
                 "xb": sp.mtv(R[b], x - p[b]), "n": sp.mtv(R[a], n)}
        held = self.held
        if held is not None:
            touching = self._depth(held, R, p) > 0
            held = {k: v[touching] for k, v in held.items()}
            old = xp.zeros((self.n_pairs,), dtype=xp.bool, device=m.device)
            old[held["pair"]] = True
            new = ~xp.take(old, pair, axis=0)
            found = {k: xp.concat([held[k], v[new]]) for k, v in found.items()}
        if found["pair"].shape[0]:
            a, b = xp.take(self.a, found["pair"], axis=0), xp.take(self.b, found["pair"], axis=0)
            n = sp.mv(R[a], found["n"])
            for body, direction in ((b, -n), (a, n)):
                sensors[body, _face(xp, R[body], direction)] = 1.0
        return self._active(found, sensors)

    def _active(self, found, sensors):
        """Hold the contacts ``found`` for the next step; ``(active, sensors)`` of :meth:`begin`."""
        xp = self.xp
        if found["pair"].shape[0] == 0:
            self.held = None
            return None, sensors
        self.held = found
        pair = found["pair"]
        a, b = xp.take(self.a, pair, axis=0), xp.take(self.b, pair, axis=0)
        active = dict(found, a=a, b=b, cap=self.depth_cap[pair], k=self.k[pair], c=self.c[pair])
        return active, sensors

    def _begin_static(self, hit, n, x, R, p, sensors):
        """:meth:`begin` over every candidate pair: the anchors of the pairs still touching are
        kept, those of the new ones set, and ``on`` marks both (the others get no force)."""
        xp = self.xp
        a, b = self.a, self.b
        Ra, Rb, pa, pb = xp.take(R, a, axis=0), xp.take(R, b, axis=0), xp.take(p, a, axis=0), xp.take(p, b, axis=0)
        held = self.anchor
        touching = held["on"] & (self._depth(held, R, p) > 0)
        keep = touching[:, None]
        anchor = {"on": touching | hit, "depth": xp.where(touching, held["depth"], 0.0),
                  "xa": xp.where(keep, held["xa"], sp.mtv(Ra, x - pa)), "xb": xp.where(keep, held["xb"], sp.mtv(Rb, x - pb)),
                  "n": xp.where(keep, held["n"], sp.mtv(Ra, n))}
        self.anchor = anchor
        n = sp.mv(Ra, anchor["n"])
        touched = xp.astype(anchor["on"], sensors.dtype) * 2.0
        flat = xp.reshape(sensors, (-1,))
        for body, Rbody, direction in ((b, Rb, -n), (a, Ra, n)):
            bk.scatter_add(xp, flat, 6 * body + _face(xp, Rbody, direction), touched)  # -1 + 2 per touch, then capped at +1
        sensors = xp.clip(xp.reshape(flat, sensors.shape), None, 1.0)
        return dict(anchor, a=a, b=b, cap=self.depth_cap, k=self.k, c=self.c), sensors

    def reset(self) -> None:
        """Forget the contacts held since the last step (the state was set anew)."""
        self.held = None
        if self.static:
            xp, m, P = self.xp, self.model, self.n_pairs
            z = lambda *s: xp.zeros(s, dtype=xp.float64, device=m.device)  # noqa: E731
            self.anchor = {"on": xp.zeros((P,), dtype=xp.bool, device=m.device), "depth": z(P), "xa": z(P, 3), "xb": z(P, 3), "n": z(P, 3)}

    def _depth(self, held, R, p):
        """Penetration of the anchored contacts ``held`` at poses ``R, p`` (not capped); without
        ``held["pair"]`` (static), of every candidate pair."""
        xp = self.xp
        pair = held.get("pair")
        a, b = (self.a, self.b) if pair is None else (xp.take(self.a, pair, axis=0), xp.take(self.b, pair, axis=0))
        Ra = xp.take(R, a, axis=0)
        xa = sp.mv(Ra, held["xa"]) + xp.take(p, a, axis=0)
        xb = sp.mv(xp.take(R, b, axis=0), held["xb"]) + xp.take(p, b, axis=0)
        return held["depth"] + xp.vecdot(sp.mv(Ra, held["n"]), xa - xb)

    def wrench(self, active, R, p, v):
        """(N, 6) body-frame contact wrenches (moment about the centre of mass, force) at a stage.

        The contacts found at the step's start are followed through the step: each contact point
        moves with its box and the normal turns with box A, so the penetration
        ``depth = depth0 + n . (x_A - x_B)`` and the normal speed are smooth functions of the
        stage state and the integrator keeps its order (forces held over the whole step leak
        energy). Both boxes are pushed, equal and opposite, along ``n`` through B's contact point
        ``x_B``, and the normal speed is that of the two boxes' material points at ``x_B``: that
        force is exactly minus the gradient of the spring energy ``k depth^2 / 2`` (the normal's
        turn with A included) and ``vn = -d depth / dt``, so the contact's power is
        ``-c vn^2 <= 0`` (up to the integrator's truncation error): it can only take energy.
        (Applied at the midpoint of the two contact points, as before, it was not that gradient.)
        Linear and angular momentum are conserved exactly (one line of action).

        Args:
            active: the contact set from :meth:`begin`.
            R, p: (N, 3, 3) world rotations and (N, 3) positions of all bodies at the stage.
            v: (N, 6) body-frame spatial velocities ``(omega, v)`` of all bodies at the stage.
        """
        xp, m = self.xp, self.model
        a, b = active["a"], active["b"]
        take = lambda x, i: xp.take(x, i, axis=0)  # noqa: E731  (several times faster than x[i])
        Ra, Rb, pa, pb, v_a, v_b = take(R, a), take(R, b), take(p, a), take(p, b), take(v, a), take(v, b)
        xa = sp.mv(Ra, active["xa"]) + pa
        xb = sp.mv(Rb, active["xb"]) + pb
        n = sp.mv(Ra, active["n"])
        depth = xp.minimum(active["depth"] + xp.vecdot(n, xa - xb), active["cap"])
        # both bodies' velocities at B's point xb: vn = -d(depth)/dt exactly (n turns with A)
        xb_in_a = sp.mtv(Ra, xb - pa)
        va = sp.mv(Ra, v_a[:, 3:] + sp.cross3(xp, v_a[:, :3], xb_in_a))
        vb = sp.mv(Rb, v_b[:, 3:] + sp.cross3(xp, v_b[:, :3], active["xb"]))
        vn = xp.vecdot(vb - va, n)
        mag = xp.clip(active["k"] * depth - active["c"] * vn, 0.0, None)
        F = mag[:, None] * n
        f = xp.zeros((m.n_bodies, 6), dtype=xp.float64, device=m.device)
        body, Rw, Fw = xp.concat([b, a]), xp.concat([Rb, Ra]), xp.concat([F, -F])  # B pushed along +n
        moment = sp.cross3(xp, xp.concat([xb, xb]) - xp.concat([pb, pa]), Fw)
        wrenches = xp.concat([sp.mtv(Rw, moment), sp.mtv(Rw, Fw)], axis=1)
        if "on" in active:  # static: every pair; those not in contact push with exactly nothing, whatever their anchors hold
            on = active["on"]
            wrenches = xp.where(xp.concat([on, on])[:, None], wrenches, 0.0)
        bk.scatter_add(xp, f, body, wrenches)
        return f
