"""Compatibility alias of :mod:`app.runtime.migrate` for importers not yet moved (the ocp kind's tests and
benchmarks). New code imports :mod:`app.runtime.migrate`; delete this module when nothing imports ``app.migrate``."""
from app.runtime.migrate import *  # noqa: F401,F403
