"""The reentry state declared once: names, API names, bounds and the Trajectory type derive from it."""
from __future__ import annotations

import math

import numpy as np

from solvers.models import shuttle as sh
from solvers.models.reentry_state import (LATITUDE, SPEED, STATE_NAMES, STATES, X_SCALE, Trajectory,
                                          box_bounds)
from solvers.reentry import ReentryProblem, Terminal, state_bounds


def test_api_names_and_units_follow_the_declaration():
    assert STATE_NAMES == ("altitude_m", "longitude_rad", "latitude_rad", "speed_mps", "flight_path_rad",
                           "heading_rad")
    assert [c.api_name for c in STATES] == ["altitude_m", "longitude_deg", "latitude_deg", "speed_mps",
                                           "flight_path_deg", "heading_deg"]
    assert STATES[LATITUDE].to_api(math.pi / 2) == 90.0 and STATES[SPEED].to_api(7.0) == 7.0
    assert X_SCALE[0] == 1e5 * sh.FT_TO_M and X_SCALE[SPEED] == 1e4 * sh.FT_TO_M


def test_state_bounds_pin_initial_and_fixed_terminal_components():
    problem = ReentryProblem(terminal=Terminal(altitude_m=24384.0, speed_mps=762.0), min_speed_mps=50.0)
    x_lb, x_ub, u_lb, u_ub = state_bounds(problem, 10)
    assert x_lb.shape == x_ub.shape == (6, 11)
    np.testing.assert_array_equal(x_lb[:, 0], problem.initial_state)
    np.testing.assert_array_equal(x_ub[:, 0], problem.initial_state)
    assert x_lb[0, -1] == x_ub[0, -1] == 24384.0 and x_lb[SPEED, -1] == x_ub[SPEED, -1] == 762.0
    assert x_lb[LATITUDE, -1] == -sh.SINGULARITY_MARGIN_RAD and x_ub[LATITUDE, -1] == sh.SINGULARITY_MARGIN_RAD
    assert x_lb[SPEED, 5] == 50.0 == box_bounds(min_speed_mps=50.0)[0][SPEED]
    np.testing.assert_array_equal(u_lb, [sh.BETTS_ALPHA_BOUNDS_RAD[0], sh.BETTS_BANK_BOUNDS_RAD[0]])
    np.testing.assert_array_equal(u_ub, [sh.BETTS_ALPHA_BOUNDS_RAD[1], sh.BETTS_BANK_BOUNDS_RAD[1]])


def test_trajectory_reads_states_by_name():
    x = np.arange(12.0).reshape(6, 2)
    tr = Trajectory(t=np.array([0.0, 1.0]), x=x, u=np.zeros((2, 2)))
    assert tr.state("latitude_rad").tolist() == [4.0, 5.0]
    assert tr.final() == dict(zip(STATE_NAMES, [1.0, 3.0, 5.0, 7.0, 9.0, 11.0]))
