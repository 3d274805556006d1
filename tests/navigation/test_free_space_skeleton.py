"""Tests of centre-lines from free space (mrta_drake/navigation/free_space_skeleton.py)."""

import numpy as np
import pytest

from mrta_drake.errors import InputError
from mrta_drake.navigation.clearance_field import ClearanceField
from mrta_drake.navigation.free_space_skeleton import SkeletonParams, centreline_graph
from mrta_drake.navigation.lane_derivation import LaneParams
from tests.navigation.free_space_worlds import PLUS, carved, samples, walls

LANES = LaneParams()


def graph_of(free_rects, params=None, keep_near=None):
    grid = carved(free_rects)
    graph = centreline_graph(ClearanceField.from_grid(grid), LANES, params or SkeletonParams(),
                             keep_near)
    return graph, walls(grid)


def test_plus_crossing_is_one_junction_and_four_straight_arms():
    graph, obstacles = graph_of(PLUS)
    degree = graph.degree()
    (junction,) = [v for v, d in degree.items() if d == 4]
    assert np.linalg.norm(graph.nodes[junction]) < 0.2
    ends = np.array([graph.nodes[v] for v, d in degree.items() if d == 1])
    assert len(ends) == 4 and len(graph.edges) == 4  # simplified to straight arms
    # Each arm ends a little before its end wall (7.2 m), on its centre-line.
    assert (np.abs(ends).max(axis=1) > 5.8).all() and (np.abs(ends).max(axis=1) < 6.8).all()
    assert np.abs(ends).min(axis=1) == pytest.approx([0.0] * 4, abs=0.1)
    for edge in graph.edges:
        line = samples(graph.nodes[edge.a], graph.nodes[edge.b])
        assert obstacles.signed_distance(line).min() >= LANES.clearance


def test_short_spurs_are_pruned():
    # A corridor with a 1.4 m wide alcove 0.4 m deep on its north side.
    alcove = [(-8.0, 8.0, -1.2, 1.2), (-0.7, 0.7, 1.0, 1.6)]
    graph, _ = graph_of(alcove)
    assert sorted(graph.degree().values()).count(1) == 2  # only the corridor's ends
    kept, _ = graph_of(alcove, SkeletonParams(min_spur=0.0))
    assert sorted(kept.degree().values()).count(1) == 3


def test_narrowing_is_an_edge_of_its_own():
    # 2.4 m wide, then 1.3 m for 4 m, then 2.4 m again: the narrowing's ends are vertices
    # (where two lanes stop fitting, a little before the narrowing's corners).
    graph, _ = graph_of([(-9.5, -2.0, -1.2, 1.2), (-2.05, 2.05, -0.65, 0.65),
                         (2.0, 9.5, -1.2, 1.2)])
    xs = sorted(x for x, _ in graph.nodes.values())
    assert len(xs) == 4
    assert -3.0 < xs[1] < -2.0 and 2.0 < xs[2] < 3.0


def test_components_near_the_given_points_are_kept():
    two = [(-8.0, -2.0, -1.2, 1.2), (2.0, 9.0, -1.2, 1.2)]  # separate, the east one longer
    largest, _ = graph_of(two)
    assert min(x for x, _ in largest.nodes.values()) > 0.0
    west, _ = graph_of(two, keep_near=[(-5.0, 0.5)])
    assert max(x for x, _ in west.nodes.values()) < 0.0
    both, _ = graph_of(two, keep_near=[(-5.0, 0.5), (5.0, 0.0)])
    assert len(both.edges) == len(largest.edges) + len(west.edges)


def test_no_free_space_wide_enough():
    with pytest.raises(InputError) as info:
        graph_of([(-5.0, 5.0, -0.3, 0.3)])
    assert str(info.value) == "clearance: no free space keeps 0.47 m from obstacles"


def test_bad_skeleton_params():
    with pytest.raises(InputError) as info:
        SkeletonParams(min_spur=-1.0)
    assert str(info.value) == "min_spur: must be >= 0 m, got -1.0"
