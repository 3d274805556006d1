"""``mrta-sim import``: an Open-RMF building made into a runnable, editable scenario folder.

``import_building`` writes, for one level (``--level``, or the only one):

- ``DIR/<name>.building.yaml``: a copy of the building, so the folder stands alone;
- ``DIR/navigation.yaml``: the derived locations and one-way roadways, in the format of
  ``models/hospital/navigation.yaml``, to edit by hand;
- ``DIR/scenario.yaml``: the world (``kind: rmf_building``), ``robots`` robots on the
  level's chargers, then parking spots and spawn points that are not task locations, then
  the other spots where a robot is least in the way (``robot_starts``), each clear of walls
  and of the others (a robot waits back on its start spot when it has nothing to do where
  no parking spot is), ``people`` people walking the level's human lanes (else visitors
  between random lane nodes), and a seeded generated task stream between the task
  locations. Where lanes pass nearer walls than the controller's
  default wall safety distance (0.6 m), as through the demos' 0.9 m doors, the scenario sets
  the controller's ``safety_distances.wall`` to the lanes' least clearance less 6 cm (at
  least the robot radius plus 5 cm), else robots stop short of those doors. Where some
  lanes are two-way corridors (outside every single-file segment), the scenario sets the
  controller's ``coordination.head_on_clearance`` (``HEAD_ON_CLEARANCE``): robots driving
  head on along a corridor's two lanes pass each other instead of one yielding
  (``control.followers``; docs/worlds.md, "Yielding on two-lane corridors"). A building
  whose lanes are all single file keeps the default: its robots meet head on only beside
  the lanes, waiting at queue slots and spots, where yielding is kept. Where some lanes are
  single-file segments, the scenario sets the deadlock watchdog's ``standstill_time`` and
  ``gridlock_time`` to 10 s (``SINGLE_FILE_WATCHDOG``): robots there cannot pass each
  other, and a standoff lasts until the watchdog breaks it.

A building with several levels and no ``level`` gets one folder running them all,
joined by the lifts (``levels_import``).
"""

import dataclasses
import math
import os
import shutil
from collections.abc import Sequence
from dataclasses import dataclass, field

import networkx as nx
import numpy as np
import yaml

from mrta_drake.control.barriers import SafetyDistances
from mrta_drake.control.nominal import NominalParams
from mrta_drake.errors import InputError
from mrta_drake.humans.people import ROUTE_MARGIN, walkable_groups
from mrta_drake.navigation.roadways import Roadways, single_file_lanes
from mrta_drake.navigation.single_servers import trip_holds
from mrta_drake.scenario.schema import LocationConfig, RoadwaysConfig, TasksConfig
from mrta_drake.scenario.stream_sizing import BATCH_SIZE, LEG_SHARE, StreamSize, size_stream
from mrta_drake.world.floor_plan import FloorPlan
from mrta_drake.world.obstacles import Obstacles
from mrta_drake.world.rmf_building import Building, Level
from mrta_drake.world.rmf_levels import laned_levels, left_out_levels
from mrta_drake.world.rmf_navigation import BuildingNavigation
from mrta_drake.world.rmf_scenario import (
    building_at,
    chosen_level,
    imported_navigation,
    imported_world,
)
from mrta_drake.world.segment_distances import distance_to_polyline

ROBOT_RADIUS = 0.22  # m, the scenario default (RobotConfig.radius)
START_GAP = 0.3  # m kept free between two robots' bodies at the start
PEOPLE_GAP = 1.0  # m from a person's first point to robot starts and earlier people's
WALL_SAFETY = SafetyDistances().wall  # m, the controller's default safety distance to walls
WALL_SAFETY_MARGIN = 0.06  # m kept between that distance and the lanes' clearance
HEAD_ON_CLEARANCE = 0.75  # m, below the lanes' 0.9 m spacing (LaneParams.offset)
SINGLE_FILE_WATCHDOG = {"standstill_time": 10.0, "gridlock_time": 10.0}  # s: see below
START_ORDER = ("is_charger", "is_parking_spot", "spawn_robot_name")
QUEUE_BERTH = 2.0  # m: a start spot off a task location keeps this far from its point and queue
ROUTE_BERTH = 1.0  # m: a leg this near a start spot passes it
LIFT_BERTH = 5.0  # m: a start spot keeps this far from a lift's cabin (its riders wait 3 m back)


@dataclass(frozen=True)
class ImportOptions:
    """What to put in the scenario: ``robots`` and ``people`` counts, the ``seed`` (people
    and tasks), ``level`` (empty: the only one, or every level of a building with several),
    navigation ``graph``, ``duration`` (s), and task batches per s per robot
    (``tasks_per_robot``; a batch holds 1 or 2 tasks)."""

    robots: int = 3
    people: int = 0
    seed: int = 0
    level: str = ""
    graph: int = 0
    duration: float = 600.0
    tasks_per_robot: float = 0.01

    def __post_init__(self):
        if self.robots < 1:
            raise InputError(None, "--robots", f"must be >= 1, got {self.robots}")
        if self.people < 0:
            raise InputError(None, "--people", f"must be >= 0, got {self.people}")
        if self.seed < 0:
            raise InputError(None, "--seed", f"must be >= 0, got {self.seed}")
        if self.graph < 0:
            raise InputError(None, "--graph", f"must be >= 0, got {self.graph}")
        if not self.duration > 0:
            raise InputError(None, "--duration", f"must be > 0 s, got {self.duration}")
        if not self.tasks_per_robot > 0:
            raise InputError(None, "tasks_per_robot", f"must be > 0, got "
                             f"{self.tasks_per_robot}")


@dataclass
class ImportReport:
    """What ``import_building`` wrote: ``scenarios`` (paths), and ``lines`` to print."""

    scenarios: list[str] = field(default_factory=list)
    lines: list[str] = field(default_factory=list)


def import_building(path: str, out_dir: str, options: ImportOptions = ImportOptions()
                    ) -> ImportReport:
    """Write the scenario folder(s) of the building in ``path`` under ``out_dir``; only
    scenarios whose people fit (``check_people_fit``)."""
    report = _write_building(path, out_dir, options)
    check_people_fit(report.scenarios, options.people)
    return report


def _write_building(path: str, out_dir: str, options: ImportOptions) -> ImportReport:
    building = building_at(path)
    report = ImportReport()
    lifts = f", {len(building.lifts)} lifts" if building.lifts else ""
    report.lines.append(f"{building.source}: {len(building.levels)} level(s) "
                        f"({', '.join(building.levels)}){lifts}, "
                        f"{building.coordinate_system.kind}")
    if options.level or len(building.levels) == 1:
        level = chosen_level(building, options.level)
        _write_level(building, level, out_dir, options, report)
        return report
    laned = laned_levels(building, options.graph)
    if len(laned) == 1:
        report.lines += left_out_levels(building, laned, options.graph)
        _write_level(building, laned[0], out_dir, options, report)
        return report
    from mrta_drake.tools.levels_import import write_all_levels

    write_all_levels(building, out_dir, options, report)
    return report


def _write_level(building: Building, level_name: str, out_dir: str, options: ImportOptions,
                 report: ImportReport) -> None:
    world = imported_world(building.source, level_name, options.graph)
    navigation = imported_navigation(building.source, level_name, options.graph)
    level = building.levels[level_name]
    rng = np.random.default_rng(options.seed)
    lanes = Roadways(navigation.roadways, navigation.locations, building.source)
    stream = servable_stream(lanes, navigation.locations, options, options.robots,
                             building.source)
    used = [navigation.locations[i].point for i in stream.locations]
    starts = robot_starts(level, navigation, lanes, world.floor_plan, options.robots,
                          work=(used, LEG_SHARE * options.duration * TasksConfig().estimate_speed))
    humans = people_section(level, navigation, starts, options.people, rng,
                            world.floor_plan.obstacles)
    os.makedirs(out_dir, exist_ok=True)
    copy = os.path.join(out_dir, os.path.basename(building.source))
    if os.path.abspath(copy) != os.path.abspath(building.source):
        shutil.copyfile(building.source, copy)
    _write_navigation(os.path.join(out_dir, "navigation.yaml"), building, level_name,
                      options.graph, navigation)
    scenario = os.path.join(out_dir, "scenario.yaml")
    write_scenario(scenario, os.path.basename(building.source), level_name, options, starts,
                    humans, scenario_blocks(navigation.roadways, world.floor_plan), stream)
    report.scenarios.append(scenario)
    roadways = navigation.roadways
    report.lines.append(
        f"{level_name}: graph {options.graph}: {len(navigation.locations)} task locations, "
        f"{len(roadways.nodes)} roadway nodes, {len(roadways.edges)} one-way lanes, "
        f"{len(world.floor_plan.obstacles)} obstacles; wrote {scenario}")
    report.lines += [f"{level_name}: {note}" for note in navigation.notes]
    report.lines.append(f"{level_name}: {stream_line(stream)}")
    if world.left_out:
        report.lines.append(f"{level_name}: {len(world.left_out)} model(s) left out, too near "
                            f"a lane: {'; '.join(world.left_out)}")


def check_people_fit(scenarios: Sequence[str], count: int) -> None:
    """Draw the people of each scenario written (paths) as a run will; where they do not
    fit, remove that scenario file and raise a one-line ``--people`` error (an import
    writes only scenarios that run)."""
    if count == 0:
        return
    from mrta_drake.humans.people import scenario_people
    from mrta_drake.humans.social_force_params import SocialForceParams
    from mrta_drake.scenario.loading import load_scenario
    from mrta_drake.world.plant import load_floor_plan_of

    for path in scenarios:
        scenario = load_scenario(path)
        floor_plan = load_floor_plan_of(scenario)
        try:
            scenario_people(scenario, SocialForceParams(), floor_plan.obstacles,
                            floor_plan.places)
        except InputError as error:
            os.remove(path)
            raise InputError(None, "--people", f"{count} people do not fit: "
                             f"{error.message}") from None


def robot_starts(level: Level, navigation: BuildingNavigation, lanes: Roadways,
                 floor_plan: FloorPlan, count: int, lifts: Sequence[tuple[float, float]] = (),
                 work: tuple[Sequence, float] = ((), 0.0)) -> list[list[float]]:
    """``count`` start poses [x, y, theta] on the level's lane nodes, each facing along its
    first lane, in this order: chargers, parking spots and spawn points that are not task
    locations; lane nodes away from the task locations and their queues that no leg between
    them passes; task locations with parking spots (a robot with nothing to do parks off the
    point); the other lane nodes away from the task locations, fewest legs passing first;
    the other task locations; then the other lane nodes within ``LIFT_BERTH`` m of the
    ``lifts``' cabins (x, y, m) on this level, where riders wait; last, any lane node.
    ``work``: the points (x, y, m) of the task locations a stream uses and a distance (m):
    spots farther than that from all of them come after every nearer one (a campus whose
    stream keeps to a few neighbouring locations)."""
    lines = navigation.centre_lines
    tasks = {loc.name for loc in navigation.locations}
    flagged = []
    for flag in START_ORDER:
        flagged += [lines.vertex_node[i] for i, v in enumerate(level.vertices)
                    if i in lines.vertex_node and (v.flag(flag) or (
                        flag == "spawn_robot_name" and v.params.get(flag)))]
    by_lift = {n for n in lines.nodes if _gap(lines.nodes[n], lifts) < LIFT_BERTH}
    open_nodes = [(n, k) for n, k in _open_nodes(navigation, lanes, floor_plan, tasks)
                  if n not in by_lift]
    task_nodes = [n for n in flagged if n in tasks] + [loc.name for loc in navigation.locations]
    parking = {loc.name for loc in navigation.locations if loc.parking}
    ranked = ([n for n in flagged if n not in tasks]
              + [n for n, k in open_nodes if k == 0] + [n for n in task_nodes if n in parking]
              + [n for n, k in open_nodes if k > 0] + task_nodes + sorted(by_lift, key=str)
              + list(lines.nodes))
    points, reach = work
    if len(points):
        near = {n for n in lines.nodes if _gap(lines.nodes[n], points) <= reach}
        ranked = [n for n in ranked if n in near] + [n for n in ranked if n not in near]
    chosen: list[list[float]] = []
    seen = set()
    for node in ranked:
        if node in seen:
            continue
        seen.add(node)
        xy = np.asarray(lines.nodes[node], dtype=float)
        if floor_plan.obstacles.signed_distance([xy])[0] < ROBOT_RADIUS + 0.05:
            continue
        if any(math.dist(xy, c[:2]) < 2 * ROBOT_RADIUS + START_GAP for c in chosen):
            continue
        chosen.append([round(float(xy[0]), 3), round(float(xy[1]), 3),
                       round(_heading(lines, node), 4)])
        if len(chosen) == count:
            return chosen
    raise InputError(None, "--robots", f"{count} robots do not fit: the level's lane nodes "
                     f"give {len(chosen)} free start spots")


def _open_nodes(navigation: BuildingNavigation, lanes: Roadways, floor_plan: FloorPlan,
                tasks: set[str]) -> list[tuple[str, int]]:
    """The lane nodes that are not task locations, not on single-file segments (driven by
    one robot at a time) and at least ``QUEUE_BERTH`` m from every location's point and
    queue slots: where a robot waiting there (at the start, or back home with nothing to
    do) leaves the rooms and their queues free; each with the number
    of legs between task locations that pass it (within ``ROUTE_BERTH`` m), fewest first (a
    robot waiting there is least in the way), then the widest open space (clearance to
    walls)."""
    lines = navigation.centre_lines
    busy = [p for loc in navigation.locations for p in (loc.point, *loc.queue)]
    single_file = {v for segment in navigation.single_file for v in segment.vertices}
    nodes = [n for n in lines.nodes if n not in tasks and n not in single_file
             and _gap(lines.nodes[n], busy) >= QUEUE_BERTH]
    points = np.array([lines.nodes[n] for n in nodes], dtype=float).reshape(-1, 2)
    clearance = floor_plan.obstacles.signed_distance(points)
    traffic = _legs_passing(lanes, points)
    return [(nodes[k], int(traffic[k])) for k in np.lexsort((-clearance, traffic))]


def _gap(xy, points) -> float:
    """Distance (m) from ``xy`` to the nearest of ``points`` (x, y); infinite if none."""
    if not len(points):
        return math.inf
    return float(np.min(np.linalg.norm(np.asarray(points, dtype=float).reshape(-1, 2)
                                       - np.asarray(xy, dtype=float), axis=1)))


def _legs_passing(lanes: Roadways, points: np.ndarray) -> np.ndarray:
    """How many legs between two task locations of ``lanes`` pass within ``ROUTE_BERTH`` m
    of each of ``points`` (k, 2), m; no legs are searched where there are no points (a
    warehouse whose lane nodes are all task locations or on single-file segments)."""
    counts = np.zeros(len(points), dtype=int)
    if not len(points):
        return counts
    for a in lanes.location_ids:
        for _, leg in lanes.legs_from(a):
            if leg is None or len(leg) < 2:
                continue
            counts += distance_to_polyline(points, leg) <= ROUTE_BERTH
    return counts


def servable_stream(lanes: Roadways, locations: list[LocationConfig],
                    options: ImportOptions, robots: int, source: str,
                    levels: list[str] | None = None) -> StreamSize:
    """The task stream ``robots`` robots can serve in ``options.duration`` between
    ``locations`` (on ``levels``, one per location, when several) on ``lanes`` (the
    roadways with ``locations``; ``scenario.stream_sizing``), from the allocator's default
    estimate of the travel times (lift rides included), along the legs robots drive (with
    the single-file segments: ``Roadways.leg`` out of a location keeps off the single-file
    lane where that location's own queue waits), with the waits for its rooms and
    single-file segments (``navigation.single_servers``)."""
    tasks = TasksConfig()
    ids, speed = lanes.location_ids, NominalParams().cruise_speed
    stream = size_stream(lanes.travel_time_estimate(tasks.estimate_speed), robots,
                         options.duration, tasks.service_time, source, levels,
                         holds=lambda i, j: trip_holds(lanes, ids[i], ids[j], speed,
                                                       tasks.service_time))
    if len(stream.locations) == len(locations) and len(set(stream.weights)) == 1:
        return stream
    return dataclasses.replace(stream, names=tuple(locations[i].name
                                                   for i in stream.locations))


def stream_line(stream: StreamSize) -> str:
    """The import report's line on the generated task stream."""
    used = (f"the {len(stream.names)} task locations near each other" if stream.names
            else "every task location")
    return (f"{len(stream.times)} task batches arriving until {stream.end:g} s, between "
            f"{used} (docs/worlds.md, \"The task stream\")")


def wall_safety(roadways: RoadwaysConfig, floor_plan: FloorPlan) -> float:
    """The controller's wall safety distance (m) that lets robots drive every lane of
    ``roadways`` (see the module docstring)."""
    nodes = roadways.nodes
    samples = [np.asarray(nodes[a]) + t * (np.asarray(nodes[b]) - np.asarray(nodes[a]))
               for a, b in roadways.edges for t in np.linspace(0.0, 1.0, 21)]
    least = float(floor_plan.obstacles.signed_distance(np.array(samples)).min())
    return round(min(WALL_SAFETY, max(ROBOT_RADIUS + 0.05, least - WALL_SAFETY_MARGIN)), 3)


def scenario_blocks(roadways: RoadwaysConfig, floor_plan: FloorPlan) -> dict:
    """The ``blocks`` the scenario sets (see the module docstring): the controller's params
    (``controller_params``) when there are any, and where some lanes are single-file
    segments the deadlock watchdog's ``SINGLE_FILE_WATCHDOG`` (a standoff between robots
    that cannot pass each other lasts until the watchdog breaks it: it acts after 10 s
    rather than 15 s and 20 s; docs/worlds.md, "Single-file loops driven one way round")."""
    blocks = {}
    if controller := controller_params(roadways, floor_plan):
        blocks["controller"] = {"kind": "cluster_cbf", "params": controller}
    if roadways.single_file:
        blocks["watchdog"] = {"params": dict(SINGLE_FILE_WATCHDOG)}
    return blocks


def controller_params(roadways: RoadwaysConfig, floor_plan: FloorPlan) -> dict:
    """The controller's params the scenario sets (see the module docstring): the wall safety
    distance when below the default, ``coordination.head_on_clearance`` when some lanes of
    ``roadways`` are two-way corridors; empty when neither."""
    params = {}
    safety = wall_safety(roadways, floor_plan)
    if safety < WALL_SAFETY:
        params["safety_distances"] = {"wall": safety}
    if _has_two_way_corridors(roadways):
        params["coordination"] = {"head_on_clearance": HEAD_ON_CLEARANCE}
    return params


def _has_two_way_corridors(roadways: RoadwaysConfig) -> bool:
    """Whether some lane of ``roadways`` lies in no single-file segment
    (``single_file_lanes``)."""
    graph = nx.DiGraph(tuple(edge) for edge in roadways.edges)
    held = {lane for segment in roadways.single_file
            for lane in single_file_lanes(graph, segment)}
    return any(lane not in held for lane in graph.edges)


def _heading(lines, node: str) -> float:
    """Direction (rad) from ``node`` to its first neighbour along the centre lines."""
    for a, b, _ in lines.edges:
        if node in (a, b):
            other = b if a == node else a
            dx = lines.nodes[other][0] - lines.nodes[node][0]
            dy = lines.nodes[other][1] - lines.nodes[node][1]
            return math.atan2(dy, dx)
    return 0.0


def people_section(level: Level, navigation: BuildingNavigation, starts, count: int,
                   rng: np.random.Generator, obstacles: Obstacles) -> dict:
    """The ``humans:`` section: walkers looping along human lanes, else visitors walking
    between lane nodes, all of one group people walk between (``humans.people``'s
    ``walkable_groups`` among ``obstacles``: in corridors too narrow to walk through in
    comfort a person stands in the robots' way for good)."""
    if count == 0:
        return {}
    if level.human_lanes:
        walkers = []
        for k in range(count):  # each first point away from the robots and earlier people
            loop = _walk(level, rng, [*starts, *(w["waypoints"][0] for w in walkers)])
            if loop is None:
                break
            walkers.append({"name": f"person{k + 1}", "waypoints": loop})
        if len(walkers) == count:
            return {"walkers": walkers}
    nodes = [xy for xy in navigation.centre_lines.nodes.values()
             if all(math.dist(xy, s[:2]) >= PEOPLE_GAP for s in starts)]
    groups = walkable_groups(nodes, obstacles)
    if not groups or len(groups[0]) < 2:
        raise InputError(None, "--people", f"the level has too few free lane nodes people "
                         f"walk between (corridors {2 * ROUTE_MARGIN:.1f} m wider than a "
                         f"person)")
    nodes = [nodes[k] for k in groups[0]]
    picked = rng.choice(len(nodes), size=min(len(nodes), 8), replace=False)
    return {"groups": [{"kind": "visitors", "count": count,
                        "points": [list(nodes[int(k)]) for k in picked]}]}


def _walk(level: Level, rng: np.random.Generator, starts, steps: int = 4):
    """Waypoints of a random walk along the human lanes: a first point on a lane (a node,
    or a point every ``PEOPLE_GAP`` along the lane) ``PEOPLE_GAP`` from each of ``starts``
    (x, y, ...: robots, and people placed before), then ``steps`` lanes on from the node it
    walks to; None when the human lanes offer no such first point."""
    neighbours: dict[int, list[int]] = {}
    for lane in level.human_lanes:
        neighbours.setdefault(lane.start, []).append(lane.end)
        neighbours.setdefault(lane.end, []).append(lane.start)
    firsts = []  # (first point, the node walked to, the node walked from)
    for a in sorted(neighbours):
        for b in sorted(set(neighbours[a])):
            pa, pb = np.asarray(level.point(a)), np.asarray(level.point(b))
            pieces = max(1, math.ceil(float(np.linalg.norm(pb - pa)) / PEOPLE_GAP))
            firsts += [(tuple(pa + (pb - pa) * k / pieces), b, a) for k in range(pieces)]
    free = [first for first in firsts
            if all(math.dist(first[0], s[:2]) >= PEOPLE_GAP for s in starts)]
    if not free:
        return None
    point, node, came_from = free[int(rng.integers(len(free)))]
    path = [came_from, node]
    for _ in range(steps):
        options = [n for n in neighbours[path[-1]] if n != path[-2]]
        path.append(int(rng.choice(options or neighbours[path[-1]])))
    points = [[round(float(c), 3) for c in xy] for xy in (point, *map(level.point, path[1:]))]
    return [p for k, p in enumerate(points) if k == 0 or p != points[k - 1]]


def _write_navigation(path: str, building: Building, level: str, graph: int,
                      navigation: BuildingNavigation) -> None:
    header = (
        f"# Navigation of level {level}, graph {graph}, of {os.path.basename(building.source)}"
        f",\n# derived by `mrta-sim import` (see docs/worlds.md, \"Open-RMF buildings\").\n"
        "# Fields follow LocationConfig and RoadwaysConfig (mrta_drake/scenario/schema.py); "
        "world frame:\n# x east, y north, metres. Edit freely: the scenario reads this file "
        "as it is.\n")
    write_yaml(path, header, navigation.as_yaml())


def write_scenario(path: str, building_file: str, level: str, options: ImportOptions,
                   starts, humans: dict, blocks: dict, stream: StreamSize | None = None,
                   ) -> None:
    """Writes the imported scenario to ``path``: the building's ``level`` ("" for every
    level), robots at ``starts``, the ``humans`` section, a generated task stream (sized
    by ``stream`` when given, else ``options.tasks_per_robot``), and ``blocks``
    (``scenario_blocks``) when there are any."""
    content = {
        "world": {"kind": "rmf_building", "floor_plan": building_file, "level": level,
                  "graph": options.graph},
        "locations": "navigation.yaml",
        "roadways": "navigation.yaml",
        "robots": [{"name": f"robot{k + 1}", "start": start} for k, start in enumerate(starts)],
        "tasks": {"generate": _generate(options, len(starts), stream)},
        "seed": options.seed,
        "duration": float(options.duration),
    }
    if humans:
        content["humans"] = humans
    if blocks:
        content["blocks"] = blocks
    where = f"level {level}" if level else "every level"
    header = (f"# {building_file}, {where}: imported by `mrta-sim import` (seed "
              f"{options.seed}).\n# Run: mrta-sim run {os.path.basename(path)}\n")
    write_yaml(path, header, content)


def _generate(options: ImportOptions, robots: int, stream: StreamSize | None) -> dict:
    """The ``tasks.generate`` block."""
    if stream is None:
        return {"rate": round(options.tasks_per_robot * robots, 6),
                "batch_size": [1, 2], "slack": [2.0, 4.0]}
    block = {"times": list(stream.times), "batch_size": list(BATCH_SIZE),
             "slack": [2.0, 4.0]}
    if stream.names:  # a neighbourhood of the task locations, or levels made alike
        block["pickup_weights"] = dict(zip(stream.names, stream.weights, strict=True))
        block["dropoff_weights"] = dict(zip(stream.names, stream.weights, strict=True))
    return block


def write_yaml(path: str, header: str, content: dict) -> None:
    """Writes ``content`` as YAML to ``path`` after the comment lines ``header``."""
    with open(path, "w", encoding="utf-8") as f:
        f.write(header)
        yaml.safe_dump(content, f, sort_keys=False, default_flow_style=None, width=100)
