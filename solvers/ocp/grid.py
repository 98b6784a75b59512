"""Where the nodes of one ``ocp`` phase sit in normalized time: :class:`Grid` (equal intervals or a
refined mesh's boundaries, LGL nodes per interval), read by the NLP (:mod:`solvers.ocp.phase`), the
re-flight (:mod:`solvers.ocp.verify`) and the limit rounds (:mod:`solvers.ocp.limits`)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from solvers.ocp.problem import PhaseProblem
from solvers.transcription.lgl import lgl_nodes


@dataclass(frozen=True)
class Grid:
    """Where the nodes of one transcription sit in normalized time ``tau``: equal intervals, or the
    interval ``boundaries`` of a refined mesh (:mod:`solvers.ocp.refine`) with, for LGL, the nodes of
    each interval (``segment_nodes``)."""

    method: str
    intervals: int
    control: str = "linear"
    substeps: int = 2
    nodes: int = 4
    boundaries: tuple[float, ...] | None = None
    segment_nodes: tuple[int, ...] | None = None

    def bounds(self) -> np.ndarray:
        """Interval boundaries in ``tau`` (intervals + 1)."""
        if self.boundaries is not None:
            return np.asarray(self.boundaries, float)
        return np.linspace(0.0, 1.0, self.intervals + 1)

    def nodes_per_interval(self) -> np.ndarray:
        """Nodes of each interval, both ends counted (2 for multiple shooting)."""
        if self.method == "multiple_shooting":
            return np.full(self.intervals, 2)
        if self.segment_nodes is not None:
            return np.asarray(self.segment_nodes, int)
        return np.full(self.intervals, self.nodes)

    def offsets(self) -> np.ndarray:
        """Index of each interval's first node, then of the last node (intervals + 1)."""
        return np.concatenate([[0], np.cumsum(self.nodes_per_interval() - 1)])

    @property
    def n_nodes(self) -> int:
        return int(self.offsets()[-1]) + 1

    @property
    def piecewise(self) -> bool:
        """Each interval holds one control value (multiple shooting's piecewise-constant controls); else
        the controls sit at the nodes."""
        return self.method == "multiple_shooting" and self.control == "constant"

    @property
    def n_controls(self) -> int:
        if self.piecewise:
            return self.intervals
        return self.n_nodes

    def tau(self) -> np.ndarray:
        b = self.bounds()
        if self.method == "multiple_shooting":
            return b
        parts = [b[k] + (b[k + 1] - b[k]) * 0.5 * (lgl_nodes(int(n)) + 1.0)[:-1]
                 for k, n in enumerate(self.nodes_per_interval())]
        return np.concatenate(parts + [[1.0]])

    def node_interval(self) -> np.ndarray:
        """The interval each node belongs to (a shared end node: the earlier one)."""
        k = np.searchsorted(self.offsets(), np.arange(self.n_nodes), side="right") - 1
        return np.minimum(k, self.intervals - 1)

    def node_intervals_both(self) -> tuple[np.ndarray, np.ndarray]:
        """For each node, the intervals on its left and right (equal inside an interval)."""
        off = self.offsets()
        idx = np.arange(self.n_nodes)
        right = self.node_interval()
        ends = np.isin(idx, off)
        left = np.where(ends, np.maximum(np.searchsorted(off, idx) - 1, 0), right)
        return left, right


def grid_of(problem: PhaseProblem) -> Grid:
    tr = problem.transcription
    return Grid(method=tr.method, intervals=tr.intervals, control=tr.control, substeps=tr.substeps,
                nodes=tr.nodes, boundaries=getattr(tr, "boundaries", None),
                segment_nodes=getattr(tr, "segment_nodes", None))
