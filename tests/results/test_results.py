"""Results of one run: the recorder, per-task and per-leg timing, deadlocks, summary.json,
and files that survive a crash."""

import dataclasses
import json
import math
import pathlib

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder, LeafSystem

from mrta_drake import load_scenario, simulate
from mrta_drake.payloads import (
    DROPOFF,
    PICKUP,
    BackOff,
    BackOffOrders,
    ControllerTelemetry,
    FleetPaths,
    FleetPlan,
    QueueRequest,
    QueueState,
    RobotMode,
    RobotPlan,
    RobotProgress,
    RoomQueue,
    SegmentHold,
    Stop,
    Visit,
    WaypointTarget,
)
from mrta_drake.results import summary
from mrta_drake.results.deadlocks import find_deadlocks, stalled_waits
from mrta_drake.results.timing import leg_rows, task_rows, task_totals
from mrta_drake.scenario.schema import HumanConfig, HumansConfig, TaskBatch, TaskConfig
from mrta_drake.stack.diagram import add_stack
from mrta_drake.stack.run_recorder import RunRecorder, _jsonable
from mrta_drake.world.obstacles import Box, Obstacles

ROOT = pathlib.Path(__file__).resolve().parents[2]
ROUTES = ROOT / "scenarios/hospital_routes_6_robots.yaml"


def _strict_json(text: str):
    def refuse(constant):
        raise ValueError(f"non-standard JSON constant {constant}")

    return json.loads(text, parse_constant=refuse)


# --- Timing of tasks and stops from a hand-made event list -----------------------------------

STREAM = [
    TaskBatch(0.0, [TaskConfig(1, 2, 100.0), TaskConfig(3, 4, 50.0)]),
    TaskBatch(40.0, [TaskConfig(0, 5, 200.0)]),
    TaskBatch(500.0, [TaskConfig(2, 3, 600.0)]),
]


def _stop(task, action, planned):
    return {"key": f"t{task}/{action}", "task": task, "action": action, "location": 0,
            "planned": planned}


def _plan(time, plans):
    return {"time": time, "type": "plan", "revision": int(time), "plans": plans}


def _start(robot, task, action, at):
    return {"time": at, "type": "start", "robot": robot, "key": f"t{task}/{action}",
            "at": at, "location": 0, "task": task, "action": action}


def _arrival(robot, task, action, at):
    return {"time": at + 0.1, "type": "arrival", "robot": robot, "key": f"t{task}/{action}",
            "location": 0, "at": at, "task": task, "action": action}


EVENTS = [
    _plan(0.0, {"A": [_stop(0, PICKUP, 20.0), _stop(0, DROPOFF, 60.0)],
                "B": [_stop(1, PICKUP, 10.0), _stop(1, DROPOFF, 30.0)]}),
    _start("A", 0, PICKUP, 0.1),
    _start("B", 1, PICKUP, 0.1),
    _arrival("B", 1, PICKUP, 12.0),
    _start("B", 1, DROPOFF, 12.0),
    _arrival("A", 0, PICKUP, 25.0),
    _start("A", 0, DROPOFF, 25.0),
    _plan(40.0, {"A": [_stop(0, DROPOFF, 70.0), _stop(2, PICKUP, 90.0),
                       _stop(2, DROPOFF, 130.0)],
                 "B": [_stop(1, DROPOFF, 45.0)]}),
    _arrival("B", 1, DROPOFF, 55.0),
    _arrival("A", 0, DROPOFF, 75.0),
    _start("A", 2, PICKUP, 75.0),
    _arrival("A", 2, PICKUP, 95.0),
    # Made after task 0 was dropped off: its 999 must not count as task 0's prediction.
    _plan(100.0, {"A": [_stop(0, DROPOFF, 999.0), _stop(2, DROPOFF, 140.0)], "B": []}),
]


def test_task_rows_take_the_latest_prediction_before_completion_and_actual_arrivals():
    rows = task_rows(STREAM, EVENTS, end_time=300.0)
    assert [r["id"] for r in rows] == [0, 1, 2, 3]
    t0, t1, t2, t3 = rows
    assert t0["robot"] == "A" and t0["arrival"] == 0.0
    assert (t0["predicted_pickup"], t0["actual_pickup"]) == (20.0, 25.0)
    assert (t0["predicted_dropoff"], t0["actual_dropoff"]) == (70.0, 75.0)
    assert (t0["status"], t0["deadline_met"], t0["lateness"]) == ("on_time", True, -25.0)
    assert (t1["robot"], t1["predicted_dropoff"], t1["actual_dropoff"]) == ("B", 45.0, 55.0)
    assert (t1["status"], t1["deadline_met"], t1["lateness"]) == ("late", False, 5.0)
    assert t2["arrival"] == 40.0 and t2["assigned_at"] == 40.0
    assert (t2["predicted_pickup"], t2["actual_pickup"]) == (90.0, 95.0)
    assert (t2["predicted_dropoff"], t2["actual_dropoff"]) == (140.0, None)
    # Picked up, not dropped off, deadline 200 passed by the end of the run (300 s).
    assert (t2["status"], t2["deadline_met"], t2["lateness"]) == ("carrying", False, None)
    assert (t3["status"], t3["deadline_met"], t3["robot"]) == ("not_released", None, None)


def test_task_totals_count_and_average_over_completed_tasks():
    totals = task_totals(task_rows(STREAM, EVENTS, end_time=300.0))
    assert totals == {
        "total": 4, "released": 3, "assigned": 3, "completed": 2, "on_time": 1, "late": 1,
        "missed": 2, "failed": 0, "completed_ids": [0, 1], "mean_lateness": -10.0,
        "max_lateness": 5.0,
        "total_tardiness": 5.0,
    }


def test_leg_rows_compare_predicted_and_actual_stop_durations():
    legs = {(leg["robot"], leg["key"]): leg for leg in leg_rows(EVENTS)}
    assert list(legs) == [("B", "t1/pickup"), ("A", "t0/pickup"), ("B", "t1/dropoff"),
                          ("A", "t0/dropoff"), ("A", "t2/pickup")]
    expected = {  # (start, end, predicted): first stop of a plan counts from its start
        ("A", "t0/pickup"): (0.1, 25.0, 20.0 - 0.1),
        ("B", "t1/pickup"): (0.1, 12.0, 10.0 - 0.1),
        ("B", "t1/dropoff"): (12.0, 55.0, 45.0 - 12.0),
        ("A", "t0/dropoff"): (25.0, 75.0, 70.0 - 25.0),
        ("A", "t2/pickup"): (75.0, 95.0, 90.0 - 70.0),
    }
    for which, (start, end, predicted) in expected.items():
        leg = legs[which]
        assert (leg["start"], leg["end"]) == (start, end)
        assert leg["actual"] == pytest.approx(end - start)
        assert leg["predicted"] == pytest.approx(predicted)


def test_events_read_back_from_file_give_the_same_tables(tmp_path):
    """NaN predictions are null on file; the tables read them as missing either way."""
    events = EVENTS + [_plan(101.0, {"A": [_stop(2, DROPOFF, math.nan)]})]
    path = tmp_path / "events.jsonl"
    path.write_text("".join(json.dumps(_jsonable(e)) + "\n" for e in events))
    back = [_strict_json(line) for line in path.read_text().splitlines()]
    assert task_rows(STREAM, back, 300.0) == task_rows(STREAM, events, 300.0)
    assert leg_rows(back) == leg_rows(events)


# --- Deadlocks on synthetic trajectories --------------------------------------------------------


def _synthetic(duration=100.0):
    times = np.arange(0.0, duration + 1e-9, 0.1)
    T = len(times)
    xy = np.zeros((T, 4, 2))
    move = np.ones((T, 4), bool)
    # robot0: drives east, stuck at x = 20 (jittering 0.2 m) from t = 20 to t = 70.
    xy[:, 0, 0] = np.clip(times, None, 20.0) + np.clip(times - 70.0, 0.0, None)
    xy[(times >= 20) & (times < 70), 0, 1] = 0.2 * np.sin(times[(times >= 20) & (times < 70)])
    # robot1: parked next to it the whole time, target inactive.
    xy[:, 1] = [21.0, 1.0]
    move[:, 1] = False
    # robot2: drives far away the whole time.
    xy[:, 2, 0] = -times
    # robot3: stuck for 20 s only (< 30 s), then from t = 75 to the end (25 s).
    xy[:, 3] = [50.0, 50.0]
    xy[:, 3, 0] += np.clip(times - 20.0, 0.0, 55.0)
    humans = np.full((T, 2, 2), np.nan)
    humans[:, 0] = [20.0, -1.5]  # near robot0
    humans[times < 30.0, 1] = [20.0, 1.0]  # near robot0, but gone before it is noticed
    return times, xy, move, humans


def test_a_robot_with_a_target_that_makes_no_progress_is_reported_with_who_was_near():
    times, xy, move, humans = _synthetic()
    found = find_deadlocks(times, xy, move, ["r0", "r1", "r2", "r3"], humans, ["h0", "h1"])
    assert len(found) == 1
    d = found[0]
    assert d.robot == "r0"
    # It has made no progress since it came within 0.5 m of x = 20.
    assert d.start == pytest.approx(19.5, abs=0.11)
    assert d.detected == pytest.approx(d.start + 30.0)
    assert d.end == pytest.approx(70.1, abs=0.11)
    assert d.position == pytest.approx((19.5, 0.0), abs=0.11)
    assert d.robots_near == ("r1",) and d.humans_near == ("h0",)


def test_a_parked_robot_is_never_deadlocked_and_a_stuck_one_stays_open_to_the_end():
    times, xy, move, _ = _synthetic()
    move[:, 0] = False  # robot0 has nothing to do: its standing still is fine
    assert find_deadlocks(times, xy, move, ["r0", "r1", "r2", "r3"]) == []
    move[:, 0] = True
    xy[times >= 70.0, 0] = xy[times == 20.0, 0]  # never gets free
    (d,) = find_deadlocks(times, xy, move, ["r0", "r1", "r2", "r3"], stuck_time=30.0)
    assert d.end is None and d.duration(100.0) == pytest.approx(80.4, abs=0.11)


def test_queueing_between_stalled_waits_neither_ends_nor_counts_towards_a_deadlock():
    # One robot stands at the origin: its wait stalls from 0 s, it queues from 20 s to
    # 35 s, stalls again from 35 s: 30 s of stalling add up at 45 s, not before.
    times = np.round(np.arange(0.0, 45.05, 0.1), 1)
    xy = np.zeros((len(times), 1, 2))
    queue = ((times >= 20.0) & (times < 35.0))[:, None]
    move = ~queue
    assert find_deadlocks(times[:-1], xy[:-1], move[:-1], ["r0"], waiting=queue[:-1]) == []
    (d,) = find_deadlocks(times, xy, move, ["r0"], waiting=queue)
    assert (d.start, d.detected, d.end) == (0.0, 45.0, None)
    assert find_deadlocks(times, xy, move, ["r0"]) == []  # without, queueing ends it
    moved = xy.copy()
    moved[times >= 30.0] = (1.0, 0.0)  # it moves up in the queue: progress
    assert find_deadlocks(times, moved, move, ["r0"], waiting=queue) == []


def test_deadlock_detection_rejects_mismatched_shapes():
    times, xy, move, _ = _synthetic(10.0)
    with pytest.raises(ValueError, match="should_move"):
        find_deadlocks(times, xy, move[:, :2], ["r0", "r1", "r2", "r3"])


# --- The recorder, on fixed inputs -------------------------------------------------------------


def test_recorder_notes_modes_plans_starts_arrivals_and_allocator_events(tmp_path):
    recorder = RunRecorder(["a", "b", "c", "d"], rate_hz=10.0, out_dir=str(tmp_path))
    context = recorder.CreateDefaultContext()
    state = np.zeros(16)
    state[4:6] = [5.0, 5.2]  # b is 0.2 m from its room point
    recorder.get_input_port(0).FixValue(context, state)  # robot_state
    stop = Stop("t0/dropoff", 2, DROPOFF, 0, math.nan)
    plan = FleetPlan((RobotPlan("a", (stop,)), RobotPlan("b"), RobotPlan("c"), RobotPlan("d")))
    fixed = {
        "telemetry": ControllerTelemetry(),
        "paths": FleetPaths(()),
        "plan": plan,
        "queue_state": QueueState((RoomQueue(2, "b", ("c",)),)),
        "progress_a": RobotProgress("a", current_stop=stop),
        "target_a": WaypointTarget("a", True, (3.0, 0.0), (6.0, 0.0), False),
        "progress_b": RobotProgress("b", current_stop=Stop("t1/pickup", 2, PICKUP, 1)),
        "target_b": WaypointTarget("b", True, (5.0, 5.0)),
        "progress_c": RobotProgress("c", current_stop=Stop("t2/pickup", 2, PICKUP, 2)),
        "target_c": WaypointTarget("c", True, (1.0, 1.0)),
        "progress_d": RobotProgress("d"),
        "target_d": WaypointTarget("d"),
        "allocator_events": ("assigned 0",),
        **{f"queue_request_{r}": QueueRequest(r) for r in "abcd"},
    }
    for name, value in fixed.items():
        recorder.GetInputPort(name).FixValue(context, value)
    recorder.ForcedPublish(context)
    visit = Visit("t0/dropoff", 2, 0.05, 0, DROPOFF)
    recorder.GetInputPort("progress_a").FixValue(context, RobotProgress("a", (visit,)))
    recorder.GetInputPort("allocator_events").FixValue(context, ("assigned 0", "late 1"))
    context.SetTime(0.1)
    recorder.ForcedPublish(context)
    recorder.close()

    idle, drive, queue, serve = RobotMode.IDLE, RobotMode.DRIVE, RobotMode.QUEUE, RobotMode.SERVE
    assert recorder.mode_array().tolist() == [[drive, serve, queue, idle],
                                              [idle, serve, queue, idle]]
    kinds = [e["type"] for e in recorder.events]
    assert kinds.count("plan") == 1 and kinds.count("arrival") == 1
    assert [e["key"] for e in recorder.events if e["type"] == "start"] == [
        "t0/dropoff", "t1/pickup", "t2/pickup"]
    assert [e["event"]["value"] for e in recorder.events if e["type"] == "allocation"] == [
        "assigned 0", "late 1"]
    on_file = [_strict_json(line) for line in (tmp_path / "events.jsonl").read_text()
               .splitlines()]
    assert len(on_file) == len(recorder.events)
    assert on_file[0]["plans"]["a"][0]["planned"] is None  # NaN is written as null



def test_a_wait_is_stalled_when_it_leads_to_no_moving_or_serving_robot():
    waits = {"a": {"b"}, "b": {"a"},  # each waits for the other: a gridlock
             "c": {"d"}, "d": {"e"},  # c waits for d, which waits for e, which drives
             "f": set(),  # what it waits for is free: it gets it next
             "g": {"a", "e"}}  # one of those it waits for drives
    # A wait leads somewhere only if each robot it waits for does (g: a is in a gridlock).
    assert stalled_waits(waits, {"e"}) == {"a", "b", "g"}
    assert stalled_waits(waits, {"b"}) == {"c", "d", "g"}  # e stands, waiting for nothing
    assert stalled_waits(waits, set()) == {"a", "b", "c", "d", "g"}
    assert stalled_waits({"h": {"i", "j"}}, {"i"}) == {"h"}  # j stands for good
    assert stalled_waits({"h": {"i", "j"}}, {"i", "j"}) == frozenset()


def _waiting_recorder(queue_state, requests, plan_stops):
    """A recorder for robots a, b, c, fixed inputs: ``queue_state``, ``requests`` (robot ->
    QueueRequest), ``plan_stops`` (robot -> its current stop); no target is active."""
    recorder = RunRecorder(["a", "b", "c"], rate_hz=10.0)
    context = recorder.CreateDefaultContext()
    fixed = {"telemetry": ControllerTelemetry(), "paths": FleetPaths(()),
             "plan": FleetPlan(tuple(RobotPlan(r, (stop,)) for r, stop in plan_stops.items())),
             "queue_state": queue_state}
    for r in "abc":
        fixed[f"progress_{r}"] = RobotProgress(r, current_stop=plan_stops.get(r))
        fixed[f"target_{r}"] = WaypointTarget(r, True, (0.0, 0.0), None, False)
        fixed[f"queue_request_{r}"] = requests.get(r, QueueRequest(r))
    for name, value in fixed.items():
        recorder.GetInputPort(name).FixValue(context, value)
    return recorder, context


def _modes_at(recorder, context, speeds) -> list[list[int]]:
    """The recorder's modes after one sample per entry of ``speeds`` (a, b, c in m/s;
    the robots stand 10 m apart, 20 m from the targets)."""
    for i, (va, vb, vc) in enumerate(speeds):
        state = np.array([20.0, 0.0, 0.0, va, 30.0, 0.0, 0.0, vb, 40.0, 0.0, 0.0, vc])
        recorder.get_input_port(0).FixValue(context, state)
        context.SetTime(0.1 * i)
        recorder.ForcedPublish(context)
    recorder.close()
    return recorder.mode_array().tolist()


def test_a_robot_waiting_for_segments_queues_only_while_what_it_waits_for_moves():
    # a waits for single-file segment 0, held by b; c holds segment 1, elsewhere.
    queues = QueueState((), segments=(SegmentHold(("b",)), SegmentHold(("c",))),
                        segment_waiting=("a",))
    requests = {"a": QueueRequest("a", segments=((0, True),)),
                "b": QueueRequest("b", segments=((0, True),)),
                "c": QueueRequest("c", segments=((1, True),))}
    stops = {r: Stop(f"t{i}/pickup", i, PICKUP, i) for i, r in enumerate("abc")}
    recorder, context = _waiting_recorder(queues, requests, stops)
    modes = _modes_at(recorder, context, [(0.0, 0.5, 0.0),  # b drives through: a queues
                                          (0.0, 0.0, 0.5)])  # b stands, c drives elsewhere
    queue, drive = RobotMode.QUEUE, RobotMode.DRIVE
    assert [row[0] for row in modes] == [queue, drive]  # a gridlock: a should move
    # a holds segment 0 with b (a segment where robots stop: one robot's at a time) and
    # waits: it waits for b all the same.
    shared = QueueState((), segments=(SegmentHold(("a", "b")), SegmentHold(("c",))),
                        segment_waiting=("a",))
    recorder, context = _waiting_recorder(shared, requests, stops)
    assert [row[0] for row in _modes_at(recorder, context, [(0.0, 0.0, 0.5)])] == [drive]


def test_a_robot_waiting_for_segments_one_of_which_a_parked_robot_holds_is_stuck():
    # a asks for single-file segments 0 and 1: b holds 0 and drives on, c, without a stop
    # (parked), holds 1 and stands. a gets both only when c leaves: it should move, however
    # b drives. Once c drives too, a queues.
    queues = QueueState((), segments=(SegmentHold(("b",)), SegmentHold(("c",))),
                        segment_waiting=("a",))
    requests = {"a": QueueRequest("a", segments=((0, True), (1, True))),
                "b": QueueRequest("b", segments=((0, True),)),
                "c": QueueRequest("c", segments=((1, True),))}
    stops = {r: Stop(f"t{i}/pickup", i, PICKUP, i) for i, r in enumerate("ab")}
    recorder, context = _waiting_recorder(queues, requests, stops)
    modes = _modes_at(recorder, context, [(0.0, 0.5, 0.0), (0.0, 0.5, 0.5)])
    assert [row[0] for row in modes] == [RobotMode.DRIVE, RobotMode.QUEUE]
    assert [row[2] for row in modes] == [RobotMode.IDLE, RobotMode.IDLE]


def test_robots_waiting_for_each_others_rooms_are_in_a_gridlock_not_queueing():
    # a holds room 0 and waits for room 1; b holds room 1 and waits for room 0; c waits
    # for room 1 too. None moves: all three should move. Once b drives, all queue.
    queues = QueueState((RoomQueue(0, "a", ("b",)), RoomQueue(1, "b", ("a", "c"))))
    stops = {"a": Stop("t0/pickup", 0, PICKUP, 1), "b": Stop("t1/pickup", 1, PICKUP, 0),
             "c": Stop("t2/pickup", 2, PICKUP, 1)}
    recorder, context = _waiting_recorder(queues, {}, stops)
    modes = _modes_at(recorder, context, [(0.0, 0.0, 0.0), (0.0, 0.4, 0.0)])
    queue, drive = RobotMode.QUEUE, RobotMode.DRIVE
    assert modes == [[drive, drive, drive], [queue, queue, queue]]


def test_recorder_notes_each_new_back_off_and_the_summary_counts_them_per_robot():
    recorder = RunRecorder(["a", "b"], rate_hz=10.0)
    context = recorder.CreateDefaultContext()
    recorder.get_input_port(0).FixValue(context, np.zeros(8))  # robot_state
    fixed = {"telemetry": ControllerTelemetry(), "paths": FleetPaths(()),
             "plan": FleetPlan(()), "queue_state": QueueState(),
             "progress_a": RobotProgress("a"), "target_a": WaypointTarget("a"),
             "progress_b": RobotProgress("b"), "target_b": WaypointTarget("b"),
             "queue_request_a": QueueRequest("a"), "queue_request_b": QueueRequest("b"),
             "allocator_events": ()}
    for name, value in fixed.items():
        recorder.GetInputPort(name).FixValue(context, value)
    first = BackOff("b", (1.0, 2.0), 0.0, 15.0, ("a",), 0.0)
    second = BackOff("b", (1.5, 2.0), 30.0, 45.0, ("a",), 15.0, releases=True)
    for t, history in ((0.0, (first,)), (0.1, (first,)), (30.0, (first, second))):
        recorder.GetInputPort("back_offs").FixValue(context, BackOffOrders(history[-1:],
                                                                            history))
        context.SetTime(t)
        recorder.ForcedPublish(context)
    noted = [e for e in recorder.events if e["type"] == "back_off"]
    assert [(e["robot"], e["at"], e["point"], e["blockers"]) for e in noted] == [
        ("b", 0.0, [1.0, 2.0], ["a"]), ("b", 30.0, [1.5, 2.0], ["a"])]
    assert "releases" not in noted[0] and noted[1]["releases"]
    assert summary._back_offs(noted) == {"count": 2, "robots": {"b": 2}, "releases": 1}

# --- Time near walls -----------------------------------------------------------------------------


def test_wall_close_time_is_robot_seconds_nearer_a_wall_than_half_the_safety_distance():
    wall = Obstacles(boxes=(Box("wall", (0.0, -1.0), (20.0, 2.0)),))  # its face: y = 0
    times = np.arange(5.0)  # each sample holds 1 s, the last none
    # Centres; the robots' surfaces are 0.1 m nearer the wall.
    ys = np.array([[1.1, 0.3, 0.3, 1.1, 0.3],  # near at 1 and 2 s (and at the end)
                   [1.1, 1.1, 1.1, 0.35, 1.1]]).T  # near at 3 s
    xy = np.stack([np.zeros_like(ys), ys], axis=-1)
    slack = np.zeros(len(times))

    def safety(wall_safety):
        return summary._safety(wall, ["a", "b"], times, xy, np.array([0.1, 0.1]),
                               np.zeros((5, 0, 2)), np.zeros(0), [], slack, wall_safety)

    assert safety(0.6)["robot_wall_close_distance"] == 0.3
    assert safety(0.6)["robot_wall_close_time"] == 3.0
    assert safety(0.45)["robot_wall_close_time"] == 2.0  # 0.225 m: robot b's 0.25 m is clear
    assert safety(0.35)["robot_wall_close_time"] == 0.0


def test_the_wall_safety_distance_is_read_from_the_controller_params():
    assert summary.controller_wall_safety(load_scenario(ROUTES)) == 0.6
    moved = load_scenario(ROUTES, overrides={
        "blocks.controller.params": {"safety_distances": {"wall": 0.8}}})
    assert summary.controller_wall_safety(moved) == 0.8


# --- A real run ----------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """30 s of the routes scenario with one nurse walking the east corridor."""
    scenario = load_scenario(ROUTES)
    nurse = HumanConfig("nurse", [[5.0, -2.0], [5.0, -20.0]])
    scenario = dataclasses.replace(scenario, humans=HumansConfig(walkers=[nurse]))
    out = tmp_path_factory.mktemp("run")
    return out, simulate(scenario, duration=30.0, out_dir=str(out), plots=False)


def test_summary_json_has_every_section_and_is_strict_json(run):
    out, result = run
    summary = _strict_json((out / "summary.json").read_text())
    assert summary == _strict_json(json.dumps(result.summary))
    assert {"scenario_hash", "seed", "versions", "real_time_factor", "tasks", "legs",
            "robots", "safety", "humans", "deadlocks", "planner_failures",
            "controller_failures"} <= summary.keys()
    assert summary["tasks"]["total"] == 0 and summary["tasks"]["per_task"] == []
    for key in ("min_robot_robot", "min_robot_wall", "min_robot_human"):
        assert summary["safety"][key] > 0.0
    assert summary["safety"]["robot_wall_close_distance"] == 0.3
    assert 0.0 <= summary["safety"]["robot_wall_close_time"] <= 6 * 30.0
    assert summary["safety"]["min_robot_human_between"][1] == "nurse"
    assert summary["humans"]["min_distance"] == pytest.approx(
        summary["safety"]["min_robot_human"])
    assert summary["deadlocks"]["count"] == 0 and summary["real_time_factor"] > 0


def test_robot_times_split_the_run_and_legs_match_arrivals(run):
    _, result = run
    robots = result.summary["robots"]
    for name, robot in robots.items():
        total = robot["busy_time"] + robot["queue_time"] + robot["idle_time"]
        assert total == pytest.approx(30.0), name
        assert robot["distance"] > 1.0
    arrivals = [e for e in result.events if e["type"] == "arrival"]
    legs = result.summary["legs"]
    assert [(leg["robot"], leg["key"]) for leg in legs] == [(e["robot"], e["key"])
                                                           for e in arrivals]
    for leg in legs:
        assert leg["predicted"] is None  # the fixed routes carry no predicted times
        assert 0.0 < leg["actual"] < 30.0
    # Every robot sets off at once to its first stop.
    modes = result.stack.recorder.mode_array()
    assert (modes[1:50] == RobotMode.DRIVE).all()


def test_events_file_holds_every_recorded_event(run):
    out, result = run
    lines = (out / "events.jsonl").read_text().splitlines()
    assert [_strict_json(line)["type"] for line in lines] == [e["type"] for e in result.events]
    assert {"plan", "start", "room"} <= {e["type"] for e in result.events}


# --- A crash midway -----------------------------------------------------------------------------


class _Crash(LeafSystem):
    """Raises at ``time`` s, as a failing block would."""

    def __init__(self, time: float):
        super().__init__()
        self.DeclarePeriodicPublishEvent(time, time, self._crash)

    def _crash(self, context):
        raise RuntimeError("block failed")


def test_a_run_that_crashes_midway_leaves_what_happened_so_far_on_disk(tmp_path):
    builder = DiagramBuilder()
    stack = add_stack(builder, load_scenario(ROUTES), out_dir=str(tmp_path))
    builder.AddSystem(_Crash(4.0))
    simulator = Simulator(builder.Build())
    with pytest.raises(RuntimeError, match="block failed"):
        simulator.AdvanceTo(10.0)
    # Read before anything is closed: what is on disk is what was flushed.
    rows = (tmp_path / "timeline.csv").read_text().splitlines()
    assert rows[0] == "time,robot,x,y,theta,v"
    times = sorted({float(row.split(",")[0]) for row in rows[1:]})
    assert times[0] == 0.0 and 3.85 < times[-1] <= 4.0
    assert len(rows) - 1 == 6 * len(times)
    events = [_strict_json(line) for line in (tmp_path / "events.jsonl").read_text()
              .splitlines()]
    assert [e["type"] for e in events] == [e["type"] for e in stack.recorder.events]
    assert {"plan", "room", "start"} <= {e["type"] for e in events}
    assert not (tmp_path / "summary.json").exists()
    stack.recorder.close()
