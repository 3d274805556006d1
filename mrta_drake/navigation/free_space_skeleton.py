"""Corridor centre-lines from an occupancy grid: the skeleton of the space robots may use.

The cells a robot's centre may occupy (clearance at least the lanes' robot radius + margin,
``LaneParams.clearance``, m) are thinned to their skeleton (scikit-image ``skeletonize``), a
one-cell-wide line along the middle of every passage, so every skeleton cell keeps that
clearance. The skeleton's cells are traced into
branches between junctions and ends, then cleaned up:

1. components: only the ones holding the skeleton cell nearest one of the ``keep_near``
   points (where robots are), or the largest when none are given;
2. spurs: branches to a dead end shorter than ``min_spur`` (the skeleton's whiskers into
   corners) are dropped, again and again, as dropping one can leave a new spur;
3. junctions joined by a branch shorter than ``junction_merge`` become one, at the middle
   (a crossing of wide corridors thins to two junctions close together);
4. each branch is cut where its width changes between room for two lanes (clearance at
   least the lane offset + the lanes' clearance) and less, runs shorter than
   ``min_width_run`` counting as their neighbours, so that a narrowing is an edge of its
   own; each piece is simplified to a polyline (Douglas-Peucker): a point is kept when the
   rest deviate more than ``simplify_tolerance`` from the straight segment that would skip
   it, or when that segment would come closer to obstacles than the lanes' clearance, so
   every segment keeps the clearance the skeleton had.

The result is a ``CentrelineGraph`` of straight two-way edges (vertices ``v0``, ``v1``, ...;
world frame, x east, y north, m).
"""

from collections.abc import Sequence
from dataclasses import dataclass

import networkx as nx
import numpy as np
from skimage.morphology import skeletonize

from mrta_drake.errors import InputError, require_non_negative
from mrta_drake.navigation.clearance_field import ClearanceField, segment_clearance
from mrta_drake.navigation.lane_derivation import (
    CentrelineEdge,
    CentrelineGraph,
    LaneParams,
    vertex_degrees,
)

_ORTHOGONAL = ((0, 1), (1, 0))
_DIAGONAL = ((1, 1), (1, -1))


@dataclass(frozen=True)
class SkeletonParams:
    """Clean-up of the skeleton, m (see the module docstring).

    ``min_spur`` 1.0: a whisker into a corner of a corridor is at most about its half-width
    less the clearance long (0.5-1 m in 2-3 m corridors), while a real dead end (an alcove,
    a door) is longer. ``junction_merge`` 1.0: a junction's lane loop is 2 x 0.45 m across,
    so two junctions closer than about that cannot each have one. ``simplify_tolerance``
    0.3: a scanned map's walls are ragged by a few cells and its skeleton wiggles with them
    (segments keep the clearance whatever the tolerance). ``min_width_run`` 1.0: about a
    robot's length and a doorway's depth.
    """

    min_spur: float = 1.0
    junction_merge: float = 1.0
    simplify_tolerance: float = 0.3
    min_width_run: float = 1.0

    def __post_init__(self):
        require_non_negative(self, "min_spur", "junction_merge", "simplify_tolerance",
                             "min_width_run", unit=" m")


def centreline_graph(field: ClearanceField, lanes: LaneParams,
                     params: SkeletonParams = SkeletonParams(),
                     keep_near: Sequence[Sequence[float]] | None = None) -> CentrelineGraph:
    """The centre-lines of the space where ``field`` (the grid's clearance, m) is at least
    the lanes' clearance; ``keep_near``: world points (x, y) whose nearest skeleton
    components are kept (default: the largest component)."""
    clearance = lanes.clearance
    pixels = _pixel_graph(skeletonize(field.distance >= clearance))
    if pixels.number_of_nodes() == 0:
        raise InputError(None, "clearance", f"no free space keeps {clearance:g} m from obstacles")
    pixels = pixels.subgraph(_kept_components(pixels, field, keep_near))
    skeleton = _Skeleton.traced(pixels, field)
    skeleton.prune_spurs(params.min_spur)
    skeleton.merge_junctions(params.junction_merge)
    return skeleton.centrelines(field, lanes, params)


def _pixel_graph(skeleton: np.ndarray) -> nx.Graph:
    """The skeleton's cells (row, col), joined to their 8 neighbours, except diagonal
    neighbours that also touch through a common orthogonal neighbour (the corner of a
    staircase, which would look like a junction)."""
    cells = set(zip(*np.nonzero(skeleton), strict=True))
    graph = nx.Graph()
    graph.add_nodes_from(sorted(cells))
    for i, j in sorted(cells):
        for di, dj in _ORTHOGONAL:
            if (i + di, j + dj) in cells:
                graph.add_edge((i, j), (i + di, j + dj))
    for i, j in sorted(cells):
        for di, dj in _DIAGONAL:
            other = (i + di, j + dj)
            if other in cells and (i + di, j) not in cells and (i, j + dj) not in cells:
                graph.add_edge((i, j), other)
    return graph


def _kept_components(pixels: nx.Graph, field: ClearanceField, keep_near) -> set:
    components = list(nx.connected_components(pixels))
    if keep_near is None:
        return max(components, key=len)
    cells = np.array(sorted(pixels.nodes))
    centres = field.grid.cell_to_world(cells[:, 0], cells[:, 1])
    kept = set()
    for point in keep_near:
        nearest = tuple(cells[np.argmin(np.linalg.norm(centres - np.asarray(point), axis=1))])
        kept |= next(c for c in components if nearest in c)
    return kept


@dataclass
class _Branch:
    a: int
    b: int
    points: np.ndarray  # (k, 2) world points from a's position to b's

    @property
    def length(self) -> float:
        return float(np.linalg.norm(np.diff(self.points, axis=0), axis=1).sum())


class _Skeleton:
    """Branches between nodes (junctions and ends), with the clean-up steps."""

    def __init__(self):
        self.position: dict[int, np.ndarray] = {}
        self.branches: list[_Branch] = []

    @classmethod
    def traced(cls, pixels: nx.Graph, field: ClearanceField) -> "_Skeleton":
        skeleton = cls()
        ends = sorted(p for p in pixels if pixels.degree(p) != 2)
        for component in sorted(map(sorted, nx.connected_components(pixels))):
            if not any(pixels.degree(p) != 2 for p in component):
                ends.append(component[0])  # a closed loop: start anywhere
        node_of = {p: k for k, p in enumerate(ends)}
        for p, k in node_of.items():
            skeleton.position[k] = field.grid.cell_to_world(*p)
        walked = set()
        for start in ends:
            for first in sorted(pixels[start]):
                if frozenset((start, first)) in walked:
                    continue
                path = [start, first]
                walked.add(frozenset(path))
                while path[-1] not in node_of:
                    step = next(p for p in sorted(pixels[path[-1]]) if p != path[-2])
                    walked.add(frozenset((path[-1], step)))
                    path.append(step)
                cells = np.array(path)
                skeleton.branches.append(_Branch(node_of[start], node_of[path[-1]],
                                                 field.grid.cell_to_world(cells[:, 0],
                                                                          cells[:, 1])))
        return skeleton

    def degree(self) -> dict[int, int]:
        return vertex_degrees(self.position, self.branches)

    def prune_spurs(self, min_spur: float) -> None:
        while True:
            degree = self.degree()
            spurs = [b for b in self.branches if b.a != b.b and b.length < min_spur
                     and sorted((degree[b.a], degree[b.b]))[0] == 1
                     and max(degree[b.a], degree[b.b]) >= 3]
            if not spurs:
                return
            for spur in spurs:
                self.branches.remove(spur)
                del self.position[spur.a if degree[spur.a] == 1 else spur.b]
            self._join_through_nodes()

    def _join_through_nodes(self) -> None:
        """Joins the two branches at every node with exactly two (not a loop's only node)."""
        while True:
            degree = self.degree()
            node = next((n for n, d in degree.items() if d == 2 and not any(
                b.a == b.b == n for b in self.branches)), None)
            if node is None:
                return
            first, second = (b for b in self.branches if node in (b.a, b.b))
            self.branches.remove(first)
            self.branches.remove(second)
            before = first.points if first.b == node else first.points[::-1]
            after = second.points if second.a == node else second.points[::-1]
            ends = (first.a if first.b == node else first.b,
                    second.b if second.a == node else second.a)
            self.branches.append(_Branch(ends[0], ends[1], np.concatenate([before, after[1:]])))
            del self.position[node]

    def merge_junctions(self, distance: float) -> None:
        while True:
            degree = self.degree()
            short = next((b for b in self.branches if b.a != b.b and b.length < distance
                          and degree[b.a] >= 3 and degree[b.b] >= 3), None)
            if short is None:
                self._join_through_nodes()
                return
            self.branches.remove(short)
            middle = short.points[len(short.points) // 2]
            self.position[short.a] = middle
            del self.position[short.b]
            for branch in self.branches:
                if short.b in (branch.a, branch.b):
                    branch.a = short.a if branch.a == short.b else branch.a
                    branch.b = short.a if branch.b == short.b else branch.b
            for branch in self.branches:
                points = branch.points.copy()
                if branch.a == short.a:
                    points[0] = middle
                if branch.b == short.a:
                    points[-1] = middle
                branch.points = points

    def centrelines(self, field: ClearanceField, lanes: LaneParams,
                    params: SkeletonParams) -> CentrelineGraph:
        step = field.grid.resolution

        def clear(a, b) -> bool:
            return segment_clearance(field, a, b, step) >= lanes.clearance - 1e-9

        nodes: dict[str, tuple[float, float]] = {}
        name_of: dict[int, str] = {}
        for k in sorted(self.position):
            name_of[k] = f"v{len(nodes)}"
            nodes[name_of[k]] = _xy(self.position[k])
        edges: dict[frozenset, CentrelineEdge] = {}
        for branch in sorted(self.branches, key=lambda b: (b.a, b.b, len(b.points))):
            points = branch.points
            wide = field(points) >= lanes.offset + lanes.clearance
            cuts = _width_changes(points, wide, params.min_width_run)
            keep = sorted({index for i, j in zip(cuts[:-1], cuts[1:], strict=True)
                           for index in _simplified(points, i, j, params.simplify_tolerance,
                                                    clear)})
            if branch.a == branch.b and len(keep) < 4:  # a loop needs two inner vertices
                keep = sorted({*keep, len(points) // 3, 2 * len(points) // 3})
            if len(keep) == 2 and frozenset((name_of[branch.a], name_of[branch.b])) in edges:
                keep = [0, len(points) // 2, len(points) - 1]
            names = [name_of[branch.a]]
            for index in keep[1:-1]:
                names.append(f"v{len(nodes)}")
                nodes[names[-1]] = _xy(points[index])
            names.append(name_of[branch.b])
            for a, b in zip(names[:-1], names[1:], strict=True):
                edges[frozenset((a, b))] = CentrelineEdge(a, b)
        return CentrelineGraph(nodes=nodes, edges=tuple(edges.values()))


def _width_changes(points: np.ndarray, wide: np.ndarray, min_run: float) -> list[int]:
    """Indices of ``points`` (a branch, ends included) where ``wide`` (room for two lanes at
    the point) changes, runs shorter than ``min_run`` (m) counting as their neighbours."""
    steps = np.linalg.norm(np.diff(points, axis=0), axis=1)
    runs = []  # [first index, last index, wide]
    for k, value in enumerate(wide):
        if runs and runs[-1][2] == value:
            runs[-1][1] = k
        else:
            runs.append([k, k, value])
    merged = []
    for run in runs:
        length = float(steps[run[0]:run[1]].sum())
        if merged and (length < min_run or merged[-1][2] == run[2]):
            merged[-1][1] = run[1]
        else:
            merged.append(run)
    return [0] + [run[0] for run in merged[1:]] + [len(points) - 1]


def _xy(point) -> tuple[float, float]:
    return float(point[0]), float(point[1])


def _simplified(points: np.ndarray, first: int, last: int, tolerance: float, clear) -> set[int]:
    """Indices of ``points[first:last + 1]`` kept by Douglas-Peucker with ``tolerance`` (m),
    also keeping a point wherever the segment skipping it is not ``clear(a, b)``."""
    keep = {first, last}
    stack = [(first, last)]
    while stack:
        i, j = stack.pop()
        if j - i < 2:
            continue
        a, b = points[i], points[j]
        relative = points[i + 1:j] - a
        chord = b - a
        length = float(np.linalg.norm(chord))
        if length == 0.0:
            deviation = np.linalg.norm(relative, axis=1)
        else:
            deviation = np.abs(chord[0] * relative[:, 1] - chord[1] * relative[:, 0]) / length
        k = i + 1 + int(np.argmax(deviation))
        if deviation.max() > tolerance or not clear(a, b):
            keep.add(k)
            stack += [(i, k), (k, j)]
    return keep
