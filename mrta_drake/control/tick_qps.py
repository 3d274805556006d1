"""The QPs of one tick, made in one compiled call: every group's safety rows, the steering of
its blocked robots, and whether its clipped nominal already meets its rows (then no solver
runs), so that only the QPs that need a solver reach Python objects and the solver."""

import itertools
from dataclasses import dataclass

import numba
import numpy as np

from mrta_drake.control.cbf_params import CbfParams
from mrta_drake.control.qp_solver import (
    LoadedQp,
    check_nominal,
    kept_rows,
    load_qp,
    padded_rows,
    qp_data_size,
)
from mrta_drake.control.safety_rows import (
    SafetyRows,
    count_rows,
    empty_rows,
    far_humans,
    fill_rows,
)
from mrta_drake.control.steering import steer
from mrta_drake.stack.compiled_helper import compiled_helper


@dataclass(frozen=True)
class QpProblem:
    """One QP of a tick: the robots whose inputs it decides (``members``), their nominal
    inputs and hard bounds (k, 2) ``[a, omega]``, and the safety rows."""

    members: tuple[int, ...]
    u_nominal: np.ndarray
    rows: SafetyRows
    lower: np.ndarray
    upper: np.ndarray


@dataclass(frozen=True, eq=False)
class TickQps:
    """The QPs of one tick (``qp_problems``), kept as the compiled kernel made them: group g's
    robots ``groups[g]``, rows ``G[G_start[g]:G_start[g + 1]]`` (flattened) and ``b``, ...
    ``[row_start[g]:row_start[g + 1]]``; whether it needs a solver; the steered nominal
    inputs, bounds and ``settled`` inputs (N, 2) of ``qp_problems``; which robots stand
    (``standing`` (N,), |v| < ``coordination.stall_speed``); and, for the QPs that need a
    solver, what ``CbfQp.solve`` would load into its program (``loaded``): whether the
    rows are ``finite``, the rows kept (``kept[row_start[g]:row_start[g] + kept_count[g]]``),
    their padded count ``sizes[g]`` and the program's data
    ``data[data_start[g]:data_start[g + 1]]`` (empty for the others). The groups as
    arrays: group g is ``members[group_start[g]:group_start[g + 1]]``."""

    groups: tuple[tuple[int, ...], ...]
    members: np.ndarray
    group_start: np.ndarray
    u_nominal: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    G: np.ndarray
    G_start: np.ndarray
    rows: tuple[np.ndarray, ...]  # b, kind, h, member, other, normal
    row_start: np.ndarray
    needs_solver: np.ndarray
    settled: np.ndarray
    standing: np.ndarray
    finite: np.ndarray
    kept: np.ndarray
    kept_count: np.ndarray
    sizes: np.ndarray
    data: np.ndarray
    data_start: np.ndarray

    def problem(self, g: int) -> QpProblem:
        """Group g's QP."""
        r0, r1 = self.row_start[g], self.row_start[g + 1]
        u_nominal, G, b, lower, upper = self.arrays(g)
        rows = SafetyRows(G, b, *(a[r0:r1] for a in self.rows[1:]))
        return QpProblem(self.groups[g], u_nominal, rows, lower, upper)

    def arrays(self, g: int) -> tuple[np.ndarray, ...]:
        """Group g's QP as ``CbfQp.solve`` takes it: nominal inputs, ``G``, ``b``, bounds."""
        group, r0, r1 = self.groups[g], self.row_start[g], self.row_start[g + 1]
        index = list(group)
        return (self.u_nominal[index], self.G[self.G_start[g]:self.G_start[g + 1]].reshape(
            r1 - r0, 2 * len(group)), self.rows[0][r0:r1], self.lower[index], self.upper[index])

    def loaded(self, g: int) -> LoadedQp:
        """Group g's QP as loaded for the solver (``CbfQp.solve_loaded``; for a group that
        ``needs_solver``)."""
        r0 = self.row_start[g]
        return LoadedQp(len(self.groups[g]), int(self.row_start[g + 1] - r0),
                        bool(self.finite[g]), self.kept[r0:r0 + self.kept_count[g]],
                        int(self.sizes[g]), self.data[self.data_start[g]:self.data_start[g + 1]])

    def turns_fixed(self, g: int, u_nominal, lower, upper) -> tuple[np.ndarray, np.ndarray]:
        """Group g's bounds ``lower``, ``upper`` (k, 2) with each standing robot's yaw rate
        fixed at its nominal's (``u_nominal`` (k, 2), clipped), for when its rows cannot all
        be met: a standing robot's yaw rate enters the rows only through ``v omega``
        (``barriers``), a term near zero whose sign is that of ``v``, so the QP would spend
        it at full rate to shave the slack, one way while the robot creeps back and the
        other way once it creeps forward, tick after tick, and it would never get away
        (issue 15)."""
        standing = self.standing[list(self.groups[g])]
        lower, upper = np.array(lower, dtype=float), np.array(upper, dtype=float)
        lower[standing, 1] = upper[standing, 1] = np.clip(
            np.asarray(u_nominal)[standing, 1], lower[standing, 1], upper[standing, 1])
        return lower, upper

    @property
    def problems(self) -> tuple[QpProblem, ...]:
        """Every group's QP."""
        return tuple(self.problem(g) for g in range(len(self.groups)))

    def to_solve(self) -> tuple[int, ...]:
        """The groups whose QPs need a solver."""
        return tuple(itertools.compress(itertools.count(), self.needs_solver.tolist()))


_NO_MOVERS = np.zeros((0, 4))


def qp_problems(groups, states, hits, hit_mask, human_positions, human_velocities, movers,
                u_nominal, lower, upper, params: CbfParams, members=None,
                group_start=None) -> TickQps:
    """The QPs of one tick for robots ``states`` (N, 4) solved in ``groups`` (tuples of robot
    indices), with their wall ``hits`` and ``hit_mask`` (as from ``WallRays``), the humans,
    ``movers`` (one (q, 4) array per group as in ``safety_rows``; None: none) and hard
    bounds ``lower``, ``upper`` (N, 2). Each group's rows are ``safety_rows``; its robots'
    ``u_nominal`` (a float array (N, 2)) are steered in place (``steer_blocked``; not with
    ``nominal.corner_steering`` off). A group
    needs a solver when its clipped nominal breaks a row (or its rows are not finite: the
    solve then fails); for the robots of the others the clipped nominal is the optimum
    (``CbfQp.solve`` would return it): ``settled`` holds it, and zero for robots in no
    group. ``members`` and ``group_start``: the groups as arrays (group g is
    ``members[group_start[g]:group_start[g + 1]]``), if the caller has them."""
    groups = tuple(map(tuple, groups))
    if members is None:
        members = np.array([i for group in groups for i in group], dtype=np.int64)
        group_start = np.cumsum([0] + [len(group) for group in groups], dtype=np.int64)
    if movers is None:
        movers, mover_start = _NO_MOVERS, np.zeros(len(groups) + 1, dtype=np.int64)
    else:
        mover_start = np.array([0] + [len(m) for m in movers], dtype=np.int64).cumsum()
        movers = np.concatenate([np.zeros((0, 4)), *movers]).reshape(-1, 4)
    n = len(states)
    states = np.ascontiguousarray(states, dtype=float).reshape(n, 4)
    lower, upper = np.ascontiguousarray(lower, dtype=float), np.ascontiguousarray(upper,
                                                                                 dtype=float)
    settled = np.zeros((n, 2))
    G, G_start, *rows, row_start, needs_solver, loads = _group_rows(
        states, np.ascontiguousarray(hits, dtype=float).reshape(n, -1, 2),
        np.ascontiguousarray(human_positions, dtype=float).reshape(-1, 2),
        np.ascontiguousarray(human_velocities, dtype=float).reshape(-1, 2),
        np.ascontiguousarray(hit_mask, dtype=bool).reshape(n, -1), members, group_start,
        movers, mover_start, params.row_params, params.coordination.stall_speed,
        params.nominal.k_v, params.nominal.k_theta, params.nominal.corner_steering, u_nominal,
        lower, upper, settled)
    standing = np.abs(states[:, 3]) < params.coordination.stall_speed
    return TickQps(groups, members, group_start, u_nominal, lower, upper, G, G_start,
                   tuple(rows), row_start, needs_solver, settled, standing, *loads)


@numba.njit(cache=True)
def _group_rows(states, hits, humans, human_velocities, mask, members, group_start, movers,
                mover_start, params, stall_speed, k_v, k_theta, corner_steering, u_nominal,
                lower, upper, settled):
    """``qp_problems`` for the groups ``members[group_start[g]:group_start[g + 1]]`` with
    movers ``movers[mover_start[g]:mover_start[g + 1]]``: every group's rows (G of group g
    flattened at ``G[G_start[g]:G_start[g + 1]]``, the other arrays at
    ``row_start[g]:row_start[g + 1]``), steering ``u_nominal`` in place (with
    ``corner_steering``; ``k_v``, ``k_theta`` as in ``steering.steer``), and whether each
    group needs its QP solved; ``settled`` gets the others' clipped nominal inputs; and
    what ``TickQps.loaded`` reads for the groups that need a solver (``_load_groups``)."""
    groups = len(group_start) - 1
    # The box the rows are proven idle against (fill_rows): the bounds and the nominal.
    box_lower, box_upper = _hull(lower, upper, u_nominal)
    far = far_humans(states, humans, human_velocities, box_lower, box_upper, params)
    radius2 = params[9] * params[9]
    room = np.zeros(groups + 1, dtype=np.int64)  # each group's place for its rows, ...
    G_room = np.zeros(groups + 1, dtype=np.int64)  # ... and for its G, at most count_rows
    for g in range(groups):
        index = members[group_start[g]:group_start[g + 1]]
        m = count_rows(states[index], mask[index], far[index],
                       movers[mover_start[g]:mover_start[g + 1]], radius2)
        room[g + 1] = room[g] + m
        G_room[g + 1] = G_room[g] + m * 2 * len(index)
    G = np.zeros(G_room[groups])
    b, kind, h, member, other, normal = empty_rows(room[groups], 0)[1:]
    row_start = np.zeros(groups + 1, dtype=np.int64)  # where they are once moved together
    G_start = np.zeros(groups + 1, dtype=np.int64)
    needs_qp = np.zeros(groups, dtype=np.bool_)
    finite = np.ones(groups, dtype=np.bool_)
    for g in range(groups):
        index = members[group_start[g]:group_start[g + 1]]
        k, r0 = len(index), room[g]
        u, group_states = u_nominal[index], states[index]
        lo, hi = lower[index].ravel(), upper[index].ravel()
        m = fill_rows(group_states, hits[index], mask[index], humans, human_velocities,
                      far[index], movers[mover_start[g]:mover_start[g + 1]], params,
                      box_lower[index], box_upper[index],
                      G[G_room[g]:G_room[g + 1]].reshape((room[g + 1] - r0, 2 * k)), b[r0:],
                      kind[r0:], h[r0:], member[r0:], other[r0:], normal[r0:])
        r1 = r0 + m
        row_start[g + 1], G_start[g + 1] = row_start[g] + m, G_start[g] + m * 2 * k
        G_g = G[G_room[g]:G_room[g] + m * 2 * k].reshape((m, 2 * k))
        if corner_steering:
            steer(u, group_states, G_g, b[r0:r1], member[r0:r1], other[r0:r1],
                  normal[r0:r1], stall_speed, k_v, k_theta)
        _scatter_rows(u_nominal, index, u)
        flat = u.ravel()
        clipped = np.minimum(np.maximum(flat, lo), hi)
        finite[g], optimal = check_nominal(G_g, b[r0:r1], flat, clipped)
        needs_qp[g] = not (finite[g] and optimal)
        if not needs_qp[g]:
            _scatter_rows(settled, index, clipped.reshape((k, 2)))
    for g in range(groups):  # the groups' rows together (forwards: never onto unread rows)
        for j in range(G_start[g + 1] - G_start[g]):
            G[G_start[g] + j] = G[G_room[g] + j]
        for row in range(row_start[g + 1] - row_start[g]):
            source, target = room[g] + row, row_start[g] + row
            b[target], kind[target], h[target] = b[source], kind[source], h[source]
            member[target], other[target] = member[source], other[source]
            normal[target, 0], normal[target, 1] = normal[source, 0], normal[source, 1]
    rows = row_start[groups]
    G, b, kind, h, member, other, normal = (G[:G_start[groups]], b[:rows], kind[:rows],
                                            h[:rows], member[:rows], other[:rows],
                                            normal[:rows])
    loads = _load_groups(G, G_start, b, row_start, members, group_start, u_nominal, lower,
                         upper, needs_qp, finite)
    return G, G_start, b, kind, h, member, other, normal, row_start, needs_qp, loads


@compiled_helper
def _load_groups(G, G_start, b, row_start, members, group_start, u_nominal, lower, upper,
                 needs_qp, finite):
    """For each group whose QP needs a solver and whose rows are finite, what ``_prepare``
    in ``CbfQp.solve`` makes of it: the rows kept, their padded count and the program's
    data (``load_qp``); ``TickQps``' ``finite`` to ``data_start``."""
    groups = len(group_start) - 1
    kept = np.empty(row_start[groups], np.int64)
    kept_count = np.zeros(groups, np.int64)
    sizes = np.zeros(groups, np.int64)
    data_start = np.zeros(groups + 1, np.int64)
    for g in range(groups):
        index = members[group_start[g]:group_start[g + 1]]
        r0, r1 = row_start[g], row_start[g + 1]
        if needs_qp[g] and finite[g]:
            G_g = G[G_start[g]:G_start[g + 1]].reshape((r1 - r0, 2 * len(index)))
            kept_count[g] = kept_rows(G_g, b[r0:r1], lower[index].ravel(),
                                      upper[index].ravel(), kept[r0:r1])
            sizes[g] = padded_rows(kept_count[g])
            data_start[g + 1] = qp_data_size(2 * len(index), sizes[g])
        data_start[g + 1] += data_start[g]
    data = np.empty(data_start[groups])
    for g in range(groups):
        if data_start[g + 1] > data_start[g]:
            index = members[group_start[g]:group_start[g + 1]]
            r0, r1 = row_start[g], row_start[g + 1]
            G_g = G[G_start[g]:G_start[g + 1]].reshape((r1 - r0, 2 * len(index)))
            load_qp(u_nominal[index].ravel(), G_g, b[r0:r1], kept[r0:r0 + kept_count[g]],
                    lower[index].ravel(), upper[index].ravel(), sizes[g],
                    data[data_start[g]:data_start[g + 1]])
    return finite, kept, kept_count, sizes, data, data_start


@compiled_helper
def _hull(lower, upper, u):
    """The smallest box (two (N, 2) arrays) that holds the box [``lower``, ``upper``] and
    ``u`` (N, 2), element by element: numba's 2-D ``np.minimum`` is another compile."""
    low, high = np.empty_like(lower), np.empty_like(upper)
    for i in range(len(u)):
        for c in range(2):
            low[i, c], high[i, c] = min(lower[i, c], u[i, c]), max(upper[i, c], u[i, c])
    return low, high


@compiled_helper
def _scatter_rows(target, index, rows):
    """``target[index] = rows`` for (k, 2) ``rows``, element by element: numba's fancy-index
    assignment (broadcasting and its error messages) takes seconds to compile."""
    for a in range(len(index)):
        target[index[a], 0], target[index[a], 1] = rows[a, 0], rows[a, 1]
