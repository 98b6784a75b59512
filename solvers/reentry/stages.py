"""The stages of a ``reentry`` solve and their weights (solvers.progress): what the job's progress bar
walks through.  One grid: the least-peak check of a heating limit, the solve without path limits it
starts from, the solve, the dense re-propagation (verification), the limit rounds that hold a path limit
between the nodes and the terminal rounds that add substeps for a final value missed (each nested: a
solve and a verification of its own); a mesh-refinement round is such a grid again inside the round's
share; the answer is the last stage.

Weights: each stage's share of the wall time, in percent, over three presets run through the kind
(``python -m benchmarks.progress_stages reentry``, 2 shared cores at load ~10, 78.4 s in all:
betts-max-crossrange, betts-max-crossrange-heat-limited, betts-max-crossrange refined to accuracy 1e-4):
least peak 5.0, solve without path limits 7.2, solve 20.6, verification 8.3, terminal rounds 42.0 (one
in each of the first two), refinement 16.7 (one round), answer 0.2.  No preset ran a limit round; its 10
is an estimate: a warm re-solve (~10 IPOPT iterations) and a dense re-propagation.
"""
from __future__ import annotations

from solvers.progress import Stage

GRID_PLAN = (Stage("least peak", 5.0), Stage("solve without path limits", 7.2), Stage("solve", 20.6),
             Stage("verification", 8.3), Stage("limit", 10.0, rounds=True), Stage("terminal", 42.0, rounds=True))
# a terminal round: the grid's own solve, verification and limit rounds again, with more substeps
ROUND_PLAN = (Stage("solve", 20.6), Stage("verification", 8.3), Stage("limit", 10.0, rounds=True))
PLAN = GRID_PLAN + (Stage("refinement", 16.7, rounds=True), Stage("answer", 0.2))
