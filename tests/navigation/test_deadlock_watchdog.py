"""The deadlock watchdog: two robots head-on in a corridor too narrow to pass stand nose to
nose for good; with the watchdog one backs into a bay, the other passes, both arrive."""

import math
import pathlib

import numpy as np
import pytest
from pydrake.common.value import Value
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantValueSource, LogVectorOutput

from mrta_drake.control.cluster_cbf_controller import ClusterCbfController
from mrta_drake.errors import InputError
from mrta_drake.navigation.costmap import Costmap
from mrta_drake.navigation.deadlock_watchdog import DeadlockWatchdog, WatchdogParams
from mrta_drake.navigation.planner_service import PlannerService
from mrta_drake.navigation.standstills import (
    Anchor,
    Pose,
    back_off_spot,
    blocked_groups,
    in_ways,
    next_anchor,
    next_pose,
    yield_order,
)
from mrta_drake.payloads import (
    Breakdown,
    Disturbances,
    HumanStates,
    Outage,
    QueueRequest,
    QueueState,
    RoomQueue,
    SegmentHold,
    WaypointTarget,
    frozen_array,
)
from mrta_drake.robots.unicycle_robots import UnicycleRobots
from mrta_drake.scenario.loading import load_scenario
from mrta_drake.stack.blocks import resolve_block
from mrta_drake.world.obstacles import Box, Obstacles

HOSPITAL = pathlib.Path(__file__).resolve().parents[2] / "scenarios/hospital_6_robots.yaml"
RADIUS = 0.22
NAMES = ("r0", "r1")
BOUNDS = (-1.0, 15.0, -2.0, 4.0)
BAY = (4.5, 6.5)  # x extent of the bay north of the corridor, m
# r1 comes out of the corridor's closed east end as r0 drives there: r0, leading, pushes r1
# back against the end, where neither can get by.
STARTS = [[7.0, 0.0, 0.0], [13.3, 0.0, math.pi]]
GOALS = [(13.0, 0.0), (1.0, 0.0)]


def _corridor_with_bay(width=1.6, bay_depth=1.6, t=0.2):
    """A corridor along x (y in [-width/2, width/2]), closed at both ends, with a bay
    opening north at ``BAY``: one robot fits in it with its wall distance, two cannot pass."""
    half, (x0, x1) = width / 2, BAY
    north = half + t / 2
    return Obstacles((
        Box("south", (7.0, -half - t / 2), (16.0, t)),
        Box("north_west", ((-1.0 + x0) / 2, north), (x0 + 1.0, t)),
        Box("north_east", ((x1 + 15.0) / 2, north), (15.0 - x1, t)),
        Box("bay_west", (x0 - t / 2, half + bay_depth / 2), (t, bay_depth)),
        Box("bay_east", (x1 + t / 2, half + bay_depth / 2), (t, bay_depth)),
        Box("bay_back", ((x0 + x1) / 2, half + bay_depth + t / 2), (x1 - x0 + 2 * t, t)),
        Box("west_end", (-0.1, 0.0), (t, width)),
        Box("east_end", (14.1, 0.0), (t, width)),
    ))


def _run(with_watchdog: bool, duration=75.0, watchdog_sees=None, world=None):
    """Robot states (T, 2, 4) at 10 Hz and the watchdog's orders at the end (None
    without it); ``watchdog_sees``: disturbances on the watchdog's input only; ``world``:
    (obstacles, bounds, starts, goals), by default the corridor with its bay, ``STARTS``
    and ``GOALS``."""
    obstacles, bounds, starts, goals = world or (_corridor_with_bay(), BOUNDS, STARTS, GOALS)
    builder = DiagramBuilder()
    robots = builder.AddSystem(UnicycleRobots(NAMES, np.array(starts), rate_hz=20.0))
    controller = builder.AddSystem(ClusterCbfController(NAMES, obstacles, rate_hz=20.0))
    planner = builder.AddSystem(PlannerService.from_obstacles(
        obstacles, bounds, NAMES, replan_rate_hz=2.0, target_check_rate_hz=10.0))
    state = robots.GetOutputPort("state")
    builder.Connect(state, controller.GetInputPort("robot_state"))
    builder.Connect(controller.GetOutputPort("commands"), robots.GetInputPort("commands"))
    builder.Connect(planner.GetOutputPort("paths"), controller.GetInputPort("paths"))
    builder.Connect(state, planner.GetInputPort("robot_state"))
    watchdog = None
    if with_watchdog:
        watchdog = builder.AddSystem(DeadlockWatchdog(
            NAMES, [RADIUS, RADIUS], Costmap.from_obstacles(obstacles, bounds),
            rate_hz=2.0))
        builder.Connect(state, watchdog.GetInputPort("robot_state"))
        builder.Connect(watchdog.GetOutputPort("back_offs"), planner.GetInputPort("back_offs"))
        if watchdog_sees is not None:
            source = builder.AddSystem(ConstantValueSource(Value[object](watchdog_sees)))
            builder.Connect(source.get_output_port(), watchdog.GetInputPort("disturbances"))
    for name, goal in zip(NAMES, goals, strict=True):
        target = builder.AddSystem(ConstantValueSource(Value[object](
            WaypointTarget(name, goal is not None, goal, None, True))))
        builder.Connect(target.get_output_port(), planner.GetInputPort(f"target_{name}"))
        if watchdog is not None:
            builder.Connect(target.get_output_port(), watchdog.GetInputPort(f"target_{name}"))
    log = LogVectorOutput(state, builder, 0.1)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    simulator.AdvanceTo(duration)
    context = simulator.get_context()
    orders = (watchdog.GetOutputPort("back_offs").Eval(watchdog.GetMyContextFromRoot(context))
              if watchdog is not None else None)
    return log.FindLog(context).data().T.reshape(-1, 2, 4), orders


def _distances_to_goals(states):
    return np.linalg.norm(states[-1, :, :2] - np.array(GOALS), axis=1)


def _min_separation(states):
    return np.linalg.norm(states[:, 0, :2] - states[:, 1, :2], axis=1).min()


def test_without_the_watchdog_the_corridor_deadlocks():
    states, _ = _run(with_watchdog=False, duration=40.0)
    assert _distances_to_goals(states)[1] > 10.0  # r1 never got out
    late = states[len(states) // 2:, :, :2]
    assert np.ptp(late, axis=0).max() < 0.5  # nose to nose for the last 20 s


def test_the_watchdog_backs_one_robot_into_the_bay_and_both_arrive():
    states, orders = _run(with_watchdog=True)
    assert (_distances_to_goals(states) < 0.5).all()
    assert _min_separation(states) >= 2 * RADIUS
    first = orders.history[0]
    # r1 yields first by priority, but no spot is free of r0's way on its side: r0 yields.
    assert first.robot == "r0" and first.blockers == ("r1",)
    # At the bay: its body reaches into the bay past the corridor's north side (0.8 m).
    assert BAY[0] < first.point[0] < BAY[1] and first.point[1] + RADIUS > 0.8
    assert first.issued - first.stalled_since == pytest.approx(15.0, abs=0.5)
    assert not orders.active


def _room_with_a_door(t=0.15):
    """A room west of a 1.3 m door (its centre the origin) in a wall along x = 0, the
    room's south wall 0.93 m south of the door's centre, a corridor east of it: room 5's
    door of the hospital."""
    return Obstacles((
        Box("door_north", (0.0, 3.325), (t, 5.35)),
        Box("door_south", (0.0, -2.825), (t, 4.35)),
        Box("room_south", (-3.0, -0.93), (6.0, t)),
        Box("room_west", (-6.0, 2.5), (t, 7.0)),
        Box("north", (-0.5, 6.0), (7.0, t)),
        Box("corridor_east", (3.0, 0.0), (t, 12.0)),
        Box("corridor_south", (1.5, -5.0), (3.0, t)),
    ))


def test_a_robot_sent_aside_makes_way_at_once():
    # Issue 15 (soak seed 107): robot1 and robot5, leaving room 5 together, stood at its
    # door, robot1 (r0) facing it 0.4 m north of its centre line, robot5 (r1) beside it
    # to the south-west, in the way r0 must swing through to pass the door. r1 was sent to
    # spots just over 0.5 m off, counted as reached (within 0.5 m) at once, and in the
    # controller no longer led (within its arrival radius of the path's end): eleven
    # orders moved it 3.5 cm each, 110 s. Sent 1 m off, it makes way and r0 leaves.
    world = (_room_with_a_door(), (-6.5, 3.5, -5.5, 6.5),
             [[-0.595, 0.393, -0.79], [-0.88, -0.15, 0.064]], [(1.5, -3.0), None])
    states, orders = _run(with_watchdog=True, duration=30.0, world=world)
    assert np.linalg.norm(states[-1, 0, :2] - (1.5, -3.0)) < 0.5  # r0 is out
    assert [order.robot for order in orders.history] == ["r1"]
    assert math.dist(orders.history[0].point, (-0.88, -0.15)) >= 1.0


def test_a_broken_down_robot_is_never_asked_to_yield():
    # r0, the only robot with a spot that makes way, reported broken down: nobody yields.
    _, orders = _run(with_watchdog=True, duration=40.0,
                     watchdog_sees=Disturbances(breakdowns=(Breakdown(0, 0.0),)))
    assert orders.history == ()


def test_stalled_robots_and_their_neighbours_form_groups():
    xy = np.array([[0.0, 0.0], [0.7, 0.0], [5.0, 0.0], [5.5, 0.0], [9.0, 0.0]])
    radii = np.full(5, RADIUS)
    stalled = np.array([True, False, False, False, True])
    assert blocked_groups(stalled, xy, radii, block_gap=0.6) == [(0, 1)]
    stalled[3] = True
    assert blocked_groups(stalled, xy, radii, block_gap=0.6) == [(0, 1), (2, 3)]


def test_idle_robots_yield_before_stalled_ones_and_low_priority_first():
    idle = np.array([False, True, False, False])
    stalled = np.array([True, False, True, False])
    assert yield_order((0, 1, 2, 3), idle, stalled, np.arange(4.0)) == [1, 2, 0, 3]


def test_a_robot_in_a_stalled_robots_way_yields_first():
    # Issue 15 (seed 106 of the soak): robot 1, a room's holder, stands behind robot 0
    # waiting at the queue's head slot, through which robot 1's way to the door leads;
    # robot 2 has queued behind robot 1. Asked by priority, robot 2 (behind, freeing
    # nothing) was sent aside 19 times over 400 s; robot 0 is the one to ask.
    xy = np.array([[4.3, -25.3], [3.7, -25.3], [3.1, -25.3]])
    ways = [xy[0:1], np.array([xy[1], (5.5, -25.35), (5.5, -26.6)]), xy[2:3]]
    stalled = np.array([False, True, False])
    idle = np.zeros(3, dtype=bool)
    in_way = in_ways((0, 1, 2), stalled, xy, np.full(3, RADIUS), ways, clearance=0.3)
    assert in_way.tolist() == [True, False, False]  # robot 2 is behind, not in the way
    priorities = np.arange(3.0)
    # Robot 1, the only stalled one, is passed over (it would make way for nobody).
    assert yield_order((0, 1, 2), idle, stalled, priorities) == [1, 2, 0]
    assert yield_order((0, 1, 2), idle, stalled, priorities, in_way) == [0, 1, 2]
    beside = xy.copy()
    beside[0] = (4.3, -24.1)  # 1.2 m beside the way: not in it
    assert not in_ways((0, 1, 2), stalled, beside, np.full(3, RADIUS), ways, 0.3)[0]


def test_only_the_first_robot_in_a_way_or_a_doorway_is_in_it():
    # r1 stalled driving west; r0 and r2 both ahead on its way, r0 nearer: r2 stands
    # behind r0 and frees nothing by moving while r0 stands. r0 waits at its door for r1
    # and r3 in its doorway: r1, the nearer, is the one in its way.
    xy = np.array([[10.0, 0.0], [10.6, 0.0], [9.0, 0.0], [12.0, 0.0]])
    ways = [xy[0:1], np.array([xy[1], (1.0, 0.0)]), xy[2:3], xy[3:4]]
    stalled = np.array([False, True, False, False])
    radii = np.full(4, RADIUS)
    group = (0, 1, 2, 3)
    assert in_ways(group, stalled, xy, radii, ways, 0.3).tolist() == [True, False, False,
                                                                     False]
    assert in_ways(group, stalled, xy, radii, ways, 0.3, {0: (1, 3)}).tolist() == [
        True, True, False, False]


def test_the_robot_in_a_waiting_holders_doorway_yields_not_one_behind_it():
    # Office seed 14 (issue 14): robot3 (r0), pantry's holder, waits at its door in a
    # single-file lane for robot6 (r1), stalled nose to nose with it on its way west, and
    # robot1 (r2), standing idle behind r1; both stand in r0's doorway. r0 has no spot
    # off r1's way; r1 was passed over as the only stalled robot, and r2, in nobody's
    # way, was sent aside for nothing (a 34 s episode). r1, first in r0's doorway, goes.
    t = 0.2
    obstacles = Obstacles((Box("south", (7.0, -1.1), (10.0, t)),
                           Box("north", (7.0, 1.1), (10.0, t)),
                           Box("west", (2.0, 0.0), (t, 2.4))))
    names = ("r0", "r1", "r2")
    watchdog = DeadlockWatchdog(names, [RADIUS] * 3,
                                Costmap.from_obstacles(obstacles, (-1.0, 21.0, -4.0, 4.0)),
                                rate_hz=2.0)
    context = watchdog.CreateDefaultContext()
    states = np.array([[10.0, 0.0, 0.0, 0.0], [10.6, 0.0, math.pi, 0.0],
                       [13.0, 1.6, math.pi, 0.0]])
    targets = [WaypointTarget("r0"), WaypointTarget("r1", True, (1.0, 0.0), None, True),
               WaypointTarget("r2")]
    requests = [QueueRequest("r0", room=0, door=("r1", "r2")), QueueRequest("r1"),
                QueueRequest("r2")]
    for request in requests:
        watchdog.GetInputPort(f"queue_request_{request.robot}").FixValue(context, request)
    watchdog.GetInputPort("queue_state").FixValue(
        context, QueueState(rooms=(RoomQueue(0, "r0"),)))
    now = 100.0
    anchors = [None, Anchor((10.6, 0.0), now - 15.0), None]
    order = watchdog._order((0, 1, 2), np.array([False, True, False]), anchors, states,
                            targets, context, now, ())
    assert order.robot == "r1" and order.blockers == ("r0", "r2")
    assert order.point[0] > 10.6


def test_an_anchor_moves_only_with_progress_and_goes_without_a_goal():
    anchor = next_anchor(None, (0.0, 0.0), True, 1.0, 0.5)
    assert anchor == Anchor((0.0, 0.0), 1.0)
    assert next_anchor(anchor, (0.4, 0.0), True, 2.0, 0.5) is anchor
    assert next_anchor(anchor, (0.6, 0.0), True, 3.0, 0.5) == Anchor((0.6, 0.0), 3.0)
    assert next_anchor(anchor, (0.0, 0.0), False, 3.0, 0.5) is None


def test_a_robot_pushed_backwards_keeps_its_standstill_time():
    # Facing east (heading 0): 0.6 m east is progress, 0.6 m west (driven backwards) is
    # not; the anchor moves with it, so progress counts from where it was pushed to.
    anchor = Anchor((0.0, 0.0), 1.0)
    assert next_anchor(anchor, (0.6, 0.0), True, 3.0, 0.5, 0.0) == Anchor((0.6, 0.0), 3.0)
    pushed = next_anchor(anchor, (-0.6, 0.0), True, 3.0, 0.5, 0.0)
    assert pushed == Anchor((-0.6, 0.0), 1.0)
    assert next_anchor(pushed, (0.0, 0.0), True, 4.0, 0.5, 0.0) == Anchor((0.0, 0.0), 4.0)


@pytest.mark.parametrize("single_file", [False, True])
def test_a_robot_pushed_back_by_another_driving_on_gets_an_order(single_file):
    # r0 drives east at 0.1 m/s into r1, which faces west (its goal behind r0) and is
    # pushed back east ahead of it: r1 moves but makes no progress. After standstill_time
    # r1 counts as stalled and r0, in its way, is sent aside (without the rule r1's anchor
    # moves on with each 0.5 m and nobody is ever stalled). Not so where r1 asks for a
    # single-file segment: there the queues order who goes.
    p = WatchdogParams()
    watchdog, context, simulator = _standing_robots((4.7, 0.0, 0.0, 0.1, 5.3, 0.0, math.pi,
                                                     -0.1), ((8.0, 0.0), (2.0, 0.0)))
    watchdog.GetInputPort("queue_state").FixValue(context, QueueState(
        segments=(SegmentHold(),), segment_waiting=("r1",) if single_file else ()))
    for name, segments in zip(NAMES, ((), ((0, False),) if single_file else ()), strict=True):
        watchdog.GetInputPort(f"queue_request_{name}").FixValue(
            context, QueueRequest(name, segments=segments))
    for step in range(1, 34):
        simulator.AdvanceTo(0.5 * step)
        x = 0.05 * step
        watchdog.GetInputPort("robot_state").FixValue(
            context, np.array([4.7 + x, 0.0, 0.0, 0.1, 5.3 + x, 0.0, math.pi, -0.1]))
    history = watchdog.GetOutputPort("back_offs").Eval(context).history
    assert [order.robot for order in history] == ([] if single_file else ["r0"])
    if not single_file:
        assert history[0].issued == pytest.approx(p.standstill_time)
        assert history[0].blockers == ("r1",)


def test_no_spot_when_the_only_way_out_is_through_the_blocker():
    obstacles = _corridor_with_bay()
    costmap = Costmap.from_obstacles(obstacles, BOUNDS)
    xy = np.array([[12.0, 0.0], [12.7, 0.0]])  # r1 against the closed east end
    ways = [(np.array([[12.0, 0.0], [13.9, 0.0]]), RADIUS)]  # r0 on to the end
    none = np.zeros((0, 2))
    assert back_off_spot(1, xy, np.full(2, RADIUS), ways, none, np.zeros(0), costmap,
                         4.0, 0.3, 0.8) is None
    spot = back_off_spot(0, xy, np.full(2, RADIUS), [(xy[1:], RADIUS)], none, np.zeros(0),
                         costmap, 4.0, 0.3, 0.8)
    assert spot is not None and spot[0] < 12.0


def test_a_spot_keeps_clear_of_every_way_and_is_the_nearest_such():
    # Several ways at once (a polyline, a straight piece, a single point), each with its
    # own radius: the spot is the one the search reaches first among the points that keep
    # clear of them all, checked here by brute force over the same grid.
    costmap = Costmap.from_obstacles(Obstacles(()), (-10.0, 10.0, -10.0, 10.0))
    xy = np.array([[0.0, 0.0], [3.0, 0.0]])
    ways = [(np.array([[0.0, -1.0], [0.0, 1.0], [2.0, 1.0]]), 0.3),
            (np.array([[-2.0, -0.5], [-0.2, -0.5]]), 0.2),
            (np.array([[0.5, -0.8]]), 0.4)]
    none = np.zeros((0, 2))
    spot = back_off_spot(0, xy, np.full(2, RADIUS), ways, none, np.zeros(0), costmap,
                         3.0, 0.3, 0.5, min_move=0.4)
    offsets = np.arange(-30, 31) * 0.1
    grid = [np.array([x, y]) for x in offsets for y in offsets]
    spots = [p for p in grid if _clear(p, ways, 0.3) and 0.4 <= np.hypot(*p) <= 3.0
             and np.linalg.norm(p - xy[1]) - 2 * RADIUS >= 0.3]
    fewest = min(round(abs(p[0]) / 0.1 + abs(p[1]) / 0.1) for p in spots)
    assert spot is not None and _clear(np.array(spot), ways, 0.3)
    assert round(abs(spot[0]) / 0.1 + abs(spot[1]) / 0.1) == fewest


def _clear(p, ways, clearance: float) -> bool:
    """Whether ``p`` keeps ``clearance`` (surface to surface) from every one of ``ways``."""
    return all(min(_point_to_piece(p, way[i], way[min(i + 1, len(way) - 1)])
                   for i in range(max(len(way) - 1, 1))) >= RADIUS + radius + clearance
               for way, radius in ways)


def _point_to_piece(p, a, b) -> float:
    """Distance (m) from ``p`` to the straight piece from ``a`` to ``b``."""
    ab = b - a
    t = 0.0 if not ab.any() else float(np.clip((p - a) @ ab / (ab @ ab), 0.0, 1.0))
    return float(np.linalg.norm(p - a - t * ab))


def test_a_robot_in_a_corridor_narrower_than_the_inflation_finds_a_spot_beyond_it():
    # The office (rmf_demos), seeds 58, 68, 76, 85 and 86: a corridor 1.0-1.2 m wide
    # between furniture has no cell beyond the inflation radius from both sides, so a
    # search on such cells only never left a robot standing in it: no order, 30-90 s of
    # standstill. Robots drive such corridors; the search crosses them (cells where a
    # robot keeps PASS_WALL_GAP from walls), to a spot in the room at the corridor's west
    # end.
    half, t = 0.45, 0.2
    obstacles = Obstacles((
        Box("corridor_south", (4.0, -half - t / 2), (8.0, t)),
        Box("corridor_north", (4.0, half + t / 2), (8.0, t)),
        Box("corridor_end", (8.0 + t / 2, 0.0), (t, 2 * half)),
        Box("room_south", (-2.0, -2.0 - t / 2), (4.0, t)),
        Box("room_north", (-2.0, 2.0 + t / 2), (4.0, t)),
        Box("room_west", (-4.0 - t / 2, 0.0), (t, 4.0 + 2 * t)),
    ))
    costmap = Costmap.from_obstacles(obstacles, (-5.0, 9.0, -3.0, 3.0))
    xy = np.array([[3.0, 0.0], [3.8, 0.0]])  # r1 drives west behind r0 and stands there
    assert not (costmap.cost_at(np.array([[x, 0.0] for x in np.arange(0.2, 7.9, 0.1)]))
                == 0).any()
    spot = back_off_spot(0, xy, np.full(2, RADIUS), [(xy[1:], RADIUS)], np.zeros((0, 2)),
                         np.zeros(0), costmap, 8.0, 0.3, 0.8)
    assert spot is not None and spot[0] < 0.0
    assert costmap.cost_at(np.array([spot]))[0] == 0


@pytest.mark.parametrize("gap", [0.0, 0.1])
def test_a_robot_pushed_against_a_wall_still_gets_a_spot(gap):
    # The hotel (rmf_demos), seed 4: robot6, pushed to within 3 mm of a wall's end, stood
    # in robot3's way for 26 s with no order: every point around it lay within the
    # costmap's inflation radius, so the search never left where it stood. It leaves
    # through cells no nearer the wall than it is, to a spot clear of walls and r0's way.
    obstacles = Obstacles((Box("south", (0.0, -0.1), (20.0, 0.2)),))
    costmap = Costmap.from_obstacles(obstacles, (-10.0, 10.0, -0.5, 6.0))
    xy = np.array([[-1.0, 0.9], [0.0, RADIUS + gap]])  # r0 drives east along the wall
    ways = [(np.array([xy[0], (5.0, 0.9)]), RADIUS)]
    spot = back_off_spot(1, xy, np.full(2, RADIUS), ways, np.zeros((0, 2)), np.zeros(0),
                         costmap, 4.0, 0.3, 0.8)
    assert spot is not None
    assert spot[1] >= 0.8 and spot[1] - 0.9 >= 2 * RADIUS + 0.3 - 1e-9


@pytest.mark.parametrize("field, value", [("standstill_time", 0.0), ("yield_time", -1.0),
                                          ("search_reach", 0.0), ("block_gap", -0.1),
                                          ("back_off_distance", 0.5),
                                          ("order_patience", 15.0), ("progress_angle", 0.0)])
def test_params_refuse_bad_values(field, value):
    with pytest.raises(InputError, match=field):
        WatchdogParams(**{field: value})


def test_a_scenario_with_a_bad_watchdog_field_is_refused_with_its_place():
    scenario = load_scenario(HOSPITAL,
                             overrides={"blocks.watchdog.params.standstill_time": -2.0})
    with pytest.raises(InputError, match=r"blocks\.watchdog\.params.*standstill_time"):
        resolve_block(scenario, "watchdog")


def test_the_paper_profile_turns_the_watchdog_off():
    scenario = load_scenario(HOSPITAL, overrides={"profile": "paper"})
    _, params = resolve_block(scenario, "watchdog")
    assert params.enabled is False


def _orders_for_robots_that_never_move(duration: float, states=(4.7, 0.0, 0.0, 0.0, 5.3,
                                                                  0.0, math.pi, 0.0),
                                       goals=((8.0, 0.0), (2.0, 0.0)), people=None):
    """The watchdog's orders for two robots in an open room that never move (whatever they
    are told), by default nose to nose, each with its goal behind the other (a goal None:
    no active target); ``people``: ``HumanStates`` standing there."""
    watchdog, context, simulator = _standing_robots(states, goals, people)
    simulator.AdvanceTo(duration)
    return watchdog.GetOutputPort("back_offs").Eval(simulator.get_context()).history


def _standing_robots(states, goals, people=None):
    """The watchdog of ``_orders_for_robots_that_never_move``, its context (robot states
    fixed) and a simulator of it, at 0 s."""
    obstacles = Obstacles((Box("south", (5.0, -4.1), (10.0, 0.2)),
                           Box("north", (5.0, 4.1), (10.0, 0.2))))
    watchdog = DeadlockWatchdog(NAMES, [RADIUS, RADIUS],
                                Costmap.from_obstacles(obstacles, (0.0, 10.0, -4.5, 4.5)),
                                rate_hz=2.0)
    context = watchdog.CreateDefaultContext()
    watchdog.GetInputPort("robot_state").FixValue(context, np.array(states))
    for name, goal in zip(NAMES, goals, strict=True):
        watchdog.GetInputPort(f"target_{name}").FixValue(
            context, WaypointTarget(name, goal is not None, goal, None, True))
    if people is not None:
        watchdog.GetInputPort("human_states").FixValue(context, people)
    return watchdog, context, Simulator(watchdog, context)


def test_a_missed_order_is_not_given_again():
    # Nobody moves: each order ends missed after yield_time, and the next standstill gets
    # the other robot first, then a robot's spot away from the one it missed.
    history = _orders_for_robots_that_never_move(duration=100.0)
    assert [order.robot for order in history[:3]] == ["r1", "r0", "r1"]
    assert math.dist(history[0].point, history[2].point) > WatchdogParams().progress_distance
    assert math.dist(history[1].point, history[3].point) > WatchdogParams().progress_distance


def test_an_order_whose_robot_stands_on_its_way_is_given_up_early():
    # Nobody moves: r1's order (at standstill_time) is given up order_patience later, a
    # miss, and the standstill it was to break, stalled since 0 s, gets its next order at
    # once: r0 (fewer misses); then r1 again, to a spot away from the one it missed.
    p = WatchdogParams()
    history = _orders_for_robots_that_never_move(duration=30.0)
    first, second, third = history[:3]
    assert (first.robot, second.robot, third.robot) == ("r1", "r0", "r1")
    assert first.issued == pytest.approx(p.standstill_time)
    assert second.issued - first.issued == pytest.approx(p.order_patience + 0.5)  # 2 Hz
    assert second.stalled_since == first.stalled_since == 0.0
    assert math.dist(first.point, third.point) > p.progress_distance


def test_a_pose_moves_on_only_when_its_robot_moves_or_turns():
    # A robot turning round to drive off to its spot makes headway before it moves.
    pose = next_pose(None, (0.0, 0.0, 3.1, 0.0), 1.0, 0.5, 0.5)
    assert pose == Pose((0.0, 0.0), 3.1, 1.0)
    assert next_pose(pose, (0.3, 0.0, -3.1, 0.0), 2.0, 0.5, 0.5) is pose  # 0.08 rad
    assert next_pose(pose, (0.0, 0.0, 2.5, 0.0), 2.0, 0.5, 0.5).since == 2.0
    assert next_pose(pose, (0.0, 0.6, 3.1, 0.0), 2.0, 0.5, 0.5).since == 2.0


@pytest.mark.parametrize("wall_y, way_out", [(1.1, False), (1.2, True), (1.4, True)])
def test_no_spot_past_a_blocker_it_would_have_to_slide_along(wall_y, way_out):
    # A 2.0 m corridor (walls' faces at +-1.0 m): r1 stands 0.6 m ahead of r0 on the axis
    # and will drive west through r0. Going round r1 with 0.3 m to it leaves r0's surface
    # less than PASS_WALL_GAP from the wall: no way out, so no spot. A 2.2 m corridor
    # leaves room to pass that way (the controller keeps both distances), a 2.6 m one
    # room to pass on FREE cells.
    obstacles = Obstacles((Box("south", (0.0, -wall_y), (20.0, 0.2)),
                           Box("north", (0.0, wall_y), (20.0, 0.2))))
    costmap = Costmap.from_obstacles(obstacles, (-10.0, 10.0, -1.6, 1.6))
    xy = np.array([[0.0, 0.0], [0.6, 0.0]])
    ways = [(np.array([[0.6, 0.0], [-5.0, 0.0]]), RADIUS)]
    spot = back_off_spot(0, xy, np.full(2, RADIUS), ways, np.zeros((0, 2)), np.zeros(0),
                         costmap, 4.0, 0.3, 0.8)
    assert (spot is not None and spot[0] > 0.6) if way_out else spot is None


@pytest.mark.parametrize("with_person", [True, False])
def test_a_robot_stalled_by_a_person_backs_off_the_persons_way(with_person):
    # r0 heads east to (8, 0) with a nurse standing 0.6 m ahead, waiting for it; r1 is far
    # off and idle. The nurse will walk on through where r0 stands: r0 steps off that line.
    nurse = HumanStates(("nurse",), frozen_array(np.array([[5.6, 0.0]])),
                        frozen_array(np.zeros((1, 2))), frozen_array(np.array([0.25])))
    history = _orders_for_robots_that_never_move(
        duration=20.0, states=(5.0, 0.0, 0.0, 0.0, 1.0, 3.0, 0.0, 0.0),
        goals=((8.0, 0.0), None), people=nurse if with_person else None)
    if not with_person:
        assert history == ()  # standing alone is no standstill to resolve
        return
    assert [(order.robot, order.blockers) for order in history] == [("r0", ("nurse",))]
    assert abs(history[0].point[1]) >= RADIUS + 0.25 + WatchdogParams().spot_clearance


def test_a_robot_is_never_sent_to_where_it_stands():
    # r1, idle, stands just behind r0 and already clear of r0's way east: the nearest spot
    # clear of it is where r1 stands, which makes no way; it is sent farther.
    history = _orders_for_robots_that_never_move(
        duration=20.0, states=(5.0, 0.0, 0.0, 0.0, 4.45, 0.55, 0.0, 0.0),
        goals=((8.0, 0.0), None))
    assert history[0].robot == "r1"
    assert math.dist(history[0].point, (4.45, 0.55)) > WatchdogParams().progress_distance


@pytest.mark.parametrize("y, cut_off, ordered", [(-3.45, False, True), (-2.0, False, False),
                                                 (-3.45, True, False)])
def test_a_robot_stalled_alone_by_a_wall_backs_off_clear_of_it(y, cut_off, ordered):
    # r0 heads east along the south wall (face at y = -4) and stands, nobody near; r1 is
    # far off and idle. 0.55 m from the wall (inside the controller's wall distance, as a
    # robot pushed round a corner) only the wall holds it: it is sent clear of walls. 2 m
    # from it nothing does: no order; nor for a robot cut off from messages (it stands
    # until they return).
    states = (5.0, y, 0.0, 0.0, 1.0, 3.0, 0.0, 0.0)
    watchdog, context, simulator = _standing_robots(states, ((8.0, y), None))
    if cut_off:
        outage = Outage(0, 0.0, math.inf, np.array(states, dtype=float).reshape(2, 4))
        watchdog.GetInputPort("disturbances").FixValue(context, Disturbances(outages=(outage,)))
    simulator.AdvanceTo(20.0)
    history = watchdog.GetOutputPort("back_offs").Eval(context).history
    if not ordered:
        assert history == ()
        return
    assert [(order.robot, order.blockers) for order in history] == [("r0", ())]
    assert history[0].point[1] + 4.0 >= WatchdogParams().wall_clearance
    assert math.dist(history[0].point, (5.0, y)) > WatchdogParams().progress_distance


def test_an_order_without_blockers_ends_when_its_robot_gets_there():
    # r0 stalled alone by the wall (as above) reaches its spot: it drives on at once, where
    # a robot making way for others stands yield_time there.
    watchdog, context, simulator = _standing_robots((5.0, -3.45, 0.0, 0.0, 1.0, 3.0, 0.0, 0.0),
                                                    ((8.0, -3.45), None))
    simulator.AdvanceTo(16.0)
    order = watchdog.GetOutputPort("back_offs").Eval(context).active[0]
    watchdog.GetInputPort("robot_state").FixValue(
        context, np.array([*order.point, 0.0, 0.0, 1.0, 3.0, 0.0, 0.0]))
    simulator.AdvanceTo(17.0)
    orders = watchdog.GetOutputPort("back_offs").Eval(context)
    assert orders.active == () and len(orders.history) == 1


@pytest.mark.parametrize("stood", [20.0, 30.0])
def test_with_no_spot_off_the_ways_a_stalled_robot_backs_off_along_its_corridor(stood):
    # Nose to nose in a 2 m corridor, each driving on through the other: every spot
    # within reach is on the other's way. Once they have stood twice standstill_time,
    # r1 (yielding first) backs off anyway, at least back_off_distance east, back along
    # the corridor it came by; before that, and on main for good, no order.
    obstacles = Obstacles((Box("south", (10.0, -1.1), (22.0, 0.2)),
                           Box("north", (10.0, 1.1), (22.0, 0.2))))
    bounds = (-1.0, 21.0, -1.5, 1.5)
    watchdog = DeadlockWatchdog(NAMES, [RADIUS, RADIUS],
                                Costmap.from_obstacles(obstacles, bounds), rate_hz=2.0)
    context = watchdog.CreateDefaultContext()
    states = np.array([[10.0, 0.0, 0.0, 0.0], [10.6, 0.0, math.pi, 0.0]])
    targets = [WaypointTarget("r0", True, (19.0, 0.0), None, True),
               WaypointTarget("r1", True, (1.0, 0.0), None, True)]
    now = 100.0
    anchors = [Anchor((float(x), float(y)), now - stood) for x, y in states[:, :2]]
    order = watchdog._order((0, 1), np.array([True, True]), anchors, states, targets,
                            context, now, ())
    if stood < 2 * WatchdogParams().standstill_time:
        assert order is None
    else:
        assert order.robot == "r1" and order.blockers == ("r0",)
        assert order.point[0] - 10.6 >= WatchdogParams().back_off_distance - 1e-9
        assert abs(order.point[1]) < 0.3
