"""The building's lanes: a directed graph of roadway nodes, and the legs robots drive on it.

A leg from location ``a`` to location ``b`` is the polyline a robot drives after serving ``a``
until it joins ``b``'s queue: ``a``'s point, ``a``'s entry path reversed (out of the room;
not where the exit node is on the point itself, whose lanes then lead out: ``way_out``),
``a``'s exit node, the shortest path along one-way lanes to ``b``'s approach node, and the
tail slot of ``b``'s queue. Legs are always computed from the graph, never written by hand.

World frame, x east, y north, metres. Lanes are one-way (right-hand traffic is encoded by the
edges: each corridor has one lane per direction).
"""

import copy
import functools
import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field

import networkx as nx
import numpy as np

from mrta_drake.errors import InputError
from mrta_drake.payloads import frozen_array
from mrta_drake.scenario.schema import LiftEdgeConfig, LocationConfig, RoadwaysConfig
from mrta_drake.world.segment_distances import segment_distances


@dataclass(frozen=True, eq=False)
class Place:
    """A location's geometry, validated: ``point`` (2,), ``queue`` (n, 2) head slot first with
    n >= 1, ``entry`` (k, 2) from the head slot to the point (intermediate points only), and
    the roadway nodes robots leave by and approach from; ``parking`` (p, 2): spots where a
    robot with nothing left to do waits off the point (p may be 0); ``overflow`` (o, 2):
    where robots beyond the last slot wait (o may be 0: on the way to the approach node)."""

    id: int
    point: np.ndarray
    queue: np.ndarray
    entry: np.ndarray
    exit_node: str
    approach_node: str
    parking: np.ndarray = field(default_factory=lambda: frozen_array(np.zeros((0, 2))))
    overflow: np.ndarray = field(default_factory=lambda: frozen_array(np.zeros((0, 2))))

    @property
    def tail(self) -> np.ndarray:
        """The last queue slot, where legs end."""
        return self.queue[-1]

    @property
    def doorway(self) -> np.ndarray:
        """(n, 2) the polyline from the head slot through the entry path to the point: the
        way into the room, where two robots cannot pass."""
        return np.array([*self.queue[:1], *self.entry, self.point], dtype=float)


def _xy(value, file, field) -> np.ndarray:
    if (
        not isinstance(value, list | tuple)
        or len(value) != 2
        or not all(isinstance(v, int | float) and math.isfinite(v) for v in value)
    ):
        raise InputError(file, field, f"expected [x, y] in metres, got {value!r}")
    return frozen_array(value)


def _spots(spots, file, field) -> np.ndarray:
    """``spots`` ([x, y] each, m) as a (k, 2) array; a bad one raises ``InputError``."""
    return frozen_array([_xy(p, file, f"{field}[{k}]") for k, p in enumerate(spots)],
                        shape=(len(spots), 2))


def _polyline_length(points: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())


def segment_crosses_box(a, b, box) -> bool:
    """Whether the segment from ``a`` to ``b`` (world points, m) touches the axis-aligned
    ``box`` (x_min, x_max, y_min, y_max), m (slab test; edges count)."""
    low, high = 0.0, 1.0
    for k, (lo, hi) in enumerate(((box[0], box[1]), (box[2], box[3]))):
        d = b[k] - a[k]
        if d == 0.0:
            if not lo <= a[k] <= hi:
                return False
            continue
        t0, t1 = (lo - a[k]) / d, (hi - a[k]) / d
        low, high = max(low, min(t0, t1)), min(high, max(t0, t1))
        if low > high:
            return False
    return True


def single_file_lanes(graph: nx.DiGraph, segment: Sequence[str]) -> list[tuple[str, str]]:
    """The lanes (from, to) of ``graph`` a single-file segment through the roadway nodes
    ``segment`` holds: every lane between two of its nodes."""
    return list(graph.subgraph(segment).edges)


def _on_segment(p, a, b, tolerance: float = 1e-3) -> bool:
    """Whether point ``p`` lies on the segment from ``a`` to ``b`` (within ``tolerance``,
    m)."""
    return float(segment_distances(p, a, b)[0]) <= tolerance


def _shortest(graph, source: str, target: str) -> list[str] | None:
    try:
        return nx.shortest_path(graph, source, target, weight="length")
    except nx.NetworkXNoPath:
        return None


def _without_repeats(points: list[np.ndarray]) -> np.ndarray:
    """``points`` (x, y) as a frozen (k, 2) array, each point equal to the one before it
    left out."""
    stacked = np.array(points, dtype=float).reshape(-1, 2)
    changed = np.empty(len(stacked), dtype=bool)
    changed[0] = True
    np.logical_or(stacked[1:, 0] != stacked[:-1, 0], stacked[1:, 1] != stacked[:-1, 1],
                  out=changed[1:])
    kept = stacked[changed]
    kept.flags.writeable = False
    return kept


class Roadways:
    """The directed lane graph of a building and its locations' queues and entries.

    Built from a scenario's ``RoadwaysConfig`` and ``LocationConfig`` list (points resolved);
    bad input raises ``InputError`` naming ``file``, the field and the value. The graph is a
    ``networkx.DiGraph`` whose nodes carry ``pos`` (x, y) and whose edges carry ``length``, m.
    """

    def __init__(
        self,
        config: RoadwaysConfig,
        locations: Sequence[LocationConfig],
        file: str | None = None,
    ):
        self._file = file
        self.graph = nx.DiGraph()
        self._node_at: dict[tuple[float, float], str] = {}
        for name, value in config.nodes.items():
            xy = _xy(value, file, f"roadways.nodes.{name}")
            key = (float(xy[0]), float(xy[1]))
            if key in self._node_at:
                raise InputError(
                    file, f"roadways.nodes.{name}",
                    f"same position {list(key)} as node '{self._node_at[key]}'",
                )
            self._node_at[key] = name
            self.graph.add_node(name, pos=xy)
        for k, edge in enumerate(config.edges):
            field = f"roadways.edges[{k}]"
            if not isinstance(edge, list | tuple) or len(edge) != 2:
                raise InputError(file, field, f"expected [from, to], got {edge!r}")
            for name in edge:
                if not isinstance(name, str | int) or name not in self.graph:
                    raise InputError(file, field, f"unknown node {name!r}")
            if edge[0] == edge[1]:
                raise InputError(file, field, f"edge from node {edge[0]!r} to itself")
            start, end = (self.node_position(name) for name in edge)
            self.graph.add_edge(edge[0], edge[1], length=float(np.linalg.norm(end - start)))
        self._lift_edges: dict[tuple[tuple[float, float], tuple[float, float]],
                               LiftEdgeConfig] = {}
        for k, hop in enumerate(config.lift_edges):
            self._add_lift_edge(hop, f"roadways.lift_edges[{k}]")
        self._segment_of: dict[tuple[tuple[float, float], tuple[float, float]],
                               tuple[int, bool]] = {}
        for k, names in enumerate(config.single_file):
            self._add_single_file(k, names)
        self.segment_count = len(config.single_file)

        self._places: dict[int, Place] = {}
        for i, location in enumerate(locations):
            self._places[location.id] = self._place(location, f"locations[{i}]")
        self.location_ids: tuple[int, ...] = tuple(sorted(self._places))
        self._check_reachable(locations)
        self._legs: dict[tuple[int, int], np.ndarray | None] = {}
        self.closures: tuple[tuple[float, float, float, float], ...] = ()
        self._closed_views: dict[tuple, Roadways] = {}

    def _add_lift_edge(self, hop: LiftEdgeConfig, field: str) -> None:
        for name in (hop.from_node, hop.to_node):
            if name not in self.graph:
                raise InputError(self._file, field, f"unknown node {name!r}")
        if not hop.length > 0:
            raise InputError(self._file, f"{field}.length", f"must be > 0 m, got {hop.length}")
        self.graph.add_edge(hop.from_node, hop.to_node, length=float(hop.length), lift=True)
        ends = tuple(tuple(float(v) for v in self.node_position(n))
                     for n in (hop.from_node, hop.to_node))
        self._lift_edges[ends] = hop

    def _add_single_file(self, k: int, names: Sequence[str]) -> None:
        """Segment ``k``: every lane between two of its nodes ``names``."""
        field = f"roadways.single_file[{k}]"
        if not isinstance(names, list | tuple) or len(names) < 2:
            raise InputError(self._file, field,
                             f"expected a list of 2 or more roadway nodes, got {names!r}")
        for name in names:
            if not isinstance(name, str | int) or name not in self.graph:
                raise InputError(self._file, field, f"unknown node {name!r}")
        order = {name: i for i, name in enumerate(names)}
        for a, b in single_file_lanes(self.graph, names):
            ends = tuple(tuple(float(v) for v in self.node_position(n)) for n in (a, b))
            self._segment_of.setdefault(ends, (k, order[a] < order[b]))

    def _place(self, location: LocationConfig, field: str) -> Place:
        file = self._file
        if location.id in self._places:
            raise InputError(file, f"{field}.id", f"duplicate location id {location.id}")
        point = _xy(location.point, file, f"{field}.point")
        if not location.queue:
            raise InputError(file, f"{field}.queue", "a location needs at least one queue slot")
        queue = [_xy(slot, file, f"{field}.queue[{k}]") for k, slot in enumerate(location.queue)]
        entry = [_xy(p, file, f"{field}.entry[{k}]") for k, p in enumerate(location.entry)]
        for attribute in ("exit_node", "approach_node"):
            name = getattr(location, attribute)
            if not isinstance(name, str | int) or name not in self.graph:
                raise InputError(file, f"{field}.{attribute}", f"unknown roadway node {name!r}")
        return Place(
            id=location.id,
            point=point,
            queue=frozen_array(queue, shape=(len(queue), 2)),
            entry=frozen_array(entry, shape=(len(entry), 2)),
            exit_node=location.exit_node,
            approach_node=location.approach_node,
            parking=_spots(location.parking, file, f"{field}.parking"),
            overflow=_spots(location.overflow, file, f"{field}.overflow"),
        )

    def _check_reachable(self, locations: Sequence[LocationConfig]) -> None:
        reached: dict[str, set] = {}  # by exit node: the nodes the lanes lead to from it
        for j, target in enumerate(locations):
            for source in locations:
                if source.id == target.id:
                    continue
                node = source.exit_node
                if node not in reached:
                    reached[node] = nx.descendants(self.graph, node) | {node}
                if target.approach_node not in reached[node]:
                    raise InputError(
                        self._file, f"locations[{j}].approach_node",
                        f"node {target.approach_node!r} of location {target.id} cannot be "
                        f"reached from exit node {source.exit_node!r} of location {source.id}",
                    )

    # --- Geometry ----------------------------------------------------------------------------

    def place(self, location: int) -> Place:
        """The geometry of ``location`` (KeyError if unknown)."""
        return self._places[location]

    def node_position(self, name: str) -> np.ndarray:
        """World (x, y) of roadway node ``name``, m."""
        return self.graph.nodes[name]["pos"]

    def node_at(self, xy) -> str | None:
        """The roadway node at exactly ``xy`` (a point taken from a leg), or None."""
        return self._node_at.get((float(xy[0]), float(xy[1])))

    # --- Closures ----------------------------------------------------------------------------

    def closed(self, boxes: Sequence[Sequence[float]]) -> "Roadways":
        """These roadways with every lane that touches one of ``boxes`` (x_min, x_max,
        y_min, y_max; m) closed: its ``closures`` are the boxes, legs and routes avoid them
        or are None where no lane is left. Views are cached per set of boxes."""
        key = tuple(tuple(float(v) for v in box) for box in boxes)
        if not key:
            return self
        view = self._closed_views.get(key)
        if view is None:
            view = copy.copy(self)
            view.graph = self.graph.copy()
            view.graph.remove_edges_from([
                (a, b) for a, b, lift in self.graph.edges(data="lift") if not lift
                and any(segment_crosses_box(self.node_position(a), self.node_position(b), box)
                       for box in key)])
            view.closures, view._legs, view._closed_views = key, {}, {}
            vars(view).pop("leg_lengths", None)  # this one's, measured without the closures
            self._closed_views[key] = view
        return view

    def crosses_closure(self, points) -> bool:
        """Whether the polyline ``points`` (k, 2) touches one of the ``closures``."""
        return any(segment_crosses_box(a, b, box) for box in self.closures
                   for a, b in zip(points[:-1], points[1:], strict=True)
                   if self.lift_edge(a, b) is None)

    @property
    def has_lifts(self) -> bool:
        return bool(self._lift_edges)

    def lift_edge(self, a, b) -> LiftEdgeConfig | None:
        """The lift ride from the roadway node at point ``a`` to the one at ``b`` (two
        consecutive points of a route), or None when they are not a ride's ends."""
        if not self._lift_edges:
            return None
        return self._lift_edges.get(((float(a[0]), float(a[1])), (float(b[0]), float(b[1]))))

    def segment_of(self, a, b) -> tuple[int, bool] | None:
        """The single-file segment the lane from the roadway node at point ``a`` to the one
        at ``b`` belongs to, as (index into ``single_file``, whether it runs along the
        segment's node order), or None."""
        if not self._segment_of:
            return None
        ends = ((float(a[0]), float(a[1])), (float(b[0]), float(b[1])))
        if ends in self._segment_of or self.node_at(b) is not None:
            return self._segment_of.get(ends)
        start = self.node_at(a)  # ``b`` a queue slot on a lane from ``a``?
        for n in () if start is None else self.graph.successors(start):
            end = self.node_position(n)
            if _on_segment(b, self.node_position(start), end):
                return self._segment_of.get((ends[0], (float(end[0]), float(end[1]))))
        return None

    def distance_to_lanes(self, xy) -> float:
        """Distance (m) from point ``xy`` (m) to the nearest lane (lift rides aside);
        infinite without lanes."""
        ends = [(self.node_position(a), self.node_position(b))
                for a, b, lift in self.graph.edges(data="lift") if not lift]
        if not ends:
            return math.inf
        starts, stops = zip(*ends, strict=True)
        return float(segment_distances(xy, starts, stops).min())

    def route_length(self, points) -> float:
        """Length (m) of the route ``points`` (k, 2), a lift ride counted as its edge's
        ``length``."""
        if not self._lift_edges:
            return _polyline_length(points)
        return sum(hop.length if (hop := self.lift_edge(a, b)) is not None
                   else math.dist(a, b) for a, b in zip(points[:-1], points[1:], strict=True))

    # --- Legs --------------------------------------------------------------------------------

    def leg(self, from_location: int, to_location: int) -> np.ndarray | None:
        """The polyline (k, 2) from ``from_location``'s point out of the room to the tail slot
        of ``to_location``'s queue, shortest along the lanes (None if closed lanes leave no
        way). The locations must differ."""
        key = (from_location, to_location)
        if key not in self._legs:
            if from_location == to_location:
                raise ValueError(f"a leg joins two different locations, got {from_location} twice")
            start = self.place(from_location)
            route = self.route_from_node(start.exit_node, to_location, self._past_queue(start))
            self._legs[key] = None if route is None else _without_repeats(
                [*self.way_out(start), *route])
        return self._legs[key]

    def legs_from(self, from_location: int) -> Iterator[tuple[int, np.ndarray | None]]:
        """``(to_location, leg)`` for every other location in ``location_ids`` order: the
        legs out of ``from_location`` from one search of the lanes for all of them, for
        all-pairs uses of large buildings (the import's start spots). Each is
        ``leg(from_location, to_location)``, or where two ways are equally short possibly
        the other one; not cached."""
        start = self.place(from_location)
        out = np.array(self.way_out(start), dtype=float).reshape(-1, 2)
        row, xy = self._node_rows
        others = [self.place(b) for b in self.location_ids if b != from_location]
        paths = self._ways(start.exit_node, self._past_queue(start),
                           [p.approach_node for p in others], nx.single_source_dijkstra_path)
        for target, names in zip(others, paths, strict=True):
            yield target.id, None if names is None else _without_repeats(np.concatenate(
                [out, xy[[row[n] for n in names]], target.tail[None]]))

    @functools.cached_property
    def _node_rows(self) -> tuple[dict[str, int], np.ndarray]:
        """Each roadway node's row in an (n, 2) array of their positions (m), and the
        array (closed views share it: they close lanes, not nodes)."""
        names = list(self.graph.nodes)
        return ({n: k for k, n in enumerate(names)},
                np.array([self.node_position(n) for n in names], dtype=float).reshape(-1, 2))

    def leg_length(self, from_location: int, to_location: int) -> float:
        """Length of ``leg(from_location, to_location)``, m; 0 from a location to itself."""
        if from_location == to_location:
            return 0.0
        return self.route_length(self.leg(from_location, to_location))

    def route_from_node(self, node: str, to_location: int,
                        avoid: tuple[str, str] | None = None) -> np.ndarray | None:
        """The polyline (k, 2) from roadway node ``node`` along the lanes to the tail slot of
        ``to_location``'s queue, or None if the lanes do not lead there; not along the lane
        ``avoid`` (from, to nodes) where another way leads there."""
        target = self.place(to_location)
        for graph in self._graphs_avoiding(avoid):
            names = _shortest(graph, node, target.approach_node)
            if names is not None:
                return _without_repeats([self.node_position(n) for n in names] + [target.tail])
        return None

    def _graphs_avoiding(self, avoid: tuple[str, str] | None) -> Iterator[nx.DiGraph]:
        """The lane graphs to search in turn for a way off the lane ``avoid`` (from, to
        nodes) where another way leads: without that lane, then the whole graph (only the
        whole graph where ``avoid`` is None)."""
        if avoid is not None:
            yield nx.restricted_view(self.graph, [], [avoid])
        yield self.graph

    def _ways(self, node: str, avoid: tuple[str, str] | None, targets: Sequence[str],
              search: Callable[..., dict]) -> list:
        """For each of the roadway nodes ``targets``, what ``search`` (a networkx
        single-source Dijkstra, weighted by ``length``: paths or lengths by node) gives for
        it from ``node``, in the first of ``_graphs_avoiding(avoid)`` whose lanes lead there
        (None where none does); a graph is searched only where the ones before leave some
        target unreached."""
        found: list = [None] * len(targets)
        left = range(len(targets))
        for graph in self._graphs_avoiding(avoid):
            if not left:
                break
            reached = search(graph, node, weight="length")
            for k in left:
                found[k] = reached.get(targets[k])
            left = [k for k in left if found[k] is None]
        return found

    def way_out(self, place: Place) -> list[np.ndarray]:
        """The points (m) a robot leaving ``place`` drives before its exit node: the point,
        then the entry path backwards (out of a room whose exit node is outside it); only
        the point where the exit node is on it (its lanes lead out whichever way the robot
        goes on: driving the entry out first would drive it twice, out and back, for a
        room at the end of its entry, or away and back, for a point on a passage)."""
        if np.array_equal(self.node_position(place.exit_node), place.point):
            return [place.point]
        return [place.point, *place.entry[::-1]]

    def _past_queue(self, place: Place) -> tuple[str, str] | None:
        """The single-file lane from ``place``'s exit node on which its own queue waits,
        which a robot leaving it could not pass: legs leave the other way where they can.
        None when the exit node is neither on the point nor beside it (nearer it than the
        head slot: a point served beside its node, as the office's patrol_B, whose holder
        otherwise left through the robot at its head slot), or the queue is elsewhere."""
        exit_xy = self.node_position(place.exit_node)
        if not self._segment_of or np.linalg.norm(exit_xy - place.point) >= \
                np.linalg.norm(place.queue[0] - place.point):
            return None
        for n in self.graph.successors(place.exit_node):
            if (self.segment_of(exit_xy, self.node_position(n)) is not None
                    and _on_segment(place.queue[0], exit_xy, self.node_position(n))):
                return (place.exit_node, n)
        return None

    def leg_to_spot(self, from_location: int, xy) -> np.ndarray:
        """The polyline (k, 2) out of ``from_location`` (``way_out``, its exit node) along
        the lanes, without lift rides, to the roadway node nearest ``xy`` it leads to, then
        ``xy`` (a robot's start spot, m)."""
        start = self.place(from_location)
        return _without_repeats([*self.way_out(start), *self._to_spot(start.exit_node, xy)])

    def route_to_spot(self, at, xy) -> np.ndarray:
        """The polyline (k, 2) from the roadway node nearest ``at`` along the lanes, without
        lift rides, to the roadway node nearest ``xy`` it leads to, then ``xy`` (m): for a
        robot away from any location's point that drives to a waiting spot."""
        return _without_repeats(self._to_spot(self._nearest(self.graph.nodes, at), xy))

    def _to_spot(self, node: str, xy) -> list:
        reached = self.paths_from(node)
        return [*(self.node_position(n) for n in reached[self._nearest(reached, xy)]),
                np.asarray(xy, dtype=float)]

    def spots_reached(self, from_location: int, spots) -> list:
        """Of ``spots`` ((x, y) m each), in their order, those whose nearest roadway node is
        reached from ``from_location``'s exit node along the lanes without lift rides: for a
        building's levels side by side, the spots on the location's level."""
        reached = self.paths_from(self.place(from_location).exit_node)
        return [spot for spot in spots
                if self._nearest(reached, spot) == self._nearest(self.graph.nodes, spot)]

    def paths_from(self, node: str) -> dict:
        """The shortest paths (node lists) from roadway node ``node`` to every node it
        reaches along the lanes without lift rides, by node."""
        graph = self.graph
        ground = nx.subgraph_view(graph, filter_edge=lambda a, b: not graph.edges[a, b].get(
            "lift", False))
        return nx.single_source_dijkstra_path(ground, node, weight="length")

    def _nearest(self, nodes, xy) -> str:
        """Of ``nodes``, the one nearest ``xy`` (m; ties by name)."""
        xy = np.asarray(xy, dtype=float)
        return min(nodes, key=lambda n: (float(np.linalg.norm(self.node_position(n) - xy)),
                                         str(n)))

    def route_from_point(self, xy, to_location: int) -> np.ndarray | None:
        """The polyline (k, 2) from the roadway node nearest ``xy`` that leads to
        ``to_location`` (for a robot that is not at a location, e.g. at the start), skipping
        nodes the straight line from ``xy`` to which touches a closure; None if none does."""
        xy = np.asarray(xy, dtype=float)
        by_distance = sorted(
            self.graph.nodes, key=lambda n: float(np.linalg.norm(self.node_position(n) - xy))
        )
        for node in by_distance:
            route = self.route_from_node(node, to_location)
            if route is not None and not self.crosses_closure([xy, self.node_position(node)]):
                return route
        return None

    def travel_time_estimate(self, speed: float) -> np.ndarray:
        """Integer travel times (s) between all locations at a nominal ``speed`` (m/s):
        ``ceil(leg_length / speed)``, 0 on the diagonal. Rows and columns follow
        ``location_ids`` (ascending ids, so the index is the id when ids are 0..n-1)."""
        if speed <= 0:
            raise ValueError(f"speed must be positive, got {speed}")
        times = np.ceil(self.leg_lengths / speed).astype(int)
        times.flags.writeable = False
        return times

    @functools.cached_property
    def leg_lengths(self) -> np.ndarray:
        """(L, L) lengths (m) of the legs between all locations (``leg_length``; rows and
        columns follow ``location_ids``, 0 on the diagonal, inf where no lane leads), from
        one search of the lanes per exit node: a leg's length is its way out to the exit
        node, the shortest way along the lanes to the approach node (off the lane past the
        own queue where another way leads there: ``_past_queue``) and the step to the
        queue's tail slot."""
        ids = self.location_ids
        places = [self.place(a) for a in ids]
        approach = [p.approach_node for p in places]
        to_tail = np.array([math.dist(self.node_position(p.approach_node), p.tail)
                            for p in places])
        along_from: dict[tuple, np.ndarray] = {}  # by exit node and lane avoided
        lengths = np.zeros((len(ids), len(ids)))
        for i, start in enumerate(places):
            out = _polyline_length(np.array(
                [*self.way_out(start), self.node_position(start.exit_node)], dtype=float))
            key = (start.exit_node, self._past_queue(start))
            if key not in along_from:
                along_from[key] = np.array(
                    [math.inf if d is None else d for d in self._ways(
                        *key, approach, nx.single_source_dijkstra_path_length)])
            lengths[i] = out + along_from[key] + to_tail
            lengths[i, i] = 0.0
        lengths.flags.writeable = False
        return lengths
