"""Which single-file segments a robot on a route needs, and where it holds back."""

import pytest

from mrta_drake.errors import InputError
from mrta_drake.navigation.roadways import Roadways
from mrta_drake.navigation.single_file import Need, SingleFileParams, need, route_runs
from mrta_drake.scenario.schema import LocationConfig, RoadwaysConfig

PARAMS = SingleFileParams(request_distance=4.0, hold_distance=1.5, clear_distance=1.0,
                          chain_gap=5.0)


def corridor():
    """Nodes every 10 m along y = 0 (A0 .. A50): two-way lanes between each pair; the
    stretches A10-A20 and A20-A30 are two single-file segments meeting at A20, A40-A50 a
    third, 10 m of ordinary lane (A30-A40) between."""
    xs = range(0, 60, 10)
    nodes = {f"A{x}": [float(x), 0.0] for x in xs}
    edges = [[f"A{a}", f"A{b}"] for a, b in zip(xs[:-1], xs[1:], strict=True)]
    edges += [[b, a] for a, b in edges]
    locations = [LocationConfig(id=i, name=f"L{i}", point=[x, 3.0], queue=[[x, 1.0]],
                                exit_node=f"A{x}", approach_node=f"A{x}")
                 for i, x in enumerate((0, 50))]
    config = RoadwaysConfig(nodes=nodes, edges=edges,
                            single_file=[["A10", "A20"], ["A30", "A20"], ["A40", "A50"]])
    return Roadways(config, locations)


EAST = tuple((float(x), 0.0) for x in range(0, 60, 10))
WEST = EAST[::-1]


def test_runs_join_segments_that_meet_and_keep_the_way_driven():
    roadways = corridor()
    east = route_runs(roadways, EAST, PARAMS.chain_gap)
    assert [(r.first, r.last, r.segments) for r in east] == [
        (1, 2, ((0, True), (1, False))), (4, 4, ((2, True),))]
    west = route_runs(roadways, WEST, PARAMS.chain_gap)
    assert [(r.first, r.last, r.segments) for r in west] == [
        (0, 0, ((2, False),)), (2, 3, ((1, True), (0, False)))]
    # A gap shorter than chain_gap joins the runs: no waiting on 10 m of lane.
    joined = route_runs(roadways, EAST, 12.0)
    assert [(r.first, r.last) for r in joined] == [(1, 4)]


@pytest.mark.parametrize("x, index, expected", [
    (2.0, 1, Need()),  # 8 m before the stretch: nothing yet
    (7.0, 1, Need(((0, True), (1, False)), False)),  # within 4 m: ask, keep driving
    (9.0, 1, Need(((0, True), (1, False)), True)),  # within 1.5 m: hold unless granted
    (15.0, 2, Need(((0, True), (1, False)), True)),  # in it
    (30.5, 4, Need(((0, True), (1, False)), False)),  # 0.5 m past its end: keep it
    (32.0, 4, Need()),  # 2 m past: give it up
    (37.0, 4, Need(((2, True),), False)),  # the next stretch
])
def test_need_along_the_route(x, index, expected):
    assert need(corridor(), EAST, index, (x, 0.0), PARAMS) == expected


def test_params_check_themselves():
    with pytest.raises(InputError, match="hold_distance"):
        SingleFileParams(hold_distance=0.0)
    with pytest.raises(InputError, match="request_distance"):
        SingleFileParams(request_distance=1.0, hold_distance=2.0)
