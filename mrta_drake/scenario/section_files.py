"""The files a scenario's ``robots:`` and ``tasks.file`` may name, in our formats or the
original MRTA-Sim ones (read unchanged, YAML or JSON), as dataclasses.

Robot setups: ours (``robots:``, a list of ``RobotConfig``) or MRTA-Sim's
(``agents: {robot1: {start: [x, y]}}``). Task files: ours (``stream:``, a list of
``TaskBatch``) or MRTA-Sim's (``tasks_stream: [{arrival, tasks: [{start, end, deadline}]}]``,
with ``agents``: each robot's start location). Unknown fields are refused in both.
"""

from dataclasses import dataclass

import numpy as np

from mrta_drake.errors import InputError
from mrta_drake.scenario.schema import (
    LocationConfig,
    RobotConfig,
    Scenario,
    TaskBatch,
    TaskConfig,
)
from mrta_drake.scenario.typed_yaml import check_shape, load_typed, read_yaml

START_REACH = 1.0  # m: a robot this close to a location's point starts there


@dataclass(frozen=True)
class RobotSetupFile:
    """Our robot setup: ``robots``, the scenario's robot list in a file of its own."""

    robots: list[RobotConfig]


@dataclass(frozen=True)
class MrtaSimAgent:
    """One robot of an MRTA-Sim robot setup: ``start`` [x, y] (m, world frame)."""

    start: list[float]


@dataclass(frozen=True)
class MrtaSimRobotSetupFile:
    """The original MRTA-Sim robot setup: ``agents`` maps each robot's name to its entry."""

    agents: dict[str, MrtaSimAgent]


@dataclass(frozen=True)
class TaskStreamFile:
    """Our task file: ``stream``, batches as in a scenario's ``tasks.stream``."""

    stream: list[TaskBatch]


@dataclass(frozen=True)
class MrtaSimTask:
    """Carry an item from location ``start`` to ``end`` by absolute time ``deadline`` (s)."""

    start: int
    end: int
    deadline: float


@dataclass(frozen=True)
class MrtaSimBatch:
    """Tasks released together at ``arrival`` (s)."""

    arrival: float
    tasks: list[MrtaSimTask]


@dataclass(frozen=True)
class MrtaSimTaskFile:
    """The original MRTA-Sim task stream; ``agents``: each robot's start location id, in
    robot order (optional)."""

    tasks_stream: list[MrtaSimBatch]
    agents: list[int] | None = None


@dataclass(frozen=True)
class TaskFile:
    """What a task file holds: its ``batches`` and, for an MRTA-Sim file that lists them,
    each robot's start location (``agents``, robot order; else None). ``source``: the
    file."""

    batches: list[TaskBatch]
    agents: list[int] | None = None
    source: str = ""


def read_robot_setup(path: str) -> list[dict]:
    """The robots of the setup file ``path`` (ours or MRTA-Sim's), as raw robot entries of a
    scenario's ``robots:`` list."""
    content = read_yaml(path, "robot setup file")
    if isinstance(content, dict) and "agents" in content:
        check_shape(content, MrtaSimRobotSetupFile, path)
        if not content["agents"]:
            raise InputError(path, "agents", "at least one robot is required")
        return [{"name": str(name), "start": entry["start"]}
                for name, entry in content["agents"].items()]
    if isinstance(content, dict) and "robots" in content:
        check_shape(content, RobotSetupFile, path)
        return content["robots"]
    raise InputError(path, None, "expected `agents:` (MRTA-Sim) or `robots:`")


def load_task_file(path: str) -> TaskFile:
    """The task file ``path``: ours (``stream:``) or MRTA-Sim's (``tasks_stream:``)."""
    content = read_yaml(path, "task file")
    if isinstance(content, dict) and "tasks_stream" in content:
        legacy = load_typed(content, MrtaSimTaskFile, path)
        batches = [TaskBatch(batch.arrival, [TaskConfig(task.start, task.end, task.deadline)
                                             for task in batch.tasks])
                   for batch in legacy.tasks_stream]
        return TaskFile(batches, legacy.agents, path)
    if isinstance(content, dict) and "stream" in content:
        return TaskFile(load_typed(content, TaskStreamFile, path).stream, None, path)
    raise InputError(path, None, "expected `tasks_stream:` (MRTA-Sim) or `stream:`")


def start_locations(robots: list[RobotConfig], locations: list[LocationConfig]
                    ) -> list[int | None]:
    """Each robot's start location id: its ``start_location``, else the first location whose
    point lies within ``START_REACH`` of its start, else None (also when the locations'
    points are not known yet)."""
    result = []
    for robot in robots:
        found = robot.start_location
        if found is None:
            for location in locations:
                if location.point and np.hypot(*np.subtract(location.point[:2],
                                                            robot.start[:2])) <= START_REACH:
                    found = location.id
                    break
        result.append(found)
    return result


def check_agents(task_file: TaskFile, scenario: Scenario) -> None:
    """An MRTA-Sim task file's ``agents`` must list the start location of each of the
    scenario's robots, in order (robots whose start location is not known are not
    compared)."""
    agents = task_file.agents
    if agents is None:
        return
    robots = scenario.robots
    if len(agents) != len(robots):
        raise InputError(task_file.source, "agents", f"{agents} gives {len(agents)} start "
                         f"locations, the scenario has {len(robots)} robots")
    known = start_locations(robots, scenario.locations)
    for i, (agent, robot, location) in enumerate(zip(agents, robots, known, strict=True)):
        if location is not None and agent != location:
            raise InputError(task_file.source, f"agents[{i}]", f"{agent}, but {robot.name} "
                             f"(robots[{i}]) starts at location {location}")
