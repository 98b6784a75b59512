"""Whether a Monte Carlo keeps what a k-sigma design promises: the one-sided normal share and the
binomial sampling tolerance (the rule of :mod:`solvers.robust_reentry.check`, for any design).

A bound ``mu + k sigma <= limit`` promises ``Phi(k)`` (k = 2: 97.72%, k = 3: 99.865%).  With ``n``
samples, the kept share of a design whose true share is the target has standard error
``sqrt(p (1 - p) / n)``; a share below ``target - z sqrt(p (1 - p) / n)``, ``z = Phi^-1(confidence)``,
is a significant shortfall.  A shortfall raises k by the gap in normal quantiles plus ``K_OVERSHOOT``
(:func:`raised_k`).
"""
from __future__ import annotations

import math
from statistics import NormalDist

_N = NormalDist()
CONFIDENCE = 0.99
K_OVERSHOOT = 0.1        # added to the quantile gap when k is raised (the next round clear of the tolerance's edge)


def normal_share(k: float) -> float:
    """One-sided normal share of k sigma: ``Phi(k)``."""
    return _N.cdf(k)


def quantile(p: float) -> float:
    """``Phi^-1(p)``, ``0 < p < 1``."""
    return _N.inv_cdf(p)


def clipped_quantile(p: float) -> float:
    """``Phi^-1(p)`` with ``p`` held 1e-12 inside (0, 1): a share of 0 or 1 has no finite quantile."""
    return quantile(min(max(p, 1e-12), 1.0 - 1e-12))


def sampling_tolerance(target: float, samples: int, confidence: float = CONFIDENCE) -> float:
    """How far below ``target`` a kept share of ``samples`` draws may fall by chance at ``confidence``."""
    return _N.inv_cdf(confidence) * math.sqrt(target * (1.0 - target) / max(samples, 1))


def kept_enough(kept: float, target: float, samples: int, confidence: float = CONFIDENCE) -> bool:
    return kept >= target - sampling_tolerance(target, samples, confidence)


def raised_k(k: float, gap: float) -> float:
    """The next round's k after a shortfall of ``gap`` in normal quantiles (target's minus measured's)."""
    return k + max(gap, 0.0) + K_OVERSHOOT
