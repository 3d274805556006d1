"""Deadlocks: robots that should be moving but make no progress (pure numpy).

A robot *should move* at a sample when it has somewhere to go that waiting does not explain:
an active target for a stop it is not queueing for or serving (the recorder's ``DRIVE``
mode). It is *stuck* once it has stayed within ``progress_distance`` of where it was at the
start of a stretch of should-move samples for ``stuck_time`` of them; samples where it
queues (``QUEUE``) in between neither end the stretch nor count. The deadlock lasts until
it gets farther than that from that place or has nothing to do (idle or serving).

Waiting for a room or a single-file segment is queueing, not being stuck, only while the
wait leads somewhere: ``stalled_waits`` finds the robots whose waits (for the robots
holding what they wait for, and so on) reach no robot that moves or serves; the recorder
asks that of every robot a wait is for (a robot asking for segments held by a robot that
moves and by one that stands for good is stuck). Robots standing
in each other's rooms or segments, each waiting for the other, are a gridlock: the recorder
counts them as ``DRIVE``, so one lasting ``stuck_time`` is a deadlock.

Units: metres, seconds; world frame.
"""

from collections.abc import Collection, Mapping
from dataclasses import dataclass

import numpy as np

STUCK_TIME = 30.0  # s without progress before a robot counts as deadlocked
PROGRESS_DISTANCE = 0.5  # m a robot must get from where it stopped to have progressed
NEIGHBOUR_RANGE = 2.0  # m, centre to centre: who is reported as near a stuck robot


@dataclass(frozen=True)
class Deadlock:
    """One robot stuck from ``start`` (its last progress, s), noticed at ``detected``
    (once ``stuck_time`` of should-move samples since ``start`` added up), until ``end``
    (s; None when still stuck at the end of the run), at ``position`` (x, y), m.
    ``robots_near`` and ``humans_near`` were within the neighbour range (centre to centre)
    when it was noticed."""

    robot: str
    start: float
    detected: float
    end: float | None
    position: tuple[float, float]
    robots_near: tuple[str, ...] = ()
    humans_near: tuple[str, ...] = ()

    def duration(self, end_of_run: float) -> float:
        """How long it was stuck, s, counting to ``end_of_run`` if it never got free."""
        return (end_of_run if self.end is None else self.end) - self.start


def find_deadlocks(times, robot_xy, should_move, robot_names, human_xy=None, human_names=(),
                   stuck_time: float = STUCK_TIME,
                   progress_distance: float = PROGRESS_DISTANCE,
                   neighbour_range: float = NEIGHBOUR_RANGE, waiting=None) -> list[Deadlock]:
    """The deadlocks in a run sampled at ``times`` (T,) s: robot positions ``robot_xy``
    (T, N, 2), ``should_move`` (T, N) bool, optional human positions ``human_xy`` (T, M, 2)
    (NaN where absent). ``waiting`` (T, N) bool (optional: none) marks the samples where a
    robot queues in a wait that leads somewhere: they neither end a stretch without
    progress nor count towards ``stuck_time``, so a robot standing through waits that
    stall, with short queueing between them, is stuck once the stalled samples add up to
    ``stuck_time``; its deadlock starts where it last progressed and is noticed then.
    Ordered by start time, then robot order."""
    t = np.asarray(times, dtype=float)
    xy = np.asarray(robot_xy, dtype=float)
    move = np.asarray(should_move, dtype=bool)
    held = np.zeros_like(move) if waiting is None else np.asarray(waiting, dtype=bool)
    humans = np.zeros((len(t), 0, 2)) if human_xy is None else np.asarray(human_xy, float)
    if (xy.shape != (len(t), len(robot_names), 2) or move.shape != xy.shape[:2]
            or held.shape != move.shape):
        raise ValueError(f"expected robot_xy (T, N, 2), should_move and waiting (T, N) with "
                         f"T = {len(t)}, N = {len(robot_names)}; got {xy.shape}, "
                         f"{move.shape}, {held.shape}")
    found = []
    for k, name in enumerate(robot_names):
        anchor, open_at = None, None  # sample where it last progressed; deadlock noticed
        stalled = 0.0  # s of should-move samples since the anchor
        for s in range(len(t)):
            if anchor is not None and held[s, k] and not move[s, k]:
                if np.linalg.norm(xy[s, k] - xy[anchor, k]) <= progress_distance:
                    continue  # queueing where it stood: the stretch goes on, uncounted
            progressed = (anchor is None or not move[s, k]
                          or np.linalg.norm(xy[s, k] - xy[anchor, k]) > progress_distance)
            if progressed:
                if open_at is not None:
                    found.append(_deadlock(name, k, t, xy, humans, robot_names, human_names,
                                           anchor, open_at, t[s], neighbour_range))
                    open_at = None
                anchor, stalled = (s if move[s, k] else None), 0.0
                continue
            stalled += t[s] - t[s - 1]
            if open_at is None and stalled >= stuck_time - 1e-9:
                open_at = s
        if open_at is not None:
            found.append(_deadlock(name, k, t, xy, humans, robot_names, human_names,
                                   anchor, open_at, None, neighbour_range))
    return sorted(found, key=lambda d: (d.start, robot_names.index(d.robot)))


def stalled_waits(waits_on: Mapping[str, Collection[str]],
                  live: Collection[str]) -> frozenset[str]:
    """The waiting robots (keys of ``waits_on``: robot -> the robots it waits for) whose
    waits lead to no robot of ``live`` (moving or serving). A robot's wait leads somewhere
    when it waits for nobody (what it waits for is free: it gets it at the next grant), or
    when every robot it waits for is live or waits in a way that leads somewhere: a robot
    asking for several single-file segments is granted them only when all their holders
    have let go, so one standing holder stalls it however the others move. The run
    recorder counts by it and the deadlock watchdog acts on it."""
    flowing = set(live)
    flowing.update(robot for robot, others in waits_on.items() if not others)
    grew = True
    while grew:
        grew = False
        for robot, others in waits_on.items():
            if robot not in flowing and flowing.issuperset(others):
                flowing.add(robot)
                grew = True
    return frozenset(waits_on).difference(flowing)


def _deadlock(name, k, t, xy, humans, robot_names, human_names, anchor, noticed, end,
              neighbour_range) -> Deadlock:
    here = xy[noticed, k]
    robot_gap = np.linalg.norm(xy[noticed] - here, axis=1)
    with np.errstate(invalid="ignore"):
        human_near = np.linalg.norm(humans[noticed] - here, axis=1) <= neighbour_range
    return Deadlock(
        robot=name,
        start=float(t[anchor]),
        detected=float(t[noticed]),
        end=None if end is None else float(end),
        position=(float(xy[anchor, k, 0]), float(xy[anchor, k, 1])),
        robots_near=tuple(other for j, other in enumerate(robot_names)
                          if j != k and robot_gap[j] <= neighbour_range),
        humans_near=tuple(human_names[j] for j in np.flatnonzero(human_near)),
    )
