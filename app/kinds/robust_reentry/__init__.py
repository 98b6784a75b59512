"""The ``robust_reentry`` kind's API edge (registry: ``SPEC``): :mod:`.params` (``RobustReentryParams``,
the reentry parameters plus uncertainty, design, Monte Carlo and confirmation), :mod:`.result_model`
(``RobustReentryResult``), :mod:`.kind` (``PRESETS``, ``run``, ``SPEC``). It reuses the reentry kind's
edge modules (:mod:`app.kinds.reentry.edge`, ``.params``, ``.result_model``): the one allowed
dependency between kinds.
"""
from app.kinds.robust_reentry.kind import PRESETS, SPEC, run
from app.kinds.robust_reentry.params import RobustReentryParams
from app.kinds.robust_reentry.result_model import RobustReentryResult

__all__ = ["PRESETS", "SPEC", "RobustReentryParams", "RobustReentryResult", "run"]
