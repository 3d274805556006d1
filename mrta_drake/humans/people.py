"""The people of a scenario: named walkers and seeded generated groups.

``generate_people`` turns the scenario's ``humans:`` section (``HumansConfig``), the humans
block's ``SocialForceParams``, a seed and the world's ``Obstacles`` into a fixed tuple of
``Person``: where each one starts, the loop of waypoints it walks and how fast, and (for
``stream`` groups) when it enters the world.

Generated loops are routed: a leg whose straight line runs too close to an obstacle is
replaced by a shortest path on a clearance grid, simplified to line-of-sight waypoints, so
the social force only has to steer around people, not to find doors.

Frames and units: world frame, x east, y north, metres, seconds, m/s.
"""

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import distance_transform_edt
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components, dijkstra

from mrta_drake.errors import InputError
from mrta_drake.humans.social_force_params import SocialForceParams
from mrta_drake.scenario.schema import HumanGroupConfig, HumansConfig
from mrta_drake.world.obstacles import Obstacles

GROUP_KINDS = ("visitors", "crowd", "stream")
LOOP_STOPS = 4  # points of interest per generated loop (visitors, crowd)
STREAM_STOPS = 3  # points visited by a stream person before walking back to its entry
CROWD_SPEED_FACTOR = 0.5  # a milling crowd walks at half the default desired speed
CROWD_MIN_LEG = 0.5  # consecutive crowd stops are at least this fraction of spread apart
START_GAP = 0.2  # m, extra surface gap between generated start points
ROBOT_START_GAP = 0.3  # m, extra gap between a person's start point and a robot's start
CLEARANCE_RESOLUTION = 0.05  # m, cell size of the clearance raster for legs and routes
ROUTE_RESOLUTION = 0.2  # m, cell size of the routing grid
ROUTE_MARGIN = 0.2  # m, clearance beyond the body radius a routing cell needs
SIGHT_MARGIN = 0.1  # m, clearance beyond the body radius along a straight leg
SIGHT_STEP = 0.05  # m, sampling step when checking a straight leg
MAX_TRIES = 200  # draws of a random point before giving up
LOOP_TRIES = 20  # loops drawn for one person before giving up on a free start
START_TRIES = 20  # start points tried along one loop


@dataclass(frozen=True)
class Person:
    """One human. Starts at ``start`` (x, y) and walks the closed loop ``waypoints`` forever,
    ``waypoints[0]`` first; enters the world at ``entry_time`` (s; 0 = present from the start).
    ``desired_speed`` in m/s."""

    name: str
    start: tuple[float, float]
    waypoints: tuple[tuple[float, float], ...]
    desired_speed: float
    entry_time: float = 0.0


def generate_people(
    config: HumansConfig,
    params: SocialForceParams,
    seed: int,
    obstacles: Obstacles,
    places: Mapping[str, Sequence[float]] | None = None,
    keep_clear: Sequence[Sequence[float]] = (),
    file: str | None = None,
) -> tuple[Person, ...]:
    """All people of ``config``: the named walkers in order, then each group's people.

    Walkers start on their first waypoint and loop through the rest as given (their legs are
    not routed: consecutive waypoints should see each other). Groups are drawn
    from ``numpy.random.default_rng(seed)`` (one child stream per group, so editing one group
    does not reshuffle the others):

    - ``visitors``: ``count`` people, each looping through ``LOOP_STOPS`` random points of
      interest (no point twice in a row), starting at a random place along the loop.
    - ``crowd``: ``count`` people, each looping through ``LOOP_STOPS`` random free points
      within ``spread`` of ``center`` (consecutive points in line of sight and at least
      max(2 ``waypoint_tolerance``, ``CROWD_MIN_LEG`` ``spread``) apart), at
      ``CROWD_SPEED_FACTOR`` times the default speed unless the group sets one.
    - ``stream``: ``count`` people entering at ``center`` at times 0, ``interval``,
      2 ``interval``, ..., each visiting ``STREAM_STOPS`` random points of interest and
      walking back to ``center``, looping.

    Points of interest are the group's ``points``, or the values of ``places`` (named places,
    e.g. the floor plan's) when the group gives none. Every generated point has clearance
    >= ``params.radius`` from all obstacles; start points present at time 0 keep a surface gap
    of ``START_GAP`` from each other and from each circle (x, y, radius) in ``keep_clear``
    (e.g. robot start poses). Raises ``InputError`` (naming ``file`` and the field) for an
    invalid config or when no free points can be found.
    """
    rngs = np.random.default_rng(seed).spawn(len(config.groups))
    builder = _Builder(config, params, obstacles, file, keep_clear)
    people = builder.walkers()
    for g, (group, rng) in enumerate(zip(config.groups, rngs, strict=True)):
        people += builder.group(g, group, rng, places or {})
    return tuple(people)


def scenario_people(scenario, params: SocialForceParams, obstacles: Obstacles,
                    places: Mapping[str, Sequence[float]]) -> tuple[Person, ...]:
    """The people of ``scenario`` (a ``Scenario``) as a run draws them: ``generate_people``
    with its seed, keeping their start points clear of every robot's start by its radius
    and ``ROBOT_START_GAP``."""
    keep_clear = [(r.start[0], r.start[1], r.radius + ROBOT_START_GAP)
                  for r in scenario.robots]
    return generate_people(scenario.humans, params, scenario.seed, obstacles, places=places,
                           keep_clear=keep_clear, file=scenario.source)


def walkable_groups(points: Sequence[Sequence[float]], obstacles: Obstacles,
                    params: SocialForceParams | None = None) -> list[list[int]]:
    """The indices of ``points`` (x, y; m) in groups people walk between as
    ``generate_people`` routes them (through cells ``ROUTE_MARGIN`` clear beyond the body
    radius), largest group first (ties: lowest index first); [] without a walkable cell
    among obstacles; one group without obstacles.
    Points of interest from different groups give a group of people no routed loop.
    ``params``: the people's (default ``SocialForceParams()``)."""
    if len(points) == 0:
        return []
    if len(obstacles) == 0:  # nothing in the way (an outdoor map without walls)
        return [list(range(len(points)))]
    radius = float((params or SocialForceParams()).radius)
    router = _Router(_ClearanceMap(obstacles), radius + ROUTE_MARGIN)
    if len(router.free_ids) == 0:
        return []
    _, labels = connected_components(router.graph, directed=False)
    groups: dict[int, list[int]] = {}
    for k, point in enumerate(points):
        groups.setdefault(int(labels[router._nearest(point)]), []).append(k)
    return sorted(groups.values(), key=lambda group: (-len(group), group[0]))


def _is_number(value) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and np.isfinite(value)


class _Builder:
    """Validation, sampling and routing shared by all walkers and groups of one config."""

    def __init__(self, config: HumansConfig, params: SocialForceParams, obstacles: Obstacles,
                 file, keep_clear):
        self.config = config
        self.params = params
        self.obstacles = obstacles
        self.file = file
        self.radius = float(params.radius)
        self.occupied = [(float(c[0]), float(c[1]), float(c[2])) for c in keep_clear]
        self.names: set[str] = set()
        self._clearance = _ClearanceMap(obstacles)
        self._router = None

    # --- walkers and groups ------------------------------------------------------------------

    def walkers(self) -> list[Person]:
        people = []
        for i, walker in enumerate(self.config.walkers):
            where = f"humans.walkers[{i}]"
            name = self._name(walker.name or f"walker{i}", f"{where}.name")
            if not walker.waypoints:
                raise InputError(self.file, f"{where}.waypoints", "needs at least one point")
            points = [self._free_point(p, f"{where}.waypoints[{k}]")
                      for k, p in enumerate(walker.waypoints)]
            self._claim_start(points[0], f"{where}.waypoints[0]")
            people.append(Person(name, points[0], tuple(points[1:] + points[:1]),
                                 self._speed(walker.desired_speed, f"{where}.desired_speed")))
        return people

    def group(self, g: int, group: HumanGroupConfig, rng, places) -> list[Person]:
        where = f"humans.groups[{g}]"
        if group.kind not in GROUP_KINDS:
            raise InputError(self.file, f"{where}.kind",
                             f"must be one of {', '.join(GROUP_KINDS)}, got {group.kind!r}")
        count = group.count
        if not isinstance(count, int) or isinstance(count, bool) or count < 0:
            raise InputError(self.file, f"{where}.count", f"must be >= 0, got {count!r}")
        default = self.params.desired_speed
        if group.kind == "crowd":
            default = CROWD_SPEED_FACTOR * default
        speed = self._speed(group.desired_speed, f"{where}.desired_speed", default)
        if group.kind == "crowd":
            return self._crowd(g, group, rng, speed)
        if group.points:
            points = [self._free_point(p, f"{where}.points[{k}]")
                      for k, p in enumerate(group.points)]
            points_field = f"{where}.points"
        else:
            points = [self._free_point(list(p), f"{where}.points (place {name!r})")
                      for name, p in places.items()]
            points_field = f"{where}.points (named places)"
        if group.kind == "visitors":
            if len(points) < 2:
                raise InputError(self.file, points_field,
                                 f"visitors need at least 2 points, got {len(points)}")
            return self._visitors(g, group, rng, speed, points, points_field)
        return self._stream(g, group, rng, speed, points, points_field)

    def _visitors(self, g, group, rng, speed, points, points_field) -> list[Person]:
        def draw_loop():
            stops = _stop_sequence(rng, len(points), LOOP_STOPS)
            return self._loop([points[s] for s in stops], points_field)

        where = f"humans.groups[{g}]"
        return [Person(self._name(f"visitors{g}_{k}", where),
                       *self._placed_loop(rng, draw_loop, where), speed)
                for k in range(group.count)]

    def _crowd(self, g, group, rng, speed) -> list[Person]:
        where = f"humans.groups[{g}]"
        center = self._point(group.center, f"{where}.center")
        if not _is_number(group.spread) or not group.spread > 0:
            raise InputError(self.file, f"{where}.spread", f"must be > 0, got {group.spread!r}")

        def draw_loop():
            return self._crowd_stops(rng, center, float(group.spread), where)

        return [Person(self._name(f"crowd{g}_{k}", where),
                       *self._placed_loop(rng, draw_loop, where), speed)
                for k in range(group.count)]

    def _stream(self, g, group, rng, speed, points, points_field) -> list[Person]:
        where = f"humans.groups[{g}]"
        entry = self._free_point(group.center, f"{where}.center")
        if not _is_number(group.interval) or not group.interval > 0:
            raise InputError(self.file, f"{where}.interval",
                             f"must be > 0, got {group.interval!r}")
        if not points:
            raise InputError(self.file, points_field, "a stream needs at least 1 point")
        people = []
        for k in range(group.count):
            stops = _stop_sequence(rng, len(points), STREAM_STOPS, cyclic=False)
            loop = self._loop([entry] + [points[s] for s in stops], points_field)
            people.append(Person(self._name(f"stream{g}_{k}", where), entry,
                                 loop[1:] + loop[:1], speed, k * float(group.interval)))
        return people

    # --- points ------------------------------------------------------------------------------

    def _name(self, name: str, where: str) -> str:
        if name in self.names:
            raise InputError(self.file, where, f"duplicate human name {name!r}")
        self.names.add(name)
        return name

    def _speed(self, value, where: str, default: float | None = None) -> float:
        if value is None:
            return float(self.params.desired_speed if default is None else default)
        if not _is_number(value) or not 0 < value <= self.params.max_speed:
            raise InputError(self.file, where,
                             f"must be in (0, max_speed {self.params.max_speed}], got {value!r}")
        return float(value)

    def _point(self, value, where: str) -> tuple[float, float]:
        if (not isinstance(value, list | tuple) or len(value) != 2
                or not all(_is_number(v) for v in value)):
            raise InputError(self.file, where, f"must be [x, y], got {value!r}")
        return (float(value[0]), float(value[1]))

    def _free_point(self, value, where: str) -> tuple[float, float]:
        point = self._point(value, where)
        clearance = float(self.obstacles.signed_distance([point])[0])
        if clearance < self.radius:
            raise InputError(self.file, where,
                             f"{list(point)} is {clearance:.2f} m from an obstacle, "
                             f"needs >= radius {self.radius}")
        return point

    def _start_is_clear(self, point) -> bool:
        return all(np.hypot(point[0] - x, point[1] - y) >= self.radius + r + START_GAP
                   for x, y, r in self.occupied)

    def _claim_start(self, point, where: str) -> None:
        if not self._start_is_clear(point):
            raise InputError(self.file, where,
                             f"start {list(point)} is too close to another human or robot")
        self.occupied.append((point[0], point[1], self.radius))

    def _placed_loop(self, rng, draw_loop, where: str):
        """A loop from ``draw_loop()`` and a free start point drawn uniformly along it (a new
        loop when this one has no room left); returns the start and the loop rotated so that
        its first waypoint is the one after the start."""
        for _ in range(LOOP_TRIES):
            placed = self._start_on_loop(rng, draw_loop())
            if placed is not None:
                return placed
        raise InputError(self.file, where, "no free start point found; too many people?")

    def _start_on_loop(self, rng, loop):
        points = np.array(loop)
        ends = np.roll(points, -1, axis=0)
        lengths = np.linalg.norm(ends - points, axis=1)
        cumulative = np.concatenate([[0.0], np.cumsum(lengths)])
        for _ in range(START_TRIES):
            s = rng.uniform(0.0, cumulative[-1])
            k = min(int(np.searchsorted(cumulative, s, side="right")) - 1, len(points) - 1)
            fraction = (s - cumulative[k]) / lengths[k] if lengths[k] > 0 else 0.0
            start = tuple(float(c) for c in points[k] + fraction * (ends[k] - points[k]))
            free = self.obstacles.signed_distance([start])[0] >= self.radius
            if free and self._start_is_clear(start):
                self.occupied.append((start[0], start[1], self.radius))
                nxt = (k + 1) % len(loop)
                return start, tuple(loop[nxt:] + loop[:nxt])
        return None

    def _crowd_stops(self, rng, center, spread: float, where: str) -> list:
        """``LOOP_STOPS`` free points within ``spread`` of ``center``; consecutive ones (and
        the last and first) in sight of each other and at least ``min_leg`` apart."""
        min_leg = max(2.0 * self.params.waypoint_tolerance, CROWD_MIN_LEG * spread)

        def draw():
            for _ in range(MAX_TRIES):
                r = spread * np.sqrt(rng.uniform())
                angle = rng.uniform(-np.pi, np.pi)
                p = (center[0] + r * np.cos(angle), center[1] + r * np.sin(angle))
                if self.obstacles.signed_distance([p])[0] >= self.radius:
                    return p
            raise InputError(self.file, f"{where}.center",
                             f"no free point within spread {spread} m of {list(center)}")

        def linked(a, b):
            return np.hypot(b[0] - a[0], b[1] - a[1]) >= min_leg and self._in_sight(a, b)

        for _ in range(MAX_TRIES):
            stops = [draw()]
            for _ in range(MAX_TRIES):
                p = draw()
                if linked(stops[-1], p):
                    stops.append(p)
                if len(stops) == LOOP_STOPS:
                    break
            if len(stops) == LOOP_STOPS and linked(stops[-1], stops[0]):
                return stops
        raise InputError(self.file, f"{where}.spread",
                         f"no loop of free points {min_leg:.2f} m apart and in sight of each "
                         f"other within {spread} m of {list(center)}")

    # --- routing -----------------------------------------------------------------------------

    def _in_sight(self, a, b) -> bool:
        """True when the straight leg a -> b keeps clearance >= radius + SIGHT_MARGIN (or the
        endpoints' own clearance, if smaller) from every obstacle."""
        a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
        n = max(int(np.ceil(np.linalg.norm(b - a) / SIGHT_STEP)), 1)
        samples = a + np.linspace(0.0, 1.0, n + 1)[:, None] * (b - a)
        clearance = self._clearance.at(samples)
        needed = min(self.radius + SIGHT_MARGIN, clearance[0], clearance[-1])
        return bool(clearance.min() >= needed - 1e-9)

    def _loop(self, stops, where: str) -> list[tuple[float, float]]:
        """The closed loop through ``stops``, with routed legs; the first element is
        ``stops[0]``."""
        loop = []
        for a, b in zip(stops, stops[1:] + stops[:1], strict=True):
            loop.append(a)
            if not self._in_sight(a, b):
                loop += self._route(a, b, where)
        return loop

    def _route(self, a, b, where: str) -> list[tuple[float, float]]:
        """Intermediate waypoints of a clear path from a to b (excluding both)."""
        if self._router is None:
            self._router = _Router(self._clearance, self.radius + ROUTE_MARGIN)
        cells = self._router.path(a, b)
        if cells is None:
            raise InputError(self.file, where,
                             f"no walkable path from {list(a)} to {list(b)}")
        path = [a] + cells + [b]
        kept, i = [], 0
        while i < len(path) - 1:
            j = i + 1
            while j + 1 < len(path) and self._in_sight(path[i], path[j + 1]):
                j += 1
            kept.append(path[j])
            i = j
        return kept[:-1]


def _stop_sequence(rng, n: int, length: int, cyclic: bool = True) -> list[int]:
    """``length`` indices into n points with no index twice in a row (nor last == first when
    ``cyclic``). With n == 1 the sequence is that one point, once."""
    if n == 1:
        return [0]
    while True:
        seq = [int(rng.integers(n))]
        while len(seq) < length:
            nxt = int(rng.integers(n - 1))
            seq.append(nxt + (nxt >= seq[-1]))
        if not cyclic or seq[-1] != seq[0]:
            return seq


class _ClearanceMap:
    """Clearance from the obstacles (m) looked up in a distance transform of their raster at
    ``CLEARANCE_RESOLUTION``: fast for long legs on big maps, and never more than the exact
    clearance (it subtracts two cells for the rasterization error). +inf off the raster."""

    def __init__(self, obstacles: Obstacles):
        self.bounds = obstacles.bounds()
        self._grid = obstacles.rasterize(self.bounds, CLEARANCE_RESOLUTION)
        occupied = self._grid.occupied
        if occupied.any():
            distance = distance_transform_edt(~occupied) * CLEARANCE_RESOLUTION
            self._values = distance - 2.0 * CLEARANCE_RESOLUTION
        else:
            self._values = np.full(occupied.shape, np.inf)

    def at(self, points) -> np.ndarray:
        points = np.asarray(points, dtype=float)
        result = np.full(len(points), np.inf)
        inside = self._grid.contains(points)
        i, j = self._grid.world_to_cell(points[inside])
        result[inside] = self._values[i, j]
        return result


class _Router:
    """Shortest paths on a grid of cells with clearance >= ``clearance`` from all obstacles,
    8-connected; step costs grow near obstacles so routes keep to corridor centres."""

    def __init__(self, clearance_map: "_ClearanceMap", clearance: float):
        x0, x1, y0, y1 = clearance_map.bounds
        res = ROUTE_RESOLUTION
        xs = np.arange(x0 + 0.5 * res, x1, res)
        ys = np.arange(y0 + 0.5 * res, y1, res)
        gx, gy = np.meshgrid(xs, ys)
        centres = np.stack([gx.ravel(), gy.ravel()], axis=1)
        sd = clearance_map.at(centres)
        rows, cols = gy.shape
        free = (sd >= clearance).reshape(rows, cols)
        penalty = 1.0 + 2.0 * np.exp(-(sd - clearance) / 0.3).reshape(rows, cols)
        ids = np.arange(rows * cols).reshape(rows, cols)
        src, dst, cost = [], [], []
        for di, dj in ((0, 1), (1, 0), (1, 1), (1, -1)):
            a = (slice(0, rows - di), slice(max(-dj, 0), cols - max(dj, 0)))
            b = (slice(di, rows), slice(max(dj, 0), cols - max(-dj, 0)))
            both = free[a] & free[b]
            step = res * np.hypot(di, dj) * 0.5 * (penalty[a] + penalty[b])
            src.append(ids[a][both])
            dst.append(ids[b][both])
            cost.append(step[both])
        src, dst, cost = (np.concatenate(v) for v in (src, dst, cost))
        n = rows * cols
        self.graph = coo_matrix((np.r_[cost, cost], (np.r_[src, dst], np.r_[dst, src])),
                                shape=(n, n)).tocsr()
        self.centres = centres
        self.free_ids = ids.ravel()[free.ravel()]
        self._trees: dict[int, np.ndarray] = {}

    def _nearest(self, p) -> int:
        d = np.linalg.norm(self.centres[self.free_ids] - np.asarray(p), axis=1)
        return int(self.free_ids[np.argmin(d)])

    def path(self, a, b) -> list[tuple[float, float]] | None:
        """Cell centres from the free cell nearest a to the free cell nearest b, or None."""
        if len(self.free_ids) == 0:
            return None
        s, t = self._nearest(a), self._nearest(b)
        if s not in self._trees:
            _, self._trees[s] = dijkstra(self.graph, indices=s, return_predecessors=True)
        predecessors = self._trees[s]
        cells = [t]
        while cells[-1] != s:
            cells.append(int(predecessors[cells[-1]]))
            if cells[-1] < 0:
                return None
        return [tuple(float(c) for c in self.centres[i]) for i in reversed(cells)]
