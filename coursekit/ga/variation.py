"""Variation: making children from selected parents by mixing operators by ratio (Sims 1994
section 6: "40% asexual, 30% crossover, 30% grafting"; paper section 1: recombination of pairs,
mutation of singles).

An operator is any callable of one of two shapes:

- unary ``op(genome, rng) -> genome`` (mutation, "asexual" reproduction);
- binary ``op(a, b, rng) -> (child1, child2)`` (crossover, grafting, interpolation...).

The arity is read from the signature (required positional parameters: 2 means unary, 3 means
binary; ``functools.partial`` and lambdas work) or declared as a third tuple element. Genomes
are opaque: Variation never looks inside them.
"""

from __future__ import annotations

import inspect
import numbers
from collections.abc import Callable, Iterable, Sequence

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["Variation", "infer_arity", "largest_remainder"]


def largest_remainder(weights: ArrayLike, total: int) -> np.ndarray:
    """Share ``total`` items out in proportion to ``weights`` (Hamilton's method).

    Floors of the exact quotas first, then one more each for the largest remainders (ties: the
    earlier weight). The result sums to ``total`` and each count is within 1 of its quota.

    >>> largest_remainder([0.5, 0.3, 0.2], 9).tolist()  # quotas 4.5, 2.7, 1.8: the two largest remainders round up
    [4, 3, 2]
    """
    w = np.asarray(weights, dtype=np.float64)
    quotas = total * w / w.sum()
    counts = np.floor(quotas).astype(np.int64)
    missing = total - int(counts.sum())
    if missing > 0:
        counts[np.argsort(-(quotas - counts), kind="stable")[:missing]] += 1
    return counts


def infer_arity(op: Callable) -> int:
    """Number of genome arguments of an operator: 1 for ``op(g, rng)``, 2 for ``op(a, b, rng)``.

    Raises:
        ValueError: if the signature cannot be read or has another shape; declare the arity
            explicitly then, as ``(ratio, op, arity)``.
    """
    try:
        sig = inspect.signature(op)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"operator {op!r}: cannot read its signature ({exc}); declare it as (ratio, op, arity)") from None
    required = 0
    for p in sig.parameters.values():
        if p.kind is p.VAR_POSITIONAL:
            raise ValueError(f"operator {op!r} takes *args; declare its arity as (ratio, op, arity)")
        if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD) and p.default is p.empty:
            required += 1
    if required not in (2, 3):
        raise ValueError(
            f"operator {op!r}: expected op(genome, rng) or op(a, b, rng), but it has {required} required "
            "positional parameters; declare its arity as (ratio, op, arity)"
        )
    return required - 1


class Variation:
    """Creates the children of a generation from the selected parents, mixing operators by ratio.

    Args:
        operators: sequence of ``(ratio, op)`` or ``(ratio, op, arity)``; ratios are
            non-negative weights (normalised, so 40/30/30 and 0.4/0.3/0.3 are the same).

    Calling ``vary(parents, rng)`` returns exactly ``len(parents)`` children. The number of
    children each operator makes is its share of ``len(parents)`` rounded by the largest
    remainder method (so 40/30/30 of 240 is exactly 96/72/72), and which parent slots go to
    which operator is a random permutation. A unary operator turns the parent in its slot into
    one child. A binary operator takes the parents of its slots two by two (random pairs, as
    the slots are shuffled) and its two children fill both slots; an odd slot left over mates
    with a random other parent and keeps the first child.

    >>> from coursekit.ga.operators import point_mutation, one_point_crossover
    >>> vary = Variation([(0.5, point_mutation), (0.5, one_point_crossover)])
    >>> vary.counts(10).tolist()
    [5, 5]
    """

    def __init__(self, operators: Sequence):
        if isinstance(operators, (str, bytes)) or not isinstance(operators, Sequence) or len(operators) == 0:
            raise ValueError(f"operators: expected a non-empty list of (ratio, op) or (ratio, op, arity), got {operators!r}")
        ratios, ops, arities = [], [], []
        for i, entry in enumerate(operators):
            if not isinstance(entry, (tuple, list)) or len(entry) not in (2, 3):
                raise ValueError(f"operators[{i}]: expected (ratio, op) or (ratio, op, arity), got {entry!r}")
            ratio, op = entry[0], entry[1]
            if isinstance(ratio, bool) or not isinstance(ratio, numbers.Real) or not np.isfinite(ratio) or ratio < 0:
                raise ValueError(f"operators[{i}]: ratio must be a finite number >= 0, got {ratio!r}")
            if not callable(op):
                raise TypeError(f"operators[{i}]: operator must be callable, got {type(op).__name__}")
            arity = entry[2] if len(entry) == 3 else infer_arity(op)
            if arity not in (1, 2) or isinstance(arity, bool):
                raise ValueError(f"operators[{i}]: arity must be 1 (op(genome, rng)) or 2 (op(a, b, rng)), got {arity!r}")
            ratios.append(float(ratio))
            ops.append(op)
            arities.append(int(arity))
        total = sum(ratios)
        if total <= 0:
            raise ValueError(f"operators: ratios must not all be zero, got {ratios}")
        if not np.isfinite(total):
            raise ValueError(f"operators: ratios must have a finite sum, got {ratios}")
        self.ratios = [r / total for r in ratios]
        self.operators = ops
        self.arities = arities

    def __repr__(self) -> str:
        parts = ", ".join(f"({r:.3g}, {getattr(op, '__name__', op)!s}, {a})" for r, op, a in zip(self.ratios, self.operators, self.arities))
        return f"Variation([{parts}])"

    def counts(self, n: int) -> np.ndarray:
        """How many of ``n`` children each operator makes (sums to ``n``)."""
        if isinstance(n, bool) or not isinstance(n, numbers.Integral) or n < 0:
            raise ValueError(f"n: expected an int >= 0, got {n!r}")
        return largest_remainder(self.ratios, int(n))

    def __call__(self, parents: Sequence, rng: np.random.Generator) -> list:
        """Make ``len(parents)`` children.

        Args:
            parents: the selected parent genomes (repeats allowed), in selection order.
            rng: ``numpy.random.Generator``; also passed to every operator call.
        Returns:
            list of children, one per parent slot.
        """
        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"rng: expected a numpy.random.Generator, got {type(rng).__name__}")
        if isinstance(parents, (str, bytes)) or not isinstance(parents, Iterable):
            raise TypeError(f"parents: expected a list of genomes, got {type(parents).__name__}")
        parents = list(parents)
        n = len(parents)
        labels = rng.permutation(np.repeat(np.arange(len(self.operators)), self.counts(n)))
        children: list = [None] * n
        for j, (op, arity) in enumerate(zip(self.operators, self.arities)):
            slots = np.flatnonzero(labels == j).tolist()
            if arity == 1:
                for s in slots:
                    children[s] = op(parents[s], rng)
                continue
            for s1, s2 in zip(slots[0::2], slots[1::2]):
                children[s1], children[s2] = self._pair(op, parents[s1], parents[s2], rng)
            if len(slots) % 2:
                s = slots[-1]
                mate = s
                if n > 1:  # a random slot other than s
                    mate = int(rng.integers(0, n - 1))
                    mate += mate >= s
                children[s] = self._pair(op, parents[s], parents[mate], rng)[0]
        return children

    @staticmethod
    def _pair(op, a, b, rng):
        out = op(a, b, rng)
        if not isinstance(out, (tuple, list)) or len(out) != 2:
            raise TypeError(
                f"binary operator {getattr(op, '__name__', op)!r} must return (child1, child2), got {type(out).__name__}"
            )
        return out[0], out[1]
