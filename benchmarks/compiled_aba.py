"""What a compiled step would buy: the textbook ABA compiled with numba against the batched numpy ABA.

Issue #11 asks for Sims' experiment in 15 minutes on 2 cores; the numpy simulator takes about 23
(``benchmarks/NOTES.md``). Its big batches are bound by memory traffic, its small ones (a lesson's
single creature, the three fittest that evolution swims again) by Python's per-call overhead. This
measures how much of the step's core a compiled loop would save at each size before anyone ports
the whole step.

The compiled kernel is :mod:`~coursekit.creatures.physics.reference`'s ABA (Featherstone's three
sweeps, one body at a time, each creature on its own) with water damping, written as plain loops
for numba: every joint transform is built from the joint's rotation (or translation) and the
model's constant parts, the congruence ``Xup' Ia Xup`` fills one triangle, and the floating root's
6 x 6 solve is a Cholesky factorisation written out (numba's ``np.linalg.solve`` calls LAPACK
once per creature, which cost more than all the sweeps at batch 300). It has no joint locks and no
contacts. Before timing, its accelerations are checked against ``reference.aba`` on every creature
of the batch (relative difference at most 1e-10, or the script fails).

The reference is what the simulator runs for one evaluation of the dynamics:
:func:`~coursekit.creatures.physics.aba.articulated_inertias` then
:func:`~coursekit.creatures.physics.aba.aba` with water damping, on the same creatures, packed
once. Both are timed as ``benchmarks/swimmers.py`` times its engines (``_timed``: the best window
of this process's CPU time, the two taking turns, one thread), on its evolved workload
(``evolved_population``: the evolved champion at batch 1, else the population of
``benchmarks/data/evolved_swimmers.json`` repeated to fill the batch).

numba is not a dependency of coursekit: ``pip install 'coursekit[compiled]'``.

    python benchmarks/compiled_aba.py [--batches 1 3 60 300] [--quick]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from swimmers import _timed, evolved_population  # noqa: E402  (one thread for BLAS, before numpy loads)

import numpy as np  # noqa: E402

from coursekit.cli import number  # noqa: E402
from coursekit.creatures.body import REVOLUTE  # noqa: E402
from coursekit.creatures.physics import reference  # noqa: E402
from coursekit.creatures.physics import spatial as sp  # noqa: E402
from coursekit.creatures.physics.aba import aba, articulated_inertias  # noqa: E402
from coursekit.creatures.physics.model import Model  # noqa: E402
from coursekit.creatures.physics.water import DRAG_COEFFICIENT, drag_diagonal, drag_matrix  # noqa: E402

try:
    import numba
except ImportError:  # pragma: no cover - said at the command line
    numba = None

TOLERANCE = 1e-10


def pack(trees) -> dict:
    """The kernel's arrays for ``trees`` (bodies of all creatures in pre-order, creature after creature)."""
    parent, rotational, axis, Xtree, shift, S, inertia, damping, first = [], [], [], [], [], [], [], [], [0]
    for t in trees:
        for i in range(t.n_bodies):
            parent.append(-1 if i == 0 else first[-1] + int(t.parent[i]))
            rotational.append(i > 0 and int(t.joint_type[i]) == REVOLUTE)
            axis.append(t.joint_axis[i] if i else np.zeros(3))
            Xtree.append(sp.transform_matrix(np, t.joint_rot[i].T, t.joint_pos_parent[i]) if i else np.eye(6))
            Xc = sp.transform_matrix(np, np.eye(3), -t.joint_pos_child[i]) if i else np.eye(6)
            shift.append(Xc[3:, :3])  # Xc = [[1, 0], [shift, 1]]: from the joint to the body's centre of mass
            S_J = np.zeros(6)
            if i:
                (S_J[:3] if rotational[-1] else S_J[3:])[:] = t.joint_axis[i]
            S.append(Xc @ S_J)
        inertia.append(np.c_[t.inertia, np.repeat(t.mass[:, None], 3, axis=1)])
        damping.append(drag_diagonal(t.half_extents, DRAG_COEFFICIENT))
        first.append(first[-1] + t.n_bodies)
    n = first[-1]
    return dict(parent=np.array(parent), rotational=np.array(rotational), axis=np.array(axis), Xtree=np.array(Xtree),
                shift=np.array(shift), S=np.array(S), inertia=np.concatenate(inertia), damping=np.concatenate(damping),
                first=np.array(first), Xup=np.empty((n, 6, 6)), v=np.empty((n, 6)), c=np.empty((n, 6)),
                IA=np.empty((n, 6, 6)), pA=np.empty((n, 6)), U=np.empty((n, 6)), d=np.empty(n), u=np.empty(n),
                a=np.empty((n, 6)))


def _kernel(parent, rotational, axis, Xtree, shift, S, inertia, damping, first, q, qd, v0, tau, a0, qdd,
            Xup, v, c, IA, pA, U, d, u, a):  # pragma: no cover - compiled by numba
    T = np.empty((6, 6))
    Ia = np.empty((6, 6))
    pa = np.empty(6)
    t6 = np.empty(6)
    E = np.empty((3, 3))
    L = np.empty((6, 6))
    for k in range(first.shape[0] - 1):
        s, e = first[k], first[k + 1]
        # 1. outwards: joint transforms, velocities, bias accelerations, rigid inertias, bias forces
        for i in range(s, e):
            j = i - k - 1  # the joint of body i (creatures before this one have one root each)
            if i == s:
                for r in range(6):
                    v[i, r] = v0[k, r]
                    c[i, r] = 0.0
            else:
                x, y, z = axis[i, 0], axis[i, 1], axis[i, 2]
                if rotational[i]:  # XJ = blockdiag(E, E), E = Rot(axis, q)'
                    cq, sq = np.cos(q[j]), np.sin(q[j])
                    C1 = 1.0 - cq
                    E[0, 0], E[1, 0], E[2, 0] = cq + x * x * C1, x * y * C1 - z * sq, x * z * C1 + y * sq
                    E[0, 1], E[1, 1], E[2, 1] = y * x * C1 + z * sq, cq + y * y * C1, y * z * C1 - x * sq
                    E[0, 2], E[1, 2], E[2, 2] = z * x * C1 - y * sq, z * y * C1 + x * sq, cq + z * z * C1
                    for r in range(3):
                        for col in range(6):
                            T[r, col] = E[r, 0] * Xtree[i, 0, col] + E[r, 1] * Xtree[i, 1, col] + E[r, 2] * Xtree[i, 2, col]
                            T[r + 3, col] = E[r, 0] * Xtree[i, 3, col] + E[r, 1] * Xtree[i, 4, col] + E[r, 2] * Xtree[i, 5, col]
                else:  # XJ = xlt(q axis)
                    px, py, pz = q[j] * x, q[j] * y, q[j] * z
                    for col in range(6):
                        t0, t1, t2 = Xtree[i, 0, col], Xtree[i, 1, col], Xtree[i, 2, col]
                        T[0, col], T[1, col], T[2, col] = t0, t1, t2
                        T[3, col] = Xtree[i, 3, col] + pz * t1 - py * t2
                        T[4, col] = Xtree[i, 4, col] - pz * t0 + px * t2
                        T[5, col] = Xtree[i, 5, col] + py * t0 - px * t1
                for col in range(6):  # Xup = Xc T
                    t0, t1, t2 = T[0, col], T[1, col], T[2, col]
                    Xup[i, 0, col], Xup[i, 1, col], Xup[i, 2, col] = t0, t1, t2
                    for r in range(3):
                        Xup[i, r + 3, col] = T[r + 3, col] + shift[i, r, 0] * t0 + shift[i, r, 1] * t1 + shift[i, r, 2] * t2
                p = parent[i]
                for r in range(6):
                    acc = 0.0
                    for m in range(6):
                        acc += Xup[i, r, m] * v[p, m]
                    v[i, r] = acc + S[i, r] * qd[j]
                w0, w1, w2, u0, u1, u2 = v[i, 0], v[i, 1], v[i, 2], v[i, 3], v[i, 4], v[i, 5]
                j0, j1, j2 = S[i, 0] * qd[j], S[i, 1] * qd[j], S[i, 2] * qd[j]
                j3, j4, j5 = S[i, 3] * qd[j], S[i, 4] * qd[j], S[i, 5] * qd[j]
                c[i, 0], c[i, 1], c[i, 2] = w1 * j2 - w2 * j1, w2 * j0 - w0 * j2, w0 * j1 - w1 * j0  # crm(v) vJ
                c[i, 3] = w1 * j5 - w2 * j4 + u1 * j2 - u2 * j1
                c[i, 4] = w2 * j3 - w0 * j5 + u2 * j0 - u0 * j2
                c[i, 5] = w0 * j4 - w1 * j3 + u0 * j1 - u1 * j0
            for r in range(6):
                for col in range(6):
                    IA[i, r, col] = 0.0
                IA[i, r, r] = inertia[i, r]
            w0, w1, w2, u0, u1, u2 = v[i, 0], v[i, 1], v[i, 2], v[i, 3], v[i, 4], v[i, 5]
            h0, h1, h2 = inertia[i, 0] * w0, inertia[i, 1] * w1, inertia[i, 2] * w2
            l0, l1, l2 = inertia[i, 3] * u0, inertia[i, 4] * u1, inertia[i, 5] * u2
            pA[i, 0] = w1 * h2 - w2 * h1 + u1 * l2 - u2 * l1 + damping[i, 0] * w0  # crf(v) I v + D v
            pA[i, 1] = w2 * h0 - w0 * h2 + u2 * l0 - u0 * l2 + damping[i, 1] * w1
            pA[i, 2] = w0 * h1 - w1 * h0 + u0 * l1 - u1 * l0 + damping[i, 2] * w2
            pA[i, 3] = w1 * l2 - w2 * l1 + damping[i, 3] * u0
            pA[i, 4] = w2 * l0 - w0 * l2 + damping[i, 4] * u1
            pA[i, 5] = w0 * l1 - w1 * l0 + damping[i, 5] * u2
        # 2. inwards: articulated inertias and bias forces
        for i in range(e - 1, s, -1):
            j = i - k - 1
            p = parent[i]
            dd = 0.0
            Sp = 0.0
            for r in range(6):
                acc = 0.0
                for m in range(6):
                    acc += IA[i, r, m] * S[i, m]
                U[i, r] = acc
                dd += S[i, r] * acc
                Sp += S[i, r] * pA[i, r]
            d[i] = dd
            u[i] = tau[j] - Sp
            for r in range(6):
                for m in range(6):
                    Ia[r, m] = IA[i, r, m] - U[i, r] * U[i, m] / dd
            for r in range(6):
                acc = 0.0
                for m in range(6):
                    acc += Ia[r, m] * c[i, m]
                pa[r] = pA[i, r] + acc + U[i, r] * u[i] / dd
            for r in range(6):
                for col in range(6):
                    acc = 0.0
                    for m in range(6):
                        acc += Ia[r, m] * Xup[i, m, col]
                    T[r, col] = acc
            for r in range(6):
                for col in range(r, 6):  # IA[p] += Xup' Ia Xup, symmetric: one triangle
                    acc = 0.0
                    for m in range(6):
                        acc += Xup[i, m, r] * T[m, col]
                    IA[p, r, col] += acc
                    if col != r:
                        IA[p, col, r] += acc
                acc = 0.0
                for m in range(6):
                    acc += Xup[i, m, r] * pa[m]
                pA[p, r] += acc
        # 3. outwards: the root from IA a0 = -pA (Cholesky), then the joints
        for r in range(6):
            for col in range(r + 1):
                acc = IA[s, r, col]
                for m in range(col):
                    acc -= L[r, m] * L[col, m]
                L[r, col] = np.sqrt(acc) if r == col else acc / L[col, col]
        for r in range(6):
            acc = -pA[s, r]
            for m in range(r):
                acc -= L[r, m] * t6[m]
            t6[r] = acc / L[r, r]
        for r in range(5, -1, -1):
            acc = t6[r]
            for m in range(r + 1, 6):
                acc -= L[m, r] * t6[m]
            t6[r] = acc / L[r, r]
        for r in range(6):
            a[s, r] = t6[r]
            a0[k, r] = t6[r]
        for i in range(s + 1, e):
            j = i - k - 1
            p = parent[i]
            Ua = 0.0
            for r in range(6):
                acc = c[i, r]
                for m in range(6):
                    acc += Xup[i, r, m] * a[p, m]
                t6[r] = acc
                Ua += U[i, r] * acc
            qdd[j] = (u[i] - Ua) / d[i]
            for r in range(6):
                a[i, r] = t6[r] + S[i, r] * qdd[j]


kernel = numba.njit(_kernel) if numba is not None else None


def compiled_aba(packed: dict, q, qd, v0, tau):
    """``(a0, qdd)`` of the packed creatures (joints in BodyTree order, creature after creature)."""
    a0, qdd = np.empty((len(packed["first"]) - 1, 6)), np.empty(len(q))
    kernel(*(packed[k] for k in ("parent", "rotational", "axis", "Xtree", "shift", "S", "inertia", "damping", "first")),
           q, qd, v0, tau, a0, qdd, *(packed[k] for k in ("Xup", "v", "c", "IA", "pA", "U", "d", "u", "a")))
    return a0, qdd


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batches", type=number(int, 1), nargs="+", default=[1, 3, 60, 300])
    parser.add_argument("--seconds", type=number(float, 0, above=True), default=1.0,
                        help="CPU seconds each of the two is timed for, in turns of 0.25 s windows")
    parser.add_argument("--quick", action="store_true", help="batches 1 and 3, short windows (CI)")
    args = parser.parse_args(argv)
    if numba is None:
        print("compiled_aba: needs numba: pip install 'coursekit[compiled]'")
        return 2
    if args.quick:
        args.batches, args.seconds = [1, 3], 0.05
    rng = np.random.default_rng(0)
    print(f"one evaluation of the dynamics (all three sweeps, water damping), evolved creatures, numba {numba.__version__}")
    print(f"{'batch':>6} {'bodies':>7} {'numpy batched ms':>17} {'compiled ms':>12} {'speed-up':>9} {'max rel. diff':>14}")
    for batch in args.batches:
        trees = [c.expand().body for c in evolved_population(batch)]
        joints = [t.n_bodies - 1 for t in trees]
        q, qd, tau = (np.concatenate([f(n) for n in joints]) for f in (
            lambda n: rng.uniform(-0.5, 0.5, n), lambda n: rng.normal(0.0, 1.0, n), lambda n: rng.normal(0.0, 0.1, n)))
        v0 = rng.normal(0.0, 0.3, (batch, 6))
        packed = pack(trees)
        a0, qdd = compiled_aba(packed, q, qd, v0, tau)
        worst, at = 0.0, 0
        for k, t in enumerate(trees):
            js = slice(at, at + joints[k])
            a0r, qddr, _ = reference.aba(t, q[js], qd[js], v0[k], tau[js], damping=drag_diagonal(t.half_extents, DRAG_COEFFICIENT))
            scale = 1.0 + max(np.abs(a0r).max(), np.abs(qddr).max(initial=0.0))
            worst = max(worst, np.abs(a0[k] - a0r).max() / scale, np.abs(qdd[js] - qddr).max(initial=0.0) / scale)
            at += joints[k]
        if not worst <= TOLERANCE:
            print(f"compiled_aba: the compiled ABA differs from reference.aba by {worst:.3g} (relative) at batch {batch}")
            return 1
        model = Model(trees)
        damping = drag_matrix(model, DRAG_COEFFICIENT, None)
        # the batched ABA takes joints in the model's internal order: the same values, permuted
        qi, qdi, ti = np.empty_like(q), np.empty_like(qd), np.empty_like(tau)
        qi[model.joint_order], qdi[model.joint_order], ti[model.joint_order] = q, qd, tau

        def batched():
            return aba(model, qi, qdi, v0, ti, damping=damping, inertias=articulated_inertias(model, qi))

        times = _timed({"numpy": batched, "compiled": lambda: compiled_aba(packed, q, qd, v0, tau)}, args.seconds)
        t_numpy, t_compiled = times["numpy"], times["compiled"]
        print(f"{batch:6d} {model.n_bodies:7d} {t_numpy * 1e3:17.3f} {t_compiled * 1e3:12.4f} {t_numpy / t_compiled:8.1f}x {worst:14.2g}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
