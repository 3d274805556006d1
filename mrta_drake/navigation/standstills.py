"""Standstills: which robots stand blocked by each other, which of them yields, and where to
(pure numpy; the ``DeadlockWatchdog`` block runs these).

Units: metres, seconds; world frame (x east, y north).
"""

import math
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass

import networkx as nx
import numpy as np

from mrta_drake.navigation.costmap import FREE, INSCRIBED, Costmap, inflation_cost
from mrta_drake.payloads import QueueRequest, QueueState
from mrta_drake.world.segment_distances import distance_to_polyline, segment_distances

PASS_WALL_GAP = 0.08  # m, surface to wall, kept by a robot driving to a back-off spot
SEARCH_STEP = 0.1  # m between the points searched for a back-off spot


@dataclass(frozen=True)
class Anchor:
    """Where (``xy``) and since when (``since``) a robot with a goal has not progressed."""

    xy: tuple[float, float]
    since: float


def next_anchor(anchor: Anchor | None, xy, has_goal: bool, now: float,
                progress_distance: float, heading: float | None = None) -> Anchor | None:
    """A robot's anchor after a sample at ``now``: none without a goal; a new one at ``xy``
    when it had none or got farther than ``progress_distance`` from it; else the same.
    With its ``heading`` (rad, from the x axis) given, a robot that got that far
    backwards (against the way it faces: the controller reverses only for safety, so
    others push it back) keeps its time: the anchor moves to ``xy``, its ``since`` kept."""
    if not has_goal:
        return None
    if anchor is None:
        return Anchor((float(xy[0]), float(xy[1])), now)
    if math.dist(anchor.xy, xy) <= progress_distance:
        return anchor
    backwards = heading is not None and ((xy[0] - anchor.xy[0]) * math.cos(heading)
                                         + (xy[1] - anchor.xy[1]) * math.sin(heading)) < 0.0
    return Anchor((float(xy[0]), float(xy[1])), anchor.since if backwards else now)


@dataclass(frozen=True)
class Pose:
    """Where (``xy``, m), facing which way (``heading``, rad, from the x axis) and since
    when (``since``, s) a robot on its way somewhere has neither moved nor turned."""

    xy: tuple[float, float]
    heading: float
    since: float


def next_pose(pose: Pose | None, state, now: float, progress_distance: float,
              progress_angle: float) -> Pose:
    """A robot's ``Pose`` after a sample at ``now`` of its ``state`` (x, y, theta, ...): a
    new one as it stands when it had none, got farther than ``progress_distance`` from
    it or turned more than ``progress_angle`` from its heading (a robot turning round
    to drive off makes headway before it moves); else the same."""
    xy, heading = (float(state[0]), float(state[1])), float(state[2])
    if (pose is None or math.dist(pose.xy, xy) > progress_distance
            or abs(math.remainder(heading - pose.heading, math.tau)) > progress_angle):
        return Pose(xy, heading, now)
    return pose


def blocked_groups(stalled: np.ndarray, xy: np.ndarray, radii: np.ndarray,
                   block_gap: float) -> list[tuple[int, ...]]:
    """The groups of robots standing in each other's way: each stalled robot (``stalled``
    (N,) bool) joined with every robot within ``block_gap`` of it (surface to surface),
    transitively; groups without two robots are left out. Each group is sorted, and the
    groups by their first member."""
    n = len(xy)
    gaps = np.linalg.norm(xy[:, None, :] - xy[None, :, :], axis=-1) - radii[:, None] - radii
    near = (gaps <= block_gap) & ~np.eye(n, dtype=bool)
    links = near & (stalled[:, None] | stalled[None, :])
    members = [k for k in range(n) if stalled[k] or links[k].any()]
    return [group for group in _joined(members, zip(*np.nonzero(links), strict=True))
            if len(group) > 1]


def _joined(members, links) -> list[tuple]:
    """The groups of ``members`` joined by ``links`` (pairs), transitively: each group
    sorted, the groups by their first member."""
    graph = nx.Graph()
    graph.add_nodes_from(members)
    graph.add_edges_from(links)
    return sorted(tuple(sorted(group)) for group in nx.connected_components(graph))


def waits_for(queues: QueueState, requests: Sequence[QueueRequest]) -> dict[str, set[str]]:
    """Who each robot waiting for a room or single-file segments waits for (robot name ->
    robot names): the room's holder; the other robots holding segments it asks for (also
    those it holds with them: where robots stop, a segment is one robot's at a time), or,
    with none, the robots before it waiting for one of those segments (first come, first
    served). The run recorder's and the watchdog's facts of a gridlock of waits."""
    waits = {robot: {queue.holder} - {None} for queue in queues.rooms
             for robot in queue.waiting}
    wanted = {request.robot: [k for k, _ in request.segments] for request in requests}
    for i, robot in enumerate(queues.segment_waiting):
        asked = wanted.get(robot, ())
        held = {other for k in asked for other in queues.segments[k].holders} - {robot}
        if not held:
            held = {other for other in queues.segment_waiting[:i]
                    if not set(wanted.get(other, ())).isdisjoint(asked)}
        waits.setdefault(robot, set()).update(held)
    return waits


def gridlocks(waits: Mapping[str, Collection[str]], stalled: Collection[str]
              ) -> list[tuple[str, ...]]:
    """The gridlocks of waits: each ``stalled`` robot (waiting, its waits leading to no
    robot that moves or serves: ``results.deadlocks.stalled_waits``) joined with the robots
    it waits for, transitively (a cycle of waits, or a chain ending in a robot that stands
    for good). Each gridlock is sorted, and the gridlocks by their first member."""
    return _joined(stalled, ((robot, other) for robot in stalled
                             for other in waits.get(robot, ())))


def wait_cycles(waits: Mapping[str, Collection[str]], asks: Mapping[str, Collection[int]],
                stands: Mapping[str, Collection[int]], still: Collection[str]
                ) -> list[tuple[str, ...]]:
    """The cycles of waits among the robots standing ``still`` (neither moving nor serving):
    robot a waits for robot b when b is one it waits for (``waits``, ``waits_for``'s) or
    b stands in a single-file segment a asks for (``stands``, ``asks``: robot -> segment
    indices): a room's holder kept off its way by a robot queueing for its room in that
    way waits for it as surely as for a segment's holder. Robots that wait for each other,
    transitively both ways, wait for good: each such group of two or more (the strongly
    connected components), sorted, the groups by their first member."""
    graph = nx.DiGraph()
    graph.add_nodes_from(still)
    graph.add_edges_from((a, b) for a in still for b in still if a != b and (
        b in waits.get(a, ()) or not set(asks.get(a, ())).isdisjoint(stands.get(b, ()))))
    return sorted(tuple(sorted(group)) for group in nx.strongly_connected_components(graph)
                  if len(group) > 1)


def yield_order(group: tuple[int, ...], idle: np.ndarray, stalled: np.ndarray,
                priorities: np.ndarray, in_way=None) -> list[int]:
    """Who of ``group`` is asked to yield first: robots standing in a stalled robot's way
    (``in_way`` (N,) bool, see ``in_ways``; none if None), then the others; within each,
    robots without a goal (``idle``: they lose nothing by moving), then the stalled ones,
    then those standing at their goal; within each, the lowest priority (largest
    ``priorities`` value) first."""
    def rank(k: int) -> tuple[int, int, float]:
        kind = 0 if idle[k] else 1 if stalled[k] else 2
        return 0 if in_way is not None and in_way[k] else 1, kind, -float(priorities[k])

    return sorted(group, key=rank)


def in_ways(group: tuple[int, ...], stalled: np.ndarray, xy: np.ndarray, radii: np.ndarray,
            ways: list[np.ndarray], clearance: float,
            doors: Mapping[int, Collection[int]] | None = None) -> np.ndarray:
    """(N,) bool: the robots of ``group`` standing first in the way of another robot of it.
    In a stalled robot's way: ahead of it (on the side of its way's first waypoint) and
    nearer its way (``ways[s]`` (P, 2), from where it stands on) than their radii and
    ``clearance`` (m); in the way of a room's holder waiting at its door: standing in
    its doorway (``doors``: robot index -> the indices of the robots it waits for there,
    ``QueueRequest.door``). Of the robots in one robot's way, only the nearest to it
    counts: a robot behind a stalled one, beside its way, or behind the first robot in it
    frees nothing by moving while the first stands."""
    in_way = np.zeros(len(xy), dtype=bool)
    doors = doors or {}
    members = set(group)
    for s in group:
        blocking = [k for k in doors.get(s, ()) if k in members and k != s]
        way = np.asarray(ways[s], dtype=float).reshape(-1, 2)
        if stalled[s] and len(way) >= 2:
            ahead = way[1] - xy[s]
            blocking += [k for k in group if k != s
                         and float(np.dot(xy[k] - xy[s], ahead)) > 0.0
                         and float(distance_to_polyline(xy[k], way))
                         < radii[k] + radii[s] + clearance]
        if blocking:
            in_way[min(blocking, key=lambda k: (float(np.linalg.norm(xy[k] - xy[s])), k))] = True
    return in_way


def back_off_spot(k: int, xy: np.ndarray, radii: np.ndarray,
                  ways: list[tuple[np.ndarray, float]],
                  people_xy: np.ndarray, people_radii: np.ndarray, costmap: Costmap,
                  reach: float, clearance: float, wall_clearance: float,
                  avoid=(), avoid_radius: float = 0.0, min_move: float = 0.0
                  ) -> tuple[float, float] | None:
    """The nearest spot to which robot ``k`` at ``xy[k]`` can drive out of the others' way,
    or None: searched on a grid of ``SEARCH_STEP`` within ``reach`` of it, moving between
    neighbouring points (4-connected) where its centre may be: on cells at least the
    costmap's robot radius plus ``PASS_WALL_GAP`` from walls (the controller's contact
    guard, ``SafetyDistances.wall_contact``, keeps about that: robots drive corridors
    narrower than twice the inflation radius, as the office's between furniture, which
    have no ``FREE`` cell), or, within the inflation radius of where it stands, on cells
    no costlier than that (never lethal: it gets out of a door, or off a wall it was
    pushed to), no nearer another robot than ``clearance`` (surface to surface), except within
    ``clearance`` of where it stands, and there no nearer than it is now. A spot is such a
    point at least ``wall_clearance`` from walls (the free points eroded by the grid steps
    beyond the inflation radius), at least ``clearance`` (surface to surface) from every
    other robot and person and from each of ``ways`` ((polyline (P, 2), radius): the way a
    blocker of that radius will follow, e.g. from where it stands to its target), at least
    ``min_move`` from where it stands, and farther than ``avoid_radius`` from each of
    ``avoid`` ((M, 2): spots it was sent to and did not reach).
    Nearest: the fewest grid moves, ties in grid order."""
    n_side = int(reach / SEARCH_STEP)
    offsets = np.arange(-n_side, n_side + 1) * SEARCH_STEP
    points = xy[k] + np.stack(np.meshgrid(offsets, offsets, indexing="ij"), axis=-1)
    # Robots and people farther than ``far`` (surface to centre) from robot k are more than
    # ``clearance`` from it at every point within ``reach`` (the only points passable, so
    # the only ones searched): leaving them out changes nothing.
    far = reach + radii[k] + clearance + 1e-6
    others = np.delete(np.arange(len(xy)), k)
    others = others[np.linalg.norm(xy[others] - xy[k], axis=-1) - radii[others] < far]
    with np.errstate(invalid="ignore"):  # people absent from the run are NaN: left out
        near = np.linalg.norm(people_xy - xy[k], axis=-1) - people_radii < far
    people_xy, people_radii = people_xy[near], people_radii[near]
    robot_gaps = (np.linalg.norm(points[..., None, :] - xy[others], axis=-1)
                  - radii[others] - radii[k])
    # Closer to another robot than ``clearance`` only while getting away from where it
    # stands (within ``clearance`` of it), and no closer than now: sliding along a robot
    # it is squeezed against is no way out (the controller keeps their distance).
    start_gaps = np.linalg.norm(xy[others] - xy[k], axis=-1) - radii[others] - radii[k]
    moved = np.hypot(*np.moveaxis(points - xy[k], -1, 0))
    cost = costmap.cost_at(points)
    free = cost == FREE
    # A robot standing nearer a wall than the inflation radius (pushed there, or in a
    # door or narrow corridor) leaves through cells no costlier than where it stands,
    # within that radius of it: else every neighbour is closed to it and it never gets
    # a spot (the hotel, seed 4: robot6 squeezed against a wall's end, 26 s, no order).
    leaving = ((cost <= min(int(costmap.cost_at(xy[k:k + 1])[0]), INSCRIBED))
               & (moved <= costmap.params.inflation_radius))
    squeezed = robot_gaps < clearance
    cp = costmap.params  # the cells beyond robot radius + PASS_WALL_GAP from walls:
    drivable = cost <= inflation_cost(cp.robot_radius + PASS_WALL_GAP, cp.robot_radius,
                                      cp.inflation_radius, cp.cost_scaling,
                                      costmap.resolution)
    passable = ((drivable | leaving) & (moved <= reach)
                & (~squeezed | ((robot_gaps >= start_gaps - 1e-9)
                                & (moved[..., None] <= clearance))).all(axis=-1))
    with np.errstate(invalid="ignore"):  # people absent from the run are NaN
        people_clear = ~((np.linalg.norm(points[..., None, :] - people_xy, axis=-1)
                          - people_radii - radii[k]) < clearance).any(axis=-1)
    steps = math.ceil((wall_clearance - costmap.params.inflation_radius) / SEARCH_STEP - 1e-9)
    spot_ok = (passable & _eroded(free, steps) & (robot_gaps >= clearance).all(axis=-1)
               & people_clear & (moved >= min_move))
    if ways:  # the costly test: every way's lanes at once, only where still spots
        still = np.flatnonzero(spot_ok)
        a, b, gap = _way_pieces(ways, radii[k] + clearance)
        keep = (segment_distances(points.reshape(-1, 2)[still], a, b) >= gap).all(axis=-1)
        spot_ok = np.zeros(spot_ok.shape, dtype=bool)
        spot_ok.flat[still[keep]] = True
    for missed in np.asarray(avoid, dtype=float).reshape(-1, 2):
        spot_ok &= np.linalg.norm(points - missed, axis=-1) > avoid_radius
    start = (n_side, n_side)
    passable[start] = True
    seen = np.zeros(passable.shape, dtype=bool)
    seen[start] = True
    frontier = [start]
    while frontier:
        reached = []
        for i, j in frontier:
            if spot_ok[i, j]:
                return (float(points[i, j, 0]), float(points[i, j, 1]))
            for a, b in ((i - 1, j), (i + 1, j), (i, j - 1), (i, j + 1)):
                if 0 <= a < passable.shape[0] and 0 <= b < passable.shape[1] \
                        and passable[a, b] and not seen[a, b]:
                    seen[a, b] = True
                    reached.append((a, b))
        frontier = reached
    return None


def near_walls(xy, costmap: Costmap, wall_clearance: float) -> bool:
    """Whether a centre at ``xy`` is nearer than ``wall_clearance`` to a wall, as
    ``back_off_spot`` judges a spot (not ``FREE`` on ``costmap`` within the grid steps of
    ``SEARCH_STEP`` beyond its inflation radius)."""
    steps = math.ceil((wall_clearance - costmap.params.inflation_radius) / SEARCH_STEP - 1e-9)
    offsets = np.arange(-steps - 1, steps + 2) * SEARCH_STEP
    points = np.asarray(xy, dtype=float) + np.stack(
        np.meshgrid(offsets, offsets, indexing="ij"), axis=-1)
    return not _eroded(costmap.cost_at(points) == FREE, steps)[steps + 1, steps + 1]


def _eroded(mask: np.ndarray, steps: int) -> np.ndarray:
    """``mask`` where every point within ``steps`` 4-connected moves is set too (the
    border counts as unset)."""
    for _ in range(max(0, steps)):
        inner = np.zeros_like(mask)
        inner[1:-1, 1:-1] = (mask[1:-1, 1:-1] & mask[:-2, 1:-1] & mask[2:, 1:-1]
                             & mask[1:-1, :-2] & mask[1:-1, 2:])
        mask = inner
    return mask


def _way_pieces(ways: list[tuple[np.ndarray, float]], margin: float
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The straight pieces of all ``ways`` ((polyline (P, 2), radius)) as starts (S, 2),
    ends (S, 2) and the least distance (S,) a spot keeps from each: its way's radius plus
    ``margin`` (m); a way of one point is a piece of no length."""
    starts, ends, gaps = [], [], []
    for way, radius in ways:
        way = np.asarray(way, dtype=float).reshape(-1, 2)
        if len(way) == 1:
            way = np.vstack([way, way])
        starts.append(way[:-1])
        ends.append(way[1:])
        gaps.append(np.full(len(way) - 1, radius + margin))
    return np.concatenate(starts), np.concatenate(ends), np.concatenate(gaps)
