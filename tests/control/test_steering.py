"""Steering of blocked robots."""

import math

import numpy as np
import pytest

from mrta_drake.control.cbf_params import CbfParams
from mrta_drake.control.safety_rows import safety_rows
from mrta_drake.control.steering import steer_blocked
from mrta_drake.control.wall_rays import WallRays
from mrta_drake.world.obstacles import Box, Obstacles


def test_standing_robot_nosing_into_a_wall_turns_along_it():
    params = CbfParams()
    wall = Obstacles((Box("wall", (1.0, 0.0), (0.2, 10.0)),))  # face at x = 0.9
    # Standing 0.6 m from the face, facing it; the goal lies 30 deg to the left.
    state = np.array([[0.3, 0.0, 0.0, 0.0]])
    hits, mask = WallRays(wall, params.sensing)(state)
    rows = safety_rows(state, hits, mask, np.zeros((0, 2)), np.zeros((0, 2)), np.zeros((0, 4)),
                       params)
    u_nom = np.array([[2.0, params.nominal.k_theta * math.radians(30.0)]])
    steered = steer_blocked(u_nom, state, rows, params)
    # Of the wall's two tangents (+-90 deg) the one nearer the goal: turn left.
    assert steered[0, 1] == pytest.approx(params.nominal.k_theta * math.pi / 2)
    assert steered[0, 0] == u_nom[0, 0]
    moving = state.copy()
    moving[0, 3] = 0.5  # a moving robot steers through its barrier rows: left alone
    np.testing.assert_array_equal(steer_blocked(u_nom, moving, rows, params), u_nom)


def test_standing_robot_turning_in_place_keeps_its_turn():
    params = CbfParams()
    wall = Obstacles((Box("wall", (1.0, 0.0), (0.2, 10.0)),))  # face at x = 0.9
    # Standing on its wall barrier's boundary (0.6 m from the face), facing the wall, its
    # goal 2.5 rad to the left: beyond the heading gate, the nominal turns in place with
    # a = -k_v v, here a rounding's worth above zero (v = -1e-17), and the wall's row reads
    # 0 >= 3e-15, broken by as much.
    state = np.array([[0.3, 0.0, 0.0, -1e-17]])
    hits, mask = WallRays(wall, params.sensing)(state)
    rows = safety_rows(state, hits, mask, np.zeros((0, 2)), np.zeros((0, 2)), np.zeros((0, 4)),
                       params)
    u_nom = np.array([[-params.nominal.k_v * state[0, 3], params.nominal.k_theta * 2.5]])
    assert u_nom[0, 0] > 0.0 and (rows.G @ u_nom[0] < rows.b).any()
    # Not a push forward: it turns towards its goal, not to the wall's tangent (where, the
    # goal outside its heading gate, it would stand for good).
    np.testing.assert_array_equal(steer_blocked(u_nom, state, rows, params), u_nom)
    pushing = np.array([[params.nominal.k_v * 0.75, u_nom[0, 1]]])  # v_des 0.75 m/s
    assert steer_blocked(pushing, state, rows, params)[0, 1] == pytest.approx(
        params.nominal.k_theta * math.pi / 2)
