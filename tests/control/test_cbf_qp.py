"""Barrier math (checked against finite differences along the unicycle flow) and the CBF QP."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mrta_drake.control.cbf_qp import (
    HUMAN,
    ROBOT,
    WALL,
    CbfParams,
    CbfQp,
    WallRays,
    cbf_rhs,
    pair_barrier,
    point_barrier,
    safety_rows,
    steer_blocked,
)
from mrta_drake.world.obstacles import Box, Obstacles

coordinate = st.floats(-3.0, 3.0)
heading = st.floats(-math.pi, math.pi)
speed = st.floats(-0.3, 1.5)
accel = st.floats(-1.0, 1.0)
yaw_rate = st.floats(-2.0, 2.0)
robot = st.tuples(coordinate, coordinate, heading, speed, accel, yaw_rate)


def _flow(state, u, t, steps=20):
    """The unicycle ``state`` [x, y, theta, v] after ``t`` s (may be negative) at constant
    input ``u`` [a, omega], by RK4."""

    def f(x):
        return np.array([x[3] * math.cos(x[2]), x[3] * math.sin(x[2]), u[1], u[0]])

    x, h = np.array(state, dtype=float), t / steps
    for _ in range(steps):
        k1 = f(x)
        k2 = f(x + 0.5 * h * k1)
        k3 = f(x + 0.5 * h * k2)
        k4 = f(x + h * k3)
        x = x + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    return x


def _derivatives(h_of_t, eps=1e-3):
    h_minus, h_0, h_plus = h_of_t(-eps), h_of_t(0.0), h_of_t(eps)
    return (h_plus - h_minus) / (2 * eps), (h_plus - 2 * h_0 + h_minus) / eps**2


@settings(max_examples=60, derandomize=True, deadline=None)
@given(robot, coordinate, coordinate, st.floats(-1.5, 1.5), st.floats(-1.5, 1.5))
def test_point_barrier_derivatives_match_finite_differences(r, ox, oy, wx, wy):
    state, u = np.array(r[:4]), np.array(r[4:])
    o, w, d = np.array([ox, oy]), np.array([wx, wy]), 0.6

    def h_of_t(t):
        x = _flow(state, u, t)
        return np.sum((x[:2] - (o + w * t)) ** 2) - d**2

    terms = point_barrier(state[:2], state[2], state[3], o, w, d)
    h_dot, h_ddot = _derivatives(h_of_t)
    assert terms.h == pytest.approx(h_of_t(0.0), abs=1e-12)
    assert terms.h_dot == pytest.approx(h_dot, rel=1e-5, abs=1e-5)
    assert terms.drift + terms.own @ u == pytest.approx(h_ddot, rel=1e-4, abs=1e-4)


@settings(max_examples=60, derandomize=True, deadline=None)
@given(robot, robot)
def test_pair_barrier_derivatives_match_finite_differences(ri, rj):
    si, ui = np.array(ri[:4]), np.array(ri[4:])
    sj, uj = np.array(rj[:4]), np.array(rj[4:])

    def h_of_t(t):
        return np.sum((_flow(si, ui, t)[:2] - _flow(sj, uj, t)[:2]) ** 2) - 0.36

    terms = pair_barrier(si, sj, 0.6)
    h_dot, h_ddot = _derivatives(h_of_t)
    assert terms.h[0] == pytest.approx(h_of_t(0.0), abs=1e-12)
    assert terms.h_dot[0] == pytest.approx(h_dot, rel=1e-5, abs=1e-5)
    assert terms.drift[0] + terms.own[0] @ ui + terms.other[0] @ uj == pytest.approx(
        h_ddot, rel=1e-4, abs=1e-4)


def test_standing_robot_cannot_steer_away_and_cbf_row_is_the_second_order_condition():
    # v = 0: omega has no effect on h_ddot; a forward push towards the point is limited.
    terms = point_barrier([0.0, 0.0], 0.0, 0.0, [[1.0, 0.0]], [[0.0, 0.0]], 0.6)
    assert terms.own[0, 1] == 0.0
    assert terms.own[0, 0] == pytest.approx(-2.0)
    b = cbf_rhs(terms, 2.0, 6.0)
    # -2 a >= -(0 + 0 + 12 * (1 - 0.36))  <=>  a <= 3.84
    assert b[0] == pytest.approx(-12 * 0.64)


def _corridor():
    return Obstacles((Box("north", (0.0, 1.5), (20.0, 0.2)),
                      Box("south", (0.0, -1.5), (20.0, 0.2))))


def test_wall_hits_world_and_body_frame_rays():
    params = CbfParams()
    states = np.array([[0.0, 0.0, 0.5, 0.0], [0.0, 0.4, 0.0, 0.0]])
    hits, mask = WallRays(_corridor(), params)(states)
    assert hits.shape == (2, 12, 2) and mask.shape == (2, 12)
    # World-frame rays 3 (90 deg) and 9 (270 deg) hit the walls' faces at y = +-1.4.
    np.testing.assert_allclose(hits[0, 3], [0.0, 1.4], atol=1e-12)
    np.testing.assert_allclose(hits[1, 9], [0.0, -1.4], atol=1e-12)
    assert not mask[0, 0] and not mask[0, 6]  # along the corridor: nothing within 10 m
    body = CbfParams(rays_in_body_frame=True)
    hits, mask = WallRays(_corridor(), body)(states)
    direction = hits[0, 1] / np.linalg.norm(hits[0, 1])
    angle = 0.5 + math.pi / 6
    np.testing.assert_allclose(direction, [math.cos(angle), math.sin(angle)])
    hits, mask = WallRays(None, params)(states)
    assert not mask.any()


def test_cluster_rows_use_each_members_own_state():
    params = CbfParams()
    states = np.array([[0.0, 0.0, 0.0, 1.0], [3.0, 1.0, math.pi / 2, 0.5]])
    hits, mask = WallRays(_corridor(), params)(states)
    humans = np.array([[1.0, -1.0]])
    rows = safety_rows(states, hits, mask, humans, np.array([[0.5, 0.0]]), np.zeros((0, 4)),
                       params)
    assert set(rows.kind) == {WALL, HUMAN, ROBOT}
    for member in range(2):
        mine = (rows.kind != ROBOT) & (np.abs(rows.G[:, 2 * member:2 * member + 2]).sum(1) > 0)
        other = 1 - member
        assert not np.any(rows.G[mine, 2 * other:2 * other + 2])
        mine_h = np.sort(rows.h[mine])
        expected = np.concatenate([
            np.sum((hits[member][mask[member]] - states[member, :2]) ** 2, 1) - 0.36,
            np.sum((humans - states[member, :2]) ** 2, 1) - 0.36])
        np.testing.assert_allclose(mine_h, np.sort(expected))
    (pair,) = np.flatnonzero(rows.kind == ROBOT)
    assert np.all(rows.G[pair] != 0.0)
    assert rows.h[pair] == pytest.approx(10.0 - 0.36)


def test_standing_robot_nosing_into_a_wall_turns_along_it():
    params = CbfParams()
    wall = Obstacles((Box("wall", (1.0, 0.0), (0.2, 10.0)),))  # face at x = 0.9
    # Standing 0.6 m from the face, facing it; the goal lies 30 deg to the left.
    state = np.array([[0.3, 0.0, 0.0, 0.0]])
    hits, mask = WallRays(wall, params)(state)
    rows = safety_rows(state, hits, mask, np.zeros((0, 2)), np.zeros((0, 2)), np.zeros((0, 4)),
                       params)
    u_nom = np.array([[2.0, params.k_theta * math.radians(30.0)]])
    steered = steer_blocked(u_nom, state, rows, params)
    # Of the wall's two tangents (+-90 deg) the one nearer the goal: turn left.
    assert steered[0, 1] == pytest.approx(params.k_theta * math.pi / 2)
    assert steered[0, 0] == u_nom[0, 0]
    moving = state.copy()
    moving[0, 3] = 0.5  # a moving robot steers through its barrier rows: left alone
    np.testing.assert_array_equal(steer_blocked(u_nom, moving, rows, params), u_nom)


def _bounds(k, a_max=1.0, w_max=2.0):
    return np.tile([-a_max, -w_max], (k, 1)), np.tile([a_max, w_max], (k, 1))


@pytest.mark.parametrize("solver", ["clarabel", "osqp"])
def test_feasible_nominal_is_returned_without_solving(solver):
    qp = CbfQp(solver)
    lo, hi = _bounds(1)
    solution = qp.solve([[3.0, 0.5]], [[1.0, 0.0]], [-2.0], lo, hi)
    assert solution.success and not solution.solved
    np.testing.assert_allclose(solution.u, [[1.0, 0.5]])  # clipped to the box


@pytest.mark.parametrize("solver", ["clarabel", "osqp"])
def test_active_row_is_met_exactly_without_slack(solver):
    qp = CbfQp(solver)
    lo, hi = _bounds(1)
    # a + omega >= 1 with nominal (0, 0): the projection is (0.5, 0.5).
    solution = qp.solve([[0.0, 0.0]], [[1.0, 1.0]], [1.0], lo, hi)
    assert solution.success and solution.solved
    np.testing.assert_allclose(solution.u, [[0.5, 0.5]], atol=1e-5)
    assert solution.slack[0] == pytest.approx(0.0, abs=1e-5)


@pytest.mark.parametrize("solver", ["clarabel", "osqp"])
def test_input_limits_hold_when_the_safety_rows_cannot(solver):
    qp = CbfQp(solver)
    lo, hi = _bounds(2)
    # Rows asking for a >= 5 and a <= -5 at once, and omega_1 >= 10.
    G = np.array([[1.0, 0.0, 0.0, 0.0], [-1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
    solution = qp.solve(np.zeros((2, 2)), G, [5.0, 5.0, 10.0], lo, hi)
    assert solution.success
    assert np.all(solution.u >= lo) and np.all(solution.u <= hi)
    assert solution.u[1, 1] == pytest.approx(2.0, abs=1e-5)
    assert solution.slack.max() > 3.0


def test_non_finite_rows_fail_instead_of_solving():
    qp = CbfQp()
    lo, hi = _bounds(1)
    assert not qp.solve([[0.0, 0.0]], [[np.nan, 0.0]], [1.0], lo, hi).success


def test_both_solvers_agree_on_crowded_problems():
    rng = np.random.default_rng(4)
    params = CbfParams()
    clarabel, osqp = CbfQp("clarabel"), CbfQp("osqp")
    obstacles = _corridor()
    feasible = infeasible = 0
    for _ in range(40):
        k = int(rng.integers(1, 5))
        states = np.column_stack([rng.uniform(-3, 3, k), rng.uniform(-0.8, 0.8, k),
                                  rng.uniform(-math.pi, math.pi, k), rng.uniform(0, 1.5, k)])
        humans = rng.uniform([-3, -1], [3, 1], (2, 2))
        hits, mask = WallRays(obstacles, params)(states)
        rows = safety_rows(states, hits, mask, humans, rng.uniform(-1, 1, (2, 2)),
                           np.zeros((0, 4)), params)
        u_nom = rng.uniform(-2, 2, (k, 2))
        lo, hi = _bounds(k)
        a = clarabel.solve(u_nom, rows.G, rows.b, lo, hi)
        b = osqp.solve(u_nom, rows.G, rows.b, lo, hi)
        assert a.success and b.success
        if max(a.slack.max(initial=0), b.slack.max(initial=0)) < 1e-6:
            feasible += a.solved
            np.testing.assert_allclose(a.u, b.u, atol=1e-4)
        else:
            # Robots spawned inside safety distances: the slack penalty dominates and the
            # optimum is flat in u; the solvers agree on its value.
            infeasible += 1
            cost = [np.sum((u.ravel() - u_nom.ravel()) ** 2) + params.slack_weight
                    * np.sum(np.maximum(0.0, rows.b - rows.G @ u.ravel())) for u in (a.u, b.u)]
            assert cost[0] == pytest.approx(cost[1], rel=1e-6)
    assert feasible >= 5 and infeasible >= 5
