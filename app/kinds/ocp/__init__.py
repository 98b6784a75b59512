"""The ``ocp`` kind's API edge, one room: ``params`` (the request models and the whole-problem
check), ``kind`` (presets, ``run``, key numbers, cost, ``SPEC``), ``result`` (the typed result and
its builder), ``plots``.  The registry reads :data:`SPEC`."""
from app.kinds.ocp.kind import PRESETS, SPEC, run
from app.kinds.ocp.params import OcpParams
from app.kinds.ocp.result import OcpResult

__all__ = ["PRESETS", "SPEC", "OcpParams", "OcpResult", "run"]
