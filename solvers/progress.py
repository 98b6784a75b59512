"""A job's progress as stages weighted by their measured cost (issue 38 item 4).

A solve declares its stages once, in order, each with its share of a typical run's wall time (measured
on the presets; the numbers and how they were measured sit beside each declaration): build, solve,
verification, the limit and refinement rounds, the Monte Carlo.  It then announces each stage as it
starts, ``progress.stage("solve")`` or ``progress.stage("refinement", round=2)``, and reports the
fraction done *within* it through the callback that returns.  The job's fraction is the stages before
it plus that fraction of the stage's weight, so the bar moves at the pace the work does.

* A stage declared ``rounds=True`` repeats an unknown number of times: round k takes half of what its
  weight still has (1/2, 1/4, ...), so no number of rounds exhausts it.
* :meth:`Progress.within` nests a plan inside one stage (a refinement round runs build, solve,
  verification and limit rounds of its own, inside the round's share).
* Before the last stage of the top-level plan starts, the fraction never passes :data:`CAP` (95%);
  it never goes back; every message names its stage and round.

The callback stays the solve protocol's ``on_progress(fraction, message)``: the message is a
:class:`ProgressMessage`, a ``str`` that also carries ``stage`` and ``round``, so every callback that
takes a string works unchanged and the service can read the stage without parsing words.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

from solvers.common import ProgressFn

CAP = 0.95   # the most a job shows before its last stage starts


@dataclass(frozen=True)
class Stage:
    """One stage of a plan: ``weight`` its share of a typical run (any scale: a plan is normalized),
    ``rounds`` whether it repeats with a number (round k gets half of its weight left)."""

    name: str
    weight: float
    rounds: bool = False


class ProgressMessage(str):
    """A progress message that names its stage: ``stage`` (e.g. "refinement round 2 / solve") and
    ``round`` (the innermost round number, or None).  To anything else it is the string it reads."""

    stage: str
    round: int | None

    def __new__(cls, text: str, *, stage: str, round: int | None = None) -> "ProgressMessage":
        out = super().__new__(cls, text)
        out.stage, out.round = stage, round
        return out


class _Shared:
    """What the nested plans of one job share: the sink, the largest fraction sent, the cap's state."""

    def __init__(self, sink: ProgressFn | None):
        self.sink, self.best, self.final = sink, 0.0, False

    def emit(self, fraction: float, text: str, stage: str, round: int | None) -> None:
        if not self.final:
            fraction = min(fraction, CAP)
        self.best = max(self.best, min(max(fraction, 0.0), 1.0))
        if self.sink is not None:
            self.sink(self.best, ProgressMessage(text, stage=stage, round=round))


class Progress:
    """A plan of :class:`Stage` over a span of the job's progress (module docstring)."""

    def __init__(self, on_progress: ProgressFn | None, plan: Sequence[Stage], *, span: tuple[float, float] = (0.0, 1.0),
                 label: str = "", round: int | None = None, shared: _Shared | None = None):
        total = sum(s.weight for s in plan)
        if not plan or total <= 0 or any(s.weight < 0 for s in plan):
            raise ValueError("a progress plan needs stages with non-negative weights and a positive total")
        self.plan = {s.name: s for s in plan}
        self._starts, start = {}, 0.0
        for s in plan:
            self._starts[s.name] = start / total
            start += s.weight
        self._total, self._span, self._label, self._round = total, span, label, round
        self._shared = shared or _Shared(on_progress)
        self._top = shared is None
        self._last = plan[-1].name

    def _locate(self, name: str, round: int | None) -> tuple[float, float, str, int | None]:
        if name not in self.plan:
            raise KeyError(f"progress stage {name!r} is not declared (declared: {', '.join(self.plan)})")
        s = self.plan[name]
        lo, w = self._starts[name], s.weight / self._total
        words = name
        if s.rounds:
            k = max(1, round or 1)
            lo, w = lo + w * (1.0 - 0.5 ** (k - 1)), w * 0.5 ** k
            words = f"{name} round {k}"
        a, b = self._span
        words = f"{self._label} / {words}" if self._label else words
        return a + (b - a) * lo, a + (b - a) * (lo + w), words, (round if s.rounds else self._round)

    def stage(self, name: str, round: int | None = None, message: str = "") -> ProgressFn:
        """Announce stage ``name`` (round ``round`` of a repeating one) and return the callback that
        reports the fraction done within it, ``(fraction in [0, 1], detail)``."""
        a, b, words, rnd = self._locate(name, round)
        if self._top and name == self._last:
            self._shared.final = True
        self._shared.emit(a, f"{words}: {message}" if message else words, words, rnd)

        def within(fraction: float, detail: str) -> None:
            f = min(max(float(fraction), 0.0), 1.0)
            self._shared.emit(a + (b - a) * f, f"{words}: {detail}" if detail else words, words, rnd)
        return within

    def within(self, name: str, plan: Sequence[Stage], round: int | None = None) -> "Progress":
        """Announce stage ``name`` and return a plan of its own inside its share (a refinement round's
        build, solve and verification)."""
        self.stage(name, round)
        a, b, words, rnd = self._locate(name, round)
        return Progress(None, plan, span=(a, b), label=words, round=rnd, shared=self._shared)

    def done(self, message: str) -> None:
        """The whole plan finished: 100%, whatever stage ran last."""
        self._shared.final = True
        self._shared.emit(1.0, message, self._last, None)

