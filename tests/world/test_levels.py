"""Levels side by side: the layout's offsets, and a building's levels joined by its lifts."""

from pathlib import Path

import pytest

from mrta_drake.errors import InputError
from mrta_drake.navigation.lift_bank import LiftParams, expected_ride_time, ride_time
from mrta_drake.navigation.roadways import Roadways
from mrta_drake.world.levels import MIN_LEVEL_GAP, LevelLayout
from mrta_drake.world.rmf_building import load_building
from mrta_drake.world.rmf_levels import building_levels, unaligned_levels

TWO_LEVELS = Path(__file__).parents[1] / "data" / "buildings" / "two_levels.building.yaml"


def test_levels_are_placed_east_of_each_other_a_gap_apart():
    layout = LevelLayout.side_by_side([("A", 0.0, (-2.0, 10.0, 0.0, 5.0)),
                                       ("B", 4.0, (0.0, 20.0, -1.0, 3.0)),
                                       ("C", 8.0, (5.0, 6.0, 0.0, 1.0))], gap=40.0)
    assert [p.offset for p in layout.levels] == [0.0, 50.0, 105.0]
    assert layout.placement("B").bounds == (50.0, 70.0, -1.0, 3.0)
    assert layout.level_of((55.0, 0.0)) == "B" and layout.level_of((30.0, 0.0)) is None
    assert layout.moved((1.0, 2.0), "A", "C") == (106.0, 2.0)
    assert layout.to_world("B", (1.0, 2.0)) == (51.0, 2.0)
    assert layout.bounds == (-2.0, 111.0, -1.0, 5.0)


def test_a_gap_below_the_minimum_is_one_line():
    with pytest.raises(InputError, match=f"level_gap: must be >= {MIN_LEVEL_GAP:g} m"):
        LevelLayout.side_by_side([("A", 0.0, (0.0, 1.0, 0.0, 1.0))], gap=5.0)


def test_a_buildings_levels_are_joined_by_rides_costing_their_time():
    levels = building_levels(load_building(TWO_LEVELS))
    offset = levels.layout.placement("L2").offset
    assert offset == pytest.approx(levels.layout.placement("L1").bounds[1] + MIN_LEVEL_GAP
                                   - (levels.layout.placement("L2").bounds[0] - offset))
    (lift,) = levels.lifts
    assert [(s.level, s.elevation) for s in lift.stops] == [("L1", 0.0), ("L2", 4.0)]
    assert lift.stop("L2").cabin == pytest.approx((10.0 + offset, -2.0))
    # Every obstacle, place and node of L2 is shifted and named after its level.
    assert all(b.name.startswith(("L1/", "L2/")) for b in levels.floor_plan.obstacles.boxes)
    assert levels.floor_plan.places["L2/l2_lab"] == pytest.approx((1.5 + offset, -2.0))
    params = LiftParams()
    roadways_config = levels.roadways_with_lifts(params, speed=0.5)
    (up, down) = roadways_config.lift_edges
    assert (up.from_level, up.to_level, down.from_level, down.to_level) == ("L1", "L2",
                                                                          "L2", "L1")
    # The ride's expected time: the ride, half a ride calling the cabin, boarding.
    assert up.length == pytest.approx((1.5 * ride_time(params, 0.0, 4.0) + params.door_time)
                                      * 0.5)
    assert up.length == pytest.approx(expected_ride_time(params, 0.0, 4.0) * 0.5)
    # The allocator's estimate counts the ride's time, not the jump across the plane.
    roadways = Roadways(roadways_config, levels.locations)
    ids = {loc.name: loc.id for loc in levels.locations}
    leg = roadways.leg(ids["L1/l1_desk"], ids["L2/l2_lab"])
    walked = sum(((b - a) ** 2).sum() ** 0.5 for a, b in zip(leg[:-1], leg[1:], strict=True)
                 if roadways.lift_edge(a, b) is None)
    assert roadways.leg_length(ids["L1/l1_desk"], ids["L2/l2_lab"]) == pytest.approx(
        walked + up.length)
    assert walked < offset  # the route does not cross the gap on foot
    # A closure never closes a ride.
    closed = roadways.closed([(11.0, offset - 1.0, -10.0, 10.0)])
    assert closed.leg(ids["L1/l1_desk"], ids["L2/l2_lab"]) is not None


def test_every_levels_single_file_segments_but_those_through_a_cabin():
    building = load_building(str(Path(__file__).parents[2] / "models" / "two_floor_clinic"
                                 / "two_floor_clinic.building.yaml"))
    levels = building_levels(building)
    segments = levels.roadways.single_file
    assert {segment[0].split("/")[0] for segment in segments} == {"L1", "L2"}
    cabins = {stop.node for lift in levels.lifts for stop in lift.stops}
    for segment in segments:
        level = segment[0].split("/")[0]
        assert all(node.startswith(f"{level}/") and node in levels.roadways.nodes
                   for node in segment)
        assert not cabins.intersection(segment)
    roadways = levels.roadways_with_lifts(LiftParams(), 0.6)
    assert Roadways(roadways, levels.locations, building.source).segment_count == len(segments)


def test_a_level_without_two_shared_fiducials_is_named(tmp_path):
    # Taken as drawn in the reference level's frame (as Open-RMF's generator does): right
    # only if it was, so the import says so.
    assert unaligned_levels(load_building(TWO_LEVELS)) == []
    renamed = tmp_path / "renamed.building.yaml"
    renamed.write_text(TWO_LEVELS.read_text().replace("85.0, B]", "85.0, X]")
                       .replace("85.0, C]", "85.0, Y]"))
    assert unaligned_levels(load_building(renamed)) == [
        "L2: 1 fiducial(s) shared with the reference level L1: taken as drawn in its frame, "
        "not aligned"]


def test_no_plan_leads_from_one_level_to_another_through_the_gap():
    # Two levels whose walls do not close them in: without the floors the planner finds a
    # way round the walls and across the gap; with them the levels are apart.
    from mrta_drake.navigation.costmap import Costmap
    from mrta_drake.navigation.grid_planner import UNREACHABLE, GridPlanner
    from mrta_drake.world.floor_plan import FloorPlan
    from mrta_drake.world.levels import combined_floor_plan
    from mrta_drake.world.obstacles import Box, Obstacles

    wall = Obstacles((Box("wall", (5.0, 2.5), (0.1, 3.0), 0.0, 2.5),))
    plans = {name: FloorPlan(name, (0.0, 10.0, 0.0, 5.0), 2.5, wall) for name in ("A", "B")}
    layout = LevelLayout.side_by_side([(name, 4.0 * k, plan.bounds)
                                       for k, (name, plan) in enumerate(plans.items())])
    plan = combined_floor_plan("two", plans, layout)
    start, goal = (2.0, 2.5), layout.to_world("B", (8.0, 2.5))
    open_gap = GridPlanner(Costmap.from_obstacles(plan.obstacles, plan.bounds, resolution=0.1))
    assert open_gap.plan(start, goal).found
    floors = GridPlanner(Costmap.from_obstacles(plan.obstacles, plan.bounds, resolution=0.1,
                                                floors=plan.floors))
    assert floors.plan(start, goal).failure == UNREACHABLE
    assert floors.plan(start, (8.0, 2.5)).found  # round its own wall, on its level
