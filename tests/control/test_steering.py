"""Steering of blocked robots."""

import math

import numpy as np
import pytest

from mrta_drake.control.cbf_params import CbfParams
from mrta_drake.control.input_limits import input_bounds
from mrta_drake.control.safety_rows import safety_rows
from mrta_drake.control.steering import PAST_TANGENT, steer_blocked
from mrta_drake.control.wall_rays import WallRays
from mrta_drake.world.obstacles import Box, Obstacles

DT = 0.05  # s, the controller's tick


def test_standing_robot_nosing_into_a_wall_turns_along_it():
    params = CbfParams()
    wall = Obstacles((Box("wall", (1.0, 0.0), (0.2, 10.0)),))  # face at x = 0.9
    # Standing 0.6 m from the face, facing it; the goal lies 30 deg to the left.
    state = np.array([[0.3, 0.0, 0.0, 0.0]])
    hits, mask = WallRays(wall, params.sensing)(state)
    rows = safety_rows(state, hits, mask, np.zeros((0, 2)), np.zeros((0, 2)), np.zeros((0, 4)),
                       params)
    u_nom = np.array([[2.0, params.nominal.k_theta * math.radians(30.0)]])
    bounds = input_bounds(state, params.nominal, DT)
    steered = steer_blocked(u_nom, state, rows, *bounds, params)
    # Of the wall's two tangents (+-90 deg) the one nearer the goal, and past it: turn left.
    assert steered[0, 1] == pytest.approx(params.nominal.k_theta * (math.pi / 2 + PAST_TANGENT))
    assert steered[0, 0] == u_nom[0, 0]
    moving = state.copy()
    moving[0, 3] = 0.5  # a moving robot steers through its barrier rows: left alone
    np.testing.assert_array_equal(steer_blocked(u_nom, moving, rows, *bounds, params), u_nom)


def test_the_blocking_row_is_judged_at_the_input_the_robot_can_be_commanded():
    # Standing at a corridor's corner (a wall point at its 0.6 m wall distance, 60 deg to
    # the right), a person standing 1.1 m straight ahead, its nominal asking 2.25 m/s^2
    # straight on (the limit is 1). At 1 m/s^2 the wall's row is the more violated (-1.0
    # against the person's -0.45): it turns along the corner, 30 deg left (and past the
    # tangent, away from the corner). Judged at 2.25
    # the person's row won (-2.95 against -2.25) and it turned 90 deg, and from there the
    # wall's row won again, tick after tick (issue 15).
    params = CbfParams()
    state = np.array([[0.0, 0.0, 0.0, 0.0]])
    corner = 0.6 * np.array([math.cos(math.radians(-60.0)), math.sin(math.radians(-60.0))])
    hits = np.zeros((1, params.sensing.ray_count, 2))
    mask = np.zeros((1, params.sensing.ray_count), dtype=bool)
    hits[0, 0], mask[0, 0] = corner, True
    rows = safety_rows(state, hits, mask, np.array([[1.1, 0.0]]), np.zeros((1, 2)),
                       np.zeros((0, 4)), params)
    u_nom = np.array([[2.25, 0.0]])
    steered = steer_blocked(u_nom, state, rows, *input_bounds(state, params.nominal, DT),
                            params)
    assert steered[0, 1] == pytest.approx(
        params.nominal.k_theta * (math.radians(30.0) + PAST_TANGENT))
    assert steered[0, 0] == u_nom[0, 0]
