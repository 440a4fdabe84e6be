"""Joint mobility limits that hold: one-sided constraints through the articulated inertia (paper section 2.3).

Sims stops joints at their limits with "restoring spring forces". A spring holds a joint only as
well as its stiffness beats the forces pushing the joint out, and an explicit integrator caps the
stiffness at about ``(2.8 / dt)^2`` times the joint's effective inertia: strong effectors on light
parts went through their limits by many times their range (a revolute joint limited to
[-1.6, 0.6] rad turned three full times), and evolution bred creatures that used the leak.

Here a joint that reaches its limit is *locked* instead (hybrid dynamics, Featherstone, *Rigid
Body Dynamics Algorithms* (2008) section 9.3; :func:`~coursekit.creatures.physics.aba.aba` with
``lock``): its acceleration is prescribed and the articulated-body algorithm computes how the
rest of the creature responds and which joint force that takes. The constraint force is
whatever it must be -- no stiffness to tune, no dependence on the effector's strength or the
part's mass -- and, being a joint force, it is internal.

At the end of every (sub-)step, for the next one (:class:`Limits`,
:meth:`~coursekit.creatures.physics.world.World.step`):

1. *Which joints lock.* A joint locks when, at its rate, it would pass its limit within the next
   step (a speculative contact), when the step carried it beyond its limit, or when it was held at
   its limit and either the lock pushed it inwards in the step's last evaluation or its own
   effector still pushes it outwards. A lock that had to pull a joint outwards, against no
   effector, is released: a limit only pushes.
2. *Two impulses through the articulated inertia* (the hybrid sweep with no velocities,
   :func:`~coursekit.creatures.physics.aba.impulse`):

   - a *stop*: a locked joint's rate is set to the rate that ends the next step exactly at its
     limit, ``(limit - q) / h``, if that is slower towards the limit than its own. It conserves
     momentum exactly and only takes energy. When several joints of a creature stop at once,
     holding one at its rate could take an impulse that does work on it -- that pulls it along
     towards its limit, because the others' stops would slow it more (a passive creature gained
     16 % in one step): such a lock is released and the stops are solved again without it
     (:meth:`Limits.release`, :attr:`Limits.ROUNDS` solves at most). A held joint at rest, which
     a stop can pull only without work, stays held: releasing every lock that pulls (an exact
     impact's complementarity problem) let joints pressed to their limits by their effectors
     chatter off them once a step, a speed of the time step (``benchmarks/NOTES.md``).
   - a *projection*: a joint the step carried beyond its limit is put back on it, and the root and
     the free joints move as that impulse would move them (post-stabilisation, Cline & Pai 2003).
     A free joint the projection would push past a limit stops at it. The creature keeps its
     centre of mass and its momentum exactly: the root takes back what the impulse leaves to
     second order, and a rigid motion of the whole body gives back the momentum that the same
     joint rates carry differently at the new pose
     (:meth:`~coursekit.creatures.physics.world.World._put_back`). No state a step ends in is
     beyond a limit.
3. *The next step.* Locked joints keep their rates (prescribed acceleration 0) while the rest of
   the body moves, so they end it at their limits; nothing stiff is left for the integrator.

A joint can still overshoot within a step, when its acceleration (``a h^2 / 2``), or the stop of
another joint of its creature, carries it past a limit it was not heading for: the projection
puts it back, and :attr:`Limits.beyond` records how far it went (the simulator's
``limit_excess``). The effectors' maximum sweep speed
(:func:`~coursekit.creatures.body.effector_strength`) keeps that small.
"""

from __future__ import annotations

import numpy as np

from . import backend as bk

def effective_inertia(model) -> np.ndarray:
    """(M,) effective inertia ``1 / (M^-1)_jj`` of every joint (internal order) at the rest pose (numpy).

    One articulated-body solve per joint rank: probe ``j`` applies a unit force to the ``j``-th
    joint of every creature at once (creatures are independent), from rest at ``q = 0``; the
    joint's own acceleration is ``(M^-1)_jj``.
    """
    from .aba import aba

    xp, C, M = model.xp, model.n_creatures, model.n_joints
    nj = np.asarray(model.joints_per_creature)
    first = np.r_[0, np.cumsum(nj)[:-1]]
    f = lambda a: bk.asarray(xp, a, device=model.device)  # noqa: E731
    zero_q, zero_v = f(np.zeros(M)), f(np.zeros((C, 6)))
    inv_diag = np.empty(M)
    for j in range(int(nj.max(initial=0))):
        rows = np.asarray(model.joint_order)[first[nj > j] + j]  # internal rows of every creature's j-th joint
        tau = np.zeros(M)
        tau[rows] = 1.0
        _, qdd, _ = aba(model, zero_q, zero_q, zero_v, f(tau))
        inv_diag[rows] = bk.to_numpy(qdd)[rows]
    if M and not np.all(inv_diag > 0):
        raise ValueError("effective_inertia: the joint-space mass matrix is not positive definite")
    return 1.0 / inv_diag


#: The largest overshoot beyond a limit, as a share of the joint's range, that a swim may show and
#: still count: past it the step does not resolve the joint's motion, and the creature scores 0
#: (:func:`~coursekit.creatures.simulate.simulate`; evolution found such creatures and bred them).
MAX_EXCESS = 0.25


class Limits:
    """The lock set of one batch, decided step by step (see the module docstring).

    Args:
        model: the packed model (its ``limits_np``); h: the (sub-)step (s).
    """

    #: Solves of the stops at most: the locks that did work are released after each but the last.
    ROUNDS = 3

    def __init__(self, model, h: float):
        xp = self.xp = model.xp
        f = lambda a: bk.asarray(xp, a, device=model.device)  # noqa: E731
        self.lo, self.hi = f(model.limits_np[:, 0]), f(model.limits_np[:, 1])
        self.mid = 0.5 * (self.lo + self.hi)
        self.tol = 1e-9 * (self.hi - self.lo)  # "at the limit", round-off included
        self.h = h
        self.reset(model)

    def reset(self, model) -> None:
        """Forget the history (after the state was set from outside)."""
        self.push = self.xp.zeros_like(self.lo)  # the locks' share of the joint forces in the last evaluation
        self.lock = self.xp.zeros(self.lo.shape, dtype=self.xp.bool, device=model.device)
        self.target = self.hi
        self.beyond = self.xp.zeros_like(self.lo)  # how far the last step carried each joint beyond its limits

    def begin(self, q, qd, tau):
        """Which joints are locked for the next step, and where the locked ones stand.

        Returns ``(lock, at)``: ``at`` (M,) is ``q`` for a locked joint within its limits and the
        limit itself for one beyond it (the projection); free joints keep ``q``.
        """
        xp = self.xp
        ahead = q + self.h * qd
        # a held joint stays locked while the lock pushed it inwards, or while its own effector
        # still pushes it outwards
        toward = xp.where(self.target == self.hi, 1.0, -1.0)
        held = self.lock & ((self.push * toward <= 0) | (tau * toward > 0))
        self.beyond = xp.clip(self.excess(q), 0.0, None)  # clip: maximum would make a tensor of 0.0 (a GPU upload)
        out = self.beyond > self.tol
        self.lock = held | out | (self.excess(ahead) > self.tol)
        self.up = xp.where(held | out, q, ahead) > self.mid
        self.target = xp.where(self.up, self.hi, self.lo)
        return self.lock, xp.where(out, self.target, q)

    def rate(self, q, qd):
        """The rate every joint starts the step with: a locked joint's ends the step exactly at its
        limit, ``(limit - q) / h``, or is its own if that is slower towards the limit."""
        xp = self.xp
        reach = (self.target - q) / self.h
        rate = xp.where(self.up, xp.minimum(qd, reach), xp.maximum(qd, reach))
        return xp.where(self.lock, rate, qd)

    def release(self, force, qd, rate):
        """Release the locks whose stop did work on their joint (``force`` (M,): the locked joints'
        impulses, taking ``qd`` to ``rate``); a joint :meth:`begin` found beyond its limit stays
        locked, to be put back. Returns the (M,) mask released."""
        work = self.lock & (force * (qd + rate) > 0) & (self.beyond <= self.tol)
        self.lock = self.lock & ~work
        return work

    def end(self, force, tau) -> None:
        """Record the locks' own share of the joint forces (``force - tau``) in a step's last evaluation."""
        self.push = force - tau

    def within(self, q, moved):
        """``moved``, stopped at a limit it would pass from within (a joint never ends further beyond a limit than ``q``)."""
        xp = self.xp
        return xp.clip(moved, xp.minimum(self.lo, q), xp.maximum(self.hi, q))

    def excess(self, q):
        """(M,) how far each joint is beyond its limits (negative inside)."""
        return self.xp.maximum(q - self.hi, self.lo - q)
