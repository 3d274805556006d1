"""Scheduled disturbances: checking a scenario's ``disturbances:`` section, and which
disturbances are in force at a time.

Three kinds, each over a time window ``[start, end)`` (s; no ``end``: to the end of the run):

- a **blockage** closes a box-shaped region to robots (``BlockageConfig``);
- a **breakdown** stops a robot and takes it out of the fleet (``BreakdownConfig``);
- an **outage** cuts a robot off from the others' cluster messages (``OutageConfig``).

``DisturbanceSchedule`` (``mrta_drake/stack/disturbance_schedule.py``) turns the section
into a ``payloads.Disturbances`` output that changes only at the windows' ends; the blocks
that react to disturbances read it (docs/architecture.md lists which).
"""

import math
from collections.abc import Sequence

from mrta_drake.errors import InputError
from mrta_drake.payloads import Blockage, Breakdown
from mrta_drake.scenario.schema import DisturbancesConfig, Scenario
from mrta_drake.world.obstacles import Box, Obstacles


def has_disturbances(config: DisturbancesConfig) -> bool:
    return bool(config.blockages or config.breakdowns or config.outages)


def _end(end: float | None) -> float:
    return math.inf if end is None else float(end)


def check_disturbances(config: DisturbancesConfig, robot_names: Sequence[str],
                       file: str) -> None:
    """Checks that need no geometry: windows, names, robots. Raises ``InputError`` naming
    the field and the value."""
    names: dict[str, int] = {}
    for i, blockage in enumerate(config.blockages):
        where = f"disturbances.blockages[{i}]"
        if not blockage.name:
            raise InputError(file, f"{where}.name", "is required")
        if blockage.name in names:
            raise InputError(file, f"{where}.name", f"duplicate blockage name "
                             f"{blockage.name!r} (also blockages[{names[blockage.name]}])")
        names[blockage.name] = i
        box = blockage.box
        if len(box) != 4 or not all(math.isfinite(v) for v in box) or not (
                box[0] < box[1] and box[2] < box[3]):
            raise InputError(file, f"{where}.box", "expected [x_min, x_max, y_min, y_max] "
                             f"with x_min < x_max and y_min < y_max, got {box}")
        _check_window(blockage, file, where)
    for kind in ("breakdowns", "outages"):
        entries = getattr(config, kind)
        for i, entry in enumerate(entries):
            where = f"disturbances.{kind}[{i}]"
            if entry.robot not in robot_names:
                raise InputError(file, f"{where}.robot", f"unknown robot {entry.robot!r} "
                                 f"(robots: {', '.join(robot_names)})")
            _check_window(entry, file, where)
            for j, other in enumerate(entries[:i]):
                if other.robot == entry.robot and (entry.start < _end(other.end)
                                                   and other.start < _end(entry.end)):
                    raise InputError(file, f"{where}.start", f"{entry.robot}'s window "
                                     f"[{entry.start:g}, {_end(entry.end):g}) overlaps "
                                     f"{kind}[{j}]'s [{other.start:g}, {_end(other.end):g})")


def _check_window(entry, file: str, where: str) -> None:
    if not (math.isfinite(entry.start) and entry.start >= 0):
        raise InputError(file, f"{where}.start", f"must be >= 0 s, got {entry.start}")
    if entry.end is not None and not entry.end > entry.start:
        raise InputError(file, f"{where}.end", f"{entry.end} is not after start {entry.start}")


def check_blockages_inside(config: DisturbancesConfig, bounds, file: str) -> None:
    """Every blockage's box must lie within the floor plan's ``bounds`` (x_min, x_max,
    y_min, y_max), m."""
    x_min, x_max, y_min, y_max = bounds
    for i, blockage in enumerate(config.blockages):
        bx0, bx1, by0, by1 = blockage.box
        if bx0 < x_min or bx1 > x_max or by0 < y_min or by1 > y_max:
            raise InputError(file, f"disturbances.blockages[{i}].box",
                             f"{blockage.box} is outside the floor plan "
                             f"{[float(v) for v in bounds]}")


def blockages(scenario: Scenario) -> tuple[Blockage, ...]:
    """The scenario's blockages as payloads, in scenario order."""
    return tuple(Blockage(b.name, tuple(float(v) for v in b.box), float(b.start), _end(b.end))
                 for b in scenario.disturbances.blockages)


def breakdowns(scenario: Scenario) -> tuple[Breakdown, ...]:
    """The scenario's breakdowns as payloads (robot indices in scenario order)."""
    names = [r.name for r in scenario.robots]
    return tuple(Breakdown(names.index(b.robot), float(b.start), _end(b.end))
                 for b in scenario.disturbances.breakdowns)


def outage_windows(scenario: Scenario) -> tuple[tuple[int, float, float], ...]:
    """The scenario's outages as (robot index, start, end) (s; end inf: open-ended)."""
    names = [r.name for r in scenario.robots]
    return tuple((names.index(o.robot), float(o.start), _end(o.end))
                 for o in scenario.disturbances.outages)


def in_force(start: float, end: float, time: float) -> bool:
    """Whether a window [``start``, ``end``) holds at ``time`` (s)."""
    return start <= time < end


def blockage_obstacles(closed: Sequence[Blockage]) -> Obstacles:
    """The boxes of ``closed`` as obstacles (for rasterizing and ray casting)."""
    return Obstacles(boxes=tuple(
        Box(b.name, (0.5 * (b.box[0] + b.box[1]), 0.5 * (b.box[2] + b.box[3])),
            (b.box[1] - b.box[0], b.box[3] - b.box[2])) for b in closed))
