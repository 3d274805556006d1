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


@pytest.mark.parametrize("solver", ["clarabel", "osqp", "active_set"])
def test_feasible_nominal_is_returned_without_solving(solver):
    qp = CbfQp(solver)
    lo, hi = _bounds(1)
    solution = qp.solve([[3.0, 0.5]], [[1.0, 0.0]], [-2.0], lo, hi)
    assert solution.success and not solution.solved
    np.testing.assert_allclose(solution.u, [[1.0, 0.5]])  # clipped to the box


@pytest.mark.parametrize("solver", ["clarabel", "osqp", "active_set"])
def test_active_row_is_met_exactly_without_slack(solver):
    qp = CbfQp(solver)
    lo, hi = _bounds(1)
    # a + omega >= 1 with nominal (0, 0): the projection is (0.5, 0.5).
    solution = qp.solve([[0.0, 0.0]], [[1.0, 1.0]], [1.0], lo, hi)
    assert solution.success and solution.solved
    np.testing.assert_allclose(solution.u, [[0.5, 0.5]], atol=1e-5)
    assert solution.slack[0] == pytest.approx(0.0, abs=1e-5)


@pytest.mark.parametrize("solver", ["clarabel", "osqp", "active_set"])
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


@pytest.mark.parametrize("solver", ["clarabel", "active_set"])
def test_non_finite_rows_fail_instead_of_solving(solver):
    qp = CbfQp(solver)
    lo, hi = _bounds(1)
    assert not qp.solve([[0.0, 0.0]], [[np.nan, 0.0]], [1.0], lo, hi).success


def _crowded_problems(seed: int, count: int):
    """``count`` QPs (nominal, rows, bounds) of 1-4 robots at random in the corridor among
    two people; some robots spawn inside safety distances (rows that need slack)."""
    rng = np.random.default_rng(seed)
    params = CbfParams()
    obstacles = _corridor()
    for _ in range(count):
        k = int(rng.integers(1, 5))
        states = np.column_stack([rng.uniform(-3, 3, k), rng.uniform(-0.8, 0.8, k),
                                  rng.uniform(-math.pi, math.pi, k), rng.uniform(0, 1.5, k)])
        humans = rng.uniform([-3, -1], [3, 1], (2, 2))
        hits, mask = WallRays(obstacles, params.sensing)(states)
        rows = safety_rows(states, hits, mask, humans, rng.uniform(-1, 1, (2, 2)),
                           np.zeros((0, 4)), params)
        yield (rng.uniform(-2, 2, (k, 2)), rows, *_bounds(k))


def _answers(solver: str, seed: int, count: int):
    """Per crowded problem (``_crowded_problems``): its nominal, rows, and Clarabel's and
    ``solver``'s solutions (both successful)."""
    clarabel, other = CbfQp("clarabel"), CbfQp(solver)
    for u_nom, rows, lo, hi in _crowded_problems(seed, count):
        a, b = (qp.solve(u_nom, rows.G, rows.b, lo, hi) for qp in (clarabel, other))
        assert a.success and b.success
        yield u_nom, rows, a, b


def test_both_solvers_agree_on_crowded_problems():
    feasible = infeasible = 0
    for u_nom, rows, a, b in _answers("osqp", 4, 40):
        if max(a.slack.max(initial=0), b.slack.max(initial=0)) < 1e-6:
            feasible += a.solved
            np.testing.assert_allclose(a.u, b.u, atol=1e-4)
        else:
            # Robots spawned inside safety distances: the slack penalty dominates and the
            # optimum is flat in u; the solvers agree on its value.
            infeasible += 1
            cost = [np.sum((u.ravel() - u_nom.ravel()) ** 2) + CbfParams().qp.slack_weight
                    * np.sum(np.maximum(0.0, rows.b - rows.G @ u.ravel())) for u in (a.u, b.u)]
            assert cost[0] == pytest.approx(cost[1], rel=1e-6)
    assert feasible >= 5 and infeasible >= 5


def test_active_set_meets_clarabel_and_hands_it_the_qps_that_need_slack():
    exact = relaxed = 0
    for u_nom, rows, a, b in _answers("active_set", 7, 60):
        assert a.solved == b.solved
        if a.slack.max(initial=0) < 1e-6:  # the slack-free optimum: the same, rows met
            exact += a.solved
            np.testing.assert_allclose(b.u, a.u, atol=1e-5)
            assert np.all(rows.G @ b.u.ravel() >= rows.b - 1e-9)
            assert np.sum((b.u - u_nom) ** 2) <= np.sum((a.u - u_nom) ** 2) + 1e-9
        else:  # rows that must be relaxed: Clarabel's answer, bit for bit
            relaxed += 1
            np.testing.assert_array_equal(b.u, a.u)
    assert exact >= 5 and relaxed >= 5


def test_active_set_answers_are_clipped_to_the_bit_as_numpy_clips():
    """Of two equal bounds numpy's clip returns the second: the acceleration bounds 0.0 and
    -0.0 leave -0.0, the sign a command carries on."""
    lower, upper = np.array([[0.0, -2.0]]), np.array([[-0.0, 2.0]])
    solution = CbfQp("active_set").solve([[0.0, 0.0]], [[0.0, 1.0]], [0.5], lower, upper)
    assert solution.solved and solution.u[0, 1] == pytest.approx(0.5)
    expected = np.minimum(np.maximum(0.0, lower[0, 0]), upper[0, 0])
    assert np.signbit(solution.u[0, 0]) == np.signbit(expected) == np.True_
