"""Robust design of an ``ocp`` problem (``shared/specs/ocp.md``, "Robust design"; issue 37).

``model`` (the question as data) and ``spec`` (parsed at the door) are standard library only; with
CasADi: ``cadet`` (the user's dynamics augmented with their first-order sensitivities: CADET of
:mod:`solvers.uncertainty.cadet` in whitened sensitivity form, the robust path, boundary and objective
terms), ``nlp`` (the augmented phases on their own transcription, multiple shooting or LGL, its numbers and
guess), ``montecarlo`` (the design re-flown over the draws: a :mod:`solvers.uncertainty.montecarlo` model),
``solver``
(:func:`solvers.ocp.robust.solver.solve_robust`: the deterministic twin, the robust NLP, the check).
"""
