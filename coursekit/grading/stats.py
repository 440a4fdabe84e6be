"""Statistical acceptance tests for stochastic operators (seed paper section 4: checking students' GA operators).

A stochastic operator cannot be compared with a reference output (students may draw random
numbers in any order), so checks test its *distribution* over many seeded calls. Every test here
rejects a correct implementation with probability at most ``ALPHA`` = 1e-8; a check run uses at
most a dozen such tests, so a correct solution fails a whole grading run with probability below
1e-6 (union bound).
"""

from __future__ import annotations

import numpy as np
from scipy import stats

ALPHA = 1e-8


def chi_square(counts, probs, alpha=ALPHA):
    """Pearson goodness-of-fit of observed ``counts`` to category probabilities ``probs``.

    Categories with zero probability must be handled by the caller (they are exact properties).
    Design cases so that every expected count is at least 5.

    Returns:
        (passed, statistic, threshold)
    """
    counts = np.asarray(counts, dtype=float)
    probs = np.asarray(probs, dtype=float)
    if counts.shape != probs.shape or counts.ndim != 1 or len(counts) < 2:
        raise ValueError(f"counts and probs must be 1-D of equal length >= 2, got {counts.shape} and {probs.shape}")
    if np.any(probs <= 0) or not np.isclose(probs.sum(), 1.0):
        raise ValueError("probs must be positive and sum to 1")
    expected = counts.sum() * probs
    stat = float(np.sum((counts - expected) ** 2 / expected))
    threshold = float(stats.chi2.isf(alpha, len(counts) - 1))
    return stat <= threshold, stat, threshold


def binomial_ok(successes, trials, p, alpha=ALPHA):
    """Is ``successes`` inside the central ``1 - alpha`` interval of Binomial(trials, p)?

    Returns:
        (passed, low, high)
    """
    lo, hi = stats.binom.interval(1 - alpha, trials, p)
    return bool(lo <= successes <= hi), int(lo), int(hi)
