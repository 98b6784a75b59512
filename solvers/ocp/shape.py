"""The shape of the ``ocp`` params, declared once: which fields each section of a problem has.

The parser (:mod:`solvers.ocp.spec`, :mod:`solvers.ocp.phase_spec`, :mod:`solvers.ocp.phases_spec`)
refuses any other field with these lists, and the service's request models
(``app/kinds/ocp/params.py``, which document the fields in ``/docs``) are held to them by a test
(``tests/unit/test_ocp_shape.py``): the standard-library parser is the declaration, because
``solvers/`` is a library usable without the service and its pydantic models, and because it alone
decides what the fields mean together (names that resolve, expressions in the language, bounds in
order, phases in time), with error paths the user wrote.  Standard library only.
"""
from __future__ import annotations

# the variables' number fields, by kind of declaration
STATE_NUMBERS = ("initial", "final", "lower", "upper", "scale")
CONTROL_NUMBERS = ("lower", "upper", "scale")
PARAMETER_NUMBERS = ("lower", "upper", "guess")

# a phase's sections, in the single-phase params and in each of params.phases
PHASE_SECTIONS = ("states", "controls", "time", "expressions", "dynamics", "path", "boundary", "transcription",
                  "guess")
# what every phase shares, at the top level
SHARED = ("title", "constants", "tables", "parameters", "objective", "guess", "plots", "accuracy",
          "accuracy_required", "search", "uncertainty", "robust")

FIELDS: dict[str, tuple[str, ...]] = {
    "params": tuple(dict.fromkeys((*SHARED[:4], *PHASE_SECTIONS, *SHARED[4:]))),   # posed as one phase
    "params.phases": (*SHARED, "phases", "links"),                                 # several phases
    "phase": ("name", *PHASE_SECTIONS),
    "state": ("name", *STATE_NUMBERS, "unit"),
    "control": ("name", *CONTROL_NUMBERS, "unit"),
    "parameter": ("name", *PARAMETER_NUMBERS),
    "table": ("axes", "values"),
    "time": ("initial", "final", "final_lower", "final_upper", "final_guess"),
    "phase.time": ("initial", "initial_lower", "initial_upper", "initial_guess", "final", "final_lower",
                   "final_upper", "final_guess"),
    "constraint": ("expr", "lower", "upper", "name"),
    "link": ("expr", "lower", "upper", "name", "non_consecutive"),
    "objective": ("sense", "expr", "integrand"),
    "transcription": ("method", "intervals", "control", "substeps", "nodes", "max_refinements", "boundaries",
                      "segment_nodes"),
    "guess": ("states", "controls", "tf", "from_job"),
    "phase.guess": ("states", "controls", "tf"),
    "params.phases.guess": ("from_job",),
    "search": ("starts", "seed"),
}
