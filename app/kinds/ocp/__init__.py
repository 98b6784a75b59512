"""The ``ocp`` kind's API edge, one room: ``params`` (the request models and the whole-problem
check), ``kind`` (presets, ``run``, key numbers, cost, ``SPEC``), ``result`` (the typed result and
its builder, one phase or several), ``plots`` (one phase or several), ``warm_start`` (``initial_guess.from_job``:
one rule for one phase and several), ``headlines``, ``footprint``.  The registry reads :data:`SPEC`."""
from app.kinds.ocp.kind import PRESETS, SPEC, run
from app.kinds.ocp.params import OcpParams
from app.kinds.ocp.result import OcpResult

__all__ = ["PRESETS", "SPEC", "OcpParams", "OcpResult", "run"]
