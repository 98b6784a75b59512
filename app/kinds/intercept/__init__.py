"""The ``intercept`` kind's API edge (registry: ``SPEC``): :mod:`.params` (``InterceptParams``),
:mod:`.result_model` (``InterceptResult``), :mod:`.results` (the result blocks and key numbers),
:mod:`.kind` (``PRESETS``, ``to_problem``, ``run``, ``SPEC``), :mod:`.oem` (the finite-thrust
trajectory as a CCSDS OEM).
"""
from app.kinds.intercept.kind import FINITE_NOTE, PAPER_NOTE, PRESETS, SPEC, run, to_problem, trajectory_guess
from app.kinds.intercept.params import InterceptParams
from app.kinds.intercept.result_model import InterceptResult

__all__ = ["FINITE_NOTE", "PAPER_NOTE", "PRESETS", "SPEC", "InterceptParams", "InterceptResult", "run",
           "to_problem", "trajectory_guess"]
