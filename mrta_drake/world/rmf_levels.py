"""Every level of an Open-RMF building in one world, joined by its lifts.

The levels' worlds (``rmf_world``) are placed side by side (``levels.LevelLayout``), their
navigations (``rmf_navigation``, lanes into lift cabins kept) are shifted alike, with roadway
nodes and task locations named ``<level>/<name>``, location ids numbered on across levels.
Each lift stops on each level it serves where a lane of the graph reaches its cabin (the
cabin's node); between every two stops of a lift there is a ride each way
(``LiftEdgeConfig``), costing the ride's expected time
(``navigation.lift_bank.expected_ride_time``) at the nominal speed ``speed`` as metres, so
routes and the allocator's travel-time estimate count it.

Metres, world frame (x east, y north).
"""

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

from mrta_drake.errors import InputError
from mrta_drake.navigation.lift_bank import (
    LiftParams,
    LiftSpec,
    LiftStop,
    expected_ride_time,
)
from mrta_drake.scenario.schema import LiftEdgeConfig, LocationConfig, RoadwaysConfig
from mrta_drake.world.floor_plan import FloorPlan
from mrta_drake.world.levels import MIN_LEVEL_GAP, LevelLayout, combined_floor_plan
from mrta_drake.world.rmf_building import Building
from mrta_drake.world.rmf_navigation import (
    BuildingNavigation,
    BuildingNavigationParams,
    in_cabin,
    level_navigation,
)
from mrta_drake.world.rmf_world import level_world


@dataclass(frozen=True, eq=False)
class BuildingLevels:
    """A building's levels in one plane: their ``layout``, the combined ``floor_plan``, the
    per-level navigations shifted and renamed, joined into ``locations`` and ``roadways``
    (without lift rides: ``roadways_with_lifts`` adds them; with the levels' single-file
    segments but those through a lift cabin, whose doors the lift bank rules), the ``lifts``
    with a stop on at least two levels, and ``notes`` on what was left out."""

    layout: LevelLayout
    floor_plan: FloorPlan
    locations: list[LocationConfig]
    roadways: RoadwaysConfig
    lifts: tuple[LiftSpec, ...]
    notes: list[str]

    def roadways_with_lifts(self, params: LiftParams, speed: float) -> RoadwaysConfig:
        """The roadways plus a ride each way between every two stops of every lift,
        ``length`` = the ride's expected time (``expected_ride_time``: waiting, boarding,
        riding; ``params``) times ``speed`` (m/s)."""
        rides = [LiftEdgeConfig(lift.name, a.node, b.node, a.level, b.level,
                                expected_ride_time(params, a.elevation, b.elevation) * speed)
                 for lift in self.lifts for a in lift.stops for b in lift.stops if a is not b]
        return dataclasses.replace(self.roadways, lift_edges=rides)


def building_levels(building: Building, graph: int = 0, gap: float = MIN_LEVEL_GAP
                    ) -> BuildingLevels:
    """The levels of ``building`` with lanes of ``graph`` (``laned_levels``), with their
    navigation, ``gap`` m apart."""
    names = laned_levels(building, graph)
    worlds = {name: level_world(building, name, graph).floor_plan for name in names}
    layout = LevelLayout.side_by_side(
        [(name, building.levels[name].elevation, worlds[name].bounds) for name in names], gap)
    floor_plan = combined_floor_plan(building.name, worlds, layout, building.source)
    nodes, edges, locations, single_file = {}, [], [], []
    notes = unaligned_levels(building) + left_out_levels(building, names, graph)
    cabin_nodes: dict[tuple[str, str], str] = {}
    for name in names:
        level = building.levels[name]
        navigation = level_navigation(building, name, worlds[name],
                                      BuildingNavigationParams(graph=graph, through_lifts=True))
        notes += [f"{name}: {note}" for note in navigation.notes]
        nodes.update({f"{name}/{node}": list(layout.to_world(name, xy))
                      for node, xy in navigation.roadways.nodes.items()})
        edges += [[f"{name}/{a}", f"{name}/{b}"] for a, b in navigation.roadways.edges]
        locations += [_shifted(loc, len(locations) + k, name, layout)
                      for k, loc in enumerate(navigation.locations)]
        level_cabins = set()
        for lift in building.lifts_through(name):
            if name not in lift.level_doors:
                continue
            cabin = _cabin_node(navigation, level, lift)
            if cabin is not None:
                cabin_nodes[lift.name, name] = f"{name}/{cabin}"
                level_cabins.add(cabin)
        single_file += [[f"{name}/{node}" for node in segment.nodes]
                        for segment in navigation.single_file
                        if not level_cabins.intersection(segment.nodes)]
    lifts = []
    for lift in building.lifts.values():
        stops = tuple(_stop(lift, name, building.levels[name].elevation,
                            cabin_nodes[lift.name, name], nodes, layout)
                      for name in names if (lift.name, name) in cabin_nodes)
        if len(stops) < 2:
            notes.append(f"lift {lift.name}: left out, its cabin is on lanes of graph {graph} "
                         f"on {len(stops)} level(s)")
            continue
        initial = lift.initial_floor if any(s.level == lift.initial_floor for s in stops) \
            else stops[0].level
        lifts.append(LiftSpec(lift.name, stops, initial, lift.width, lift.depth, lift.yaw))
    if len(names) > 1 and not lifts:
        raise InputError(building.source, "lifts", f"no lift joins two levels on lanes of "
                         f"graph {graph}: robots could not leave their level (import one "
                         f"level with --level)")
    roadways = RoadwaysConfig(nodes=nodes, edges=edges, single_file=single_file)
    return BuildingLevels(layout, floor_plan, locations, roadways, tuple(lifts), notes)


def laned_levels(building: Building, graph: int) -> list[str]:
    """The names of ``building``'s levels that have lanes of navigation ``graph``, in the
    file's order (a level without them, e.g. drawn but not yet given lanes, has nowhere
    for robots to drive); InputError when none has."""
    names = [name for name, level in building.levels.items() if graph in level.graphs()]
    if not names:
        raise InputError(building.source, "levels", f"no level has lanes of graph {graph}")
    return names


def left_out_levels(building: Building, laned: Sequence[str], graph: int) -> list[str]:
    """A note for each level of ``building`` not among ``laned`` (``laned_levels``)."""
    return [f"{name}: left out, no lanes of graph {graph}" for name in building.levels
            if name not in laned]


def unaligned_levels(building: Building) -> list[str]:
    """A note for each level of a ``reference_image`` building that shares fewer than two
    fiducials with the reference level: it is taken as drawn in that level's frame
    (``rmf_coordinates``), which is right only if it was; lifts and stairs may not line
    up."""
    if building.coordinate_system.kind != "reference_image":
        return []
    reference = {f.name for f in building.levels[building.reference_level].fiducials}
    notes = []
    for name, level in building.levels.items():
        shared = len(reference & {f.name for f in level.fiducials})
        if name != building.reference_level and shared < 2:
            notes.append(f"{name}: {shared} fiducial(s) shared with the reference level "
                         f"{building.reference_level}: taken as drawn in its frame, not "
                         "aligned")
    return notes


def _stop(lift, level: str, elevation: float, node: str, nodes, layout: LevelLayout
          ) -> LiftStop:
    """``lift``'s stop on ``level``: its cabin ``node``, centre and (first) door there, in
    the combined plane."""
    doors = lift.level_doors.get(level, ())
    door = (layout.to_world(level, lift.to_world(lift.doors[doors[0]].xy)) if doors
            else None)
    return LiftStop(level, tuple(nodes[node]), elevation, node,
                    layout.to_world(level, lift.xy), door)


def _cabin_node(navigation: BuildingNavigation, level, lift) -> str | None:
    """The roadway node of ``navigation`` inside ``lift``'s cabin on ``level``, or None."""
    lines = navigation.centre_lines
    for vertex, node in lines.vertex_node.items():
        if in_cabin(level.point(vertex), lift) and node in navigation.roadways.nodes:
            return node
    return None


def _shifted(location: LocationConfig, new_id: int, level: str, layout: LevelLayout
             ) -> LocationConfig:
    def moved(points):
        return [list(layout.to_world(level, p)) for p in points]

    return LocationConfig(
        id=new_id, name=f"{level}/{location.name}",
        point=list(layout.to_world(level, location.point)), queue=moved(location.queue),
        entry=moved(location.entry), exit_node=f"{level}/{location.exit_node}",
        approach_node=f"{level}/{location.approach_node}", parking=moved(location.parking),
        overflow=moved(location.overflow))
