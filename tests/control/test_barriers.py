"""Barrier math, checked against finite differences along the unicycle flow."""

import math

import numba
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mrta_drake.control.barriers import BarrierTerms, cbf_rhs, pair_other, point_barrier

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

    terms = _pair_barrier(si, sj, 0.6)
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


@numba.njit(cache=True)
def _pair_other(rx, ry, heading_j, v_j):
    """``pair_other`` (a ``compiled_helper``: only compiled code calls it) on arrays."""
    return pair_other(rx, ry, heading_j, v_j)


def _pair_barrier(state_i, state_j, safety_distance):
    """Barrier terms of robot pairs; ``state_i``, ``state_j`` (m, 4) ``[x, y, theta, v]``.
    ``own`` are the coefficients of robot i's input, ``other`` those of robot j's (as the
    safety rows' pair rows make them)."""
    si = np.atleast_2d(np.asarray(state_i, dtype=float))
    sj = np.atleast_2d(np.asarray(state_j, dtype=float))
    vj = sj[:, 3]
    terms = point_barrier(si[:, :2], si[:, 2], si[:, 3], sj[:, :2],
                          np.stack([vj * np.cos(sj[:, 2]), vj * np.sin(sj[:, 2])], axis=-1),
                          safety_distance)
    other = np.stack(_pair_other(*(np.ascontiguousarray(a) for a in (
        terms.offset[:, 0], terms.offset[:, 1], sj[:, 2], vj))), axis=-1)
    return BarrierTerms(terms.h, terms.h_dot, terms.drift, terms.own, other, terms.offset,
                        terms.distance)
