"""Compatibility alias of :mod:`app.runtime.settings` for importers not yet moved (the ocp kind's tests and
benchmarks). New code imports :mod:`app.runtime.settings`; delete this module when nothing imports ``app.settings``."""
from app.runtime.settings import *  # noqa: F401,F403
