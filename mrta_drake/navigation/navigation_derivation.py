"""Navigation derived from free space: locations and one-way lanes for any map, in the format
of a navigation file (``locations:`` and ``roadways:``, as ``models/hospital/navigation.yaml``).

``derive_navigation`` chains the steps (docs/worlds.md, "Navigation from a ROS map"):

1. clearance of free space (``ClearanceField``) on the map's occupancy grid;
2. corridor centre-lines: the skeleton of the space keeping the lanes' clearance
   (``free_space_skeleton``), components near the points only;
3. each named point joined by a single-file dead-end access (``location_derivation``);
4. every part of the graph that hangs off a single edge (a bridge) and holds no point is
   dropped: rooms and alcoves nobody is sent to, spurs (a point that lay on a centre-line
   must now be a dead end, and gets its single-file access);
5. lanes (``lane_derivation``); each point's access zone (what its farthest single-file
   bridge cuts off with it, used by no robot going elsewhere) is cut down to its path to
   the point, single file, and the lanes are derived again;
6. each location's queue, entry, exit, approach and parking (``location_derivation``),
   checked by ``Roadways`` (every location reachable from every other along the lanes).

The result also lists the single-file segments outside the access zones
(``roadways.single_file``, roadway node ids along each), driven one way at a time.
"""

import dataclasses
from dataclasses import dataclass

import networkx as nx
import yaml

from mrta_drake.errors import require_positive
from mrta_drake.navigation.clearance_field import ClearanceField
from mrta_drake.navigation.free_space_skeleton import SkeletonParams, centreline_graph
from mrta_drake.navigation.lane_derivation import (
    CentrelineGraph,
    LaneParams,
    Lanes,
    derive_lanes,
)
from mrta_drake.navigation.location_derivation import (
    LocationParams,
    NamedPoint,
    access_zone,
    attach_points,
    location_config,
    with_access_stubs,
)
from mrta_drake.navigation.roadways import Roadways
from mrta_drake.world.floor_plan import FloorPlan
from mrta_drake.world.obstacles import Obstacles
from mrta_drake.world.occupancy_grid import OccupancyGrid


@dataclass(frozen=True)
class NavigationParams:
    """Parameters of every step; ``resolution`` (m): the grid floor plans and obstacles
    are rasterized at (the costmap's 0.05 m)."""

    lanes: LaneParams = LaneParams()
    skeleton: SkeletonParams = SkeletonParams()
    locations: LocationParams = LocationParams()
    resolution: float = 0.05

    def __post_init__(self):
        require_positive(self, "resolution", unit=" m")


def derive_navigation(world: OccupancyGrid | FloorPlan | Obstacles, points: list[NamedPoint],
                      params: NavigationParams = NavigationParams(),
                      points_file: str | None = None) -> dict:
    """Locations (ids in ``points`` order) and lanes for ``world``, as a navigation file's
    content: ``locations`` (``LocationConfig`` fields) and ``roadways`` (``RoadwaysConfig``
    fields, ``single_file`` the lists of roadway node ids of the single-file segments
    outside the access zones). ``points_file`` names the points' file in errors."""
    field = ClearanceField.from_grid(_grid(world, params.resolution))
    names = {point.name for point in points}
    graph = centreline_graph(field, params.lanes, params.skeleton,
                             keep_near=[point.point for point in points])
    graph = attach_points(graph, points, field, params.lanes, params.locations, points_file)
    graph = with_access_stubs(_without_parts_lacking(graph, names), points, params.locations,
                              points_file)
    first = derive_lanes(graph, field, params.lanes)
    single = {frozenset(pair) for segment in first.single_file
              for pair in zip(segment.vertices[:-1], segment.vertices[1:], strict=True)}
    zones = [access_zone(graph, single, point.name, names - {point.name}) for point in points]
    graph = _with_zones(graph, zones)
    lanes = derive_lanes(graph, field, params.lanes)
    locations = [location_config(i, point, path, lanes, field, params.locations, points_file)
                 for i, (point, (path, _)) in enumerate(zip(points, zones, strict=True))]
    Roadways(lanes.roadways, locations, file=points_file)
    return {
        "locations": [dataclasses.asdict(location) for location in locations],
        "roadways": {"nodes": dict(lanes.roadways.nodes),
                     "edges": [list(edge) for edge in lanes.roadways.edges],
                     "single_file": _outside_zones(lanes, [path for path, _ in zones])},
    }


def write_navigation(path, navigation: dict, comment: str = "") -> None:
    """Writes ``navigation`` (from ``derive_navigation``) as YAML to ``path``, each line of
    ``comment`` as a comment line on top."""
    header = "".join(f"# {line}\n" if line else "#\n" for line in comment.splitlines())
    body = yaml.safe_dump(navigation, sort_keys=False, default_flow_style=None, width=100)
    with open(path, "w", encoding="utf-8") as f:
        f.write(header + body)


def _grid(world, resolution: float) -> OccupancyGrid:
    if isinstance(world, OccupancyGrid):
        return world
    if isinstance(world, FloorPlan):
        return world.occupancy(resolution)
    return world.rasterize(world.bounds(), resolution)


def _without_parts_lacking(graph: CentrelineGraph, keep: set[str]) -> CentrelineGraph:
    """``graph`` without the components and bridge-separated parts that hold no vertex of
    ``keep``."""
    g = nx.Graph()
    g.add_nodes_from(graph.nodes)
    g.add_edges_from((edge.a, edge.b) for edge in graph.edges)
    drop = set().union(*(c for c in nx.connected_components(g) if not c & keep))
    for u, v in nx.bridges(g):
        cut = g.copy()
        cut.remove_edge(u, v)
        for side in (nx.node_connected_component(cut, u), nx.node_connected_component(cut, v)):
            if not side & keep:
                drop |= side
    return CentrelineGraph(
        nodes={v: xy for v, xy in graph.nodes.items() if v not in drop},
        edges=tuple(e for e in graph.edges if e.a not in drop and e.b not in drop))


def _with_zones(graph: CentrelineGraph, zones: list[tuple[list[str], set[str]]]) -> CentrelineGraph:
    """``graph`` with each access zone (path, part) cut down to its path, single file."""
    dropped = set().union(*(part - set(path) for path, part in zones))
    inside = set().union(*(part for _, part in zones))
    on_paths = {frozenset(pair) for path, _ in zones
                for pair in zip(path[:-1], path[1:], strict=True)}
    edges = []
    for edge in graph.edges:
        pair = frozenset((edge.a, edge.b))
        if pair in on_paths:
            edges.append(dataclasses.replace(edge, single_file=True))
        elif not pair & dropped and not pair <= inside:
            edges.append(edge)
    return CentrelineGraph(nodes={v: xy for v, xy in graph.nodes.items() if v not in dropped},
                           edges=tuple(edges))


def _outside_zones(lanes: Lanes, zones: list[list[str]]) -> list[list[str]]:
    """The roadway nodes of each run of ``lanes``' single-file segments outside the access
    zones (vertex paths), in order along it."""
    held = {frozenset(pair) for zone in zones for pair in zip(zone[:-1], zone[1:], strict=True)}
    runs = []
    for segment in lanes.single_file:
        run = [segment.vertices[0]]
        for v, w in zip(segment.vertices[:-1], segment.vertices[1:], strict=True):
            if frozenset((v, w)) in held:
                runs.append((segment, run))
                run = [w]
            else:
                run.append(w)
        runs.append((segment, run))
    result = []
    for segment, run in runs:
        if len(run) > 1:
            on_run = {n for v, w in zip(run[:-1], run[1:], strict=True)
                      for n in (*lanes.ends[(v, w)], *lanes.ends[(w, v)])}
            result.append([n for n in segment.nodes if n in on_run])
    return result
