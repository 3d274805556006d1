"""An Open-RMF building as a scenario's world: ``world: {kind: rmf_building, floor_plan:
X.building.yaml, level: L1, graph: 0}``.

The level's world (``rmf_world``) is the scenario's floor plan; the scenario's
``locations`` and ``roadways``, when left out, are derived from the level's lanes of
``graph`` (``rmf_navigation``). Without ``world.level`` a building with several levels
runs whole: its levels side by side, joined by its lifts (``rmf_levels``). Buildings,
worlds and navigation are cached per file version, so the loader, the checks and the
diagram share one import.
"""

import dataclasses
import functools
import os

from mrta_drake.errors import InputError
from mrta_drake.navigation.lift_bank import LiftParams, LiftSpec
from mrta_drake.scenario.schema import Scenario
from mrta_drake.scenario.typed_yaml import load_typed
from mrta_drake.world.floor_plan import FloorPlan
from mrta_drake.world.rmf_building import Building, load_building
from mrta_drake.world.rmf_levels import BuildingLevels, building_levels
from mrta_drake.world.rmf_navigation import (
    BuildingNavigation,
    BuildingNavigationParams,
    level_navigation,
)
from mrta_drake.world.rmf_world import LevelWorld, level_world


def building_at(path: str) -> Building:
    """The building in file ``path`` (cached while the file is unchanged)."""
    path = os.path.abspath(path)
    return _building(path, _version(path))


def chosen_level(building: Building, level: str, source: str | None = None) -> str:
    """``level`` checked against ``building``; when empty, its only level. InputError
    naming ``source``'s ``world.level`` for a building with several."""
    if level:
        if level not in building.levels:
            raise InputError(source, "world.level", f"{level!r} is not a level of "
                             f"{building.source} (levels: {', '.join(building.levels)})")
        return level
    if len(building.levels) == 1:
        return next(iter(building.levels))
    raise InputError(source, "world.level", f"{building.source} has {len(building.levels)} "
                     f"levels ({', '.join(building.levels)}): choose one")


def runs_all_levels(scenario: Scenario) -> bool:
    """Whether ``scenario``'s world is a building with several levels and no
    ``world.level``: all of them run, joined by the lifts."""
    world = scenario.world
    return (world.kind == "rmf_building" and not world.level
            and len(building_at(world.floor_plan).levels) > 1)


def imported_levels(path: str, graph: int = 0) -> BuildingLevels:
    """Every level of the building in ``path`` in one plane (cached)."""
    path = os.path.abspath(path)
    return _levels(path, _version(path), graph)


def building_lifts(scenario: Scenario) -> tuple[LiftSpec, ...]:
    """The lifts robots ride in ``scenario``'s world (none unless it runs several
    levels)."""
    if not runs_all_levels(scenario):
        return ()
    return imported_levels(scenario.world.floor_plan, scenario.world.graph).lifts


def lift_params(scenario: Scenario) -> LiftParams:
    """The lifts' parameters, ``blocks.lifts.params``."""
    return load_typed(scenario.blocks.lifts.params, LiftParams, scenario.source,
                      "blocks.lifts.params")


def imported_world(path: str, level: str, graph: int = 0) -> LevelWorld:
    """The world of ``level`` of the building in ``path`` (cached)."""
    path = os.path.abspath(path)
    return _world(path, _version(path), level, graph)


def imported_navigation(path: str, level: str, graph: int = 0) -> BuildingNavigation:
    """The navigation of ``graph`` on ``level`` of the building in ``path`` (cached)."""
    path = os.path.abspath(path)
    return _navigation(path, _version(path), level, graph)


def building_floor_plan(scenario: Scenario) -> FloorPlan:
    """The floor plan of a scenario whose world is an Open-RMF building."""
    world = scenario.world
    if runs_all_levels(scenario):
        return imported_levels(world.floor_plan, world.graph).floor_plan
    level = chosen_level(building_at(world.floor_plan), world.level, scenario.source)
    return imported_world(world.floor_plan, level, world.graph).floor_plan


def with_building_navigation(scenario: Scenario) -> Scenario:
    """``scenario`` with its ``locations`` and ``roadways``, where left out, derived from
    its building's level."""
    if scenario.locations and scenario.roadways.nodes:
        return scenario
    world = scenario.world
    if runs_all_levels(scenario):
        levels = imported_levels(world.floor_plan, world.graph)
        return dataclasses.replace(
            scenario,
            locations=scenario.locations or [dataclasses.replace(loc) for loc in
                                             levels.locations],
            roadways=scenario.roadways if scenario.roadways.nodes else
            levels.roadways_with_lifts(lift_params(scenario), scenario.tasks.estimate_speed))
    level = chosen_level(building_at(world.floor_plan), world.level, scenario.source)
    navigation = imported_navigation(world.floor_plan, level, world.graph)
    return dataclasses.replace(
        scenario,
        locations=scenario.locations or [dataclasses.replace(loc) for loc in
                                         navigation.locations],
        roadways=scenario.roadways if scenario.roadways.nodes else dataclasses.replace(
            navigation.roadways, nodes=dict(navigation.roadways.nodes),
            edges=list(navigation.roadways.edges),
            single_file=[list(nodes) for nodes in navigation.roadways.single_file]))


def _version(path: str) -> tuple[float, int]:
    try:
        stat = os.stat(path)
    except OSError:
        raise InputError(path, None, "building file not found") from None
    return (stat.st_mtime, stat.st_size)


@functools.lru_cache(maxsize=4)
def _building(path: str, version) -> Building:
    return load_building(path)


@functools.lru_cache(maxsize=8)
def _world(path: str, version, level: str, graph: int) -> LevelWorld:
    return level_world(_building(path, version), level, graph)


@functools.lru_cache(maxsize=4)
def _levels(path: str, version, graph: int) -> BuildingLevels:
    return building_levels(_building(path, version), graph)


@functools.lru_cache(maxsize=8)
def _navigation(path: str, version, level: str, graph: int) -> BuildingNavigation:
    world = _world(path, version, level, graph)
    return level_navigation(_building(path, version), level, world.floor_plan,
                            BuildingNavigationParams(graph=graph))

