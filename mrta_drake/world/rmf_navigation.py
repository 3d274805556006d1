"""Navigation of one level of an Open-RMF building: the roadway lane graph and the task
locations with their queues, entries and parking spots.

- **Centre lines**: the lanes of one navigation graph (``graph_idx``) of the level, lanes
  into a lift cabin left out (running across levels comes later); vertices at one position
  are one node. A named vertex keeps its name as node name, the others are ``v<index>``.
- **One-way lanes**: ``one_way_lanes``, the shared lane step
  (``navigation.lane_derivation``): right-hand lanes offset from the centre lines where the
  free width allows, single-file segments elsewhere and around task locations that are not
  dead ends (their lanes then meet on the vertex, the location's point). Lanes too narrow
  for two that lie on a loop of the lane graph (no bridge) are then driven one way round
  it (``one_way_round_loops``, ``circulation``): robots on them follow each other and never
  meet head-on; the dead ends and the stretches between loops stay single-file segments.
- **Task locations**: the vertices with ``pickup_dispenser`` or ``dropoff_ingestor``, then
  the other named vertices (in the demos most destinations are named holding points or
  parking spots), except chargers, pass-through points and lift cabins; only those in the
  largest set that can all reach each other along the one-way lanes are kept
  (``BuildingNavigation.notes`` names the others). Ids follow that order from 0. A
  location on a passage (its vertex has more than one lane) is served beside its lanes
  (``_beside``), where a robot serving blocks nobody, when there is room within
  ``serve_reach``.
- **Queues**: back from the point along the lane that approaches it: the head slot
  ``head_gap`` m from the point (or on the first unnamed holding point within the queue's
  length), then ``queue_slots`` slots ``slot_spacing`` m apart, continuing along the lanes
  feeding it; a slot nearer a wall than ``slot_clearance`` moves on back. By a
  single-file lane a slot stands aside, ``slot_lane_gap`` from every lane (a robot waiting
  on it would block everyone driving through), and moves on back where there is no room
  aside. The node beyond the tail is the approach node, the point's own node the exit
  node, the nodes between the head slot and the point the entry. On offset lanes the queue
  lies along the lane arriving, robots leave by the other.
- **Parking**: up to ``parking_spots`` spots ``parking_distance`` m from the point, clear of
  walls by ``slot_clearance``, at least ``parking_lane_gap`` m from every lane,
  ``slot_spacing`` from the points, slots and spots placed before, and in line of sight of
  the point.
- **Waiting spots beyond the queue** (``overflow``): where those of the waypoint generator
  (1 m apart from the tail slot towards the approach node) come nearer than
  ``slot_clearance`` to a wall or a piece of furniture, the location lists its own: those
  spots, each too near one moved off the lanes or dropped (``_overflow``).

Metres, world frame (x east, y north).
"""

import dataclasses
import math
from collections import Counter
from dataclasses import dataclass, field

import networkx as nx
import numpy as np

from mrta_drake.errors import InputError, require_positive
from mrta_drake.navigation.lane_derivation import (
    CentrelineEdge,
    CentrelineGraph,
    LaneParams,
    Lanes,
    SingleFileSegment,
    derive_lanes,
)
from mrta_drake.scenario.schema import LocationConfig, RoadwaysConfig
from mrta_drake.world.floor_plan import FloorPlan
from mrta_drake.world.rmf_building import Building, Level, Vertex
from mrta_drake.world.segment_distances import segment_distances

NOT_TASK_FLAGS = ("is_charger", "is_passthrough_point")


@dataclass(frozen=True)
class BuildingNavigationParams:
    """How the navigation of a level is derived (see the module docstring). Defaults:
    three 1 m slots as in the hospital's hand-made queues; the head slot 1.3 m from the
    point, outside the waypoint generator's 1 m reach tolerance; slots and spots 0.45 m
    clear of walls (a 0.22 m robot plus margin)."""

    graph: int = 0
    queue_slots: int = 3
    slot_spacing: float = 1.0
    head_gap: float = 1.3
    slot_clearance: float = 0.45
    parking_spots: int = 2
    parking_distance: float = 1.4
    parking_lane_gap: float = 0.7
    through_lifts: bool = False  # keep the lanes into lift cabins (several levels)
    zone_length: float = 12.0  # m: single-file lanes into a dead-end point up to this long
    # are its entry, the queue waiting before them
    slot_lane_gap: float = 0.7  # m: a slot by a single-file lane stands this far from every
    # lane, so robots pass it (two 0.22 m robots and 0.26 m between them)
    queue_reach: float = 5.0  # m: slots lie at most this far back beyond the head slot's
    # place; where none fits beside the single-file lanes, they stand on them
    serve_reach: float = 1.5  # m: a location on a passage is served beside its lanes, at
    # most this far from its vertex
    overflow_spots: int = 5  # waiting spots beyond the tail slot that are checked: the
    # import's default fleet of 6 less the room's holder
    overflow_reach: float = 2.0  # m: a waiting spot too near an obstacle moves at most this far
    circulation: bool = True  # lanes too narrow for two on a loop: one way round it

    def __post_init__(self):
        if self.graph < 0:
            raise InputError(None, "graph", f"must be >= 0, got {self.graph}")
        if self.queue_slots < 1:
            raise InputError(None, "queue_slots", f"must be >= 1, got {self.queue_slots}")
        for name in ("parking_spots", "overflow_spots"):
            if getattr(self, name) < 0:
                raise InputError(None, name, f"must be >= 0, got {getattr(self, name)}")
        require_positive(self, "slot_spacing", "head_gap", "slot_clearance", "parking_distance",
                         "parking_lane_gap", "zone_length", "slot_lane_gap", "queue_reach",
                         "serve_reach", "overflow_reach", unit=" m")


@dataclass(frozen=True)
class CentreLines:
    """The undirected lane centre lines of one graph of a level: ``nodes`` name -> (x, y)
    m, ``edges`` (a, b, two_way), ``vertex_node`` building vertex index -> node name."""

    nodes: dict[str, tuple[float, float]]
    edges: tuple[tuple[str, str, bool], ...]
    vertex_node: dict[int, str]


@dataclass(frozen=True)
class BuildingNavigation:
    """What robots of one graph drive on at one level: ``roadways`` (their
    ``single_file`` the segments' nodes), ``locations`` (ids 0..n-1), the ``centre_lines``
    they came from, the ``single_file`` segments (for one robot at a time), and ``notes``
    on what was left out."""

    roadways: RoadwaysConfig
    locations: list[LocationConfig]
    centre_lines: CentreLines
    single_file: tuple[SingleFileSegment, ...] = ()
    notes: list[str] = field(default_factory=list)

    def as_yaml(self) -> dict:
        """The ``locations`` and ``roadways`` sections, as in ``models/hospital/
        navigation.yaml``."""
        return {
            "locations": [
                {"id": loc.id, "name": loc.name, "point": loc.point, "queue": loc.queue,
                 "entry": loc.entry, "exit_node": loc.exit_node,
                 "approach_node": loc.approach_node, "parking": loc.parking,
                 "overflow": loc.overflow}
                for loc in self.locations],
            "roadways": {"nodes": dict(self.roadways.nodes),
                         "edges": [list(e) for e in self.roadways.edges],
                         "single_file": [list(nodes) for nodes in self.roadways.single_file]},
        }


def centre_lines(building: Building, level: Level, graph: int,
                 through_lifts: bool = False) -> CentreLines:
    """The lanes of ``graph`` on ``level`` as undirected centre lines (lanes ending in a
    lift cabin left out unless ``through_lifts``)."""
    cabins = [] if through_lifts else list(building.lifts_through(level.name))
    vertex_node: dict[int, str] = {}
    at: dict[tuple[float, float], str] = {}
    nodes: dict[str, tuple[float, float]] = {}
    directed: dict[tuple[str, str], None] = {}  # ordered like the file
    for lane in level.lanes:
        if lane.graph != graph:
            continue
        ends = (lane.start, lane.end)
        if any(in_cabin(level.point(i), lift) for i in ends for lift in cabins):
            continue
        for i in ends:
            if i in vertex_node:
                continue
            xy = _rounded(level.point(i))
            if xy not in at:
                at[xy] = _node_name(level.vertices[i], i, nodes)
                nodes[at[xy]] = xy
            vertex_node[i] = at[xy]
        a, b = vertex_node[lane.start], vertex_node[lane.end]
        if a != b:
            directed[a, b] = None
            if lane.bidirectional:
                directed[b, a] = None
    edges = []
    for a, b in directed:
        if (b, a) not in directed:
            edges.append((a, b, False))
        elif (b, a) not in [(x, y) for x, y, _ in edges]:
            edges.append((a, b, True))
    if not edges:
        graphs = ", ".join(str(g) for g in level.graphs()) or "none"
        raise InputError(building.source, f"levels.{level.name}.lanes",
                         f"no lanes of graph {graph} (graphs on this level: {graphs})")
    return CentreLines(nodes, tuple(edges), vertex_node)


def in_cabin(xy, lift) -> bool:
    """Whether ``xy`` (m) lies in ``lift``'s cabin, grown by 5 cm on every side."""
    c, s = math.cos(lift.yaw), math.sin(lift.yaw)
    dx, dy = xy[0] - lift.xy[0], xy[1] - lift.xy[1]
    return (abs(c * dx + s * dy) <= 0.5 * lift.width + 0.05
            and abs(-s * dx + c * dy) <= 0.5 * lift.depth + 0.05)


def _rounded(xy) -> tuple[float, float]:
    return (round(float(xy[0]), 3), round(float(xy[1]), 3))


def _node_name(vertex: Vertex, index: int, taken) -> str:
    if not vertex.name:
        return f"v{index}"
    name, k = vertex.name, 2
    while name in taken:
        name, k = f"{vertex.name}_{k}", k + 1
    return name


def one_way_lanes(lines: CentreLines, floor_plan: FloorPlan, shared: set[str],
                  circulation: bool = False) -> Lanes:
    """The lane step (``navigation.lane_derivation``): right-hand one-way lanes along the
    centre lines where the free width of ``floor_plan`` allows, else single-file segments;
    the edges at the vertices ``shared`` (task locations that are not dead ends) stay single
    file, so that their lanes meet on the vertex itself, and single-file segments end there
    (a robot queueing on one side leaves the other side to the robot leaving). With
    ``circulation``, the single-file lanes too narrow for two that lie on loops are then
    driven one way round them (``one_way_round_loops``)."""
    graph = CentrelineGraph(
        nodes=lines.nodes,
        edges=tuple(CentrelineEdge(a, b, one_way=not two_way,
                                   single_file=a in shared or b in shared)
                    for a, b, two_way in lines.edges))
    lanes = derive_lanes(graph, floor_plan.obstacles.signed_distance, LaneParams(),
                         frozenset(shared))
    ways = one_way_round_loops(graph, _too_narrow(graph, floor_plan, lanes)) \
        if circulation else {}
    if not ways:
        return lanes
    graph = CentrelineGraph(nodes=graph.nodes, edges=tuple(
        CentrelineEdge(*ways[frozenset((e.a, e.b))], one_way=True)
        if frozenset((e.a, e.b)) in ways else e for e in graph.edges))
    return derive_lanes(graph, floor_plan.obstacles.signed_distance, LaneParams(),
                        frozenset(shared))


def _too_narrow(graph: CentrelineGraph, floor_plan: FloorPlan, lanes: Lanes):
    """The single-file segments of ``graph`` where two lanes do not fit (``lanes``, its
    lanes, also has those single file for a task location on them: where two lanes fit,
    a loop through such locations keeps its two ways)."""
    if not any(e.single_file for e in graph.edges):
        return lanes.single_file
    free = CentrelineGraph(nodes=graph.nodes, edges=tuple(
        dataclasses.replace(e, single_file=False) for e in graph.edges))
    return derive_lanes(free, floor_plan.obstacles.signed_distance, LaneParams()).single_file


def one_way_round_loops(graph: CentrelineGraph, single_file) -> dict:
    """The single-file edges of ``graph`` that lie on a loop (no bridge), each given the
    one way (a, b) that keeps every vertex reachable from every other it was reachable
    from (Robbins' orientation: a depth-first search drives its tree edges away from the
    root and the others back towards it); keyed by frozenset((a, b))."""
    single = {frozenset(pair) for segment in single_file
              for pair in zip(segment.vertices[:-1], segment.vertices[1:], strict=True)}
    undirected = nx.Graph()
    undirected.add_nodes_from(sorted(graph.nodes))
    undirected.add_edges_from((e.a, e.b) for e in graph.edges)
    bridges = {frozenset(edge) for edge in nx.bridges(undirected)}
    ways = {}
    for a, b, kind in nx.dfs_labeled_edges(undirected):
        key = frozenset((a, b))
        if kind in ("forward", "nontree") and a != b and key not in ways:
            ways[key] = (a, b)
    fixed = {frozenset((e.a, e.b)): (e.a, e.b) for e in graph.edges if e.one_way}
    oriented = {key: way for key, way in ways.items()
                if key in single and key not in bridges and key not in fixed}
    return oriented if _reach_kept(graph, oriented) else {}


def _reach_kept(graph: CentrelineGraph, oriented: dict) -> bool:
    """Whether orienting ``oriented`` keeps the strongly connected parts of ``graph``."""
    def parts(ways):
        directed = nx.DiGraph()
        directed.add_nodes_from(graph.nodes)
        for e in graph.edges:
            key = frozenset((e.a, e.b))
            if key in ways:
                directed.add_edge(*ways[key])
            else:
                directed.add_edge(e.a, e.b)
                if not e.one_way:
                    directed.add_edge(e.b, e.a)
        return {frozenset(c) for c in nx.strongly_connected_components(directed)}
    return parts({}) == parts(oriented)


def level_navigation(building: Building, level_name: str, floor_plan: FloorPlan,
                     params: BuildingNavigationParams = BuildingNavigationParams()
                     ) -> BuildingNavigation:
    """The navigation of graph ``params.graph`` on level ``level_name``; ``floor_plan`` is
    the level's world (``rmf_world.level_world``)."""
    level = building.level(level_name)
    lines = centre_lines(building, level, params.graph, params.through_lifts)
    candidates = _task_vertices(level, lines)
    degree = Counter(v for a, b, _ in lines.edges for v in (a, b))
    lanes = one_way_lanes(lines, floor_plan, {lines.vertex_node[i] for i in candidates
                                              if degree[lines.vertex_node[i]] > 1},
                          params.circulation)
    roadways = dataclasses.replace(lanes.roadways, single_file=[
        list(segment.nodes) for segment in lanes.single_file])
    graph = nx.DiGraph()
    for name, xy in roadways.nodes.items():
        graph.add_node(name, pos=np.asarray(xy, dtype=float))
    for a, b in roadways.edges:
        graph.add_edge(a, b, length=math.dist(roadways.nodes[a], roadways.nodes[b]))
    notes = []
    if lanes.single_file:
        notes.append(f"{len(lanes.single_file)} single-file segment(s), where two lanes do not "
                     "fit or a task location is not a dead end (driven by one robot at a "
                     "time)")
    if lanes.tight:
        notes.append(f"{len(lanes.tight)} lane(s) nearer walls than "
                     f"{LaneParams().clearance:g} m")
    kept = _mutually_reachable([lines.vertex_node[i] for i in candidates], graph)
    for i in candidates:
        if lines.vertex_node[i] not in kept:
            notes.append(f"{level.vertices[i].name}: left out, not reachable both ways "
                         "along the lanes from the other task locations")
    candidates = [i for i in candidates if lines.vertex_node[i] in kept]
    if len(candidates) < 2:
        raise InputError(building.source, f"levels.{level.name}.vertices",
                         f"graph {params.graph} has {len(candidates)} task location(s) "
                         "that can reach each other: need at least 2 named vertices on its "
                         "lanes")
    held = {lines.vertex_node[i] for i, v in enumerate(level.vertices)
            if v.flag("is_holding_point") and not v.name and i in lines.vertex_node}
    holding = {node for (v, w), ends in lanes.ends.items() for vertex, node in zip(
        (v, w), ends, strict=True) if vertex in held}  # the lane ends beside each
    segments = np.array([[roadways.nodes[a], roadways.nodes[b]] for a, b in roadways.edges],
                        dtype=float)
    single = {(a, b) for segment in lanes.single_file
              for a in segment.nodes for b in segment.nodes if graph.has_edge(a, b)}
    rooms = _Rooms.of_lanes(graph, single)
    points = [np.asarray(roadways.nodes[lines.vertex_node[i]], dtype=float)
              for i in candidates]
    for k, i in enumerate(candidates):  # on a passage: served beside it where there is room
        if degree[lines.vertex_node[i]] > 1:
            points[k] = _beside(points[k], _Aside(segments, points[:k] + points[k + 1:]),
                                floor_plan, params)
    taken = list(points)
    locations, moved, dropped = [], 0, 0
    for location_id, (i, point) in enumerate(zip(candidates, points, strict=True)):
        node = lines.vertex_node[i]
        queue, entry, approach, zone = _queue(graph, node, holding, single, rooms,
                                              floor_plan, _Aside(segments, taken), params)
        if len(entry) and not zone and _off_lanes(np.array(queue[:1]), segments)[0] \
                >= params.slot_lane_gap - 0.01:
            entry = []  # from a head slot beside the lanes straight to the point
        parking = [] if zone else _parking(point, segments, floor_plan, taken + queue,
                                           params)
        overflow, moves, drops = _overflow(queue[-1], roadways.nodes[approach], floor_plan,
                                           _Aside(segments, taken + queue + parking), params)
        moved, dropped = moved + moves, dropped + drops
        taken += queue + parking + overflow
        locations.append(LocationConfig(
            id=location_id, name=node, point=_listed(point), queue=queue, entry=entry,
            exit_node=node, approach_node=approach, parking=parking, overflow=overflow))
    if moved or dropped:
        notes.append(f"waiting spots beyond the queues too near walls or furniture: {moved} "
                     f"moved, {dropped} dropped")
    return BuildingNavigation(roadways, locations, lines, lanes.single_file, notes)


def _task_vertices(level: Level, lines: CentreLines) -> list[int]:
    """Vertex indices of the task locations, dispensers and ingestors first, one per
    node."""
    chosen, nodes = [], set()
    for workcells in (True, False):
        for i, vertex in enumerate(level.vertices):
            node = lines.vertex_node.get(i)
            if node is None or node in nodes or not vertex.name:
                continue
            is_workcell = bool(vertex.params.get("pickup_dispenser")
                               or vertex.params.get("dropoff_ingestor"))
            if is_workcell != workcells or "lift_cabin" in vertex.params:
                continue
            if not is_workcell and any(vertex.flag(f) for f in NOT_TASK_FLAGS):
                continue
            chosen.append(i)
            nodes.add(node)
    return chosen


def _mutually_reachable(nodes: list[str], graph: nx.DiGraph) -> set[str]:
    """The largest subset of ``nodes`` lying in one strongly connected component."""
    best: set[str] = set()
    for component in nx.strongly_connected_components(graph):
        inside = {n for n in nodes if n in component}
        if len(inside) > len(best):
            best = inside
    return best


@dataclass(frozen=True)
class _Aside:
    """What a queue slot beside a single-file lane keeps clear of: ``lanes`` (m, 2, 2)
    every lane's ends, ``taken`` the slots and parking spots placed before, m."""

    lanes: np.ndarray
    taken: list


@dataclass(frozen=True)
class _Rooms:
    """A level's lanes, taken both ways, split at the single-file lanes: ``of`` each node's
    room (the nodes it reaches without single-file lanes), ``stretch_of`` each single-file
    lane end's stretch (the nodes single-file lanes join it to), by node."""

    of: dict[str, set[str]]
    stretch_of: dict[str, set[str]]

    @classmethod
    def of_lanes(cls, graph: nx.DiGraph, single: set[tuple[str, str]]) -> "_Rooms":
        """The rooms and stretches of ``graph``, its single-file lanes ``single`` ((from,
        to) nodes)."""
        lanes = nx.restricted_view(graph.to_undirected(as_view=True), [], single)
        return cls({n: room for room in nx.connected_components(lanes) for n in room},
                   {n: part for part in nx.connected_components(nx.Graph(list(single)))
                    for n in part})


def _queue(graph: nx.DiGraph, node: str, holding: set[str], single: set[tuple[str, str]],
           rooms: "_Rooms", floor_plan: FloorPlan, aside: _Aside,
           params: BuildingNavigationParams):
    """Queue slots (head first), entry points and approach node of the location at
    ``node``: slots laid back along the lanes that lead to it, beside those lanes where they
    are single file (``single``: their (from, to) nodes; ``_slot_at``). The head slot is
    the unnamed holding point (``holding``) within the queue's length, else, where the
    point is a dead end whose lanes in are single file for at most ``zone_length`` up to the
    first junction (a room behind its door, a spur), it lies beyond that junction and those
    lanes are the entry (a robot waiting on them would block the holder's only way out):
    then ``zone`` is True. So too where the point lies in a room whose only way out is one
    single-file stretch (its door, ``_door_path``), within ``zone_length``: the head slot
    lies beyond the door and a holding point in the room is no slot (a robot waiting there
    would stand at the door, in the holder's way out: the two-floor clinic's rooms, 10
    robots, seed 1, three rooms so blocked from 350 s to the end, 9 of 22 tasks done).
    Where no slot fits beside the single-file lanes, the other ways back from where the
    lanes first branch are tried, then the first one's lanes."""
    door = _door_path(graph, node, single, rooms, params.zone_length)
    for turn in (0, 1, 2, 0):
        path = _approach_path(graph, node, single, turn, door)
        positions = [graph.nodes[n]["pos"] for n in path]
        along = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(positions, axis=0),
                                                                axis=1))])
        span = params.head_gap + (params.queue_slots - 1) * params.slot_spacing
        lead = _dead_end_lead(graph, path)
        inside = 0  # holding points before this index of path are in the room
        if not 0 < lead <= _single_file_lead(path, single):
            lead = inside = max(len(door) - 1, 0)
        held = next((along[k] for k, name in enumerate(path[1:], start=1)
                     if name in holding and along[k] <= span and k >= inside), None)
        zone = held is None and 0 < lead and along[lead] <= params.zone_length
        if held is not None:
            head = held
        elif zone:
            head = along[lead] + params.head_gap
        else:
            head = params.head_gap
        slots, distances = _slots(path, positions, along, head, single, floor_plan, aside,
                                  params)
        if slots:
            break
    if not slots:  # nothing beside the single-file lanes: on them
        slots, distances = _slots(path, positions, along, head, set(), floor_plan, aside,
                                  params)
    if not slots:  # the lanes end right here: one slot between the point and its neighbour
        distances = [0.5 * along[-1]]
        slots = [_at(positions, along, distances[0])]
    beyond = int(np.searchsorted(along, distances[-1], side="right"))
    approach = path[min(beyond, len(path) - 1)]
    entry = [_listed(positions[k]) for k in range(1, len(path))
             if along[k] < distances[0]][::-1]
    return [_listed(s) for s in slots], entry, approach, zone


def _slots(path, positions, along, head: float, single: set[tuple[str, str]],
           floor_plan: FloorPlan, aside: "_Aside", params: BuildingNavigationParams):
    """Up to ``queue_slots`` slots (``_slot_at``) from ``head`` m back along ``path``,
    ``slot_spacing`` apart or more, within ``queue_reach`` beyond ``head``; and their
    distances along ``path``."""
    slots, distances = [], []
    end = min(along[-1], head + params.queue_reach)
    for k in range(params.queue_slots):
        distance = head + k * params.slot_spacing
        if distances and distance <= distances[-1]:
            distance = distances[-1] + params.slot_spacing
        while distance <= end:
            xy = _slot_at(path, positions, along, distance, single, floor_plan,
                          _Aside(aside.lanes, aside.taken + slots), params)
            if xy is not None:
                slots.append(xy)
                distances.append(distance)
                break
            distance += 0.1
    return slots, distances


def _beside(vertex: np.ndarray, aside: "_Aside", floor_plan: FloorPlan,
            params: BuildingNavigationParams) -> np.ndarray:
    """Where a location on a passage at ``vertex`` is served: the nearest spot within
    ``serve_reach`` of it and in its sight, ``slot_lane_gap`` from every lane,
    ``slot_clearance`` from walls and ``slot_spacing`` from ``aside.taken``; else the vertex
    itself."""
    radii = np.arange(params.slot_lane_gap, params.serve_reach + 1e-9, 0.05)
    angles = np.arange(32) * (2 * math.pi / 32)
    spots = (vertex + np.stack([np.outer(radii, np.cos(angles)),
                                np.outer(radii, np.sin(angles))], axis=-1)).reshape(-1, 2)
    sd = floor_plan.obstacles.signed_distance
    # Lanes farther than serve_reach + slot_lane_gap from the vertex clear every spot.
    near = segment_distances(vertex, aside.lanes[:, 0], aside.lanes[:, 1]) <= (
        params.serve_reach + params.slot_lane_gap)
    ok = sd(spots) >= params.slot_clearance
    if near.any():
        ok &= _off_lanes(spots, aside.lanes[near]) >= params.slot_lane_gap - 1e-9
    ok &= _spaced(spots, aside.taken, params.slot_spacing)
    for spot in spots[ok]:
        line = vertex + np.linspace(0.0, 1.0, 12)[:, None] * (spot - vertex)
        if sd(line).min() >= params.slot_clearance - 0.2:
            return np.round(spot, 3)
    return vertex


def _dead_end_lead(graph: nx.DiGraph, path: list[str]) -> int:
    """How many lanes from the start of ``path`` (back from a point) lead nowhere else: the
    point joins only the next node, each node up to the lead's end only its two neighbours
    on ``path`` (0 where the point is not a dead end, or the path ends in the dead end)."""
    def neighbours(n):
        return set(graph.predecessors(n)) | set(graph.successors(n))
    if len(path) < 3 or neighbours(path[0]) != {path[1]}:
        return 0
    lead = 1
    while lead < len(path) - 1 and neighbours(path[lead]) == {path[lead - 1], path[lead + 1]}:
        lead += 1
    return lead if lead < len(path) - 1 else 0


def _slot_at(path, positions, along, distance: float, single: set[tuple[str, str]],
             floor_plan: FloorPlan, aside: _Aside, params: BuildingNavigationParams):
    """A queue slot for ``distance`` m back along ``path``, or None: there on the lane,
    ``slot_clearance`` from walls; beside a single-file lane the nearest spot at least
    ``slot_lane_gap`` from every lane (up to 1.5 m more), in sight of the lane, clear of
    walls and ``slot_spacing`` from ``aside.taken`` (points, slots and spots placed
    before)."""
    on = _at(positions, along, distance)
    sd = floor_plan.obstacles.signed_distance
    k = min(int(np.searchsorted(along, distance, side="right")) - 1, len(path) - 2)
    if (path[k + 1], path[k]) not in single:
        return on if sd([on])[0] >= params.slot_clearance else None
    u = (positions[k + 1] - positions[k]) / max(along[k + 1] - along[k], 1e-9)
    normal = np.array([-u[1], u[0]])
    offsets = params.slot_lane_gap + np.arange(0.0, 1.55, 0.05)
    spots = np.concatenate([on + np.outer(offsets, normal), on - np.outer(offsets, normal)])
    spots = spots[np.argsort(np.concatenate([offsets, offsets]), kind="stable")]
    ok = ((sd(spots) >= params.slot_clearance)
          & (_off_lanes(spots, aside.lanes) >= params.slot_lane_gap - 1e-9))
    ok &= _spaced(spots, aside.taken, params.slot_spacing)
    for spot in spots[ok]:
        line = on + np.linspace(0.0, 1.0, 12)[:, None] * (spot - on)
        if sd(line).min() >= params.slot_clearance - 0.2:
            return spot
    return None


def _door_path(graph: nx.DiGraph, node: str, single: set[tuple[str, str]], rooms: "_Rooms",
               reach: float) -> list[str]:
    """The path back against the lanes from ``node`` out of the room holding it, to the
    node past its door, at most ``reach`` m long: a room is the part of ``graph`` that
    ``node`` reaches without single-file lanes (``single``; ``rooms``), a door the one
    single-file stretch that joins it to the rest; [] where there is no such room (``node`` on a
    passage, in a spur of single-file lanes, or in a part with several ways out)."""
    lanes = graph.to_undirected(as_view=True)
    room = rooms.of[node]
    doors = set().union(*(rooms.stretch_of[n] for n in room if n in rooms.stretch_of)) - room
    beyond = {n for n in doors
              if any(m not in room and (n, m) not in single for m in lanes.neighbors(n))}
    if len(beyond) != 1:
        return []
    path = nx.shortest_path(graph, beyond.pop(), node, weight="length")[::-1]
    length = sum(graph.edges[b, a]["length"] for a, b in zip(path[:-1], path[1:], strict=True))
    return path if length <= reach else []


def _approach_path(graph: nx.DiGraph, node: str, single: set[tuple[str, str]],
                   turn: int = 0, start: list[str] = ()) -> list[str]:
    """Nodes from ``node`` back against the lanes that reach it: each step to the
    predecessor whose lane is most in line with the last (the longest lane first), never
    revisiting, and not into a dead end while another way is left (where the path first
    branches, the ``turn``-th best way instead); at least 8 m long beyond the single-file
    lanes (``single``) it starts with, when the lanes allow. ``start``: the path's first
    nodes, from ``node`` (e.g. out of its room, ``_door_path``), if any."""
    path, length, lead = list(start) or [node], 0.0, 0.0
    while True:
        options = [p for p in graph.predecessors(path[-1]) if p not in path]
        if not options:
            return path
        options.sort(key=lambda p: _back_step_rank(graph, path, p), reverse=True)
        if len(options) > 1:
            path.append(options[min(turn, len(options) - 1)])
            turn = 0
        else:
            path.append(options[0])
        step = graph.edges[path[-1], path[-2]]["length"]
        length += step
        if lead == length - step and (path[-1], path[-2]) in single:
            lead = length
        if length - lead >= 8.0:
            return path


def _single_file_lead(path: list[str], single: set[tuple[str, str]]) -> int:
    """How many lanes from the start of ``path`` (a path back against the lanes) are
    single file."""
    lead = 0
    while lead < len(path) - 1 and (path[lead + 1], path[lead]) in single:
        lead += 1
    return lead


def _back_step_rank(graph: nx.DiGraph, path: list[str], option: str):
    """How well stepping back from ``path[-1]`` to ``option`` continues ``path`` (larger is
    better): from the location, the longest lane; after that, not a dead end, then the
    cosine of the turn."""
    here = graph.nodes[path[-1]]["pos"]
    if len(path) == 1:
        return graph.edges[option, path[-1]]["length"]
    heading = here - graph.nodes[path[-2]]["pos"]
    step = graph.nodes[option]["pos"] - here
    through = any(q != path[-1] for q in graph.predecessors(option))
    cosine = float(step @ heading) / max(float(np.linalg.norm(step) * np.linalg.norm(heading)),
                                         1e-9)
    return through, cosine


def _at(positions, along, distance) -> np.ndarray:
    """The point ``distance`` m along the polyline ``positions`` (cumulated ``along``)."""
    k = min(int(np.searchsorted(along, distance, side="right")) - 1, len(positions) - 2)
    span = along[k + 1] - along[k]
    t = 0.0 if span <= 0 else (distance - along[k]) / span
    return positions[k] + t * (positions[k + 1] - positions[k])


def _parking(point: np.ndarray, lanes: np.ndarray, floor_plan: FloorPlan, taken: list,
             params: BuildingNavigationParams) -> list[list[float]]:
    """Spots around ``point`` off the lanes and clear of walls (see the module
    docstring), ``slot_spacing`` from the points, slots and spots ``taken`` (m) before
    (a robot parked nearer would stand in the way of one waiting there: office, patrol_A2's
    spot 0.39 m from patrol_D1's second slot), nearest the point's free side first."""
    if params.parking_spots == 0:
        return []
    angles = np.arange(16) * (2 * math.pi / 16)
    spots = point + params.parking_distance * np.column_stack([np.cos(angles),
                                                               np.sin(angles)])
    obstacles = floor_plan.obstacles
    clear = ((obstacles.signed_distance(spots) >= params.slot_clearance)
             & _spaced(spots, taken, params.slot_spacing))
    off_lanes = _off_lanes(spots, lanes)
    chosen = []
    for k in np.argsort(-off_lanes, kind="stable"):
        if not clear[k] or off_lanes[k] < params.parking_lane_gap:
            continue
        line = point + np.linspace(0.0, 1.0, 12)[:, None] * (spots[k] - point)
        if obstacles.signed_distance(line).min() < params.slot_clearance - 0.2:
            continue
        if all(np.linalg.norm(spots[k] - np.asarray(c)) >= 0.9 for c in chosen):
            chosen.append(_listed(spots[k]))
        if len(chosen) == params.parking_spots:
            break
    return chosen


def _overflow(tail, approach, floor_plan: FloorPlan, aside: _Aside,
              params: BuildingNavigationParams) -> tuple[list[list[float]], int, int]:
    """Where robots beyond the last queue slot wait, and how many spots were moved and
    dropped: [] where the waypoint generator's own spots (``WaypointPolicy._queue_spot``:
    ``slot_spacing`` apart from the ``tail`` slot towards the ``approach`` node, at most as
    far as it; the first ``overflow_spots``) keep ``slot_clearance`` from obstacles (walls
    and furniture), else those spots: each one too near an obstacle moved to the nearest
    place within ``overflow_reach`` that keeps it, ``slot_lane_gap`` from every lane and
    in sight of the tail, or dropped where there is none; a spot nearer than
    ``slot_spacing`` to the tail, the approach node, ``aside.taken`` or the spots before is
    dropped too. The approach node itself, on the lanes, is kept as it is (the last spot
    where the spots reach it), and is the one spot where all others were dropped. The
    office's coe: its one slot stands in an aisle beside the corridor, a cubicle between
    it and the approach node; the first two spots on that line lay 0.34 and 0.17 m inside
    the cubicle, goals the planner cannot reach."""
    tail, approach = np.asarray(tail, dtype=float), np.asarray(approach, dtype=float)
    length = float(np.linalg.norm(approach - tail))
    if length == 0.0 or params.overflow_spots == 0:
        return [], 0, 0
    backs = list(dict.fromkeys(min(k * params.slot_spacing, length)
                               for k in range(1, params.overflow_spots + 1)))
    spots = [tail + (approach - tail) * (back / length) for back in backs]
    sd = floor_plan.obstacles.signed_distance
    near = [back < length and sd([spot])[0] < params.slot_clearance
            for spot, back in zip(spots, backs, strict=True)]
    if not any(near):
        return [], 0, 0
    radii = np.arange(0.05, params.overflow_reach + 1e-9, 0.05)
    angles = np.arange(32) * (2 * math.pi / 32)
    ring = np.stack([np.outer(radii, np.cos(angles)), np.outer(radii, np.sin(angles))],
                    axis=-1).reshape(-1, 2)
    chosen: list[list[float]] = []
    moved = 0
    for spot, back, too_near in zip(spots, backs, near, strict=True):
        if back >= length:
            chosen.append(_listed(spot))
            continue
        taken = aside.taken + chosen + [list(tail)] + [list(approach)] * int(
            backs[-1] >= length)
        around = spot + ring if too_near else spot[None]
        ok = _spaced(around, taken, params.slot_spacing)
        if too_near:
            ok &= ((sd(around) >= params.slot_clearance)
                   & (_off_lanes(around, aside.lanes) >= params.slot_lane_gap - 1e-9))
        for place in around[ok]:
            line = tail + np.linspace(0.0, 1.0, 24)[:, None] * (place - tail)
            if not too_near or sd(line).min() >= params.slot_clearance - 0.2:
                chosen.append(_listed(place))
                moved += int(too_near)
                break
    dropped = len(spots) - len(chosen)
    return chosen or [_listed(approach)], moved, dropped


def _listed(xy) -> list[float]:
    return [round(float(xy[0]), 3), round(float(xy[1]), 3)]


def _spaced(spots: np.ndarray, taken: list, spacing: float) -> np.ndarray:
    """Whether each of ``spots`` (k >= 1, 2) keeps ``spacing`` (m, less 1e-9) from every
    one of the points ``taken`` (m); only those within ``spacing`` of the spots' bounding
    box are measured (each other one is farther than ``spacing`` from every spot)."""
    taken = np.asarray(taken, dtype=float).reshape(-1, 2)
    low, high = spots.min(axis=0) - spacing, spots.max(axis=0) + spacing
    taken = taken[np.all((taken >= low) & (taken <= high), axis=1)]
    if not len(taken):
        return np.ones(len(spots), dtype=bool)
    gaps = np.linalg.norm(spots[:, None, :] - taken[None], axis=2)
    return gaps.min(axis=1) >= spacing - 1e-9


def _off_lanes(points: np.ndarray, lanes: np.ndarray) -> np.ndarray:
    """Each of ``points`` (k, 2)'s distance to the nearest of ``lanes`` (m, 2, 2), m."""
    return segment_distances(points, lanes[:, 0], lanes[:, 1]).min(axis=1)
