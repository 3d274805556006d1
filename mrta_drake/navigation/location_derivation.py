"""Locations from named points: each point joined to the centre-lines, with its queue slots,
entry, exit and approach nodes and parking spots (``LocationConfig``).

World frame, x east, y north, m. The steps, for each point:

1. Access (``attach_points``, ``with_access_stubs``): a dead-end edge from the point to the
   nearest centre-line point a robot can drive to it from in a straight line (clearance at
   least the lanes' along the way; within ``snap`` of a vertex, to that vertex), marked
   single file. A point on a centre-line (within ``on_line``) becomes a vertex of it; once
   the dead ends nobody uses are dropped it must be a dead end, whose last ``access_stub``
   is marked single file. The point is a dead end: its lanes meet on it, unshifted.
2. Access zone (``access_zone``): the part of the graph holding the point that a single-file
   edge cuts off from the rest (a bridge; the access itself is one) and that no robot going
   elsewhere uses, the largest such part, e.g. a room behind its doorway. One robot at a
   time holds it, the location's room, so only its shortest path to the point is kept,
   single file: its roadway nodes make the ``entry`` path, and ``exit_node`` is where its
   lane out ends.
3. Queue (``location_config``): ``queue_slots`` slots, ``slot_spacing`` apart, the head
   ``head_gap`` before the zone, back along the lane that leads into it and on along the
   lanes feeding that one (keeping to lanes over junction links, and out of single-file
   segments, where waiting robots would block both ways: fewer slots where the lanes there
   are too short). Each slot is moved up to ``queue_shift`` to the right of its lane (off
   it, so traffic can pass) where it stays ``wall_safety`` from obstacles, or goes further
   back where it would not or where it would be nearer than ``slot_spacing`` to another
   slot (the lanes may turn back). ``approach_node``: where the tail slot's lane segment
   starts.
4. Parking (points marked ``parking``): up to ``parking_spots`` spots ``parking_distance``
   from the point in sight of it, ``wall_safety`` from obstacles, ``aside`` from every lane
   (the zone's included) and queue slot, and ``aside`` from each other; the most open first.
"""

import math
from dataclasses import dataclass, field

import networkx as nx
import numpy as np

from mrta_drake.errors import InputError, require_non_negative, require_positive
from mrta_drake.navigation.clearance_field import Clearance, segment_clearance, segment_samples
from mrta_drake.navigation.lane_derivation import (
    CentrelineEdge,
    CentrelineGraph,
    LaneParams,
    Lanes,
)
from mrta_drake.scenario.schema import LocationConfig
from mrta_drake.scenario.typed_yaml import load_typed, read_yaml
from mrta_drake.world.segment_distances import segment_distances

_CANDIDATE_STEP = 0.1  # m between the centre-line points tried for an access
_SEARCH_STEP = 0.1  # m between the places along the lanes tried for a queue slot
_POINT_SPACING = 1.0  # m between two points at least: the waypoint generator's reach
# tolerance, within which a robot counts as at a location's point


@dataclass(frozen=True)
class NamedPoint:
    """A location to derive: ``name``, ``point`` [x, y] (m) where robots serve it, and
    whether robots with nothing to do may park there (``parking``)."""

    name: str = ""
    point: list[float] = field(default_factory=list)
    parking: bool = False


@dataclass(frozen=True)
class NamedPoints:
    """A points file: ``points``, in location id order."""

    points: list[NamedPoint] = field(default_factory=list)


def load_points(path) -> list[NamedPoint]:
    """The named points of YAML file ``path``; bad content raises ``InputError``."""
    path = str(path)
    points = load_typed(read_yaml(path, "points file"), NamedPoints, path).points
    names = set()
    for i, point in enumerate(points):
        if not point.name:
            raise InputError(path, f"points[{i}].name", "is required")
        if point.name in names:
            raise InputError(path, f"points[{i}].name", f"duplicate name {point.name!r}")
        names.add(point.name)
        if len(point.point) != 2 or not all(math.isfinite(v) for v in point.point):
            raise InputError(path, f"points[{i}].point",
                             f"expected [x, y] in metres, got {point.point}")
        for k, other in enumerate(points[:i]):
            gap = math.dist(point.point, other.point)
            if gap < _POINT_SPACING:
                raise InputError(path, f"points[{i}].point", (
                    f"{point.point} is {gap:.2f} m from points[{k}] ({other.name!r}); "
                    f"points must be at least {_POINT_SPACING:g} m apart"))
    if len(points) < 2:
        raise InputError(path, "points", f"at least two points are required (the roadways "
                         f"join them), got {len(points)}")
    return points


@dataclass(frozen=True)
class LocationParams:
    """Queues and parking, m (see the module docstring).

    ``queue_slots`` 3, ``slot_spacing`` 1.0: as the hospital's hand-made queues and the
    original stack. ``head_gap`` 1.0: the head slot one spacing before the room, so the
    robot leaving it passes the queue. ``wall_safety`` 0.6: the controller's wall safety
    distance (``CbfParams.safety_distances.wall``): a robot cannot stop nearer a wall.
    ``queue_shift`` 0.45: at most one lane offset off the lane. ``snap`` 0.3: accesses
    closer than this to a vertex join it rather than make a new one. ``on_line`` 0.1: a
    point this close to a centre-line is on it. ``access_stub`` 1.0: the single-file end of
    a dead end that a point became, where its two lanes meet. ``parking_spots`` 2;
    ``parking_distance`` [1.6, 3.0]: beyond the waypoint generator's reach tolerance (1 m)
    of the point with a robot's width to spare, and within a room's size; ``aside`` 1.0:
    the waypoint generator's door clearance, within which a moving robot holds up a robot
    entering.
    """

    queue_slots: int = 3
    slot_spacing: float = 1.0
    head_gap: float = 1.0
    wall_safety: float = 0.6
    queue_shift: float = 0.45
    snap: float = 0.3
    on_line: float = 0.1
    access_stub: float = 1.0
    parking_spots: int = 2
    parking_distance: tuple[float, float] = (1.6, 3.0)
    aside: float = 1.0

    def __post_init__(self):
        if self.queue_slots < 1:
            raise InputError(None, "queue_slots", f"must be >= 1, got {self.queue_slots}")
        if self.parking_spots < 0:
            raise InputError(None, "parking_spots", f"must be >= 0, got {self.parking_spots}")
        require_positive(self, "slot_spacing", "wall_safety", unit=" m")
        require_non_negative(self, "head_gap", "queue_shift", "snap", "on_line", "access_stub",
                             "aside", unit=" m")
        low, high = self.parking_distance
        if not 0.0 < low <= high:
            raise InputError(None, "parking_distance",
                             f"need 0 < min <= max, got {list(self.parking_distance)}")


# --- Access ------------------------------------------------------------------------------


def attach_points(graph: CentrelineGraph, points: list[NamedPoint], clearance: Clearance,
                  lane_params: LaneParams, params: LocationParams = LocationParams(),
                  file: str | None = None) -> CentrelineGraph:
    """``graph`` with each point a vertex (named as the point): on a single-file access edge
    from the nearest centre-line point in sight, or, within ``on_line`` of a centre-line, on
    it. ``file`` names the points file in errors."""
    nodes = dict(graph.nodes)
    edges = list(graph.edges)
    needed = lane_params.clearance
    for i, point in enumerate(points):
        xy = np.asarray(point.point, dtype=float)
        if point.name in nodes:
            raise InputError(file, f"points[{i}].name",
                             f"{point.name!r} is also a centre-line vertex's name")
        own = float(clearance(xy[None])[0])
        if own < needed:
            raise InputError(file, f"points[{i}].point", f"{point.point} is {own:.2f} m from "
                             f"an obstacle; a location needs {needed:.2f} m")
        found = _nearest_in_sight(nodes, edges, xy, clearance, needed, lane_params.check_step)
        if found is None:
            raise InputError(file, f"points[{i}].point", f"{point.point}: no centre-line in "
                             f"sight keeping {needed:.2f} m from obstacles")
        k, spot = found
        nodes[point.name] = (float(xy[0]), float(xy[1]))
        if np.linalg.norm(spot - xy) < params.on_line:
            edges = _split(nodes, edges, k, point.name)
            continue
        edge = edges[k]
        vertex = next((end for end in (edge.a, edge.b)
                       if np.linalg.norm(np.asarray(nodes[end]) - spot) <= params.snap), None)
        if vertex is None:
            vertex = f"{point.name}_access"
            nodes[vertex] = (float(spot[0]), float(spot[1]))
            edges = _split(nodes, edges, k, vertex)
        edges.append(CentrelineEdge(vertex, point.name, single_file=True))
    return CentrelineGraph(nodes=nodes, edges=tuple(edges))


def _nearest_in_sight(nodes, edges, xy, clearance, needed, step):
    """(edge index, point on it) of the nearest centre-line point that a straight line from
    ``xy`` reaches keeping ``needed`` from obstacles, or None. Access edges (single file, to
    a dead end) are left out."""
    degree = CentrelineGraph(nodes=nodes, edges=tuple(edges)).degree()
    candidates = []  # (distance, edge index, point on the edge)
    for k, edge in enumerate(edges):
        if edge.single_file and 1 in (degree[edge.a], degree[edge.b]):
            continue
        for spot in segment_samples(nodes[edge.a], nodes[edge.b], _CANDIDATE_STEP):
            candidates.append((float(np.linalg.norm(spot - xy)), k, spot))
    for _, k, spot in sorted(candidates, key=lambda c: c[0]):
        if segment_clearance(clearance, xy, spot, step) >= needed - 1e-9:
            return k, spot
    return None


def _split(nodes, edges: list[CentrelineEdge], k: int, vertex: str) -> list[CentrelineEdge]:
    """``edges`` with edge ``k`` split at ``vertex`` (already in ``nodes``); a half that
    would have no length is left out (``vertex`` takes the end's place)."""
    edge = edges[k]
    halves = [CentrelineEdge(a, b, edge.one_way, edge.single_file)
              for a, b in ((edge.a, vertex), (vertex, edge.b)) if nodes[a] != nodes[b]]
    return edges[:k] + halves + edges[k + 1:]


def with_access_stubs(graph: CentrelineGraph, points: list[NamedPoint],
                      params: LocationParams = LocationParams(),
                      file: str | None = None) -> CentrelineGraph:
    """``graph`` (each point a vertex) with every point a dead end on a single-file edge:
    a point's edge that is not single file is split ``access_stub`` from it (at most half
    way) and the point's part marked single file. A point with more than one edge (on a
    passage between other places) raises ``InputError``."""
    nodes, edges = dict(graph.nodes), list(graph.edges)
    for i, point in enumerate(points):
        at = [k for k, edge in enumerate(edges) if point.name in (edge.a, edge.b)]
        if len(at) != 1:
            raise InputError(file, f"points[{i}].point", f"{point.point} lies on a passage "
                             f"between other places; move it aside (at least "
                             f"{params.on_line:g} m) so that it gets a dead-end access")
        (k,) = at
        edge = edges[k]
        if edge.single_file:
            continue
        other = edge.b if edge.a == point.name else edge.a
        here, there = np.asarray(nodes[point.name]), np.asarray(nodes[other])
        length = float(np.linalg.norm(there - here))
        stub = here + min(params.access_stub, 0.5 * length) / length * (there - here)
        vertex = f"{point.name}_access"
        nodes[vertex] = (float(stub[0]), float(stub[1]))
        edges[k] = CentrelineEdge(other, vertex)
        edges.append(CentrelineEdge(vertex, point.name, single_file=True))
    return CentrelineGraph(nodes=nodes, edges=tuple(edges))


def access_zone(graph: CentrelineGraph, single_file: set[frozenset], point: str,
                stops: set[str]) -> tuple[list[str], set[str]]:
    """``point``'s access zone: the part of ``graph`` holding ``point`` that a single-file
    bridge (a pair of vertices in ``single_file``) cuts off, the largest such part that
    holds no vertex of ``stops`` (the other points) while the rest holds at least two (so
    that only robots going to or from ``point`` use it), or else ``point``'s own edge.
    Returns the shortest centre-line path from the bridge's other end through the part to
    ``point``, and the part's vertices."""
    g = nx.Graph()
    for edge in graph.edges:
        g.add_edge(edge.a, edge.b, length=math.dist(graph.nodes[edge.a], graph.nodes[edge.b]))
    (own,) = g[point]
    part, outside = {point}, own
    for u, v in nx.bridges(g):
        if frozenset((u, v)) not in single_file:
            continue
        cut = g.copy()
        cut.remove_edge(u, v)
        side = nx.node_connected_component(cut, point)
        if len(side) > len(part) and not side & stops and len(stops - side) >= 2:
            part, outside = side, (v if u in side else u)
    path = nx.shortest_path(g.subgraph(part | {outside}), outside, point, weight="length")
    return path, part


# --- Queue, entry, exit, parking ---------------------------------------------------------


def location_config(index: int, point: NamedPoint, zone: list[str], lanes: Lanes,
                    clearance: Clearance, params: LocationParams = LocationParams(),
                    file: str | None = None) -> LocationConfig:
    """The ``LocationConfig`` (id ``index``) of ``point`` whose access zone is ``zone``
    (vertices from its start to the point) on ``lanes``."""
    nodes = lanes.roadways.nodes
    into, out_of = lanes.ends[(zone[0], zone[1])], lanes.ends[(zone[1], zone[0])]
    zone_nodes = {n for v, w in zip(zone[:-1], zone[1:], strict=True)
                  for n in (*lanes.ends[(v, w)], *lanes.ends[(w, v)])}
    shared = {n for segment in lanes.single_file for n in segment.nodes}
    entry = [nodes[into[0]]] + [nodes[lanes.ends[(v, w)][1]] for v, w in
                                zip(zone[:-2], zone[1:-1], strict=True)]
    upstream = _upstream(lanes, into[0], zone_nodes - {into[0]}, shared,
                         np.subtract(nodes[lanes.ends[(zone[0], zone[1])][1]], nodes[into[0]]))
    queue, approach = _queue(upstream, nodes, clearance, params)
    if not queue:
        raise InputError(file, f"points[{index}].point", f"{point.point}: no room for a "
                         f"queue slot {params.wall_safety:g} m from obstacles on the two-lane "
                         f"lanes before it")
    way_in = np.array([queue[0], *entry, point.point])
    parking = _parking(np.asarray(point.point, dtype=float), way_in, np.array(queue), lanes,
                       clearance, params) if point.parking else []
    if point.parking and not parking:
        raise InputError(file, f"points[{index}].parking", f"no parking spot fits around "
                         f"{point.point}")
    return LocationConfig(
        id=index, name=point.name, point=[float(v) for v in point.point],
        queue=[_listed(slot) for slot in queue], entry=[_listed(p) for p in entry],
        exit_node=out_of[1], approach_node=approach, parking=[_listed(p) for p in parking])


def _listed(xy) -> list[float]:
    return [round(float(xy[0]), 3), round(float(xy[1]), 3)]


def _upstream(lanes: Lanes, start: str, closed: set[str], shared: set[str],
              heading) -> list[str]:
    """Roadway nodes from ``start`` against the traffic: at each node the predecessor along
    a lane if there is one (else along a junction link), the one turning least; none in
    ``closed``, none twice, and no step between two nodes of ``shared`` (single-file
    segments) nor past one."""
    nodes = lanes.roadways.nodes
    lane_pairs = set(lanes.ends.values())
    before: dict[str, list[str]] = {n: [] for n in nodes}
    for a, b in lanes.roadways.edges:
        before[b].append(a)
    path, seen = [start], {start} | closed
    heading = np.asarray(heading, dtype=float)
    while path[-1] == start or path[-1] not in shared:
        here = path[-1]
        options = [p for p in before[here]
                   if p not in seen and not (p in shared and here in shared)]
        if not options:
            break
        options = [p for p in options if (p, here) in lane_pairs] or options
        previous = max(options, key=lambda p: _cosine(np.subtract(nodes[here], nodes[p]),
                                                      heading))
        heading = np.subtract(nodes[here], nodes[previous])
        path.append(previous)
        seen.add(previous)
    return path


def _cosine(a: np.ndarray, b: np.ndarray) -> float:
    return float(a @ b) / float(np.linalg.norm(a) * np.linalg.norm(b))


def _queue(upstream: list[str], nodes, clearance: Clearance,
           params: LocationParams) -> tuple[list[np.ndarray], str]:
    """Queue slots (head first) back along the node path ``upstream`` and the approach
    node (where the tail slot's segment starts)."""
    points = np.array([nodes[n] for n in upstream], dtype=float)
    lengths = np.linalg.norm(np.diff(points, axis=0), axis=1)
    reach = np.concatenate([[0.0], np.cumsum(lengths)])
    slots, approach = [], upstream[-1]
    along = params.head_gap
    while len(slots) < params.queue_slots and along <= reach[-1]:
        k = min(int(np.searchsorted(reach, along, side="right")) - 1, len(lengths) - 1)
        base = points[k] + (along - reach[k]) / lengths[k] * (points[k + 1] - points[k])
        travel = (points[k] - points[k + 1]) / lengths[k]
        right = np.array([travel[1], -travel[0]])
        slot = next((base + shift * right for shift in np.arange(params.queue_shift, -1e-9, -0.05)
                     if clearance((base + shift * right)[None])[0] >= params.wall_safety), None)
        if slot is not None and all(np.linalg.norm(slot - other) >= params.slot_spacing - 1e-9
                                    for other in slots):
            slots.append(slot)
            approach = upstream[k + 1]
            along += params.slot_spacing
        else:
            along += _SEARCH_STEP
    return slots, approach


def _parking(point: np.ndarray, way_in: np.ndarray, queue: np.ndarray, lanes: Lanes,
             clearance: Clearance, params: LocationParams) -> list[np.ndarray]:
    nodes = lanes.roadways.nodes
    segments = [(nodes[a], nodes[b]) for a, b in lanes.roadways.edges]
    segments += list(zip(way_in[:-1], way_in[1:], strict=True))
    starts, ends = np.array(segments, dtype=float).reshape(-1, 2, 2).transpose(1, 0, 2)
    low, high = params.parking_distance
    candidates = []
    for radius in np.arange(low, high + 1e-9, 0.2):
        for angle in np.radians(np.arange(0.0, 360.0, 15.0)):
            spot = point + radius * np.array([math.cos(angle), math.sin(angle)])
            room = float(clearance(spot[None])[0])
            if (room >= params.wall_safety
                    and segment_clearance(clearance, point, spot, 0.05) >= params.wall_safety
                    and segment_distances(spot, starts, ends).min() >= params.aside
                    and np.linalg.norm(queue - spot, axis=1).min() >= params.aside):
                candidates.append((-room, radius, angle, spot))
    spots = []
    for *_, spot in sorted(candidates, key=lambda c: c[:3]):
        if len(spots) < params.parking_spots and all(
                np.linalg.norm(spot - other) >= params.aside for other in spots):
            spots.append(spot)
    return spots
