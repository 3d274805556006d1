"""The QPs of one tick: the rows that cannot bind are left out without changing an answer."""

import numpy as np
import pytest

from mrta_drake.control.active_set import NOT_LOADED, SOLVED, UNMET
from mrta_drake.control.cbf_params import CbfParams
from mrta_drake.control.input_limits import input_bounds
from mrta_drake.control.qp_solver import CbfQp
from mrta_drake.control.safety_rows import HUMAN, safety_rows
from mrta_drake.control.steering import steer_blocked
from mrta_drake.control.tick_qps import qp_problems


def _random_tick(rng, params):
    """Robots in clusters of 1-4 within a few metres, people near and far (a 40 m floor),
    wall points near some robots; nominal inputs partly outside the input bounds, some
    robots standing and pushing forward (steered)."""
    sizes = rng.integers(1, 5, size=rng.integers(2, 6))
    centres = rng.uniform(-20.0, 20.0, size=(len(sizes), 2))
    xy = np.concatenate([c + rng.uniform(-1.5, 1.5, size=(s, 2))
                         for c, s in zip(centres, sizes, strict=True)])
    n = len(xy)
    speed = np.where(rng.random(n) < 0.3, 0.0, rng.uniform(-0.2, 1.0, n))
    states = np.column_stack([xy, rng.uniform(-np.pi, np.pi, n), speed])
    humans = np.concatenate([rng.uniform(-20.0, 20.0, size=(30, 2)),
                             xy[rng.integers(0, n, 6)] + rng.uniform(-1.2, 1.2, (6, 2))])
    walking = rng.uniform(-1.4, 1.4, size=humans.shape)
    rays = params.sensing.ray_count + 1
    hits = xy[:, None, :] + rng.uniform(-1.5, 1.5, size=(n, rays, 2))
    mask = rng.random((n, rays)) < 0.3
    lower, upper = input_bounds(states, params.nominal, 0.05)
    u_nominal = rng.uniform(-1.5, 1.5, size=(n, 2)) * (upper - lower) + lower
    u_nominal[speed == 0.0, 0] = 2.0  # standing, pushing forward
    groups, start = [], 0
    for s in sizes:
        groups.append(tuple(range(start, start + s)))
        start += s
    return tuple(groups), states, hits, mask, humans, walking, u_nominal, lower, upper


@pytest.mark.parametrize("seed", range(8))
def test_rows_left_out_change_no_answer(seed):
    """Against every row of every group (``safety_rows``), steered, checked and solved as
    ``CbfQp.solve`` does: the same steering, the same settled inputs, the same QPs handed to
    the solver and their answers to the bit, with most people's rows left out."""
    params = CbfParams()
    rng = np.random.default_rng(seed)
    groups, states, hits, mask, humans, walking, u_nominal, lower, upper = _random_tick(
        rng, params)
    qps = qp_problems(groups, states, hits, mask, humans, walking, None, u_nominal.copy(),
                      lower, upper, params)
    solver, human_rows, kept_human_rows = CbfQp("clarabel"), 0, 0
    for g, group in enumerate(groups):
        index = list(group)
        rows = safety_rows(states[index], hits[index], mask[index], humans, walking,
                           np.zeros((0, 4)), params)
        steered = steer_blocked(u_nominal[index], states[index], rows, params)
        np.testing.assert_array_equal(qps.u_nominal[index], steered)
        every = solver.solve(steered, rows.G, rows.b, lower[index], upper[index])
        assert bool(qps.needs_solver[g]) == every.solved
        if every.solved:
            fewer = solver.solve_loaded(qps.loaded(g))
            np.testing.assert_array_equal(fewer.u, every.u)
            assert fewer.slack.max(initial=0.0) == every.slack.max(initial=0.0)
        else:
            np.testing.assert_array_equal(qps.settled[index], every.u)
        kept = qps.problem(g).rows
        human_rows += (rows.kind == HUMAN).sum()
        kept_human_rows += (kept.kind == HUMAN).sum()
        # The rows kept are rows of the full set, in its order.
        full = {(tuple(G), b) for G, b in zip(rows.G, rows.b, strict=True)}
        assert all((tuple(G), b) in full for G, b in zip(kept.G, kept.b, strict=True))
    assert 0 < kept_human_rows < human_rows / 2


def test_a_tick_solved_in_one_call_is_each_qp_solved_alone():
    """``CbfQp.solve_all`` writes each QP's answer to its own robots, the answer
    ``solve_loaded`` gives that QP alone, and hands on the QPs that need the slack."""
    params = CbfParams()
    solver, counts = CbfQp("active_set"), np.zeros(4, dtype=int)
    for seed in range(12):
        groups, states, hits, mask, humans, walking, u_nominal, lower, upper = _random_tick(
            np.random.default_rng(seed), params)
        u_nominal[:, 0] *= 0.2  # gentler than _random_tick's: most rows can all be met
        qps = qp_problems(groups, states, hits, mask, humans, walking, None, u_nominal,
                          lower, upper, params)
        u = qps.settled.copy()
        status = solver.solve_all(qps.data, qps.data_start, qps.kept_count, qps.sizes,
                                  qps.members, qps.group_start, u)
        for g, group in enumerate(groups):
            index, counts[status[g]] = list(group), counts[status[g]] + 1
            if status[g] == SOLVED:
                np.testing.assert_array_equal(u[index], solver.solve_loaded(qps.loaded(g)).u)
            else:
                np.testing.assert_array_equal(u[index], qps.settled[index])
                assert (status[g] == NOT_LOADED) == (not qps.needs_solver[g]
                                                     or not qps.finite[g])
    assert counts[SOLVED] >= 3 and counts[UNMET] >= 3, counts
    assert CbfQp("clarabel").solve_all(qps.data, qps.data_start, qps.kept_count, qps.sizes,
                                       qps.members, qps.group_start, u) is None
