"""How robots treated the humans in one run, from logged trajectories (pure numpy).

Every distance here is surface to surface: centre distance minus the robot's and the human's
radius (negative when the bodies overlap). A sample's state is taken to hold until the next
sample, so sample k weighs ``times[k + 1] - times[k]`` s and the last sample weighs nothing.
A human absent at a sample (not yet entered) has NaN coordinates there and is ignored.

Units: metres, seconds; world frame.
"""

from dataclasses import dataclass

import numpy as np

PERSONAL_SPACE = 0.5  # m, surface to surface
DETOUR_RANGE = 2.0  # m, surface to surface
CORNER_RADIUS = 1.0  # m, how near its waypoint a human's turn is looked for


@dataclass(frozen=True)
class HumanMetrics:
    """Per-run human-robot interaction figures.

    - ``min_distance``: smallest robot-human surface distance, m (inf with no robot or no
      human present); ``min_distance_time``: the first time it occurred, s (nan if none).
    - ``personal_space_time``: robot-seconds robots spent with their surface closer than
      ``personal_space`` to some human's surface (a robot near two humans counts once).
    - ``contacts``: contact onsets: per robot-human pair, the samples where the surface
      distance is <= 0 but was not at the previous sample (or is at the first sample).
    - ``encounters``: per human, maximal runs of consecutive samples where the human is
      present and some robot is within ``detour_range``; ``encounter_length``: path length
      the humans walked during them, m; ``detour_length``: the sum over encounters of that
      path length minus the length of the straight route through the encounter: from its
      first position, via the human's turning points, to its last position, m: the extra
      walking done while robots were near. The turning points are, for each of the human's
      waypoints (when given) and each stretch of the encounter within ``corner_radius`` of
      it, the sample nearest the waypoint; without waypoints the route is the straight
      line, and the human's own corners inside an encounter count as detour (compare runs
      with and without robots then).
    """

    min_distance: float
    min_distance_time: float
    personal_space_time: float
    contacts: int
    encounters: int
    encounter_length: float
    detour_length: float


def human_metrics(
    times,
    robot_xy,
    human_xy,
    robot_radii,
    human_radii,
    personal_space: float = PERSONAL_SPACE,
    detour_range: float = DETOUR_RANGE,
    human_waypoints=None,
    corner_radius: float = CORNER_RADIUS,
) -> HumanMetrics:
    """Metrics of one run from ``times`` (T,) s increasing, ``robot_xy`` (T, N, 2),
    ``human_xy`` (T, M, 2) (NaN where a human is absent), ``robot_radii`` (N,) or scalar and
    ``human_radii`` (M,) or scalar, m; optionally ``human_waypoints``: per human, its
    waypoints ((x, y) each, e.g. ``Person.waypoints``), to tell route corners from detours."""
    t = np.asarray(times, dtype=float)
    robots = np.asarray(robot_xy, dtype=float)
    humans = np.asarray(human_xy, dtype=float)
    n, m = robots.shape[1], humans.shape[1]
    if robots.shape != (len(t), n, 2) or humans.shape != (len(t), m, 2):
        raise ValueError(f"expected robot_xy (T, N, 2) and human_xy (T, M, 2) with T = {len(t)}, "
                         f"got {robots.shape} and {humans.shape}")
    if len(t) == 0:
        return HumanMetrics(float("inf"), float("nan"), 0.0, 0, 0, 0.0, 0.0)
    r_robot = np.broadcast_to(np.asarray(robot_radii, dtype=float), (n,))
    r_human = np.broadcast_to(np.asarray(human_radii, dtype=float), (m,))
    weights = np.append(np.diff(t), 0.0)

    centre = np.linalg.norm(robots[:, :, None, :] - humans[:, None, :, :], axis=3)
    surface = centre - r_robot[None, :, None] - r_human[None, None, :]  # (T, N, M), NaN absent
    if np.isfinite(surface).any():
        k = np.nanargmin(surface)
        min_distance = float(surface.flat[k])
        min_time = float(t[np.unravel_index(k, surface.shape)[0]])
    else:
        min_distance, min_time = float("inf"), float("nan")

    with np.errstate(invalid="ignore"):
        intruding = (surface < personal_space).any(axis=2)  # (T, N)
        touching = surface <= 0.0
        near = (surface < detour_range).any(axis=1)  # (T, M)
    onsets = touching[0].sum() + (touching[1:] & ~touching[:-1]).sum()

    present = np.isfinite(humans).all(axis=2)
    steps = np.linalg.norm(np.diff(humans, axis=0), axis=2)  # (T-1, M)
    encounters, walked, detour = 0, 0.0, 0.0
    for j in range(m):
        waypoints = np.zeros((0, 2)) if human_waypoints is None else np.reshape(
            np.asarray(human_waypoints[j], dtype=float), (-1, 2))
        for first, last in _runs(near[:, j] & present[:, j]):
            path = humans[first:last + 1, j]
            length = float(steps[first:last, j].sum())
            route = path[np.r_[0, _turns(path, waypoints, corner_radius), len(path) - 1]]
            encounters += 1
            walked += length
            detour += length - float(np.linalg.norm(np.diff(route, axis=0), axis=1).sum())

    return HumanMetrics(
        min_distance=min_distance,
        min_distance_time=min_time,
        personal_space_time=float((intruding * weights[:, None]).sum()),
        contacts=int(onsets),
        encounters=encounters,
        encounter_length=walked,
        detour_length=detour,
    )


def _turns(path: np.ndarray, waypoints: np.ndarray, radius: float) -> np.ndarray:
    """Sorted indices into ``path`` (k, 2) of the samples nearest each waypoint, one per
    stretch of the path within ``radius`` of that waypoint."""
    turns = []
    for w in waypoints:
        distance = np.linalg.norm(path - w, axis=1)
        for first, last in _runs(distance < radius):
            turns.append(first + int(np.argmin(distance[first:last + 1])))
    return np.array(sorted(turns), dtype=int)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) sample indices, inclusive, of each maximal run of True in ``mask``."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    starts = np.flatnonzero(edges == 1)
    ends = np.flatnonzero(edges == -1) - 1
    return list(zip(starts.tolist(), ends.tolist(), strict=True))
