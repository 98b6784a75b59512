"""Compatibility alias of :mod:`app.api.params` for importers not yet moved (the ocp kind's tests and
benchmarks). New code imports :mod:`app.api.params`; delete this module when nothing imports ``app.params``."""
from app.api.params import *  # noqa: F401,F403
