"""Compatibility alias of :mod:`app.service.quota` for importers not yet moved (the ocp kind's tests and
benchmarks). New code imports :mod:`app.service.quota`; delete this module when nothing imports ``app.quota``."""
from app.service.quota import *  # noqa: F401,F403
