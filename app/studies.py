"""Compatibility alias of :mod:`app.service.studies` for importers not yet moved (the ocp kind's tests and
benchmarks). New code imports :mod:`app.service.studies`; delete this module when nothing imports ``app.studies``."""
from app.service.studies import *  # noqa: F401,F403
