"""One-way lanes from a graph of corridor centre-lines, for right-hand traffic.

Input: a ``CentrelineGraph`` (vertices at world positions, x east, y north, m; straight
edges, two-way unless marked one-way) and a clearance function (``clearance_field``:
distance from world points to the nearest obstacle, m). Output: ``Lanes``, the
``RoadwaysConfig`` that ``Roadways`` drives on and the single-file segments.

- Two lanes: a two-way edge becomes two one-way lanes, each ``offset`` to the right of its
  travel direction, when both keep ``robot_radius + margin`` from obstacles all along.
- Single file: otherwise (or when the edge is marked ``single_file``) it stays one segment on
  its centre line, driven both ways by one robot at a time. ``Lanes.single_file`` lists the
  maximal chains of such edges (joined at vertices with no other edge, but for the
  ``stops`` given: vertices where robots stop, such as task locations on a passage) with
  their roadway nodes, for whoever queues robots for them.
- A one-way edge is one lane on its centre line.
- Corners: at a vertex, the lane arriving on one edge and the lane leaving on the next edge
  counterclockwise meet where their lines cross (a right turn); where the lines do not cross
  ahead of the vertex and near it (a straight run, a reflex or a sharp angle) each lane ends
  beside the vertex and a short link joins them.
- Junctions (three or more edges): the corners are also joined counterclockwise across each
  edge's mouth, a small loop like a roundabout for right-hand traffic: a robot turns right at
  the corner it arrives at, and drives around the loop to go straight, turn left or U-turn.
- Dead ends (one edge): a single node on the vertex itself, where both lanes meet.

A lane that comes closer to obstacles than ``robot_radius + margin`` or runs backwards (its
edge too short for the corners at its ends; allowed for a single-file dead end, whose lanes
then both meet on it from beside) turns its edge single file; a junction link that
does turns every edge at its vertex single file; then the corners are laid out again. Lanes
still short of the clearance (a centre line itself too close to obstacles) are listed in
``Lanes.tight``.
"""

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from mrta_drake.errors import InputError, require_non_negative, require_positive
from mrta_drake.navigation.clearance_field import Clearance, segment_clearance
from mrta_drake.scenario.schema import RoadwaysConfig

_DIGITS = 3  # roadway node positions are rounded to mm


@dataclass(frozen=True)
class CentrelineEdge:
    """A straight centre-line from vertex ``a`` to vertex ``b``. ``one_way``: traffic from
    ``a`` to ``b`` only. ``single_file``: one shared segment whatever the free width."""

    a: str
    b: str
    one_way: bool = False
    single_file: bool = False


@dataclass(frozen=True)
class CentrelineGraph:
    """Corridor centre-lines: ``nodes`` vertex name -> (x, y), m, world frame; ``edges``
    straight, at most one between two vertices."""

    nodes: Mapping[str, tuple[float, float]]
    edges: tuple[CentrelineEdge, ...]

    def __post_init__(self):
        seen = set()
        for k, edge in enumerate(self.edges):
            for end in (edge.a, edge.b):
                if end not in self.nodes:
                    raise InputError(None, f"edges[{k}]", f"unknown vertex {end!r}")
            pair = frozenset((edge.a, edge.b))
            if pair in seen:
                raise InputError(None, f"edges[{k}]",
                                 f"second edge between {edge.a!r} and {edge.b!r}")
            if math.dist(self.nodes[edge.a], self.nodes[edge.b]) == 0.0:
                raise InputError(None, f"edges[{k}]",
                                 f"zero length: {edge.a!r} and {edge.b!r} coincide")
            seen.add(pair)

    def degree(self) -> dict[str, int]:
        """The number of edges at each vertex."""
        return vertex_degrees(self.nodes, self.edges)


def vertex_degrees(vertices, edges) -> dict:
    """The number of ``edges`` (with ends ``a`` and ``b``) at each of ``vertices``."""
    count = dict.fromkeys(vertices, 0)
    for edge in edges:
        count[edge.a] += 1
        count[edge.b] += 1
    return count


@dataclass(frozen=True)
class LaneParams:
    """Lane layout parameters, m.

    ``offset`` 0.45: each lane's distance from its corridor's centre-line, as the hospital's
    hand-made lanes (the reference corridors are 2.1-2.8 m wall to wall; 0.4-0.5 m fits a
    2.2 m corridor for 0.3 m robots). ``robot_radius`` 0.22: a scenario's default robot
    radius (the original costmap's inscribed radius). ``margin`` 0.25: room between the robot
    and obstacles. Lanes keep ``robot_radius + margin`` = 0.47 m from obstacles: two lanes
    fit a corridor 2 x (0.45 + 0.47) = 1.84 m wide, so every reference corridor takes two,
    and a 1.3 m doorway (0.65 m at its middle) lets a single-file centre-line through.
    ``check_step`` 0.05: spacing of the clearance samples along lanes (a map cell).
    """

    offset: float = 0.45
    robot_radius: float = 0.22
    margin: float = 0.25
    check_step: float = 0.05

    def __post_init__(self):
        require_positive(self, "offset", "robot_radius", "check_step", unit=" m")
        require_non_negative(self, "margin", unit=" m")

    @property
    def clearance(self) -> float:
        """Distance every lane keeps from obstacles, m."""
        return self.robot_radius + self.margin


@dataclass(frozen=True)
class SingleFileSegment:
    """A chain of single-file centre-line edges, driven both ways by one robot at a time:
    ``vertices`` from one end to the other, ``nodes`` the roadway nodes on it in that order."""

    vertices: tuple[str, ...]
    nodes: tuple[str, ...]


@dataclass(frozen=True)
class Lanes:
    """The derived lanes. ``roadways``: the one-way lane graph. ``single_file``: segments
    for one robot at a time. ``ends[(v, w)]``: the roadway nodes where the lane from vertex
    ``v`` towards vertex ``w`` starts (beside ``v``) and ends (beside ``w``), for every
    lane. ``tight``: roadway edges that keep less than the clearance from obstacles."""

    roadways: RoadwaysConfig
    single_file: tuple[SingleFileSegment, ...]
    ends: Mapping[tuple[str, str], tuple[str, str]]
    tight: tuple[tuple[str, str], ...]


def derive_lanes(graph: CentrelineGraph, clearance: Clearance,
                 params: LaneParams = LaneParams(), stops: frozenset[str] = frozenset()
                 ) -> Lanes:
    """One-way lanes along ``graph`` (see the module docstring); ``clearance`` maps world
    points (k, 2) to their distance from obstacles (k,), m. Single-file chains end at the
    vertices ``stops`` (where robots stop): a robot waiting on one side of such a vertex
    leaves the other side free for a robot leaving it that way."""
    single = {k for k, edge in enumerate(graph.edges) if edge.single_file and not edge.one_way}
    while True:
        layout = _Layout(graph, single, params, stops)
        more = layout.edges_to_narrow(clearance) - single
        if not more:
            return layout.lanes(clearance)
        single |= more


class _Layout:
    """Corners and links of every vertex for one choice of single-file edges."""

    def __init__(self, graph: CentrelineGraph, single: set[int], params: LaneParams,
                 stops: frozenset[str] = frozenset()):
        self.graph, self.single, self.params, self.stops = graph, single, params, stops
        self.position = {v: np.asarray(xy, dtype=float) for v, xy in graph.nodes.items()}
        self.neighbours: dict[str, list[tuple[str, int]]] = {v: [] for v in graph.nodes}
        for k, edge in enumerate(graph.edges):
            self.neighbours[edge.a].append((edge.b, k))
            self.neighbours[edge.b].append((edge.a, k))
        self.node_at: dict[tuple[float, float], str] = {}
        self.node_position: dict[str, tuple[float, float]] = {}
        self.start: dict[tuple[str, str], str] = {}  # (v, w): node beside v leaving to w
        self.end: dict[tuple[str, str], str] = {}  # (w, v): node beside v arriving from w
        self.links: list[tuple[str, str, str]] = []  # (vertex, from node, to node)
        for v in graph.nodes:
            self._lay_out(v)

    # --- Layout --------------------------------------------------------------------------

    def _offset(self, k: int) -> float:
        edge = self.graph.edges[k]
        return 0.0 if edge.one_way or k in self.single else self.params.offset

    def _lay_out(self, v: str) -> None:
        here = self.position[v]
        around = sorted(self.neighbours[v], key=lambda item: _angle(self.position[item[0]] - here))
        if len(around) == 1:
            (w, _), = around
            node = self._node(v, here)
            self.start[(v, w)] = self.end[(w, v)] = node
            return
        for i, (w, k) in enumerate(around):
            w_next, k_next = around[(i + 1) % len(around)]
            arrive, leave = _corner(here, self.position[w], self._offset(k),
                                    self.position[w_next], self._offset(k_next))
            self.end[(w, v)] = self._node(v, arrive)
            self.start[(v, w_next)] = self._node(v, leave)
            if self.end[(w, v)] != self.start[(v, w_next)]:
                self.links.append((v, self.end[(w, v)], self.start[(v, w_next)]))
        if len(around) >= 3:
            for w, _ in around:  # across each edge's mouth, counterclockwise
                if self.start[(v, w)] != self.end[(w, v)]:
                    self.links.append((v, self.start[(v, w)], self.end[(w, v)]))

    def _node(self, v: str, xy: np.ndarray) -> str:
        """The roadway node at ``xy`` (rounded to mm), made if new: named ``v`` on the vertex
        itself, else ``v_<k>``."""
        key = _rounded(xy)
        if key not in self.node_at:
            name, count = v, 0
            while key != _rounded(self.position[v]) and (
                    name == v or name in self.node_position or name in self.graph.nodes):
                name, count = f"{v}_{count}", count + 1
            self.node_at[key] = name
            self.node_position[name] = key
        return self.node_at[key]

    # --- Checks --------------------------------------------------------------------------

    def lanes_of(self, k: int) -> list[tuple[str, str]]:
        """The lanes (start node, end node) of edge ``k``, from ``a`` first."""
        return [(self.start[way], self.end[way]) for way in _ways(self.graph.edges[k])]

    def _short(self, clearance: Clearance, a: str, b: str) -> bool:
        step = self.params.check_step
        return segment_clearance(clearance, self.node_position[a], self.node_position[b],
                                 step) < self.params.clearance - 1e-9

    def _two_way_at(self, v: str) -> set[int]:
        return {k for _, k in self.neighbours[v] if not self.graph.edges[k].one_way}

    def edges_to_narrow(self, clearance: Clearance) -> set[int]:
        """Edges to make single file for the lanes to keep clearance and run forwards."""
        narrow = set()
        for k, edge in enumerate(self.graph.edges):
            along = self.position[edge.b] - self.position[edge.a]
            dead_end = 1 in (len(self.neighbours[edge.a]), len(self.neighbours[edge.b]))
            for index, (start, end) in enumerate(self.lanes_of(k)):
                ahead = np.subtract(self.node_position[end], self.node_position[start]) @ along
                backwards = ahead * (1 if index == 0 else -1) <= 0.0
                if backwards and k in self.single and dead_end:
                    backwards = False  # a stub shorter than the lanes' offset: both meet on it
                if backwards or self._short(clearance, start, end):
                    if edge.one_way or k in self.single:
                        narrow |= self._two_way_at(edge.a) | self._two_way_at(edge.b)
                    else:
                        narrow.add(k)
        for v, a, b in self.links:
            if self._short(clearance, a, b):
                narrow |= self._two_way_at(v)
        return narrow

    # --- Result --------------------------------------------------------------------------

    def lanes(self, clearance: Clearance) -> Lanes:
        pairs = [lane for k in range(len(self.graph.edges)) for lane in self.lanes_of(k)]
        pairs += [(a, b) for _, a, b in self.links]
        edges = list(dict.fromkeys(pair for pair in pairs if pair[0] != pair[1]))
        roadways = RoadwaysConfig(
            nodes={name: list(xy) for name, xy in self.node_position.items()},
            edges=[list(pair) for pair in edges])
        ends = {way: (self.start[way], self.end[way])
                for edge in self.graph.edges for way in _ways(edge)}
        return Lanes(roadways=roadways, single_file=self._single_file_segments(),
                     ends=ends, tight=tuple(pair for pair in edges
                                            if self._short(clearance, *pair)))

    def _single_file_segments(self) -> tuple[SingleFileSegment, ...]:
        single_at = {v: [(w, k) for w, k in self.neighbours[v] if k in self.single]
                     for v in self.graph.nodes}

        def inner(v):  # a vertex a chain runs through
            return (len(self.neighbours[v]) == 2 and len(single_at[v]) == 2
                    and v not in self.stops)

        done, segments = set(), []
        starts = [v for v in self.graph.nodes if single_at[v] and not inner(v)]
        starts += [v for v in self.graph.nodes if inner(v)]  # chains that are closed loops
        for v0 in starts:
            for w, k in single_at[v0]:
                if k in done:
                    continue
                chain, ks = [v0, w], [k]
                done.add(k)
                while inner(chain[-1]) and chain[-1] != v0:
                    w, k = next((x, j) for x, j in single_at[chain[-1]] if j not in done)
                    chain.append(w)
                    ks.append(k)
                    done.add(k)
                segments.append(SingleFileSegment(tuple(chain), self._nodes_along(chain)))
        return tuple(segments)

    def _nodes_along(self, chain: list[str]) -> tuple[str, ...]:
        """The roadway nodes of the lanes along ``chain``, ordered along it."""
        found: dict[str, float] = {}
        travelled = 0.0
        for v, w in zip(chain[:-1], chain[1:], strict=True):
            a, b = self.position[v], self.position[w]
            length = float(np.linalg.norm(b - a))
            for node in (self.start[(v, w)], self.end[(w, v)], self.end[(v, w)],
                         self.start[(w, v)]):
                along = float(np.subtract(self.node_position[node], a) @ (b - a)) / length
                found.setdefault(node, travelled + along)
            travelled += length
        return tuple(sorted(found, key=found.get))


def _ways(edge: CentrelineEdge) -> list[tuple[str, str]]:
    """The (from, to) vertices of the lanes of ``edge``."""
    return [(edge.a, edge.b)] if edge.one_way else [(edge.a, edge.b), (edge.b, edge.a)]


def _rounded(xy) -> tuple[float, float]:
    return round(float(xy[0]), _DIGITS), round(float(xy[1]), _DIGITS)


def _angle(vector: np.ndarray) -> float:
    return math.atan2(vector[1], vector[0])


def _corner(here: np.ndarray, towards_in: np.ndarray, offset_in: float,
            towards_out: np.ndarray, offset_out: float) -> tuple[np.ndarray, np.ndarray]:
    """Where the lane arriving at vertex ``here`` from ``towards_in`` (``offset_in`` to its
    right) ends and where the lane leaving towards ``towards_out`` (the next edge
    counterclockwise, ``offset_out`` to its right) starts: the crossing of their lines when
    it lies ahead of the vertex on both edges and within twice the larger offset of it (an
    angle of 60 degrees or more between two-lane edges), else each lane's point beside the
    vertex."""
    u_in = (towards_in - here) / np.linalg.norm(towards_in - here)
    u_out = (towards_out - here) / np.linalg.norm(towards_out - here)
    n_in = np.array([-u_in[1], u_in[0]])  # right of travel towards ``here``
    n_out = np.array([u_out[1], -u_out[0]])  # right of travel away from ``here``
    normals = np.array([n_in, n_out])
    if abs(np.linalg.det(normals)) > 1e-9:
        crossing = np.linalg.solve(normals, [offset_in, offset_out])
        if (crossing @ u_in >= -1e-9 and crossing @ u_out >= -1e-9
                and np.linalg.norm(crossing) <= 2.0 * max(offset_in, offset_out) + 1e-9):
            return here + crossing, here + crossing
    return here + offset_in * n_in, here + offset_out * n_out
