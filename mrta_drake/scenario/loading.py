"""Loading and validating scenario files.

``load_scenario(path)`` is the one loader the CLI, tests and tutorials use. It reads the
scenario YAML (schema in ``schema.py``) with ``typed_yaml``, resolves the sections that may
live in files of their own, reads the original MRTA-Sim robot-setup and task-stream files
unchanged (``section_files.py``), and checks everything it can without building the
diagram. Every problem is an ``InputError`` whose one-line message names the file, the field
and the value.

Sections that may be a path (relative to the scenario file) instead of inline data:
``robots`` (our list, or an MRTA-Sim ``agents:`` setup in YAML or JSON), ``locations`` and
``roadways`` (a YAML file holding that key), and ``tasks.file`` (our ``stream:`` list or an
MRTA-Sim ``tasks_stream`` file, whose ``agents`` must then match the robots' start
locations).

The scenario's ``profile`` (``profiles.py``) fills the fields it switches, after
``overrides`` and where neither they nor the file set them.

A ``tasks.generate`` block is expanded into seeded random batches (``task_generation.py``)
with the scenario's seed, after ``overrides`` (e.g. ``{"seed": 3}``) are applied.
"""

import copy
import dataclasses
import math
import os
import re
from collections.abc import Mapping

from mrta_drake.errors import InputError
from mrta_drake.scenario.disturbances import check_blockages_inside, check_disturbances
from mrta_drake.scenario.profiles import with_profile
from mrta_drake.scenario.schema import LocationConfig, RoadwaysConfig, RobotConfig, Scenario
from mrta_drake.scenario.section_files import (
    TaskFile,
    check_agents,
    load_task_file,
    read_robot_setup,
)
from mrta_drake.scenario.task_streams import add_generated_tasks
from mrta_drake.scenario.typed_yaml import load_typed, read_yaml


def load_scenario(path: str, *, check_world: bool = True,
                  overrides: Mapping[str, object] | None = None) -> Scenario:
    """Read and validate the scenario at ``path``. With ``check_world`` the floor plan is
    loaded too, and robot starts are checked against walls. ``overrides`` sets fields by
    dotted name (``{"seed": 3, "blocks.controller.kind": "go_to_goal"}``) before the
    scenario is checked; a field under a list cannot be set."""
    path = os.fspath(path)
    raw = read_yaml(path, "scenario file")
    if not isinstance(raw, dict):
        raise InputError(path, None, f"expected a mapping of sections, got {type(raw).__name__}")
    if "agents" in raw and "robots" not in raw:
        raise InputError(path, "agents", "this is an MRTA-Sim robot setup, not a scenario; "
                         "reference it from a scenario as `robots: <file>`")
    if "tasks_stream" in raw:
        raise InputError(path, "tasks_stream", "this is an MRTA-Sim task stream, not a "
                         "scenario; reference it from a scenario as `tasks: {file: <file>}`")
    if "levels" in raw and "world" not in raw:
        raise InputError(path, "levels", "this is an Open-RMF building map, not a scenario; "
                         "make one from it with `mrta-sim import FILE --out DIR`")
    if "image" in raw and "resolution" in raw and "world" not in raw:
        raise InputError(path, "image", "this is a ROS map, not a scenario; make one from it "
                         "with `mrta-sim import FILE --locations POINTS.yaml --out DIR`")
    base = os.path.dirname(os.path.abspath(path))
    raw = dict(raw)
    robots_file = None
    sections = {}  # section -> the file it was read from
    if isinstance(raw.get("robots"), str):
        robots_file = _resolve(base, raw["robots"])
        raw["robots"] = read_robot_setup(robots_file)
    for key in ("locations", "roadways"):
        if isinstance(raw.get(key), str):
            section_file = _resolve(base, raw[key])
            content = read_yaml(section_file, f"{key} file")
            if not isinstance(content, dict) or key not in content:
                raise InputError(section_file, key, f"file has no `{key}:` section")
            raw[key] = content[key]
            sections[key] = section_file
    raw.pop("source", None)
    raw = with_profile(_with_overrides(raw, overrides or {}, path), path)
    try:
        scenario = load_typed(raw, Scenario, path)
        scenario = _resolve_files(scenario, base, path)
        task_file = load_task_file(scenario.tasks.file) if scenario.tasks.file else TaskFile([])
        scenario = _with_task_file(scenario, task_file)
        if scenario.world.kind == "rmf_building":
            from mrta_drake.world.rmf_scenario import with_building_navigation

            scenario = with_building_navigation(scenario)
        check_scenario(scenario, robots_file or path)
        check_agents(task_file, scenario)
        if scenario.tasks.generate is not None:
            scenario = add_generated_tasks(scenario)
            check_scenario(scenario, robots_file or path)  # with the generated tasks
    except InputError as error:
        raise _in_section_file(error, path, sections) from None
    if check_world:
        from mrta_drake.world.plant import check_robot_starts, load_floor_plan_of

        floor_plan = load_floor_plan_of(scenario)
        check_robot_starts(scenario, floor_plan)
        check_blockages_inside(scenario.disturbances, floor_plan.bounds, scenario.source)
    return scenario


def _in_section_file(error: InputError, path: str, sections: Mapping[str, str]
                     ) -> InputError:
    """``error``, about the scenario ``path``, naming the file its section was read from
    instead where that section is one of ``sections`` (``locations: navigation.yaml``)."""
    head = re.split(r"[.\[]", error.field or "", maxsplit=1)[0]
    if head in sections and error.file and os.path.abspath(error.file) == os.path.abspath(path):
        return InputError(sections[head], error.field, error.message)
    return error


def _with_overrides(raw: dict, overrides: Mapping[str, object], path: str) -> dict:
    """A copy of the raw scenario ``raw`` with each dotted field of ``overrides`` set."""
    raw = copy.deepcopy(raw)
    for name, value in overrides.items():
        keys = name.split(".")
        node = raw
        for depth, key in enumerate(keys[:-1]):
            if node.get(key) is None:
                node[key] = {}
            node = node[key]
            if not isinstance(node, dict):
                raise InputError(path, ".".join(keys[:depth + 1]),
                                 f"cannot set {name}: this field is not a mapping")
        node[keys[-1]] = copy.deepcopy(value)
    return raw


def _resolve(base: str, name: str) -> str:
    return name if os.path.isabs(name) else os.path.normpath(os.path.join(base, name))


def _resolve_files(scenario: Scenario, base: str, path: str) -> Scenario:
    """Make file references absolute (the files must exist)."""
    world = scenario.world
    if not world.floor_plan:
        raise InputError(path, "world.floor_plan", "is required (a floor-plan, ROS map or "
                         "Open-RMF building file)")
    floor_plan = _resolve(base, world.floor_plan)
    if not os.path.isfile(floor_plan):
        raise InputError(path, "world.floor_plan", f"file not found: {world.floor_plan!r}")
    tasks = scenario.tasks
    task_file = _resolve(base, tasks.file) if tasks.file else ""
    travel = _resolve(base, tasks.travel_times) if tasks.travel_times else ""
    if travel and not os.path.isfile(travel):
        raise InputError(path, "tasks.travel_times", f"file not found: {tasks.travel_times!r}")
    scenic = _resolve(base, world.scenic) if world.scenic else ""
    if scenic and not os.path.isfile(scenic):
        raise InputError(path, "world.scenic", f"file not found: {world.scenic!r}")
    return dataclasses.replace(
        scenario,
        world=dataclasses.replace(world, floor_plan=floor_plan, scenic=scenic),
        tasks=dataclasses.replace(tasks, file=task_file, travel_times=travel),
        source=os.path.abspath(path),
    )


def _with_task_file(scenario: Scenario, task_file: TaskFile) -> Scenario:
    """The scenario with the task file's batches after its inline stream."""
    tasks = scenario.tasks
    stream = list(tasks.stream) + task_file.batches
    return dataclasses.replace(scenario, tasks=dataclasses.replace(tasks, stream=stream))


def check_scenario(scenario: Scenario, file: str) -> None:
    """Checks that need no world geometry: names, ids, references, numbers."""
    path = scenario.source or file
    _check_robots(scenario.robots, file)
    ids = _check_locations(scenario.locations, scenario.roadways, path)
    for i, robot in enumerate(scenario.robots):
        if robot.start_location is not None and robot.start_location not in ids:
            raise InputError(path, f"robots[{i}].start_location",
                             f"unknown location {robot.start_location}")
        for k, location in enumerate(robot.route):
            if location not in ids:
                raise InputError(path, f"robots[{i}].route[{k}]", f"unknown location {location}")
    for (edge_index, edge) in enumerate(scenario.roadways.edges):
        if len(edge) != 2:
            raise InputError(path, f"roadways.edges[{edge_index}]",
                             f"expected [from, to], got {edge}")
        for name in edge:
            if name not in scenario.roadways.nodes:
                raise InputError(path, f"roadways.edges[{edge_index}]", f"unknown node {name!r}")
    for name, point in scenario.roadways.nodes.items():
        _check_point(point, path, f"roadways.nodes.{name}")
    task_file = scenario.tasks.file or path
    previous = -math.inf
    for b, batch in enumerate(scenario.tasks.stream):
        where = f"tasks.stream[{b}]"
        if batch.arrival < 0 or batch.arrival < previous:
            raise InputError(task_file, f"{where}.arrival",
                             f"must be >= 0 and not before the previous batch, got {batch.arrival}")
        previous = batch.arrival
        for t, task in enumerate(batch.tasks):
            for key in ("pickup", "dropoff"):
                if getattr(task, key) not in ids:
                    raise InputError(task_file, f"{where}.tasks[{t}].{key}",
                                     f"unknown location {getattr(task, key)}")
            if task.deadline < batch.arrival:
                raise InputError(task_file, f"{where}.tasks[{t}].deadline",
                                 f"{task.deadline} is before the batch arrival {batch.arrival}")
    if scenario.tasks.stream and ids != set(range(len(ids))):
        raise InputError(path, "locations", f"ids must be 0..{len(ids) - 1} when there are "
                         f"tasks (they index the travel-time matrix), got {sorted(ids)}")
    if not 0 < scenario.tasks.estimate_speed < math.inf:
        raise InputError(path, "tasks.estimate_speed",
                         f"must be a finite number > 0 m/s, got {scenario.tasks.estimate_speed}")
    if not 0 <= scenario.tasks.service_time < math.inf:
        raise InputError(path, "tasks.service_time", f"must be a finite number >= 0 s, got "
                         f"{scenario.tasks.service_time}")
    for rate in dataclasses.fields(scenario.rates):
        value = getattr(scenario.rates, rate.name)
        if not 0 < value < math.inf:
            raise InputError(path, f"rates.{rate.name}",
                             f"must be a finite number > 0 Hz, got {value}")
    if scenario.seed < 0:
        raise InputError(path, "seed", f"must be >= 0 (numpy's seeds are non-negative "
                         f"integers), got {scenario.seed}")
    if not 0 < scenario.duration < math.inf:
        raise InputError(path, "duration",
                         f"must be a finite number > 0 s, got {scenario.duration}")
    if scenario.world.kind not in ("floor_plan", "ros_map", "rmf_building"):
        raise InputError(path, "world.kind", f"must be floor_plan, ros_map or rmf_building, "
                         f"got {scenario.world.kind!r}")
    if scenario.world.levels_view not in ("stacked", "side_by_side"):
        raise InputError(path, "world.levels_view", f"must be stacked or side_by_side, "
                         f"got {scenario.world.levels_view!r}")
    check_disturbances(scenario.disturbances, [r.name for r in scenario.robots], path)


def _check_point(point, file, field) -> None:
    if len(point) != 2 or not all(map(math.isfinite, point)):
        raise InputError(file, field, f"expected [x, y] in metres, got {point}")


def _check_robots(robots: list[RobotConfig], file: str) -> None:
    if not robots:
        raise InputError(file, "robots", "at least one robot is required")
    names = set()
    for i, robot in enumerate(robots):
        where = f"robots[{i}]"
        if not robot.name:
            raise InputError(file, f"{where}.name", "is required")
        if robot.name in names:
            raise InputError(file, f"{where}.name", f"duplicate robot name {robot.name!r}")
        names.add(robot.name)
        if len(robot.start) not in (2, 3) or not all(map(math.isfinite, robot.start)):
            raise InputError(file, f"{where}.start", f"expected finite [x, y] or [x, y, "
                             f"theta], got {robot.start}")
        if not 0 < robot.radius < math.inf:
            raise InputError(file, f"{where}.radius", f"must be a finite number > 0 m, got "
                             f"{robot.radius}")
        if robot.capacity < 1:
            raise InputError(file, f"{where}.capacity", f"must be >= 1, got {robot.capacity}")
    for i, a in enumerate(robots):
        for j in range(i):
            b = robots[j]
            gap = math.dist(a.start[:2], b.start[:2]) - a.radius - b.radius
            if gap < 0:
                raise InputError(file, f"robots[{i}].start",
                                 f"{a.name} at {a.start[:2]} overlaps {b.name} at {b.start[:2]}")


def _check_locations(locations: list[LocationConfig], roadways: RoadwaysConfig,
                     file: str) -> set[int]:
    ids = set()
    names = set()
    for i, location in enumerate(locations):
        where = f"locations[{i}]"
        if location.id < 0:
            raise InputError(file, f"{where}.id", f"must be >= 0, got {location.id}")
        if location.id in ids:
            raise InputError(file, f"{where}.id", f"duplicate location id {location.id}")
        ids.add(location.id)
        if location.name and location.name in names:
            raise InputError(file, f"{where}.name", f"duplicate location name {location.name!r}")
        names.add(location.name)
        if location.point:
            _check_point(location.point, file, f"{where}.point")
        for key in ("queue", "entry", "parking", "overflow"):
            for k, point in enumerate(getattr(location, key)):
                _check_point(point, file, f"{where}.{key}[{k}]")
        for key in ("exit_node", "approach_node"):
            node = getattr(location, key)
            if node and node not in roadways.nodes:
                raise InputError(file, f"{where}.{key}", f"unknown roadway node {node!r}")
    return ids
