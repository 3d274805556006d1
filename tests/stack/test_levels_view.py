"""The stacked levels' view: points of the combined plane drawn at their level's elevation,
cabins moving between floors, and the switch between stacked and side by side."""

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator

from mrta_drake.navigation.lift_bank import LiftSpec, LiftStop
from mrta_drake.payloads import LiftState, LiftStatus
from mrta_drake.stack.levels_view import LevelsView, StackedView
from mrta_drake.world.floor_plan import FloorPlan
from mrta_drake.world.levels import LevelLayout
from mrta_drake.world.obstacles import Box, Obstacles

LAYOUT = LevelLayout.side_by_side([("L1", 0.0, (0.0, 20.0, 0.0, 10.0)),
                                   ("L2", 4.0, (0.0, 20.0, 0.0, 10.0))])
OFFSET = LAYOUT.placement("L2").offset  # 50 m: 20 m wide + the 30 m gap
LIFT = LiftSpec("lift", (LiftStop("L1", (5.0, 5.0), 0.0, "L1/cab"),
                         LiftStop("L2", (5.0 + OFFSET, 5.0), 4.0, "L2/cab")), "L1", 2.0, 2.0)
SCENARIO = Path(__file__).parents[2] / "scenarios" / "two_floor_6_robots.yaml"


def test_a_point_is_drawn_on_its_level_at_the_levels_elevation():
    view = StackedView(LAYOUT)
    assert OFFSET == pytest.approx(50.0)
    assert view.point((3.0, 2.0), 0.1) == pytest.approx((3.0, 2.0, 0.1))
    assert view.point((53.0, 2.0), 0.1) == pytest.approx((3.0, 2.0, 4.1))
    assert view.point((53.0, 2.0), 0.0, level="L1") == pytest.approx((53.0, 2.0, 0.0))
    assert view.point((35.0, 2.0)) == pytest.approx((35.0, 2.0, 0.0))  # in the gap: kept
    points = view.points(np.array([[3.0, 53.0], [2.0, 2.0], [0.0, 0.5]]))
    assert points == pytest.approx(np.array([[3.0, 3.0], [2.0, 2.0], [0.0, 4.5]]))


def test_a_cabin_rises_between_the_floors_during_its_ride():
    view = StackedView(LAYOUT)
    riding = LiftStatus("lift", "L1", ("a",), phase="travel", trip=("L1", "L2", 10.0, 20.0))
    assert view.cabin_elevation(LIFT, riding, 10.0) == pytest.approx(0.0)
    assert view.cabin_elevation(LIFT, riding, 15.0) == pytest.approx(2.0)
    assert view.cabin_elevation(LIFT, riding, 25.0) == pytest.approx(4.0)
    assert view.cabin_elevation(LIFT, LiftStatus("lift", "L2"), 0.0) == pytest.approx(4.0)


class FakeMeshcat:
    """Keeps the last transform set per path."""

    def __init__(self):
        self.objects, self.poses = set(), {}

    def SetObject(self, path, shape, rgba=None):
        self.objects.add(path)

    def SetTransform(self, path, transform, time_in_recording=None):
        self.poses[path] = transform.translation()


def test_the_view_draws_robots_and_riders_on_their_floors():
    plan = FloorPlan(name="two", bounds=LAYOUT.bounds, wall_height=2.0,
                     obstacles=Obstacles((Box("L2/wall", (60.0, 9.0), (10.0, 0.2), 0.0, 2.0),),
                                         ()))
    meshcat = FakeMeshcat()
    system = LevelsView(meshcat, plan, LAYOUT, [LIFT], [("a", 0.2), ("b", 0.2)],
                        rate_hz=10.0)
    assert meshcat.poses["levels/building/box_0"] == pytest.approx((10.0, 9.0, 4.0 + 0.5))
    simulator = Simulator(system)
    context = simulator.get_mutable_context()
    system.GetInputPort("robot_state").FixValue(context, [5.0, 5.0, 0.0, 0.0,
                                                          58.0, 3.0, 0.0, 0.0])
    system.GetInputPort("lift_state").FixValue(context, LiftState((LiftStatus(
        "lift", "L1", ("a",), phase="travel", trip=("L1", "L2", 0.0, 10.0)),)))
    simulator.AdvanceTo(5.0)
    assert meshcat.poses["levels/robots/b"] == pytest.approx((8.0, 3.0, 4.1))
    assert meshcat.poses["levels/cabins/lift"] == pytest.approx((5.0, 5.0, 2.0 + 1.1))
    assert meshcat.poses["levels/robots/a"] == pytest.approx((5.0, 5.0, 2.1))  # riding


@pytest.mark.parametrize("levels_view", ["stacked", "side_by_side"])
def test_the_switch_picks_the_stacked_view_or_the_plants_own(levels_view):
    from pydrake.geometry import Meshcat

    from mrta_drake import load_scenario
    from mrta_drake.stack.diagram import build_diagram

    scenario = load_scenario(SCENARIO)
    scenario = dataclasses.replace(scenario, world=dataclasses.replace(
        scenario.world, levels_view=levels_view))
    meshcat = Meshcat()
    stack = build_diagram(scenario, meshcat=meshcat)
    simulator = Simulator(stack.diagram)
    simulator.AdvanceTo(0.1)
    stacked = levels_view == "stacked"
    assert meshcat.HasPath("/drake/levels/robots/robot4") == stacked
    assert (stack.visualizer is None) == stacked
    assert meshcat.HasPath("/drake/traffic/lanes")


def test_a_bad_levels_view_is_one_line_naming_the_field(tmp_path):
    from mrta_drake import load_scenario
    from mrta_drake.errors import InputError

    text = SCENARIO.read_text().replace(
        "  kind: rmf_building\n", "  kind: rmf_building\n  levels_view: upside_down\n")
    path = tmp_path / "scenario.yaml"
    path.write_text(text.replace("../models/", f"{SCENARIO.parents[1]}/models/"))
    with pytest.raises(InputError, match=r"world.levels_view.*upside_down"):
        load_scenario(path)
