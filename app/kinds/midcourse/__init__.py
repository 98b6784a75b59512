"""The ``midcourse`` kind's API edge (registry: ``SPEC``): :mod:`.params` (``MidcourseParams``),
:mod:`.result_model` (``MidcourseResult``), :mod:`.kind` (``PRESETS``, ``to_problem``, ``run``,
``SPEC``, the result and its key numbers), :mod:`.oem` (the front point's transfer as a CCSDS OEM).
"""
from app.kinds.midcourse.kind import PAPER_NOTE, PRESETS, SPEC, build_result, key_numbers, run, to_problem
from app.kinds.midcourse.params import MidcourseParams
from app.kinds.midcourse.result_model import MidcourseResult

__all__ = ["PAPER_NOTE", "PRESETS", "SPEC", "MidcourseParams", "MidcourseResult", "build_result", "key_numbers",
           "run", "to_problem"]
