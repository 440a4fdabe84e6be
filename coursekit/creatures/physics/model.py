"""A population of body trees packed into one batch, sorted by tree depth (paper section 2.4).

All bodies of all creatures live in flat arrays. They are stored level by level -- every root
first (in creature order), then every *inner* body (one with children) of depth 1, of depth 2,
and so on, and last every leaf (bodies ``L..N-1``) -- each group sorted by parent, so each level
is one contiguous slice and the children of a level can be summed into their parents with one
segment sum. The ABA sweeps the inner levels one by one and all leaves at once (see
:mod:`~coursekit.creatures.physics.aba`). Bodies ``C..N-1`` (``C`` creatures, ``N`` bodies) are
the joints, so per-joint arrays have ``M = N - C`` rows in the same order.

Everything of a joint that depends on its coordinate ``q`` alone -- the transform ``Xup``, the
pose ``(E, r)`` and, for leaves, what they pass to their parent -- is stored as constant
coefficients of a small polynomial basis in ``q`` (the fast forms of
:mod:`~coursekit.creatures.physics.jcalc`), so evaluating it is one stacked product.

The user-facing layout (MuJoCo's, see :func:`coursekit.creatures.mjcf.to_mjcf`) lists each
creature's joints in BodyTree order; :attr:`Model.joint_order` maps between the two.
"""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np

from coursekit.creatures.body import BodyTree

from . import backend as bk
from . import jcalc
from . import spatial as sp


def validated(creature, i: int):
    """``creature`` after its own ``validate()`` (if it has one), errors prefixed ``creatures[i]``:
    a genotype may have been changed since it was built."""
    if hasattr(creature, "validate"):
        try:
            creature.validate()
        except (TypeError, ValueError) as e:
            raise type(e)(f"creatures[{i}]: {e}") from None
    return creature


def as_trees(creatures: Any) -> list[BodyTree]:
    """BodyTrees of ``creatures``: BodyTrees, or objects with ``.expand().body`` or ``.body``
    (validated first)."""
    if isinstance(creatures, BodyTree) or hasattr(creatures, "expand") or hasattr(creatures, "body"):
        creatures = [creatures]
    if isinstance(creatures, (str, bytes)) or not hasattr(creatures, "__iter__"):
        raise TypeError(f"creatures: expected a creature, a BodyTree or a list of them, got {type(creatures).__name__}")
    trees = []
    for i, c in enumerate(creatures):
        if isinstance(c, BodyTree):
            trees.append(c)
        elif hasattr(c, "expand"):
            trees.append(validated(c, i).expand().body)
        elif isinstance(getattr(c, "body", None), BodyTree):
            trees.append(c.body)
        else:
            raise TypeError(f"creatures[{i}]: expected a BodyTree or a creature with .expand(), got {type(c).__name__}")
    if not trees:
        raise ValueError("creatures: need at least one creature, got an empty list")
    return trees


class Model:
    """Constant data of a packed population, on one backend.

    Args:
        creatures: BodyTrees or creatures (see :func:`as_trees`).
        backend: "numpy" or "torch".
        device: torch device (ignored for numpy).
    """

    def __init__(self, creatures: Any, backend: str = "numpy", device: Any | None = None):
        self.trees = as_trees(creatures)
        self.backend = backend
        xp = self.xp = bk.namespace(backend)
        self.device = device
        trees = self.trees
        C = self.n_creatures = len(trees)
        sizes = np.array([t.n_bodies for t in trees])
        N = self.n_bodies = int(sizes.sum())
        self.n_joints = N - C
        self.bodies_per_creature = sizes
        first = np.r_[0, np.cumsum(sizes)[:-1]]
        creature = np.repeat(np.arange(C), sizes)
        parent = np.concatenate([np.where(t.parent >= 0, t.parent + f, -1) for t, f in zip(trees, first)])
        depth = np.concatenate([t.depth for t in trees])

        # depth-sorted order: the roots (in creature order), then the inner joints (bodies with
        # children) level by level, then every leaf; each group sorted by the parent's new position
        is_parent = np.zeros(N, dtype=bool)
        is_parent[parent[parent >= 0]] = True
        leaf = ~is_parent & (depth > 0)
        groups = [np.flatnonzero(depth == 0)]
        groups += [np.flatnonzero((depth == d) & ~leaf) for d in range(1, int(depth.max()) + 1)]
        groups = [g for g in groups if len(g)] + [np.flatnonzero(leaf)]
        order = []
        new_pos = np.full(N, -1)
        bounds = []
        for members in groups:
            if len(order):
                members = members[np.lexsort((members, new_pos[parent[members]]))]
            bounds.append((len(order), len(order) + len(members)))
            new_pos[members] = np.arange(len(order), len(order) + len(members))
            order.extend(members.tolist())
        order = np.asarray(order, dtype=np.int64)
        self.order = order  # sorted position -> packed (creature-concatenated pre-order) index
        self.position = new_pos  # packed index -> sorted position
        self.creature = creature[order]
        par = np.where(parent[order] >= 0, new_pos[np.maximum(parent[order], 0)], -1)
        self.parent = par
        L = self.leaf_start = bounds[-1][0]  # bodies L..N-1 are the leaves (joint rows L-C..M-1)
        self.n_leaves = N - L
        self.levels = []  # inner joints, by depth: (start, stop, parent positions, Segments)
        for (ps, pe), (s, e) in itertools.pairwise(bounds[:-1]):
            self.levels.append((s, e, bk.index(xp, par[s:e], device=device), bk.Segments(xp, par[s:e], (ps, pe), device=device)))
        self.leaf_parent = bk.index(xp, par[L:], device=device)
        self.joint_parent = bk.index(xp, par[C:], device=device)
        self.leaf_segments = bk.Segments(xp, par[L:], (0, L), device=device)
        self.joint_segments = bk.Segments(xp, par[C:], (0, L), device=device)  # every joint into its parent
        # joints: sorted body C + j; user layout: creature-concatenated BodyTree order (bodies 1..)
        packed_joint = np.concatenate([np.arange(f + 1, f + n) for f, n in zip(first, sizes)])
        self.joint_order = new_pos[packed_joint] - C  # user joint k -> internal joint row
        self.joints_per_creature = sizes - 1
        self.joint_creature = self.creature[C:]

        cat = lambda name: np.concatenate([getattr(t, name) for t in trees])[order]  # noqa: E731
        self.half_extents_np = cat("half_extents")
        self.massless_np = cat("massless")  # massless frames of multi-DOF joints (no water, no contacts)
        part_parent = np.concatenate([np.where(p >= 0, p + f, -1) for p, f in zip((t.part_parent() for t in trees), first)])
        self.part_parent_np = np.where(part_parent[order] >= 0, new_pos[np.maximum(part_parent[order], 0)], -1)
        mass = np.concatenate([t.mass for t in trees])[order]
        inertia = np.concatenate([t.inertia for t in trees])[order]
        self.mass_np = mass
        self.inertia_diag_np = np.concatenate([inertia, np.repeat(mass[:, None], 3, axis=1)], axis=1)  # (N, 6)
        jt = cat("joint_type")[C:]
        axis = cat("joint_axis")[C:]
        jpc = cat("joint_pos_child")[C:]
        S = jcalc.motion_subspaces(jt, axis, jpc)
        rev = jcalc.rotational(jt)
        self.joint_type_np = jt
        self.limits_np = cat("limits")[C:]
        self.gain_np = cat("gain")[C:]
        self.strength_np = cat("strength")[C:]
        self.S_np = S
        self.axis_np = axis
        self.jpp_np = cat("joint_pos_parent")[C:]
        self.joint_rot_np = cat("joint_rot")[C:]

        f = lambda a: bk.asarray(xp, a, device=device)  # noqa: E731
        self.inertia_diag = f(self.inertia_diag_np)
        self.S = f(S)
        # rolled components for the cross products of aba._velocities_and_bias
        roll1, roll2 = [1, 2, 0, 4, 5, 3], [2, 0, 1, 5, 3, 4]
        self.roll1, self.roll2 = bk.index(xp, roll1, device=device), bk.index(xp, roll2, device=device)
        self.S_roll1, self.S_roll2 = f(S.T[roll1].reshape(2, 3, -1)), f(S.T[roll2].reshape(2, 3, -1))  # (2, 3, M)
        It = self.inertia_diag_np.T
        self.euler_factor = f(np.stack([It[[2, 0, 1]] - It[[1, 2, 0]], It[3:]]))  # (2, 3, N): I2 - I1, m
        self.revolute = bk.asarray(xp, rev, dtype=xp.bool, device=device)
        consts = jcalc.rodrigues_constants(axis, self.jpp_np, jpc, self.joint_rot_np)
        # E, r and Xup are of degree one in jcalc.joint_basis(q): constant coefficients
        pose = jcalc.fit_joint_basis(rev, consts, lambda E, r: np.concatenate([E.mT.reshape(-1, 9), r], axis=1))
        self.pose_rows_basis = f(np.transpose(pose, (1, 2, 0)))  # (3, 12, M): rows of E' and r
        X_basis = jcalc.fit_joint_basis(rev, consts, lambda E, r: sp.transform_matrix(np, E, r).reshape(-1, 36))
        if bk.is_numpy(xp):
            # Xup = [[E, 0], [-E rx, E]] has 18 distinct entries: numpy streams their coefficients
            # (M, 3, 19: E, -E rx and a zero column) and gathers the 36 entries from them after
            # (see jcalc.transform_matrices); the full basis is twice the memory traffic
            block = np.arange(36).reshape(6, 6)
            self.X_basis = np.ascontiguousarray(np.concatenate(
                [X_basis[:, :, block[:3, :3].reshape(-1)], X_basis[:, :, block[3:, :3].reshape(-1)], np.zeros_like(X_basis[:, :, :1])], axis=2))
            expand = np.full((6, 6), 18)
            expand[:3, :3] = expand[3:, 3:] = np.arange(9).reshape(3, 3)
            expand[3:, :3] = 9 + np.arange(9).reshape(3, 3)
            self.X_expand = expand.reshape(-1)
        else:  # torch: (3, M, 36), rows for addcmul (see jcalc.transform_matrices)
            self.X_basis = f(np.ascontiguousarray(X_basis.transpose(1, 0, 2)))
        # leaves never change their articulated inertia: U = I S, d = S'U and Ia = I - U U'/d are
        # constants, and what a leaf passes to its parent, Xup' Ia Xup, is a fixed combination of
        # five constant matrices (degree two in jcalc.joint_basis)
        Il, Sl = self.inertia_diag_np[L:], S[L - C :]
        Ul = Il * Sl
        dl = np.sum(Sl * Ul, axis=1)
        U0, d0 = np.zeros_like(S), np.ones(N - C)
        U0[L - C :], d0[L - C :] = Ul, dl
        self.U_leaf, self.d_leaf = f(U0), f(d0)
        Ia = np.einsum("ni,ij->nij", Il, np.eye(6)) - Ul[:, :, None] * Ul[:, None, :] / dl[:, None, None]
        leaf = {name: value[L - C :] for name, value in consts.items()}

        def congruence(E, r):
            X = sp.transform_matrix(np, E, r)
            return (X.mT @ Ia @ X).reshape(-1, 36)

        leaf_P = jcalc.fit_joint_basis(rev[L - C :], leaf, congruence, k=5)
        self.leaf_P = f(leaf_P)
        # symmetric matrices are summed as their 21 upper entries (less memory to stream) and
        # expanded to 6x6 after
        upper = np.flatnonzero(np.triu(np.ones((6, 6), dtype=bool)))  # flat positions i <= j
        i, j = np.indices((6, 6))
        mirrored = np.minimum(i, j) * 6 + np.maximum(i, j)  # entry (i, j) of a symmetric matrix
        self.sym_expand = bk.index(xp, np.searchsorted(upper, mirrored).reshape(-1), device=device)
        self.leaf_P_varying = f(np.ascontiguousarray(leaf_P[:, 1:, upper]))  # terms cos q .. sin 2q (q .. q^2)
        # the rigid inertias of the roots and inner bodies, plus their leaves' constant terms
        inner = np.einsum("ni,ij->nij", self.inertia_diag_np[:L], np.eye(6))
        np.add.at(inner, par[L:], leaf_P[:, 0].reshape(-1, 6, 6))
        self.inner_inertia = f(inner.reshape(-1, 36)[:, upper])  # (L, 21)
        # and a leaf's W = Xup' U / d, of degree one
        leaf_W = jcalc.fit_joint_basis(rev[L - C :], leaf, lambda E, r: sp.mtv(sp.transform_matrix(np, E, r), Ul) / dl[:, None])
        self.leaf_W = f(np.ascontiguousarray(leaf_W.transpose(1, 0, 2)))  # (3, leaves, 6)
        self.half_extents = f(self.half_extents_np)
        self.mass = f(mass)
        self.body_creature = bk.index(xp, self.creature, device=device)
        self.by_creature = np.argsort(self.creature, kind="stable")
        self.creature_start = np.r_[0, np.cumsum(sizes)[:-1]]
        self.total_mass = np.bincount(self.creature, weights=mass, minlength=C)

    # ------------------------------------------------------------------ user layout helpers
    @property
    def nq(self) -> np.ndarray:
        """(C,) qpos length per creature: 7 + joints."""
        return 7 + self.joints_per_creature

    @property
    def nv(self) -> np.ndarray:
        """(C,) qvel length per creature: 6 + joints."""
        return 6 + self.joints_per_creature

    def segment_sum(self, values: Any) -> Any:
        """Sum per-body rows (N, ...) into per-creature rows (C, ...)."""
        xp = self.xp
        if bk.is_torch(xp):
            out = xp.zeros((self.n_creatures,) + tuple(values.shape[1:]), dtype=values.dtype, device=self.device)
            bk.scatter_add(xp, out, self.body_creature, values)
            return out
        return np.add.reduceat(values[self.by_creature], self.creature_start, axis=0)
