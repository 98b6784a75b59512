"""The reentry state, declared once: name, unit, NLP scale and box bounds of each component.

Everything that lists the state derives from :data:`STATES`: the solver's names
(``altitude_m``, ``latitude_rad`` ...), the NLP scaling, the box bounds, the Monte Carlo's
terminal quantities, the index constants used instead of bare ``x[2]``, and the API edge's
names (``api_name``: radians become degrees there).  The order is the one of
:mod:`solvers.models.reentry_dynamics`: ``x = (h, lon, lat, v, gamma, psi)``, psi from north;
controls ``u = (alpha, bank)``.  :class:`Trajectory` is the one shape in which both reentry
solutions (deterministic and robust) expose their time histories.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from solvers.models import shuttle as sh

_BIG = 1e3   # "free" bound on angles that may wind (longitude, heading), rad


@dataclass(frozen=True)
class StateComponent:
    """One component of the state: solver name (SI/radians), unit, NLP scale and box bounds."""

    name: str
    unit: str
    scale: float
    lower: float
    upper: float
    label: str        # for messages ("flight path angle")

    @property
    def is_angle(self) -> bool:
        return self.unit == "rad"

    @property
    def api_name(self) -> str:
        """The name at the API edge: ``_rad`` becomes ``_deg``, other names are kept."""
        return self.name[:-len("_rad")] + "_deg" if self.is_angle else self.name

    def to_api(self, value):
        """A value (float or array) in the API's unit: degrees for angles, SI otherwise."""
        return np.degrees(value) if self.is_angle else value

    def from_api(self, value):
        return math.radians(value) if self.is_angle else value


# Betts' scaling advice: h / 1e5 ft, v / 1e4 ft/s, angles in radians.  Bounds keep the
# equations away from their singularities (|lat|, |gamma| <= 89 deg; the speed's lower bound is
# the problem's min_speed_mps, Betts' 100 ft/s by default).
STATES: tuple[StateComponent, ...] = (
    StateComponent("altitude_m", "m", 1e5 * sh.FT_TO_M, -1e4, 2e5, "altitude"),
    StateComponent("longitude_rad", "rad", 1.0, -_BIG, _BIG, "longitude"),
    StateComponent("latitude_rad", "rad", 1.0, -sh.SINGULARITY_MARGIN_RAD, sh.SINGULARITY_MARGIN_RAD,
                   "latitude"),
    StateComponent("speed_mps", "m/s", 1e4 * sh.FT_TO_M, sh.BETTS_MIN_SPEED_MPS, 2e4, "speed"),
    StateComponent("flight_path_rad", "rad", 1.0, -sh.SINGULARITY_MARGIN_RAD, sh.SINGULARITY_MARGIN_RAD,
                   "flight path angle"),
    StateComponent("heading_rad", "rad", 1.0, -_BIG, _BIG, "heading"),
)
CONTROLS: tuple[StateComponent, ...] = (
    StateComponent("alpha_rad", "rad", 1.0, *sh.BETTS_ALPHA_BOUNDS_RAD, "angle of attack"),
    StateComponent("bank_rad", "rad", 1.0, *sh.BETTS_BANK_BOUNDS_RAD, "bank angle"),
)

NX, NU = len(STATES), len(CONTROLS)
STATE_NAMES = tuple(c.name for c in STATES)
STATE_INDEX = {c.name: i for i, c in enumerate(STATES)}
X_SCALE = tuple(c.scale for c in STATES)
U_SCALE = tuple(c.scale for c in CONTROLS)

ALTITUDE, LONGITUDE, LATITUDE, SPEED, FLIGHT_PATH, HEADING = (STATE_INDEX[n] for n in STATE_NAMES)
ALPHA, BANK = 0, 1


def box_bounds(*, min_speed_mps: float) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper state bounds (NX,) of the declaration, with the problem's speed floor."""
    lo = np.array([c.lower for c in STATES])
    hi = np.array([c.upper for c in STATES])
    lo[SPEED] = min_speed_mps
    return lo, hi


@dataclass
class Trajectory:
    """A reentry time history: ``t`` (N,) s, ``x`` (NX, N) states and ``u`` (NU, N) controls at the
    same times (SI/radians, order of :data:`STATES`/:data:`CONTROLS`), and path quantities by name
    (e.g. ``heat_rate_w_m2``), each (N,)."""

    t: np.ndarray
    x: np.ndarray
    u: np.ndarray
    path: dict[str, np.ndarray] = field(default_factory=dict)

    def state(self, name: str) -> np.ndarray:
        """One state component's history by its solver name (``latitude_rad``)."""
        return self.x[STATE_INDEX[name]]

    def final(self) -> dict[str, float]:
        """The final state by solver name."""
        return {c.name: float(self.x[i, -1]) for i, c in enumerate(STATES)}
