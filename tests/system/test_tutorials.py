"""Each tutorial runs (short durations) and shows what its text says it shows."""

import importlib.util
import pathlib
import sys

import numpy as np
import pytest

from mrta_drake.allocation import AllocationProblem, verify_allocation
from mrta_drake.scenario.travel_times import load_travel_times

TUTORIALS = pathlib.Path(__file__).resolve().parents[2] / "tutorials"


def tutorial(number: int):
    """The tutorial module whose file name starts with ``number`` (two digits), imported as
    running it as a script would (its folder on the path, for ``tutorial_common``)."""
    if str(TUTORIALS) not in sys.path:
        sys.path.insert(0, str(TUTORIALS))
    (path,) = TUTORIALS.glob(f"{number:02d}_*.py")
    spec = importlib.util.spec_from_file_location(f"tutorial_{number:02d}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_every_tutorial_is_listed_in_the_readme():
    readme = (TUTORIALS / "README.md").read_text()
    scripts = sorted(p.name for p in TUTORIALS.glob("[0-9][0-9]_*.py"))
    assert len(scripts) == 7
    for name in scripts:
        assert f"({name})" in readme


def test_01_hand_built_diagram_has_every_block_and_our_monitor(tmp_path, capsys):
    shown = tutorial(1).main(["--duration", "3", "--out", str(tmp_path)])
    for block in ("allocator", "room_queues", "planner", "controller", "robots", "humans",
                  "recorder", "waypoints", "speed_monitor"):
        assert block in shown["systems"]
    assert shown["feeds"] == {"controller.robot_state": "robots.state",
                              "controller.paths": "planner.paths",
                              "controller.human_states": "humans.human_states"}
    # Our monitor and the recorder watched the same robots: same top speeds, all moving.
    assert np.allclose(shown["top_speed"], shown["recorded_top_speed"], atol=0.01)
    assert (shown["top_speed"] > 0.5).all()
    assert shown["plan"].revision == 1
    assert {"timeline.csv", "events.jsonl", "diagram.dot"} <= {
        p.name for p in tmp_path.iterdir()}
    assert "speed_monitor" in capsys.readouterr().out


def test_02_custom_allocator_differs_from_smt_both_valid_and_runs_in_the_loop():
    module = tutorial(2)
    shown = module.main(["--duration", "5"])
    smt, ours = shown["offline"]["smt"], shown["offline"]["earliest_pickup"]
    assert shown["violations"] == {"smt": (), "earliest_pickup": ()}
    problem = shown["problem"]
    assert verify_allocation(problem, smt) == () and verify_allocation(problem, ours) == ()
    assert smt.routes != ours.routes
    # What the tutorial says: SMT has every task on time, the dispatcher leaves some late.
    assert smt.status == "feasible" and not smt.late_tasks and ours.late_tasks
    # In the loop, the first batch (at 0 s, robots idle at their start) went where our
    # allocator sends it.
    first = [t for t in problem.tasks if t.release == 0.0]
    alone = module.EarliestPickupAllocator().allocate(
        AllocationProblem(problem.travel, problem.robots, first, problem.service_time))
    expected = {a.task: problem.robots[r].name for r, route in enumerate(alone.routes)
                for a in route}
    per_task = shown["summaries"]["earliest_pickup"]["tasks"]["per_task"]
    assert {t["id"]: t["robot"] for t in per_task if t["id"] in expected} == expected


def test_03_without_cbfs_robots_come_closer_to_people_and_walls():
    summaries = tutorial(3).main(["--duration", "10"])["summaries"]
    cbf, plain = summaries["cluster_cbf"]["safety"], summaries["go_to_goal"]["safety"]
    assert plain["min_robot_human"] < cbf["min_robot_human"]
    assert plain["min_robot_wall"] < cbf["min_robot_wall"]
    assert cbf["robot_human_contacts"] == 0
    assert summaries["stop_and_go"]["safety"]["min_robot_robot"] is not None


def test_04_leader_rules_pick_different_leaders_from_identical_runs():
    shown = tutorial(4).main(["--duration", "5"])
    for rule in ("distance_to_goal", "nearly_there_first"):
        time, members, identical_before = shown["divergence"][rule]
        assert 0.0 < time < 5.0 and len(members) >= 2 and identical_before
        k = int(np.flatnonzero(shown["runs"]["priority"].times == time)[0])
        assert shown["leaders"]["priority"][k][members] != shown["leaders"][rule][k][members]


def test_04_nearly_there_rule_puts_near_robots_first():
    rule = tutorial(4).nearly_there_first
    keys = rule(np.array([0.0, 1.0, 2.0]), np.array([10.0, 2.0, 1.0]))
    assert np.argsort(keys).tolist() == [1, 2, 0]


def test_05_people_and_scenic_objects_join_the_run():
    module = tutorial(5)
    shown = module.main(["--duration", "6"])
    objects = shown["objects"]
    seeds = sorted(objects)
    assert [o.name for o in objects[seeds[0]]] == [
        "wheelchair_0", "wheelchair_1", "wheelchair_2", "cart_3", "cart_4"]
    assert [o.center for o in objects[seeds[0]]] != [o.center for o in objects[seeds[1]]]
    busy, empty = shown["runs"]["busy"], shown["runs"]["empty"]
    placed = {o.name for o in objects[seeds[0]]}
    assert placed <= {o.name for o in busy.stack.world.obstacles.boxes}
    assert not placed & {o.name for o in empty.stack.world.obstacles.boxes}
    assert len(busy.stack.humans.people) == 1 + 4 + 3 and empty.stack.humans is None
    assert busy.summary["humans"] is not None and empty.summary["humans"] is None
    assert busy.summary["safety"]["robot_wall_contacts"] == 0
    assert busy.summary["safety"]["robot_human_contacts"] == 0
    # Closing cross corridor 1 sends the robots whose legs cross it round another way.
    blocked = shown["runs"]["blocked"]
    (blockage,) = blocked.summary["disturbances"]
    assert blockage["name"] == "cross_corridor_1" and blockage["robots_rerouted"]
    assert not busy.summary["disturbances"]
    detours = [e for e in blocked.events if e["type"] == "detour"]
    assert detours and all(e["at"] >= 2.0 for e in detours)


def test_06_sweep_over_the_assumed_speed_writes_table_and_plot(tmp_path):
    shown = tutorial(6).main(["--duration", "5", "--speeds", "0.4", "0.8", "--workers", "2",
                              "--out", str(tmp_path)])
    assert [row["status"] for row in shown["rows"]] == ["ok", "ok"]
    assert (tmp_path / "results.csv").is_file()
    assert pathlib.Path(shown["plot"]).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    measured, estimate = shown["measured"], shown["estimate"]
    assert measured.shape == estimate.shape == (6, 6)
    assert not np.array_equal(measured, estimate)
    # The robots' real average speed lies between the speeds swept; the tutorial marks it.
    assert 0.4 < shown["measured_speed"] < 0.8
    # Assuming a slower speed, the allocator predicts later drop-offs.
    slow, fast = ({t["id"]: t["predicted_dropoff"] for t in s["tasks"]["per_task"]}
                  for s in shown["summaries"])
    assert slow[0] > fast[0] > 0


@pytest.mark.parametrize("number", range(1, 7))
def test_tutorial_has_a_teaching_docstring_and_the_common_options(number):
    module = tutorial(number)
    assert len(module.__doc__.split()) > 150
    assert module.__doc__.startswith(f"Tutorial {number}: ")
    for option in ("--duration", "--meshcat", "--out"):
        assert option in module.__doc__


def test_06_collect_measures_the_matrix_afresh_and_writes_it(tmp_path):
    shown = tutorial(6).main(["--collect", "--duration", "2", "--speeds", "0.6", "--workers",
                              "1", "--out", str(tmp_path)])
    written = load_travel_times(shown["measured_file"], 6)
    assert shown["measured_file"] == str(tmp_path / "travel_times.yaml")
    np.testing.assert_array_equal(written, shown["measured"])
    assert (np.diag(written) == 0).all() and (written + np.eye(6) > 0).all()
    # Driven for real: slower on average than the robots' top speed, turning and queueing.
    assert 0.3 < shown["measured_speed"] < 1.0


def test_07_an_imported_two_floor_building_runs_tasks_across_floors_through_the_lifts():
    shown = tutorial(7).main(["--duration", "400"])
    summary = shown["summary"]
    assert summary["tasks"]["completed"] >= 3
    assert any(a != b for pair in shown["by_floors"] for a, b in [pair.split(" -> ")])
    assert len(shown["rides"]) >= 2
    assert {ride["level"] for ride in shown["rides"]} <= set(shown["layout"].names)
    safety = summary["safety"]
    assert safety["robot_robot_contacts"] == 0 and safety["robot_wall_contacts"] == 0
    assert summary["deadlocks"]["count"] == 0
