"""``mrta-sim import``: building files made into runnable scenario folders."""

import dataclasses
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from mrta_drake.errors import InputError
from mrta_drake.navigation.roadways import Roadways
from mrta_drake.scenario.loading import load_scenario
from mrta_drake.tools.building_import import (
    HEAD_ON_CLEARANCE,
    PEOPLE_GAP,
    SINGLE_FILE_WATCHDOG,
    ImportOptions,
    controller_params,
    import_building,
    people_section,
    robot_starts,
)
from mrta_drake.tools.cli import main
from mrta_drake.world.obstacles import Box
from mrta_drake.world.plant import load_floor_plan_of
from mrta_drake.world.rmf_building import load_building
from mrta_drake.world.rmf_navigation import level_navigation
from mrta_drake.world.rmf_world import level_world

BUILDINGS = Path(__file__).parents[1] / "data" / "buildings"
ONE_LEVEL = BUILDINGS / "one_level.building.yaml"
TWO_LEVELS = BUILDINGS / "two_levels.building.yaml"


def test_import_writes_a_scenario_that_loads(tmp_path):
    report = import_building(str(ONE_LEVEL), str(tmp_path),
                             ImportOptions(robots=3, people=2, seed=4))
    assert report.scenarios == [str(tmp_path / "scenario.yaml")]
    assert (tmp_path / "one_level.building.yaml").read_text() == ONE_LEVEL.read_text()
    scenario = load_scenario(tmp_path / "scenario.yaml")
    assert scenario.world.kind == "rmf_building" and scenario.world.level == "L1"
    # The charger first; no lane node here is 2 m from every task location and queue slot,
    # so then the parking spot park_1, a task location too (the false flag is no parking
    # spot), then the first task location.
    starts = [robot.start[:2] for robot in scenario.robots]
    assert starts == [[1.5, -6.0], [14.5, -6.0], [4.0, -2.0]]
    # People walk the human lane; tasks run between the four task locations.
    for walker in scenario.humans.walkers:
        assert all(point[1] == pytest.approx(-4.9) for point in walker.waypoints)
    assert len(scenario.humans.walkers) == 2
    tasks = [task for batch in scenario.tasks.stream for task in batch.tasks]
    assert tasks and {t.pickup for t in tasks} | {t.dropoff for t in tasks} <= {0, 1, 2, 3}
    # The pantry door (1.2 m) leaves lanes 0.6 m from its jambs: the controller is told;
    # robots head on along the corridor's two lanes pass each other.
    assert scenario.blocks.controller.params == {
        "safety_distances": {"wall": 0.54}, "coordination": {"head_on_clearance": 0.75}}


def test_head_on_passing_is_set_only_where_some_lanes_are_two_way_corridors(tmp_path):
    import_building(str(ONE_LEVEL), str(tmp_path), ImportOptions(robots=1))
    scenario = load_scenario(tmp_path / "scenario.yaml")
    floor_plan = load_floor_plan_of(scenario, objects=False)
    roadways = scenario.roadways
    assert controller_params(roadways, floor_plan)["coordination"] == {
        "head_on_clearance": HEAD_ON_CLEARANCE}
    # Every lane but one in single-file segments: still a two-way stretch.
    segments = [list(edge) for edge in roadways.edges]
    one_left = dataclasses.replace(roadways, single_file=segments[1:])
    assert "coordination" in controller_params(one_left, floor_plan)
    # Every lane single file (driven one way at a time): robots never pass head on.
    all_single = dataclasses.replace(roadways, single_file=segments)
    assert "coordination" not in controller_params(all_single, floor_plan)


def test_the_watchdog_acts_sooner_only_where_some_lanes_are_single_file(tmp_path):
    # narrow_corridor's corridor is single file: robots there cannot pass each other, and a
    # standoff lasts until the watchdog breaks it. open_hall's lanes all fit two.
    import_building(str(BUILDINGS / "narrow_corridor.building.yaml"), str(tmp_path / "n"),
                    ImportOptions(robots=2))
    narrow = load_scenario(tmp_path / "n" / "scenario.yaml")
    assert narrow.roadways.single_file
    assert narrow.blocks.watchdog.params == SINGLE_FILE_WATCHDOG
    import_building(str(BUILDINGS / "open_hall.building.yaml"), str(tmp_path / "o"),
                    ImportOptions(robots=2))
    hall = load_scenario(tmp_path / "o" / "scenario.yaml")
    assert not hall.roadways.single_file and hall.blocks.watchdog.params == {}


def test_robots_start_where_they_are_least_in_the_way(tmp_path):
    building = BUILDINGS / "open_hall.building.yaml"
    import_building(str(building), str(tmp_path), ImportOptions(robots=4))
    scenario = load_scenario(tmp_path / "scenario.yaml")
    starts = [robot.start[:2] for robot in scenario.robots]
    # The charger; the spur's bare node, which no leg between the task locations passes;
    # the task locations (both have parking spots); the hall's middle node, which every
    # leg passes, last.
    assert starts == [[10.0, 7.0], [10.0, 1.0], [2.0, 4.0], [18.0, 4.0]]
    # With no such node (every node on single-file lanes, or near a point or queue): the
    # charger, then the task location with parking spots, then the other one.
    import_building(str(BUILDINGS / "cartesian.building.yaml"), str(tmp_path / "c"),
                    ImportOptions(robots=3))
    cartesian = load_scenario(tmp_path / "c" / "scenario.yaml")
    shelf = next(loc for loc in cartesian.locations if loc.name == "east_shelf")
    bench = next(loc for loc in cartesian.locations if loc.name == "west_bench")
    assert [r.start[:2] for r in cartesian.robots][1:] == [shelf.point, bench.point]


def test_robots_start_near_the_task_locations_the_stream_uses():
    building = load_building(str(BUILDINGS / "open_hall.building.yaml"))
    world = level_world(building, "ground")
    navigation = level_navigation(building, "ground", world.floor_plan)
    # Work only at east_shelf (18, 4): the spots within 5 m of it first, east_shelf's own
    # point (it has parking spots), then any lane node near it, before the charger 8 m off.
    lanes = Roadways(navigation.roadways, navigation.locations)
    starts = robot_starts(building.levels["ground"], navigation, lanes, world.floor_plan, 3,
                          work=([(18.0, 4.0)], 5.0))
    assert [s[:2] for s in starts] == [[18.0, 4.0], [14.0, 4.0], [10.0, 7.0]]


def test_the_task_stream_is_sized_to_be_served_in_the_run(tmp_path):
    building = BUILDINGS / "narrow_corridor.building.yaml"
    report = import_building(str(building), str(tmp_path), ImportOptions(robots=2))
    raw = yaml.safe_load((tmp_path / "scenario.yaml").read_text())
    generate = raw["tasks"]["generate"]
    assert "rate" not in generate and "pickup_weights" not in generate  # every location
    scenario = load_scenario(tmp_path / "scenario.yaml")
    arrivals = [batch.arrival for batch in scenario.tasks.stream]
    assert arrivals == generate["times"] and arrivals[0] == 0.0
    assert any(f"{len(arrivals)} task batches arriving until" in line for line in report.lines)
    # The last batch leaves a longest and a mean task's time before the end of the run.
    written = yaml.safe_load((tmp_path / "navigation.yaml").read_text())
    assert written["roadways"]["single_file"]  # the corridor
    assert max(arrivals) < scenario.duration - 2 * (2 * 16.0 / 0.6)
    assert len(arrivals) > 1


def test_a_single_file_corridor_bounds_the_stream_below_the_fleet(tmp_path):
    # Every leg drives the corridor, one robot at a time: six robots get the stream that
    # the corridor serves with the waits for it, not six robots' worth (13 batches by the
    # fleet alone).
    building = BUILDINGS / "narrow_corridor.building.yaml"
    report = import_building(str(building), str(tmp_path), ImportOptions(robots=6))
    assert any(line.startswith("ground: 8 task batches") for line in report.lines)


def test_navigation_file_is_the_derived_navigation(tmp_path):
    import_building(str(ONE_LEVEL), str(tmp_path), ImportOptions(robots=2))
    written = yaml.safe_load((tmp_path / "navigation.yaml").read_text())
    scenario = load_scenario(tmp_path / "scenario.yaml")
    assert [loc["name"] for loc in written["locations"]] == [
        loc.name for loc in scenario.locations]
    # Left out, the scenario derives the same navigation from the building itself.
    content = yaml.safe_load((tmp_path / "scenario.yaml").read_text())
    del content["locations"], content["roadways"]
    (tmp_path / "derived.yaml").write_text(yaml.safe_dump(content))
    derived = load_scenario(tmp_path / "derived.yaml")
    assert derived.locations == scenario.locations
    assert derived.roadways == scenario.roadways


def test_people_without_human_lanes_are_visitors_between_lane_nodes(tmp_path):
    import_building(str(BUILDINGS / "cartesian.building.yaml"), str(tmp_path),
                    ImportOptions(robots=1, people=3))
    scenario = load_scenario(tmp_path / "scenario.yaml")
    (group,) = scenario.humans.groups
    assert group.kind == "visitors" and group.count == 3
    floor_plan = load_floor_plan_of(scenario)
    assert floor_plan.obstacles.signed_distance(np.array(group.points)).min() > 0.5


def test_several_levels_give_one_folder_running_them_all(tmp_path):
    report = import_building(str(TWO_LEVELS), str(tmp_path), ImportOptions(robots=2))
    assert report.scenarios == [str(tmp_path / "scenario.yaml")]
    scenario = load_scenario(tmp_path / "scenario.yaml")
    names = [loc.name for loc in scenario.locations]
    assert names == ["L1/l1_desk", "L1/l1_store", "L2/l2_lab", "L2/l2_office"]
    rides = scenario.roadways.lift_edges
    assert {(r.lift, r.from_level, r.to_level) for r in rides} == {("lift_a", "L1", "L2"),
                                                                    ("lift_a", "L2", "L1")}
    # One robot per level; the generated stream has tasks that change levels.
    assert [round(r.start[0]) < 30 for r in scenario.robots] == [True, False]
    tasks = [task for batch in scenario.tasks.stream for task in batch.tasks]
    assert any(names[t.pickup][:2] != names[t.dropoff][:2] for t in tasks)
    # Sized like one level's stream, the lift rides in its travel times.
    generate = yaml.safe_load((tmp_path / "scenario.yaml").read_text())["tasks"]["generate"]
    assert "rate" not in generate and generate["times"][0] == 0.0
    assert any("task batches arriving until" in line for line in report.lines)
    # The 1 m lift door sets the wall safety distance.
    assert scenario.blocks.controller.params["safety_distances"]["wall"] < 0.5


def test_one_chosen_level(tmp_path):
    report = import_building(str(TWO_LEVELS), str(tmp_path),
                             ImportOptions(robots=2, level="L2"))
    assert report.scenarios == [str(tmp_path / "scenario.yaml")]


def test_a_building_with_several_levels_and_no_lift_between_them_is_one_line(tmp_path):
    building = yaml.safe_load(TWO_LEVELS.read_text())
    building["lifts"] = {}
    (tmp_path / "no_lift.building.yaml").write_text(yaml.safe_dump(building))
    (tmp_path / "scenario.yaml").write_text(yaml.safe_dump({
        "world": {"kind": "rmf_building", "floor_plan": "no_lift.building.yaml"},
        "robots": [{"name": "r", "start": [1.5, -2.0]}]}))
    with pytest.raises(InputError) as info:
        load_scenario(tmp_path / "scenario.yaml")
    assert str(info.value) == (
        f"{tmp_path / 'no_lift.building.yaml'}: lifts: no lift joins two levels on lanes of "
        "graph 0: robots could not leave their level (import one level with --level)")


def test_a_level_without_lanes_is_left_out(tmp_path):
    building = yaml.safe_load(TWO_LEVELS.read_text())
    building["levels"]["L2"]["lanes"] = []  # drawn, not yet given lanes
    building["lifts"] = {}
    path = tmp_path / "drawn.building.yaml"
    path.write_text(yaml.safe_dump(building))
    report = import_building(str(path), str(tmp_path / "out"), ImportOptions(robots=2))
    assert "L2: left out, no lanes of graph 0" in report.lines
    scenario = load_scenario(tmp_path / "out" / "scenario.yaml")
    assert scenario.world.level == "L1"
    assert [loc.name for loc in scenario.locations] == ["l1_desk", "l1_store"]
    building["levels"]["L1"]["lanes"] = []
    path.write_text(yaml.safe_dump(building))
    with pytest.raises(InputError, match=r"drawn.building.yaml: levels: no level has lanes "
                       r"of graph 0$"):
        import_building(str(path), str(tmp_path / "none"), ImportOptions(robots=2))


def test_too_many_robots_is_one_line():
    with pytest.raises(InputError, match=r"--robots: 40 robots do not fit: the level's lane "
                       r"nodes give \d+ free start spots"):
        import_building(str(ONE_LEVEL), "unused", ImportOptions(robots=40))


def test_cli_import(tmp_path, capsys):
    assert main(["import", str(ONE_LEVEL), "--robots", "2", "--seed", "1", "--out",
                 str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "L1: graph 0: 4 task locations" in out
    assert "chair_on_lane" in out  # the model left out is named
    assert main(["import", str(ONE_LEVEL), "--robots", "0", "--out", str(tmp_path)]) == 2
    assert capsys.readouterr().err == "error: --robots: must be >= 1, got 0\n"
    assert main(["import", str(ONE_LEVEL), "--seed", "-1", "--out", str(tmp_path)]) == 2
    assert capsys.readouterr().err == "error: --seed: must be >= 0, got -1\n"
    assert main(["import", str(TWO_LEVELS), "--level", "L5", "--out", str(tmp_path)]) == 2
    assert "'L5' is not a level" in capsys.readouterr().err


def test_cli_import_refuses_more_people_than_fit(tmp_path, capsys):
    # The office with 40 people imported, and its scenario then stopped at the run's start:
    # no free start point for a visitor. The import draws the people as a run does, and
    # writes no scenario where they do not fit.
    assert main(["import", str(ONE_LEVEL), "--robots", "1", "--people", "60", "--out",
                 str(tmp_path)]) == 2
    assert capsys.readouterr().err == (
        "error: --people: 60 people do not fit: no free start point found; too many "
        "people?\n")
    assert not (tmp_path / "scenario.yaml").exists()
    assert main(["import", str(ONE_LEVEL), "--robots", "1", "--people", "3", "--out",
                 str(tmp_path)]) == 0
    assert (tmp_path / "scenario.yaml").exists()


def test_cli_broken_building_has_no_traceback(tmp_path):
    broken = Path(__file__).parents[1] / "data" / "broken_buildings" / "no_scale.building.yaml"
    result = subprocess.run([sys.executable, "-m", "mrta_drake.tools.cli", "import",
                             str(broken), "--out", str(tmp_path / "out")],
                            capture_output=True, text=True)
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1 and "Traceback" not in result.stderr
    assert "levels.L1.measurements: none on the reference level" in result.stderr


@pytest.mark.parametrize("seed", range(12))
def test_people_start_apart_from_each_other_as_from_the_robots(tmp_path, seed):
    # Airport terminal, 4 people, seed 301: two walkers drew the same first lane node and
    # the run refused the scenario.
    import_building(str(ONE_LEVEL), str(tmp_path), ImportOptions(robots=1, people=3,
                                                                  seed=seed))
    humans = load_scenario(tmp_path / "scenario.yaml").humans
    # The 5 m human lane has two nodes, too few for three people: they start along it.
    assert len(humans.walkers) == 3 and not humans.groups
    firsts = [walker.waypoints[0] for walker in humans.walkers]
    assert all(y == pytest.approx(-4.9) and 5.5 <= x <= 10.5 for x, y in firsts)
    assert all(np.hypot(a[0] - b[0], a[1] - b[1]) >= PEOPLE_GAP
               for k, a in enumerate(firsts) for b in firsts[k + 1:])


def _cartesian_level():
    building = load_building(str(BUILDINGS / "cartesian.building.yaml"))
    floor_plan = level_world(building, "ground").floor_plan
    return (building.levels["ground"], level_navigation(building, "ground", floor_plan),
            floor_plan.obstacles)


def test_visitors_walk_between_lane_nodes_people_can_walk_between():
    # Lane nodes at x = 2 and 5 west of a wall at x = 6.5, three at x = 8 east of it:
    # visitors' points are the three, the larger group; without the wall, any five.
    level, navigation, obstacles = _cartesian_level()
    wall = obstacles.added(boxes=[Box("wall", (6.5, 3.0), (0.2, 10.0))])
    humans = people_section(level, navigation, [], 3, np.random.default_rng(0), wall)
    assert sorted(x for x, _ in humans["groups"][0]["points"]) == [8.0, 8.0, 8.0]
    humans = people_section(level, navigation, [], 3, np.random.default_rng(0), obstacles)
    assert len(humans["groups"][0]["points"]) == 5
    # Every node walled in alone: no two nodes people walk between.
    boxed = wall.added(boxes=[Box("west", (3.5, 3.0), (0.2, 10.0)),
                              Box("low", (9.0, 2.1), (5.0, 0.2)),
                              Box("high", (9.0, 3.9), (5.0, 0.2))])
    with pytest.raises(InputError, match="too few free lane nodes people walk between"):
        people_section(level, navigation, [], 3, np.random.default_rng(0), boxed)
