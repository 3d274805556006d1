"""``mrta-sim import`` of a building with several levels and no ``--level``: one folder that
runs them all, joined by the lifts (docs/worlds.md, "Levels and lifts").

Writes, like a single level's import (``building_import``): the building's copy;
``navigation.yaml``, the locations (``<level>/<name>``) and roadways of every level side by
side in one plane, with the lift rides (``roadways.lift_edges``, their ``length`` the ride's
time at the default ``tasks.estimate_speed`` and lift parameters); and ``scenario.yaml``,
with the robots shared out over the levels in turn (each level's starts as in a single
level's import), the people likewise, and a generated task stream between all locations,
so that many tasks change levels, sized like a single level's (``scenario.stream_sizing``)
with the lift rides in its travel times.
"""

import dataclasses
import os
import shutil

import numpy as np

from mrta_drake.errors import InputError
from mrta_drake.navigation.lift_bank import LiftParams
from mrta_drake.navigation.roadways import Roadways
from mrta_drake.scenario.schema import RoadwaysConfig, TasksConfig
from mrta_drake.tools.building_import import (
    ImportOptions,
    ImportReport,
    people_section,
    robot_starts,
    scenario_blocks,
    servable_stream,
    stream_line,
    write_scenario,
    write_yaml,
)
from mrta_drake.world.rmf_building import Building
from mrta_drake.world.rmf_levels import BuildingLevels
from mrta_drake.world.rmf_scenario import imported_levels, imported_navigation, imported_world


def write_all_levels(building: Building, out_dir: str, options: ImportOptions,
                     report: ImportReport) -> None:
    """Write the folder running every level of ``building`` into ``out_dir``."""
    levels = imported_levels(building.source, options.graph)
    names = levels.layout.names
    shares = {name: len(range(k, options.robots, len(names))) for k, name in enumerate(names)}
    people = {name: len(range(k, options.people, len(names))) for k, name in enumerate(names)}
    rng = np.random.default_rng(options.seed)
    starts, humans = [], {}
    for name in names:
        world = imported_world(building.source, name, options.graph)
        navigation = imported_navigation(building.source, name, options.graph)
        if not shares[name]:
            continue
        lanes = Roadways(navigation.roadways, navigation.locations, building.source)
        level_starts = robot_starts(building.levels[name], navigation, lanes, world.floor_plan,
                                    shares[name], [lift.xy for lift in building.lifts.values()
                                                   if name in lift.level_doors])
        for group, entries in people_section(building.levels[name], navigation, level_starts,
                                             people[name], rng,
                                             world.floor_plan.obstacles).items():
            humans.setdefault(group, []).extend(
                _shifted_people(entries, levels, name, len(humans.get(group, ()))))
        starts += [[*levels.layout.to_world(name, s[:2]), s[2]] for s in level_starts]
    os.makedirs(out_dir, exist_ok=True)
    copy = os.path.join(out_dir, os.path.basename(building.source))
    if os.path.abspath(copy) != os.path.abspath(building.source):
        shutil.copyfile(building.source, copy)
    roadways = _write_navigation(os.path.join(out_dir, "navigation.yaml"), building,
                                 options.graph, levels)
    scenario = os.path.join(out_dir, "scenario.yaml")
    stream = servable_stream(Roadways(roadways, levels.locations, building.source),
                             levels.locations, options, len(starts), building.source,
                             [levels.layout.level_of(loc.point[:2]) for loc in levels.locations])
    write_scenario(scenario, os.path.basename(building.source), "", options,
                    [[round(float(v), 3) for v in s] for s in starts], humans,
                    scenario_blocks(levels.roadways, levels.floor_plan), stream)
    report.scenarios.append(scenario)
    report.lines.append(
        f"all levels ({', '.join(names)}) side by side: {len(levels.locations)} task "
        f"locations, lifts {', '.join(lift.name for lift in levels.lifts)}; wrote {scenario}")
    report.lines.append(f"all levels: {stream_line(stream)}")
    report.lines += levels.notes


def _shifted_people(entries: list[dict], levels: BuildingLevels, level: str, taken: int
                    ) -> list[dict]:
    """People entries (walkers or visitor groups) of one level moved into the plane, walkers
    renamed on from ``taken``."""
    moved = []
    for k, entry in enumerate(entries):
        entry = dict(entry)
        for key in ("waypoints", "points"):
            if key in entry:
                entry[key] = [list(levels.layout.to_world(level, p)) for p in entry[key]]
        if "name" in entry:
            entry["name"] = f"person{taken + k + 1}"
        moved.append(entry)
    return moved


def _write_navigation(path: str, building: Building, graph: int, levels: BuildingLevels
                      ) -> RoadwaysConfig:
    """Write the navigation of every level to ``path``; returns its roadways."""
    if not levels.lifts:
        raise InputError(building.source, "lifts", "no lift joins two levels")
    roadways = levels.roadways_with_lifts(LiftParams(), TasksConfig().estimate_speed)
    header = (
        f"# Navigation of every level, graph {graph}, of {os.path.basename(building.source)}, "
        "side by side\n# (offsets: " + ", ".join(
            f"{p.name} {p.offset:g} m" for p in levels.layout.levels) + "), derived by "
        "`mrta-sim import` (docs/worlds.md, \"Levels and lifts\").\n"
        "# Fields follow LocationConfig and RoadwaysConfig (mrta_drake/scenario/schema.py); "
        "world frame:\n# x east, y north, metres. A lift edge's length is its ride's time "
        "at 0.6 m/s.\n")
    content = {
        "locations": [dataclasses.asdict(loc) for loc in levels.locations],
        "roadways": {"nodes": roadways.nodes, "edges": roadways.edges,
                     "lift_edges": [dataclasses.asdict(e) for e in roadways.lift_edges],
                     "single_file": roadways.single_file},
    }
    write_yaml(path, header, content)
    return roadways
