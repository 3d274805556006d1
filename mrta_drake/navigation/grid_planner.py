"""A cost-aware 2D grid planner over a ``Costmap``, in the manner of Nav2's Smac 2D planner.

The search is A* over the costmap's cells, 8-connected, on cells a robot's centre may occupy
(cost below ``INSCRIBED``); a diagonal move also needs both cells beside it, so no move cuts
a corner of a blocked cell. A path's cost is the line integral of the traversal factor
``1 + cost_weight * cost / 252`` along it (m): a move between neighbouring cells ``u`` and
``v`` costs ``|uv| * (factor(u) + factor(v)) / 2``. A* is guided by the larger of the octile
distance and an ALT bound (distances to a few landmark cells, computed once per costmap), so a
query explores few cells beyond the path. The grid path is then shortcut by line of sight,
taking a straight segment only where it touches no cell of cost ``INSCRIBED`` or more and
costs no more than the grid path it replaces, and resampled into world-frame points. Only a
start inside the inscribed zone (moved out by ``snap_radius``) has a first leg within it.

Search, landmark distances, shortcutting and resampling run in Numba-compiled kernels. A
``GridPlanner`` computes its landmark distances in a thread of its own (the compiled search
releases the GIL), so that the caller goes on building while it runs; the first query or
costmap change waits for it. It keeps per-query scratch arrays and its answers on the current
costmap: it is not thread-safe.
"""

import math
import threading
from dataclasses import dataclass

import numba
import numpy as np
from scipy import ndimage

from mrta_drake.navigation.costmap import INSCRIBED, LETHAL, MAX_NON_OBSTACLE, Costmap
from mrta_drake.payloads import frozen_array
from mrta_drake.stack.compiled_helper import compiled_helper

_SQRT2 = math.sqrt(2.0)
# Favour cells nearer the goal among equal-cost candidates; bounds the excess path cost by
# this fraction.
_TIE_BREAK = 1e-7
_ANSWERS = 256  # answers kept per costmap (all dropped when full)

START_OFF_GRID = "start off the grid"
START_IN_OBSTACLE = "start in an obstacle"
GOAL_OFF_GRID = "goal off the grid"
GOAL_IN_OBSTACLE = "goal in an obstacle"
UNREACHABLE = "goal unreachable"

_BLOCKED = object()  # a point in an obstacle or deep in the inscribed zone


@dataclass(frozen=True)
class PlannerParams:
    """Grid planner parameters.

    ``cost_weight``: weight of the costmap cost in the traversal factor (Smac 2D's
    ``cost_travel_multiplier``). ``point_spacing`` (m): largest gap between consecutive
    output points. ``snap_radius`` (m): a start or goal inside the inscribed zone (but not in
    an obstacle) moves to the nearest traversable cell within this distance.
    ``landmarks``: number of ALT landmark cells (0 = octile heuristic only).
    """

    cost_weight: float = 2.0
    point_spacing: float = 0.25
    snap_radius: float = 0.3
    landmarks: int = 8

    def __post_init__(self):
        if self.cost_weight < 0.0 or self.point_spacing <= 0.0 or self.snap_radius < 0.0:
            raise ValueError("need cost_weight >= 0, point_spacing > 0, snap_radius >= 0")
        if self.landmarks < 0:
            raise ValueError("landmarks must be non-negative")


@dataclass(frozen=True, eq=False)
class PlanResult:
    """One query's answer. On success ``points`` (k >= 2, 2) are world-frame points (m) from
    the start to the goal (or their snapped cells), ``cells`` (m, 2) the (row, col) grid path
    and ``cost`` its cost (m, see the module docstring). On failure ``failure`` says why,
    ``points`` and ``cells`` are empty and ``cost`` is inf. Arrays are read-only."""

    points: np.ndarray
    cells: np.ndarray
    cost: float
    failure: str | None = None

    @property
    def found(self) -> bool:
        return self.failure is None

    @classmethod
    def failed(cls, reason: str) -> "PlanResult":
        return cls(frozen_array(np.zeros((0, 2))), frozen_array(np.zeros((0, 2)), dtype=int),
                   math.inf, reason)


class GridPlanner:
    """Plans paths between world points over ``costmap`` (see the module docstring)."""

    def __init__(self, costmap: Costmap, params: PlannerParams = PlannerParams()):
        self._params = params
        self._costmap = self._landmark_costmap = costmap
        self._factor = self._factors(costmap.cost.ravel())
        # Without corner cutting, cells connect as 4-neighbours.
        self._component, _ = ndimage.label(costmap.traversable)
        self._answers = {}  # PlanResult by (start, goal) bytes, on ``_costmap``
        rows, cols = costmap.shape
        n = rows * cols
        self._g = np.empty(n)
        self._parent = np.empty(n, dtype=np.int64)
        self._stamp = np.zeros(n, dtype=np.int64)
        self._heap_key = np.empty(max(n, 16))
        self._heap_item = np.empty(max(n, 16), dtype=np.int64)
        self._query = 0
        self._landmark = np.zeros((n, 0))  # no landmarks while computing them
        # The landmark searches (~0.5 s on the hospital floor) run in a thread, the compiled
        # search without the GIL, while the caller goes on building; the first query waits.
        self._landmarks_done = None
        self._landmark_thread = threading.Thread(
            target=self._compute_landmarks, args=(params.landmarks,), daemon=True)
        self._landmark_thread.start()

    @property
    def costmap(self) -> Costmap:
        return self._costmap

    @property
    def base_costmap(self) -> Costmap:
        """The costmap the planner was made with (``use_costmap`` may only raise its costs)."""
        return self._landmark_costmap

    def use_costmap(self, costmap: Costmap) -> None:
        """Plan on ``costmap`` from now on (e.g. ``Costmap.with_obstacles`` of the one the
        planner was made with). Its costs must be nowhere below those of the costmap the
        planner was made with, whose landmark distances it keeps: they stay lower bounds.
        Only the cells whose cost differs from the current costmap's are looked at (the
        others passed the check before), and the components are found again only if one of
        them changed traversability."""
        self._wait_for_landmarks()
        base = self._landmark_costmap
        if costmap.shape != base.shape:
            raise ValueError("the new costmap must cover the planner's grid")
        old, new = self._costmap.cost.ravel(), costmap.cost.ravel()
        changed = np.flatnonzero(old != new)
        if np.any(new[changed] < base.cost.ravel()[changed]):
            raise ValueError("the new costmap's costs must be nowhere below the planner's own")
        self._factor[changed] = self._factors(new[changed])
        if np.any((old[changed] < INSCRIBED) != (new[changed] < INSCRIBED)):
            self._component, _ = ndimage.label(costmap.traversable)
        self._costmap = costmap
        self._answers.clear()

    def _factors(self, cost: np.ndarray) -> np.ndarray:
        """Traversal factors (see the module docstring) of cells of ``cost``; inf where not
        traversable."""
        factor = 1.0 + self._params.cost_weight * cost.astype(float) / MAX_NON_OBSTACLE
        return np.where(cost < INSCRIBED, factor, np.inf)

    @property
    def params(self) -> PlannerParams:
        return self._params

    def plan(self, start, goal) -> PlanResult:
        """A path from world point ``start`` to world point ``goal`` (m); never raises for
        a point off the grid, in an obstacle or cut off from the other. Recent answers are
        kept until the costmap changes: a repeated query gets the same ``PlanResult``."""
        start = np.array(start, dtype=float)  # writable copies: one compiled _path_points
        goal = np.array(goal, dtype=float)
        key = (start.tobytes(), goal.tobytes())
        result = self._answers.get(key)
        if result is None:
            if len(self._answers) == _ANSWERS:
                self._answers.clear()
            result = self._answers[key] = self._plan(start, goal)
        return result

    def _plan(self, start: np.ndarray, goal: np.ndarray) -> PlanResult:
        start_cell = self._snap(start)
        if start_cell is None:
            return PlanResult.failed(START_OFF_GRID)
        if start_cell is _BLOCKED:
            return PlanResult.failed(START_IN_OBSTACLE)
        goal_cell = self._snap(goal)
        if goal_cell is None:
            return PlanResult.failed(GOAL_OFF_GRID)
        if goal_cell is _BLOCKED:
            return PlanResult.failed(GOAL_IN_OBSTACLE)
        if self._component[start_cell] != self._component[goal_cell]:
            return PlanResult.failed(UNREACHABLE)
        rows, cols = self._costmap.shape
        start_index = start_cell[0] * cols + start_cell[1]
        goal_index = goal_cell[0] * cols + goal_cell[1]
        if not self._search(start_index, goal_index):
            return PlanResult.failed(UNREACHABLE)
        cells = _trace(self._parent, goal_index, cols)
        grid = self._costmap.grid
        cost = self._g[goal_index] * grid.resolution
        points = _path_points(self._factor, rows, cols, cells, start, goal,
                              np.asarray(grid.origin, dtype=float), grid.resolution,
                              self._params.point_spacing)
        points.flags.writeable = False
        cells.flags.writeable = False
        return PlanResult(points, cells, float(cost))

    def _snap(self, xy: np.ndarray):
        """The cell (row, col) to plan from for world point ``xy``: its own cell if
        traversable, else the nearest traversable cell within the snap radius; None off the
        grid, ``_BLOCKED`` in an obstacle or with no such cell."""
        if not (math.isfinite(xy[0]) and math.isfinite(xy[1])):
            return None
        grid = self._costmap.grid
        # As ``OccupancyGrid.world_to_cell``, on scalars.
        i = math.floor((xy[1] - grid.origin[1]) / grid.resolution)
        j = math.floor((xy[0] - grid.origin[0]) / grid.resolution)
        cost = self._costmap.cost
        rows, cols = cost.shape
        if not (0 <= i < rows and 0 <= j < cols):
            return None
        if cost[i, j] < INSCRIBED:
            return i, j
        if cost[i, j] == LETHAL:
            return _BLOCKED
        reach = int(self._params.snap_radius / grid.resolution)
        i0, i1 = max(i - reach, 0), min(i + reach + 1, rows)
        j0, j1 = max(j - reach, 0), min(j + reach + 1, cols)
        ii, jj = np.mgrid[i0:i1, j0:j1]
        d2 = (ii - i) ** 2 + (jj - j) ** 2
        candidate = (cost[i0:i1, j0:j1] < INSCRIBED) & (d2 <= reach * reach)
        if not candidate.any():
            return _BLOCKED
        k = np.argmin(np.where(candidate, d2, np.iinfo(d2.dtype).max))
        return int(ii.flat[k]), int(jj.flat[k])

    def _search(self, start: int, goal: int) -> bool:
        """Runs A* from ``start`` to ``goal`` into the scratch arrays, once the landmark
        distances are there; True if ``goal`` was reached."""
        self._wait_for_landmarks()
        return self._run_search(start, goal)

    def _wait_for_landmarks(self) -> None:
        """Waits for the landmark thread (which reads the factors, the components and the
        scratch arrays); raises what stopped it."""
        if self._landmark_thread is not None:
            self._landmark_thread.join()
            self._landmark_thread = None
            if self._landmarks_done is not True:
                raise self._landmarks_done

    def _compute_landmarks(self, count: int) -> None:
        """The landmark thread: sets the landmark distances and ``_landmarks_done`` (True, or
        the exception that stopped it, raised by the first query)."""
        try:
            self._landmark = self._landmark_distances(count)
            self._landmarks_done = True
        except Exception as error:  # handed to the caller's thread
            self._landmarks_done = error

    def _run_search(self, start: int, goal: int) -> bool:
        """Runs A* (or, with ``goal`` < 0, Dijkstra over the whole component) into the
        scratch arrays; True if ``goal`` was reached."""
        rows, cols = self._costmap.shape
        while True:
            self._query += 1
            status = _search(self._factor, rows, cols, start, goal, self._landmark, self._g,
                             self._parent, self._stamp, self._query, self._heap_key,
                             self._heap_item)
            if status >= 0:
                return status == 1
            size = 2 * len(self._heap_key)
            self._heap_key = np.empty(size)
            self._heap_item = np.empty(size, dtype=np.int64)

    def _landmark_distances(self, count: int) -> np.ndarray:
        """(cells, count) path costs (in cells) from ``count`` landmarks spread by farthest
        point selection over the largest traversable component; 0 elsewhere."""
        n = self._factor.size
        sizes = np.bincount(self._component.ravel())
        sizes[0] = 0
        if count == 0 or sizes.max() == 0:
            return np.zeros((n, 0))
        landmark = np.zeros((n, count))
        main = np.flatnonzero(self._component.ravel() == sizes.argmax())
        self._run_search(int(main[0]), -1)
        nearest = self._closed_distances()[main]
        for k in range(count):
            self._run_search(int(main[np.argmax(nearest)]), -1)
            distance = self._closed_distances()
            landmark[:, k] = np.where(np.isfinite(distance), distance, 0.0)
            nearest = np.minimum(nearest, distance[main]) if k else distance[main]
        return landmark

    def _closed_distances(self) -> np.ndarray:
        return np.where(self._stamp == -self._query, self._g, np.inf)


@numba.njit(cache=True, inline="always")
def _neighbour(k, i, j):
    """The k-th (0..7) neighbour of cell (i, j) and the step length, in cells."""
    if k == 0:
        return i - 1, j - 1, _SQRT2
    if k == 1:
        return i - 1, j, 1.0
    if k == 2:
        return i - 1, j + 1, _SQRT2
    if k == 3:
        return i, j - 1, 1.0
    if k == 4:
        return i, j + 1, 1.0
    if k == 5:
        return i + 1, j - 1, _SQRT2
    if k == 6:
        return i + 1, j, 1.0
    return i + 1, j + 1, _SQRT2


@numba.njit(cache=True, nogil=True)
def _search(factor, rows, cols, start, goal, landmark, g, parent, stamp, query, heap_key,
            heap_item):
    """A* from cell index ``start`` to ``goal`` over cells of finite ``factor``; with
    ``goal`` < 0, Dijkstra over all cells reachable from ``start``.

    Costs ``g`` (in cells) and ``parent`` are valid where ``stamp`` is ``query`` (open) or
    ``-query`` (closed); other entries are stale, which spares clearing the arrays. Returns
    1 if the goal was reached, 0 if not, -1 if the heap was too small.
    """
    goal_i, goal_j = (goal // cols, goal % cols) if goal >= 0 else (0, 0)
    closed = -query
    stamp[start] = query
    g[start] = 0.0
    parent[start] = -1
    heap_key[0] = 0.0
    heap_item[0] = start
    size = 1
    while size > 0:
        current = heap_item[0]
        size -= 1
        key = heap_key[size]
        item = heap_item[size]
        pos = 0
        while True:
            child = 2 * pos + 1
            if child >= size:
                break
            if child + 1 < size and heap_key[child + 1] < heap_key[child]:
                child += 1
            if key <= heap_key[child]:
                break
            heap_key[pos] = heap_key[child]
            heap_item[pos] = heap_item[child]
            pos = child
        heap_key[pos] = key
        heap_item[pos] = item
        if stamp[current] == closed:
            continue  # a stale duplicate entry
        stamp[current] = closed
        if current == goal:
            return 1
        ci = current // cols
        cj = current - ci * cols
        g_current = g[current]
        f_current = factor[current]
        for k in range(8):
            ni, nj, length = _neighbour(k, ci, cj)
            if ni < 0 or ni >= rows or nj < 0 or nj >= cols:
                continue
            nxt = ni * cols + nj
            seen = stamp[nxt]
            f_next = factor[nxt]
            if seen == closed or not f_next < np.inf:
                continue
            if ni != ci and nj != cj and not (factor[ci * cols + nj] < np.inf
                                              and factor[ni * cols + cj] < np.inf):
                continue  # no cutting corners: a diagonal move needs both side cells
            g_next = g_current + length * 0.5 * (f_current + f_next)
            if seen == query and g_next >= g[nxt]:
                continue
            stamp[nxt] = query
            g[nxt] = g_next
            parent[nxt] = current
            h = 0.0
            if goal >= 0:
                di = abs(ni - goal_i)
                dj = abs(nj - goal_j)
                h = max(di, dj) + (_SQRT2 - 1.0) * min(di, dj)
                for m in range(landmark.shape[1]):
                    h = max(h, abs(landmark[goal, m] - landmark[nxt, m]))
                h *= 1.0 + _TIE_BREAK
            if size == heap_key.shape[0]:
                return -1
            pos = size
            size += 1
            key = g_next + h
            while pos > 0:
                up = (pos - 1) >> 1
                if heap_key[up] <= key:
                    break
                heap_key[pos] = heap_key[up]
                heap_item[pos] = heap_item[up]
                pos = up
            heap_key[pos] = key
            heap_item[pos] = nxt
    return 0


@numba.njit(cache=True)
def _trace(parent, goal, cols):
    """(count, 2) cells (row, col) from the search's start to cell index ``goal`` of a grid
    of ``cols`` columns, following ``parent``."""
    count = 1
    k = goal
    while parent[k] >= 0:
        k = parent[k]
        count += 1
    path = np.empty((count, 2), dtype=np.int64)
    k = goal
    for m in range(count - 1, -1, -1):
        path[m, 0] = k // cols
        path[m, 1] = k % cols
        k = parent[k]
    return path


@numba.njit(cache=True, inline="always")
def _blocked(factor, rows, cols, i, j):
    return i < 0 or i >= rows or j < 0 or j >= cols or not factor[i * cols + j] < np.inf


@compiled_helper
def _segment_cost(factor, rows, cols, u0, v0, u1, v1):
    """Integral of ``factor`` along the straight segment between continuous cell
    coordinates (u0, v0) and (u1, v1) (u = column, v = row), in cells; inf if the segment
    touches, even at a single point, a cell of infinite factor or leaves the grid. Walks the
    cells the segment crosses (Amanatides and Woo); through an exact corner it counts both
    side cells as touched."""
    du = u1 - u0
    dv = v1 - v0
    length = math.sqrt(du * du + dv * dv)
    j = int(math.floor(u0))
    i = int(math.floor(v0))
    step_j = 1 if du > 0 else -1
    step_i = 1 if dv > 0 else -1
    # Parameter t in [0, 1] at which the segment crosses the next column / row boundary.
    t_next_j = ((j + 1 if du > 0 else j) - u0) / du if du != 0 else np.inf
    t_next_i = ((i + 1 if dv > 0 else i) - v0) / dv if dv != 0 else np.inf
    t_delta_j = abs(1.0 / du) if du != 0 else np.inf
    t_delta_i = abs(1.0 / dv) if dv != 0 else np.inf
    t = 0.0
    total = 0.0
    while True:
        if _blocked(factor, rows, cols, i, j):
            return np.inf
        t_exit = min(t_next_j, t_next_i, 1.0)
        total += (t_exit - t) * length * factor[i * cols + j]
        if t_exit >= 1.0:
            return total
        t = t_exit
        if t_next_j == t_next_i:
            if (_blocked(factor, rows, cols, i + step_i, j)
                    or _blocked(factor, rows, cols, i, j + step_j)):
                return np.inf
            i += step_i
            j += step_j
            t_next_i += t_delta_i
            t_next_j += t_delta_j
        elif t_next_j < t_next_i:
            j += step_j
            t_next_j += t_delta_j
        else:
            i += step_i
            t_next_i += t_delta_i


@compiled_helper
def _shortcut(factor, rows, cols, uv):
    """The vertices of polyline ``uv`` (k, 2) (continuous cell coordinates) kept by greedy
    line-of-sight shortcutting: from each kept vertex, jump to the farthest vertex found by
    doubling then bisection whose straight segment is traversable and costs no more than
    the polyline between them."""
    k = uv.shape[0]
    cumulative = np.zeros(k)
    for m in range(1, k):
        cumulative[m] = cumulative[m - 1] + _segment_cost(
            factor, rows, cols, uv[m - 1, 0], uv[m - 1, 1], uv[m, 0], uv[m, 1])
    keep = [0]
    a = 0
    while a < k - 1:
        good = a + 1
        bad = k
        span = 2
        while a + span < k:
            b = a + span
            cost = _segment_cost(factor, rows, cols, uv[a, 0], uv[a, 1], uv[b, 0], uv[b, 1])
            if cost <= cumulative[b] - cumulative[a] + 1e-9:
                good = b
                span *= 2
            else:
                bad = b
                break
        if bad == k and good < k - 1:
            b = k - 1
            cost = _segment_cost(factor, rows, cols, uv[a, 0], uv[a, 1], uv[b, 0], uv[b, 1])
            if cost <= cumulative[b] - cumulative[a] + 1e-9:
                good = b
        while bad - good > 1:
            b = (good + bad) // 2
            cost = _segment_cost(factor, rows, cols, uv[a, 0], uv[a, 1], uv[b, 0], uv[b, 1])
            if cost <= cumulative[b] - cumulative[a] + 1e-9:
                good = b
            else:
                bad = b
        keep.append(good)
        a = good
    out = np.empty((len(keep), 2))
    for m in range(len(keep)):
        out[m, 0], out[m, 1] = uv[keep[m], 0], uv[keep[m], 1]
    return out


@numba.njit(cache=True)
def _path_points(factor, rows, cols, cells, start, goal, origin, resolution, spacing):
    """World points (m) of grid path ``cells`` (row, col) from world point ``start`` to
    ``goal`` (see the module docstring): the start, the cells' centres and, if it lies in
    the last cell, the goal, shortcut in continuous cell coordinates (u, v) = (column, row),
    where cell (i, j) spans [j, j + 1) x [i, i + 1), then resampled."""
    count = cells.shape[0]
    uv = np.empty((count + 2, 2))
    uv[0, 0] = (start[0] - origin[0]) / resolution
    uv[0, 1] = (start[1] - origin[1]) / resolution
    for m in range(count):
        uv[m + 1, 0] = cells[m, 1] + 0.5
        uv[m + 1, 1] = cells[m, 0] + 0.5
    end = count + 1
    goal_u = (goal[0] - origin[0]) / resolution
    goal_v = (goal[1] - origin[1]) / resolution
    if math.floor(goal_v) == cells[count - 1, 0] and math.floor(goal_u) == cells[count - 1, 1]:
        uv[end, 0] = goal_u
        uv[end, 1] = goal_v
        end += 1
    # The first leg leaves the inscribed zone when the start is outside the first cell; then
    # only what follows it is shortcut. Element by element: numba's slice assignment and
    # array expressions take seconds to compile.
    first = 0 if math.floor(uv[0, 1]) == cells[0, 0] and math.floor(uv[0, 0]) == cells[0, 1] \
        else 1
    kept = _shortcut(factor, rows, cols, uv[first:end])
    points = np.empty((first + len(kept), 2))
    if first:
        points[0, 0], points[0, 1] = uv[0, 0] * resolution, uv[0, 1] * resolution
    for m in range(len(kept)):
        points[first + m, 0] = kept[m, 0] * resolution
        points[first + m, 1] = kept[m, 1] * resolution
    return _resample(points, spacing, origin)


@compiled_helper
def _resample(points, spacing, origin):
    """``points`` (k, 2) with evenly spaced points added on each segment so that no gap
    exceeds ``spacing``, the vertices kept, all shifted by ``origin``."""
    segments = points.shape[0] - 1
    pieces = np.empty(segments, dtype=np.int64)
    total = 1
    for s in range(segments):
        length = math.hypot(points[s + 1, 0] - points[s, 0], points[s + 1, 1] - points[s, 1])
        pieces[s] = max(math.ceil(length / spacing - 1e-9), 1)
        total += pieces[s]
    out = np.empty((total, 2))
    k = 0
    for s in range(segments):
        du = points[s + 1, 0] - points[s, 0]
        dv = points[s + 1, 1] - points[s, 1]
        for q in range(pieces[s]):
            fraction = q / pieces[s]
            out[k, 0] = origin[0] + (points[s, 0] + fraction * du)
            out[k, 1] = origin[1] + (points[s, 1] + fraction * dv)
            k += 1
    out[k, 0] = origin[0] + points[segments, 0]
    out[k, 1] = origin[1] + points[segments, 1]
    return out
