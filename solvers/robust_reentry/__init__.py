"""Robust reentry design with CADET covariance propagation (the ``robust_reentry`` job kind).

The public face: :class:`RobustReentryProblem`, :class:`Uncertainty`, :class:`RobustSettings`,
:class:`Prediction`, :class:`RobustReentrySolution` (:mod:`.problem`); :func:`solve`,
:func:`resolve`, :func:`predict`, :func:`verify` (:mod:`.solver`); the Monte Carlo model
(:mod:`.mc`, with its numba kernel :mod:`.kernel`) and the confirmation loop's statistics
(:mod:`.check`). This kind builds on the deterministic one (:mod:`solvers.reentry`), the one
kind another kind may import. Names are imported on first use (:mod:`solvers.lazy`).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from solvers.lazy import lazy_exports

_EXPORTS = {
    **dict.fromkeys(("NS", "WARM_IPOPT", "SIGMA_SCALE", "S_SCALE", "SIGMA_NORM", "Uncertainty", "RobustSettings",
                     "RobustReentryProblem", "Prediction", "RobustReentrySolution"), "problem"),
    **dict.fromkeys(("solve", "resolve", "predict", "verify"), "solver"),
    **dict.fromkeys(("TERMINAL_INDEX", "monte_carlo_spec"), "mc"),
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)

if TYPE_CHECKING:  # the same names, for readers, type checkers and import-graph tools
    from solvers.robust_reentry.mc import TERMINAL_INDEX, monte_carlo_spec
    from solvers.robust_reentry.problem import (NS, S_SCALE, SIGMA_NORM, SIGMA_SCALE, WARM_IPOPT, Prediction,
                                                RobustReentryProblem, RobustReentrySolution, RobustSettings,
                                                Uncertainty)
    from solvers.robust_reentry.solver import predict, resolve, solve, verify
