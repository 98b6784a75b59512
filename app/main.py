"""Compatibility alias of :mod:`app.api.main` for importers not yet moved (the ocp kind's tests and
benchmarks). New code imports :mod:`app.api.main`; delete this module when nothing imports ``app.main``."""
from app.api.main import *  # noqa: F401,F403
