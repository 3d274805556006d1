"""The CBF QP and its solvers."""

import math

import numpy as np
import pytest

from mrta_drake.control.cbf_params import CbfParams
from mrta_drake.control.qp_solver import CbfQp
from mrta_drake.control.safety_rows import safety_rows
from mrta_drake.control.wall_rays import WallRays
from mrta_drake.world.obstacles import Box, Obstacles


def _corridor():
    return Obstacles((Box("north", (0.0, 1.5), (20.0, 0.2)),
                      Box("south", (0.0, -1.5), (20.0, 0.2))))


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
        hits, mask = WallRays(obstacles, params.sensing)(states)
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
            cost = [np.sum((u.ravel() - u_nom.ravel()) ** 2) + params.qp.slack_weight
                    * np.sum(np.maximum(0.0, rows.b - rows.G @ u.ravel())) for u in (a.u, b.u)]
            assert cost[0] == pytest.approx(cost[1], rel=1e-6)
    assert feasible >= 5 and infeasible >= 5
