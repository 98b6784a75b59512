"""The service's limits on an ``ocp`` problem: the parser's :class:`solvers.ocp.spec.OcpLimits` read from the
settings (``TRAJLAB_OCP_MAX_*``), and a refusal's reason with the setting that raises the limit it names, so
every limit is a setting and its 422 names it."""
from __future__ import annotations

from dataclasses import fields

SETTING_PREFIX = "TRAJLAB_OCP_"


def settings_or_default(settings=None):
    if settings is None:
        from app.runtime.settings import get_settings

        settings = get_settings()
    return settings


def limits(settings=None):
    """The :class:`solvers.ocp.spec.OcpLimits` of the service settings (``TRAJLAB_OCP_MAX_*``)."""
    from solvers.ocp.spec import OcpLimits

    settings = settings_or_default(settings)
    values = {f.name: getattr(settings, f"ocp_{f.name}") for f in fields(OcpLimits)
              if hasattr(settings, f"ocp_{f.name}")}
    return OcpLimits(**values)


def setting_of(reason: str) -> str:
    """The reason with the setting that raises each limit it names (``max_states`` ->
    ``TRAJLAB_OCP_MAX_STATES``), so a 422 says what to change."""
    from solvers.ocp.spec import OcpLimits

    named = [f.name for f in fields(OcpLimits) if f.name in reason]
    # longest first: max_expression_nodes before a shorter name it contains
    named = [n for n in sorted(named, key=len, reverse=True)
             if not any(n != m and n in m for m in named)]
    settings = [SETTING_PREFIX + n.upper() for n in named if SETTING_PREFIX + n.upper() not in reason]
    return f"{reason} (setting {', '.join(settings)})" if settings else reason
