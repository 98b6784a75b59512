"""The ``reentry`` kind's API edge (registry: ``SPEC``), a package of small modules:

- :mod:`.params`       ``ReentryParams`` and its nested models (API units, paper defaults);
- :mod:`.vehicle`      the vehicle, aerodynamics and atmosphere parameters (also ``/v1/vehicles``);
- :mod:`.edge`         ``to_problem``, ``guess_from_result`` and the result blocks;
- :mod:`.result_model` ``ReentryResult`` and its blocks (typed result);
- :mod:`.kind`         ``PRESETS``, ``run`` and ``SPEC``.

``robust_reentry`` builds on this kind and may import its ``params``, ``vehicle``, ``edge`` and
``result_model`` modules (never ``kind``); no other kind imports it.
"""
from app.kinds.reentry.edge import to_problem
from app.kinds.reentry.kind import PRESETS, SPEC, preset_posed, run
from app.kinds.reentry.params import ReentryParams
from app.kinds.reentry.result_model import ReentryResult

__all__ = ["PRESETS", "SPEC", "ReentryParams", "ReentryResult", "preset_posed", "run", "to_problem"]
