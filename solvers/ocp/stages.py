"""The stages of an ``ocp`` solve and their weights (solvers.progress): what the job's progress bar
walks through.  One grid is build, solve, verification (the re-flight of every phase), the limit rounds
that tighten a path limit exceeded between the nodes, and the accuracy check (a warm solve on the nested
finer mesh, verified: solvers.ocp.estimate); a refinement round (to ``accuracy``, or for a final value
missed) is such a grid again, nested inside the round's share; the answer is the last stage.

Weights: each stage's share of the wall time in percent (``python -m benchmarks.progress_stages ocp``
and ``ocp-refined``; 2 shared cores at load ~10).
* A grid (bryson-denham, goddard-rocket, hang-glider, van-der-pol-state-limit as given, 40.7 s in all):
  build 1.65, solve 5.06, verification 20.3, check 72.9.  No preset ran a limit round; its 10 is an
  estimate (a warm re-solve, ~15 IPOPT iterations against a cold solve's ~60, and a re-flight).  Without
  ``accuracy`` no preset refined (a final value missed): its 10 is an estimate, so the rare round is
  announced and moves within a small share rather than holding every other job back.
* With ``accuracy`` (brachistochrone from 4 intervals by multiple shooting and by LGL, betts-shuttle-ocp
  from 50 intervals, accuracy 1e-6; 247 s of the 253 s in the shuttle): the grid as given 3.0 (its stages
  in the proportions above), refinement 97.0 (1, 1 and 2 rounds).
"""
from __future__ import annotations

from solvers.progress import Stage

GRID_PLAN = (Stage("build", 1.65), Stage("solve", 5.06), Stage("verification", 20.3),
             Stage("limit", 10.0, rounds=True), Stage("check", 72.9))
# the accuracy check: a warm solve of the same problem on the nested finer mesh, verified
CHECK_PLAN = GRID_PLAN[:4]
PLAN = GRID_PLAN + (Stage("refinement", 10.0, rounds=True), Stage("answer", 0.05))
_GRID = sum(s.weight for s in GRID_PLAN)
REFINED_PLAN = tuple(Stage(s.name, 3.0 * s.weight / _GRID, s.rounds) for s in GRID_PLAN) + (
    Stage("refinement", 97.0, rounds=True), Stage("answer", 0.05))
