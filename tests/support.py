"""Test doubles of the service side (never of a solver): a job context without a worker."""
from __future__ import annotations


class RecordingContext:
    """A :class:`app.kinds.base.JobContext` that records progress, keeps stored
    results in a dict (for warm starts) and answers ``should_stop`` True from the
    ``stop_after``-th poll on (for cancellation tests)."""

    job_id = "test"

    def __init__(self, stored: dict | None = None, stop_after: int | None = None):
        self.messages: list[tuple[float, str]] = []
        self.stored = stored or {}
        self.stop_after = stop_after
        self.polls = 0

    def progress(self, fraction: float, message: str) -> None:
        self.messages.append((fraction, message))

    def should_stop(self) -> bool:
        self.polls += 1
        return self.stop_after is not None and self.polls >= self.stop_after

    def load_result(self, job_id: str) -> dict:
        if job_id not in self.stored:
            raise LookupError(f"job {job_id} not found or not succeeded")
        return self.stored[job_id]

    def run_monte_carlo(self, spec: dict, samples: int, seed: int, chunk_size: int | None = None) -> dict:
        """In this process, as a worker does below its fan-out threshold."""
        from solvers.uncertainty.montecarlo import run_monte_carlo

        return run_monte_carlo(spec, samples, seed, chunk_size)
