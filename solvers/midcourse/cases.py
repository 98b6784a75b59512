"""Paper 002's midcourse case, the one place presets, tests and benchmarks read it from.

Tables 1-2 (launch-inertial frame: positions relative to the launch point, SI) and
the launch frame fitted to the paper's own nominal (spec ``midcourse.md``: the
paper gives neither the launch site nor R0), and Table 3's correction schedules.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

if TYPE_CHECKING:   # the API edge reads the numbers here without loading the numerics
    from solvers.astro.j2 import LaunchFrame

LAUNCH_LATITUDE_RAD = math.radians(28.3214)     # geodetic B0, fitted
LAUNCH_AZIMUTH_RAD = math.radians(135.7033)     # A0, fitted
LAUNCH_HEIGHT_M = 1757.5                        # above WGS-84, fitted

R0_M = (4052278.09, -1153200.39, -103191.17)
V0_MPS = (8297.4213, -5571.1055, 398.5626)
R_TARGET_M = (-14219839.24, -35409571.30, 667441.50)
V_TARGET_MPS = (-1889.2754, 781.3548, -73.1586)
POSITION_ERROR_M = (-100.0, 100.0, 100.0)
VELOCITY_ERROR_MPS = (10.0, -10.0, 10.0)
TF_S = 12900.0
# Default minimum time between two corrections.  A real stage cannot fire twice within
# milliseconds: between burns it must settle, re-acquire its navigation solution and re-plan,
# and a navigation update cycle or a thruster's minimum off-time is tens of seconds to minutes.
# With 0 the GA put two corrections 0.2 ms apart (one burn split in two, issue 15).
MIN_SPACING_S = 60.0

TABLE3_SCHEDULES_S = [[], [6000.0], [8000.0], [3000.0, 8000.0], [1000.0, 8000.0],
                      [2000.0, 5000.0, 8000.0], [1000.0, 5000.0, 8000.0]]


def paper_frame() -> LaunchFrame:
    from solvers.astro.j2 import LaunchFrame

    return LaunchFrame.from_geodetic(latitude_rad=LAUNCH_LATITUDE_RAD, azimuth_rad=LAUNCH_AZIMUTH_RAD,
                                     height_m=LAUNCH_HEIGHT_M)
