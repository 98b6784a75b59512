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

# Robust design (solvers.ocp.robust.solver): the deterministic twin (an ocp solve, its own stages nested), the
# robust NLP's build and solve, the rounds that hold its mean +- k sigma between the nodes, the Monte Carlo;
# a confirmation round (the constraints' k raised) is build, solve, limit rounds and Monte Carlo again.
# Weights: share of the wall time in percent (python -m benchmarks.progress_stages ocp-robust: the two robust
# presets through the kind, Monte Carlo in process, 15.7 s in all, 2 shared cores): deterministic twin 78.2
# (its accuracy check solve included), robust build 0.73, robust solve 1.97, limit rounds 3.06 (one round, in
# rocket-ascent-q-limit-robust), Monte Carlo 7.16 (2000 samples each), confirmation 8.86 (one round), answer
# 0.01.  A confirmation round nests the round's stages in the same proportions.
ROBUST_ROUND_PLAN = (Stage("robust build", 0.73), Stage("robust solve", 1.97), Stage("limit", 3.06, rounds=True),
                     Stage("monte carlo", 7.16))
ROBUST_PLAN = (Stage("deterministic twin", 78.2),) + ROBUST_ROUND_PLAN + (
    Stage("confirmation", 8.86, rounds=True), Stage("answer", 0.01))
# the design alone (solve_robust called without a plan): no Monte Carlo, no confirmation
ROBUST_DESIGN_PLAN = ROBUST_PLAN[:4] + (Stage("answer", 0.01),)


# Several starts (search.starts, app/kinds/ocp/search.py): the starts (each an ocp solve, fanned out), then
# the judging of their answers.  Weights (python -m benchmarks.progress_stages ocp-search: brachistochrone
# with 4 starts, hang-glider with 3, one after the other in process, 23.2 s): starts 23.23 s, answer under
# 5 ms (0.00 %; 0.01 keeps it a stage of its own); each start moves the bar as it finishes.
SEARCH_PLAN = (Stage("starts", 99.99), Stage("answer", 0.01))
