"""Compatibility alias of :mod:`app.service.broker` for importers not yet moved (the ocp kind's tests and
benchmarks). New code imports :mod:`app.service.broker`; delete this module when nothing imports ``app.broker``."""
from app.service.broker import *  # noqa: F401,F403
