"""Closed-loop tests of the CBF controller (and the go-to-goal baseline) with kinematic robots."""

import dataclasses
import math
import pathlib

import numpy as np
import pytest
from pydrake.common.value import Value
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder, LeafSystem
from pydrake.systems.primitives import ConstantValueSource, LogVectorOutput

from mrta_drake.control.cbf_params import CbfParams, CoordinationParams
from mrta_drake.control.cluster_cbf_controller import ClusterCbfController
from mrta_drake.control.controller_common import predict_states
from mrta_drake.control.go_to_goal_controller import GoToGoalController
from mrta_drake.control.nominal import NominalParams, nominal_control
from mrta_drake.control.wall_rays import SensingParams, WallRays
from mrta_drake.errors import InputError
from mrta_drake.payloads import PATH_OK, FleetPaths, HumanStates, RobotPath, frozen_array
from mrta_drake.results.summary import SLACK_TOLERANCE
from mrta_drake.robots.unicycle_robots import UnicycleRobots
from mrta_drake.world.obstacles import Box, Obstacles

ROOT = pathlib.Path(__file__).resolve().parents[2]
RADIUS = 0.22  # robot body radius, m
MODES = ["clusters", "decentralized", "centralized"]


class _Walker(LeafSystem):
    """One human walking at constant velocity from ``start`` (test source)."""

    def __init__(self, start, velocity):
        super().__init__()
        self.start, self.velocity = np.asarray(start, float), np.asarray(velocity, float)
        self.DeclareAbstractOutputPort("human_states", lambda: Value[object](HumanStates()),
                                       self._calc)

    def position(self, t):
        return self.start + self.velocity * t

    def _calc(self, context, output):
        output.set_value(HumanStates(
            ("h",), frozen_array(self.position(context.get_time()), shape=(1, 2)),
            frozen_array(self.velocity, shape=(1, 2)), frozen_array([0.25])))


def _run(starts, paths, obstacles, duration, params=None, walker=None, controller=None,
         priorities=None):
    """Simulate; returns robot states (T, N, 4) sampled at 20 Hz and the controller."""
    names = [f"r{i}" for i in range(len(starts))]
    builder = DiagramBuilder()
    robots = builder.AddSystem(UnicycleRobots(names, np.asarray(starts, dtype=float),
                                              rate_hz=20.0))
    if controller is None:
        controller = ClusterCbfController(names, obstacles, params, priorities, rate_hz=20.0)
    builder.AddSystem(controller)
    fleet = FleetPaths(tuple(RobotPath(name, PATH_OK, frozen_array(points))
                             for name, points in zip(names, paths, strict=True)))
    source = builder.AddSystem(ConstantValueSource(Value[object](fleet)))
    builder.Connect(source.get_output_port(), controller.GetInputPort("paths"))
    builder.Connect(robots.GetOutputPort("state"), controller.GetInputPort("robot_state"))
    builder.Connect(controller.GetOutputPort("commands"), robots.GetInputPort("commands"))
    if walker is not None:
        builder.AddSystem(walker)
        builder.Connect(walker.get_output_port(), controller.GetInputPort("human_states"))
    states = LogVectorOutput(robots.GetOutputPort("state"), builder, 0.05)
    commands = LogVectorOutput(controller.GetOutputPort("commands"), builder, 0.05)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    simulator.AdvanceTo(duration)
    context = simulator.get_context()
    log = states.FindLog(context)
    n = len(names)
    cmd = commands.FindLog(context).data().T.reshape(-1, n, 2)
    assert np.all(np.abs(cmd[:, :, 1]) <= 2.0 + 1e-9)
    assert np.all((cmd[:, :, 0] >= -0.3 - 1e-9) & (cmd[:, :, 0] <= 1.5 + 1e-9))
    telemetry = controller.GetOutputPort("telemetry").Eval(
        controller.GetMyContextFromRoot(context))
    return log.data().T.reshape(-1, n, 4), telemetry


def _arrival_times(states, goals, tolerance=0.1):
    near = np.linalg.norm(states[:, :, :2] - np.asarray(goals)[None], axis=2) <= tolerance
    settled = near & near[-1][None]  # and still there at the end
    return [0.05 * int(np.argmax(settled[:, i])) if settled[-1, i] else math.inf
            for i in range(states.shape[1])]


def _min_separation(states):
    n = states.shape[1]
    return min(np.linalg.norm(states[:, i, :2] - states[:, j, :2], axis=1).min()
               for i in range(n) for j in range(i + 1, n))


def _min_wall_distance(states, obstacles):
    return obstacles.signed_distance(states[:, :, :2].reshape(-1, 2)).min()


def _coordinated(mode: str, followers: str = "in_the_way") -> CbfParams:
    return CbfParams(coordination=CoordinationParams(mode=mode, followers=followers))


def _corridor(width=2.8, length=14.0):
    half, t = width / 2, 0.2
    return Obstacles((Box("north", (length / 2, half + t / 2), (length + 4, t)),
                      Box("south", (length / 2, -half - t / 2), (length + 4, t))))


@pytest.mark.parametrize("mode", MODES)
def test_head_on_swap_in_corridor(mode):
    obstacles = _corridor()
    starts = [[1.0, 0.0, 0.0], [13.0, 0.0, math.pi]]
    goals = [[13.0, 0.0], [1.0, 0.0]]
    states, telemetry = _run(starts, [[s[:2], g] for s, g in zip(starts, goals, strict=True)],
                             obstacles, 34.0, _coordinated(mode))
    assert max(_arrival_times(states, goals)) < 34.0
    assert _min_separation(states) >= 2 * RADIUS
    assert _min_wall_distance(states, obstacles) >= RADIUS
    np.testing.assert_allclose(states[-1, :, :2], goals, atol=0.05)  # at rest on the end
    assert np.all(np.abs(states[-1, :, 3]) < 1e-3)
    assert telemetry.failures == 0


def _crossing():
    half, size = 1.4, 6.0
    c = half + size / 2
    return Obstacles(tuple(Box(f"block{i}{j}", (i * c, j * c), (size, size))
                           for i in (-1, 1) for j in (-1, 1)))


@pytest.mark.parametrize("mode,bound", [("clusters", 55.0), ("decentralized", 22.0),
                                        ("centralized", 22.0)])
def test_four_robots_cross_an_intersection(mode, bound):
    obstacles = _crossing()
    starts = [[-6.0, 0.0, 0.0], [6.0, 0.0, math.pi], [0.0, -6.0, math.pi / 2],
              [0.0, 6.0, -math.pi / 2]]
    goals = [[6.0, 0.0], [-6.0, 0.0], [0.0, 6.0], [0.0, -6.0]]
    states, telemetry = _run(starts, [[s[:2], g] for s, g in zip(starts, goals, strict=True)],
                             obstacles, bound, _coordinated(mode))
    assert max(_arrival_times(states, goals)) < bound
    assert _min_separation(states) >= 2 * RADIUS
    assert _min_wall_distance(states, obstacles) >= RADIUS
    assert telemetry.failures == 0


def _room_with_door(gap=1.4):
    # A wall at x = 0 with a doorway |y| < gap / 2 between a corridor (x < 0) and a room.
    h, span = gap / 2, 6.0
    return Obstacles((Box("jamb_n", (0.0, h + span / 2), (0.2, span)),
                      Box("jamb_s", (0.0, -h - span / 2), (0.2, span)),
                      Box("corridor_n", (-5.0, 3.0), (10.0, 0.2)),
                      Box("corridor_s", (-5.0, -3.0), (10.0, 0.2))))


@pytest.mark.parametrize("mode", ["clusters", "centralized"])
def test_robot_goes_in_through_a_doorway_while_another_comes_out(mode):
    # Decentralized CBFs (no coordination) deadlock here: the two stop nose to nose in the
    # doorway. The cluster leader (robot 0, going in) backs the other one out of the way.
    obstacles = _room_with_door()
    starts = [[-4.0, 0.0, 0.0], [3.0, 0.0, math.pi]]
    paths = [[(-4.0, 0.0), (-1.0, 0.0), (1.0, 0.0), (3.5, 1.0)],
             [(3.0, 0.0), (1.0, 0.0), (-1.0, 0.0), (-4.0, -1.0)]]
    goals = [p[-1] for p in paths]
    states, telemetry = _run(starts, paths, obstacles, 28.0, _coordinated(mode))
    assert max(_arrival_times(states, goals)) < 28.0
    assert _min_separation(states) >= 2 * RADIUS
    assert _min_wall_distance(states, obstacles) >= RADIUS


def test_thin_post_between_two_rays_is_kept_off_the_robot_by_the_contact_guard():
    # A 4 cm post 0.1 m beside a path at 15 degrees: it lies between the wall rays (30
    # degrees apart) until the robot is nearly on it (rays alone: the robot's centre comes
    # within 0.244 m of it); the closest wall point keeps it at least the contact guard
    # (SafetyDistances.wall_contact) away, and the robot still gets by.
    heading = np.radians(15.0)
    along = np.array([np.cos(heading), np.sin(heading)])
    side = np.array([-along[1], along[0]])
    post = Obstacles((Box("post", tuple(0.12 * side), (0.04, 0.04)),))  # near face 0.1 m off
    path = [tuple(-4.0 * along), tuple(4.0 * along)]
    states, _ = _run([[*(-4.0 * along), heading]], [path], post, 15.0)
    clearance = post.signed_distance(states[:, 0, :2]).min()
    assert clearance >= CbfParams().safety_distances.wall_contact - 0.005
    assert _arrival_times(states, [path[-1]])[0] < 15.0


def _divider():
    # A 0.1 m thick wall along y = 0 from x = -3 to its end at x = 0.
    return Obstacles((Box("divider", (-1.5, 0.0), (3.0, 0.1)),))


def _unseen_by_rays(position, obstacles, reach):
    """Whether none of the wall rays of a robot at ``position`` sees an obstacle within
    ``reach`` m."""
    hits, mask = WallRays(obstacles, SensingParams(closest_point_range=0.0))(
        np.array([[*position, 0.0, 0.0]]))
    return not np.any(mask[0] & (np.linalg.norm(hits[0] - position, axis=1) < reach))


def test_a_robot_rounding_a_thin_wall_end_that_no_ray_sees_keeps_off_it():
    # Driving at the divider's end from the north-east (as in the Open-RMF office demo),
    # the world-frame rays at 180 and 210 degrees pass above it and east of it; the path
    # rounds the end 0.125 m off its corner. Rays alone: the robot's centre comes within
    # 0.158 m of the wall at 0.55 m/s (a contact); the closest point keeps it off.
    divider, path = _divider(), [(1.8, 0.85), (0.3, 0.1), (-0.1, -0.35), (-2.0, -0.9)]
    assert _unseen_by_rays((0.6, 0.25), divider, 1.0)
    states, _ = _run([[1.8, 0.85, math.atan2(-0.75, -1.5)]], [path], divider, 12.0)
    assert _min_wall_distance(states, divider) >= RADIUS + 0.02
    assert _arrival_times(states, [path[-1]])[0] < 12.0


def test_a_fast_robot_rounding_a_thin_wall_end_brakes_in_time():
    # The same rounding from 3 m further out: the robot meets the end at full speed, where
    # a fixed guard range (0.4 m) leaves too little room to brake; the range grows with the
    # speed towards the point (SensingParams.closest_point_braking).
    divider, path = _divider(), [(4.5, 2.2), (0.3, 0.1), (-0.1, -0.35), (-2.0, -0.9)]
    states, _ = _run([[4.5, 2.2, math.atan2(-2.1, -4.2)]], [path], divider, 16.0)
    # (A fixed range: the centre comes within 0.240 m of the wall at 0.75 m/s; with the
    # braking room, 0.376 m.)
    assert states[:, 0, 3].max() > 0.7  # at speed on the way in
    assert _min_wall_distance(states, divider) >= CbfParams().safety_distances.wall_contact - 0.005
    assert _arrival_times(states, [path[-1]])[0] < 16.0


def test_a_robot_backing_off_towards_a_thin_wall_end_that_no_ray_sees_keeps_off_it():
    # A robot parked just south of the divider's line, 0.45 m east of its end, backs off
    # from a leader whose path runs through its spot. Rays alone: it backs into the end
    # (centre 0.199 m from it); the closest point stops it short.
    divider = _divider()
    start, path = (0.45, -0.12), [(3.0, -0.1), (0.3, -0.1), (0.3, -1.5)]
    assert _unseen_by_rays(start, divider, 1.0)
    states, _ = _run([[*start, 0.0], [3.0, -0.1, math.pi]], [[start, start], path], divider,
                     8.0, priorities=[1.0, 0.0])
    assert states[:, 0, 3].min() < -0.1  # it did back off
    assert _min_wall_distance(states[:, :1], divider) >= RADIUS + 0.02


def test_path_cutting_a_corner_is_followed_around_it():
    # The path passes 0.57 m from the corner of a block, inside the 0.6 m safety distance:
    # the robot stops nose to the corner; a standing unicycle's barrier rows do not involve
    # its yaw rate, so it must turn along the corner itself (steer_blocked) to get on.
    block = Obstacles((Box("block", (2.0, -2.0), (4.0, 4.0)),))  # corner at (0, 0)
    path = [(-3.0, 0.3), (-0.3, 0.3), (-0.3, -1.0), (-1.5, -3.0)]
    states, _ = _run([[-3.0, 0.3, 0.0]], [path], block, 25.0)
    assert _arrival_times(states, [path[-1]])[0] < 25.0
    assert _min_wall_distance(states, block) >= RADIUS
    # Without corner steering (the paper) it stays nosed into the corner.
    params = CbfParams(nominal=NominalParams(corner_steering=False))
    states, _ = _run([[-3.0, 0.3, 0.0]], [path], block, 25.0, params)
    assert np.isinf(_arrival_times(states, [path[-1]])[0])
    assert _min_wall_distance(states, block) >= RADIUS


def test_heading_speed_factor_scales_the_desired_speed_by_cos_heading_error():
    # Heading error 0.5 rad (inside the gate), standing: a = k_v v_des, v_des = k_x x 0.5 m.
    path = RobotPath("r", PATH_OK, frozen_array([[0.0, 0.0], [5.0, 0.0]]))
    state = np.array([0.0, 0.0, 0.5, 0.0])
    plain = nominal_control(state, path, NominalParams())
    scaled = nominal_control(state, path, NominalParams(heading_speed_factor=True))
    assert scaled[0] == pytest.approx(plain[0] * math.cos(0.5))
    assert scaled[1] == plain[1]


def test_without_the_braking_profile_the_desired_speed_is_k_x_dist_to_the_end():
    # 0.4 m before the end of a stop-at-end path at 1 m/s, the end is the local goal: the
    # braking profile sets the desired speed sqrt(2 brake_accel 0.4 m) and feeds its
    # deceleration forward; the paper's nominal asks for k_x 0.4 m alone.
    path = RobotPath("r", PATH_OK, frozen_array([[0.0, 0.0], [0.4, 0.0]]), stop_at_end=True)
    state = np.array([0.0, 0.0, 0.0, 1.0])
    params = NominalParams()
    braked = nominal_control(state, path, params)
    plain = nominal_control(state, path, NominalParams(braking_profile=False))
    v_stop = math.sqrt(2.0 * params.brake_accel * 0.4)
    assert braked[0] == pytest.approx(params.k_v * (v_stop - 1.0) - params.brake_accel)
    assert plain[0] == pytest.approx(params.k_v * (params.k_x * 0.4 - 1.0))


@pytest.mark.parametrize("hands_on", [True, False])
def test_a_stalled_leader_hands_the_lead_on_only_with_the_switch(hands_on):
    # Two robots 1 m apart in one cluster, both with somewhere to go; robot 0 leads by
    # priority and has stood 3 s (the stall time) as the blocked leader.
    params = CbfParams(coordination=CoordinationParams(stalled_leader_hands_on=hands_on))
    controller = ClusterCbfController(["r0", "r1"], None, params, rate_hz=20.0)
    states = np.array([[0.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]])
    fleet = FleetPaths(tuple(RobotPath(name, PATH_OK, frozen_array([[x, 0.0], [x, 5.0]]))
                             for name, x in (("r0", 0.0), ("r1", 1.0))))
    plan = controller.plan(states, fleet, stall_times=np.array([3.0, 0.0]))
    assert plan.clusters == (((1, 0),) if hands_on else ((0, 1),))


@pytest.mark.parametrize("start,velocity", [((5.0, -5.0), (0.0, 1.0)),
                                            ((5.0, -3.0), (0.0, 0.5)),
                                            ((4.0, 2.0), (0.0, -0.8))])
def test_human_crossing_the_path_is_kept_at_the_safety_distance(start, velocity):
    walker = _Walker(start, velocity)
    states, _ = _run([[1.0, 0.0, 0.0]], [[(1.0, 0.0), (10.0, 0.0)]], None, 16.0,
                     walker=walker)
    t = 0.05 * np.arange(len(states))
    human = walker.position(t[:, None])
    distance = np.linalg.norm(states[:, 0, :2] - human, axis=1)
    assert distance.min() >= 0.6 - 0.02
    assert _arrival_times(states, [[10.0, 0.0]])[0] < 16.0


def test_human_walking_into_the_robot_makes_it_back_off():
    # A walker at 1 m/s straight at the robot: the robot cannot keep 0.6 m (it reverses at
    # most 0.3 m/s), but it stops and backs off instead of driving on.
    walker = _Walker((9.0, 0.0), (-1.0, 0.0))
    states, _ = _run([[1.0, 0.0, 0.0]], [[(1.0, 0.0), (12.0, 0.0)]], None, 8.0,
                     walker=walker)
    t = 0.05 * np.arange(len(states))
    distance = np.linalg.norm(states[:, 0, :2] - walker.position(t[:, None]), axis=1)
    closing = (distance < 1.0) & (np.arange(len(distance)) <= np.argmin(distance))
    assert closing.any() and np.all(states[closing, 0, 3] <= 0.0)


def test_solver_failure_brakes_every_robot_of_the_qp_and_is_counted():
    controller = ClusterCbfController(["a", "b"], rate_hz=20.0)
    states = np.array([[0.0, 0.0, 0.0, 1.0], [1.0, 0.0, 0.0, 0.02]])
    paths = FleetPaths(tuple(RobotPath(n, PATH_OK, frozen_array([[0.0, 0.0], [9.0, 0.0]]))
                             for n in "ab"))
    broken = HumanStates(("h",), frozen_array([[np.nan, 0.0]]), frozen_array([[0.0, 0.0]]),
                         frozen_array([0.25]))
    u, telemetry = controller.control(0.0, states, paths, broken)
    assert telemetry.failures == 2
    # Full braking, but never below the reverse speed limit -0.3 m/s after one 0.05 s step.
    np.testing.assert_allclose(u, [[-1.0, 0.0], [-1.0, 0.0]])
    u, telemetry = controller.control(0.0, states, paths)
    assert telemetry.failures == 0 and telemetry.clusters == ((0, 1),)


def test_fixed_step_commands_after_a_late_start():
    # The original derived dt from wall-clock gaps; here dt is 1 / rate whatever the time.
    names = ["a"]
    builder = DiagramBuilder()
    controller = builder.AddSystem(ClusterCbfController(names, rate_hz=20.0))
    robots = builder.AddSystem(UnicycleRobots(names, np.array([[0.0, 0.0, 0.0]]), rate_hz=20.0))
    fleet = FleetPaths((RobotPath("a", PATH_OK, frozen_array([[0.0, 0.0], [9.0, 0.0]])),))
    source = builder.AddSystem(ConstantValueSource(Value[object](fleet)))
    builder.Connect(source.get_output_port(), controller.GetInputPort("paths"))
    builder.Connect(robots.GetOutputPort("state"), controller.GetInputPort("robot_state"))
    builder.Connect(controller.GetOutputPort("commands"), robots.GetInputPort("commands"))
    simulator = Simulator(builder.Build())
    simulator.get_mutable_context().SetTime(1000.0)
    simulator.AdvanceTo(1000.01)
    context = controller.GetMyContextFromRoot(simulator.get_context())
    v, omega = controller.GetOutputPort("commands").Eval(context)
    assert v == pytest.approx(1.0 * 0.05)  # one step at the acceleration limit
    telemetry = controller.GetOutputPort("telemetry").Eval(context)
    assert telemetry.time == pytest.approx(1000.0) and telemetry.clusters == ((0,),)


def test_go_to_goal_baseline_reaches_goals_but_collides_head_on():
    obstacles = _corridor()
    starts = [[1.0, 0.0, 0.0], [13.0, 0.0, math.pi]]
    goals = [[13.0, 0.0], [1.0, 0.0]]
    baseline = GoToGoalController(["r0", "r1"], obstacles, rate_hz=20.0)
    states, telemetry = _run(starts, [[s[:2], g] for s, g in zip(starts, goals, strict=True)],
                             obstacles, 20.0, controller=baseline)
    assert max(_arrival_times(states, goals)) < 20.0  # kinematic robots pass through
    assert _min_separation(states) < 2 * RADIUS
    assert telemetry.min_barrier_robot > 0.0 and telemetry.clusters == ()


FLOOR_PLAN = ROOT / "models/hospital/floor_plan.yaml"


@pytest.mark.skipif(not FLOOR_PLAN.is_file(), reason="hospital floor plan not written yet")
def test_head_on_swap_in_the_hospital_east_corridor():
    from mrta_drake.world.floor_plan import load_floor_plan

    obstacles = load_floor_plan(FLOOR_PLAN).obstacles
    x = 5.0  # east corridor, x 3.6 .. 6.4
    starts = [[x, -2.0, -math.pi / 2], [x, -14.0, math.pi / 2]]
    goals = [[x, -14.0], [x, -2.0]]
    states, telemetry = _run(starts, [[s[:2], g] for s, g in zip(starts, goals, strict=True)],
                             obstacles, 34.0)
    assert max(_arrival_times(states, goals)) < 34.0
    assert _min_separation(states) >= 2 * RADIUS
    assert _min_wall_distance(states, obstacles) >= RADIUS


def test_the_telemetry_port_gives_the_tick_s_telemetry():
    """The telemetry is kept as numbers in the state; the port turns them back into the very
    telemetry the tick made, clusters (leader first) included."""
    n = 5
    controller = ClusterCbfController([f"robot{i}" for i in range(n)], rate_hz=20.0)
    simulator = Simulator(controller)
    context = simulator.get_mutable_context()
    starts = [[0.0, 0.0, 0.0, 0.0], [9.0, 0.0, 0.0, 0.0], [1.0, 0.0, math.pi, 0.0],
              [9.0, 2.0, 0.0, 0.0], [30.0, 0.0, 0.0, 0.0]]
    controller.get_input_port(0).FixValue(context, np.ravel(starts))
    paths = FleetPaths(tuple(RobotPath(f"robot{i}", PATH_OK, frozen_array([s[:2], [s[0], 5.0]]))
                             for i, s in enumerate(starts)))
    controller.get_input_port(1).FixValue(context, Value[object](paths))
    simulator.AdvanceTo(0.01)  # one tick, at t = 0
    telemetry = controller.GetOutputPort("telemetry").Eval(context)
    _, expected = controller.control(0.0, starts, paths)
    assert telemetry.clusters == ((0, 2), (1, 3), (4,))
    assert telemetry == expected


def test_each_solver_call_is_in_the_telemetry_with_its_size_and_time():
    # Two robots driving at each other 1 m apart (one cluster: one QP of 2) and one alone
    # nosing into a wall 0.7 m ahead (a QP of 1): both QPs need the solver.
    wall = Obstacles((Box("wall", (20.7, 0.0), (0.2, 4.0)),))
    n = 3
    controller = ClusterCbfController([f"robot{i}" for i in range(n)], wall, rate_hz=20.0)
    simulator = Simulator(controller)
    context = simulator.get_mutable_context()
    starts = [[0.0, 0.0, 0.0, 0.8], [1.0, 0.0, math.pi, 0.8], [19.9, 0.0, 0.0, 0.8]]
    ends = [[5.0, 0.0], [-4.0, 0.0], [25.0, 0.0]]
    controller.get_input_port(0).FixValue(context, np.ravel(starts))
    paths = FleetPaths(tuple(RobotPath(f"robot{i}", PATH_OK, frozen_array([s[:2], e]))
                             for i, (s, e) in enumerate(zip(starts, ends, strict=True))))
    controller.get_input_port(1).FixValue(context, Value[object](paths))
    simulator.AdvanceTo(0.01)
    telemetry = controller.GetOutputPort("telemetry").Eval(context)
    assert sorted(size for size, _ in telemetry.qp_calls) == [1, 2]
    assert all(seconds > 0.0 for _, seconds in telemetry.qp_calls)
    assert telemetry.solve_time == pytest.approx(sum(t for _, t in telemetry.qp_calls))


def _slowed(params, states, paths):
    """Per robot, whether one tick's nominal input is the slow-down nominal."""
    names = [f"r{i}" for i in range(len(states))]
    fleet = FleetPaths(tuple(RobotPath(name, PATH_OK, frozen_array(points))
                             for name, points in zip(names, paths, strict=True)))
    controller = ClusterCbfController(names, params=params, rate_hz=20.0)
    plan = controller.plan(np.asarray(states, float), fleet)
    assert len(plan.clusters) == 1 and plan.clusters[0][0] == 0  # robot 0 leads
    return [bool(u[0] <= 0.0 and u[1] == 0.0) for u in plan.u_nominal]


def test_only_followers_in_the_way_of_a_robot_ranked_above_get_the_slow_down_nominal():
    lane = [(0.0, 0.0), (8.0, 0.0)]  # robot 0 (the leader) drives east along y = 0
    ahead_of_it = [[0.0, 0.0, 0.0, 0.0], [2.5, 0.6, math.pi / 2, 0.0]]
    beside_it = [[0.0, 0.0, 0.0, 0.0], [2.5, 2.5, 0.0, 0.0]]
    crossing_it = [[0.0, 0.0, 0.0, 0.0], [0.5, 2.5, -math.pi / 2, 0.0]]
    on_it = [lane, [(2.5, 0.6), (2.5, 6.0)]]
    beside = [lane, [(2.5, 2.5), (9.0, 2.5)]]
    across = [lane, [(0.5, 2.5), (0.5, -4.0)]]  # passes 0.5 m from robot 0
    default = CbfParams()
    assert _slowed(default, ahead_of_it, on_it) == [False, True]
    assert _slowed(default, crossing_it, across) == [False, True]
    assert _slowed(default, beside_it, beside) == [False, False]
    # One behind the other on the same way: the barriers keep the gap, nobody waits.
    behind_it = [[2.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0]]
    ahead_on_it = [[0.0, 0.0, 0.0, 0.0], [2.0, 0.0, 0.0, 0.0]]
    assert _slowed(default, behind_it, [[(2.0, 0.0), (9.0, 0.0)], lane]) == [False, False]
    assert _slowed(default, ahead_on_it, [lane, [(2.0, 0.0), (9.0, 0.0)]]) == [False, False]
    head_on = [[0.0, 0.0, 0.0, 0.0], [2.5, 0.0, math.pi, 0.0]]
    assert _slowed(default, head_on, [lane, [(2.5, 0.0), (-6.0, 0.0)]]) == [False, True]
    # The paper's rule: every follower slows down.
    assert _slowed(_coordinated("clusters", "all"), beside_it, beside) == [False, True]
    with pytest.raises(ValueError, match="followers"):
        CoordinationParams(followers="none")


def test_robots_head_on_on_the_two_lanes_of_a_corridor_pass_with_a_head_on_clearance():
    # Lanes 0.9 m apart (LaneParams.offset 0.45 each side of the centre line): with
    # head_on_clearance 0.75 m the robot driving west on the other lane passes the leader.
    lane = [(0.0, 0.0), (8.0, 0.0)]  # robot 0 (the leader) drives east along y = 0
    passing = CbfParams(coordination=CoordinationParams(head_on_clearance=0.75))
    other_lane = [[0.0, 0.0, 0.0, 0.0], [2.5, 0.9, math.pi, 0.0]]
    west = [lane, [(2.5, 0.9), (-6.0, 0.9)]]
    assert _slowed(passing, other_lane, west) == [False, False]
    assert _slowed(CbfParams(), other_lane, west) == [False, True]  # by default: in the way
    # Nearer than head_on_clearance to the leader's lane (0.6 m): in its way.
    near_lane = [[0.0, 0.0, 0.0, 0.0], [2.5, 0.6, math.pi, 0.0]]
    assert _slowed(passing, near_lane, [lane, [(2.5, 0.6), (-6.0, 0.6)]]) == [False, True]
    # On the leader's line ahead of it, as without head_on_clearance: in its way from 1 m
    # past the horizon (here 2 m, the pair within the 4 m cluster radius) on.
    short = CoordinationParams(yield_horizon=2.0)
    for x, slowed in ((2.95, True), (3.05, False)):
        states = [[0.0, 0.0, 0.0, 0.0], [x, 0.0, math.pi, 0.0]]
        line = [lane, [(x, 0.0), (-6.0, 0.0)]]
        assert _slowed(CbfParams(coordination=short), states, line) == [False, slowed]
        assert _slowed(CbfParams(coordination=dataclasses.replace(
            short, head_on_clearance=0.75)), states, line) == [False, slowed]
    # Crossing 0.9 m ahead of the leader (not head on): still in its way.
    crossing = [[0.0, 0.0, 0.0, 0.0], [0.9, 2.5, -math.pi / 2, 0.0]]
    assert _slowed(passing, crossing, [lane, [(0.9, 2.5), (0.9, -4.0)]]) == [False, True]
    # Turning across the leader's lane 1.7 m on, 0.8 m ahead of it: in its way, though
    # head on at first.
    assert _slowed(passing, other_lane, [lane, [(2.5, 0.9), (0.8, 0.9), (0.8, -4.0)]]) == [
        False, True]
    with pytest.raises(InputError, match="head_on_clearance: must be at most yield_clearance"):
        CoordinationParams(head_on_clearance=1.2)


def test_a_follower_out_of_the_leaders_way_drives_on():
    # Two robots on parallel lanes 2.5 m apart are one cluster all the way: under the
    # paper's rule the follower waits until the leader is 4 m away (and then trails it).
    starts = [[0.0, 0.0, 0.0], [0.0, 2.5, 0.0]]
    paths = [[(0.0, 0.0), (8.0, 0.0)], [(0.0, 2.5), (8.0, 2.5)]]
    goals = [p[-1] for p in paths]
    times = {}
    for rule in ("in_the_way", "all"):
        states, _ = _run(starts, paths, None, 20.0, _coordinated("clusters", rule))
        times[rule] = _arrival_times(states, goals)
    assert abs(times["in_the_way"][1] - times["in_the_way"][0]) < 0.5
    assert times["all"][1] - times["all"][0] > 3.0


def test_a_body_standing_right_of_the_lane_is_passed_on_its_left():
    # A robot standing 0.4 m right of the lane, 0.43 m from a wall (like one at a queue
    # slot by the corridor wall): passing it on the right would squeeze between it and the
    # wall, where there is no room.
    params = NominalParams()
    path = RobotPath("r", PATH_OK, frozen_array([(0.0, 0.0), (0.0, 8.0)]))  # north
    state = [0.0, 0.0, math.pi / 2, 0.75]

    def turn(x, speed):  # the yaw rate with a body at (x, 1.5) moving at speed
        return nominal_control(state, path, params, bodies=[(x, 1.5, speed)])[1]

    assert turn(0.4, 0.0) > 0.1  # turns left (west), away from the body
    assert turn(0.1, 0.0) < -0.1  # a body near the lane's middle: passed on the right
    assert turn(0.4, 0.5) < -0.1  # oncoming traffic: passed on the right
    assert nominal_control(state, path, params, bodies=[(0.4, 1.5)])[1] < -0.1  # moving


def test_a_robot_standing_inside_the_wall_distance_gets_away_instead_of_chattering():
    # Issue 15 (seed 105 of the soak), rebuilt small: robot a stands 0.55 m from a wall
    # (inside its 0.6 m safety distance) with the wall nearly abeam, rolling back at
    # 0.023 m/s, robot b parked 1.6 m behind it (so they are one QP). The wall row cannot
    # be met; when the QP chose a's yaw rate, whose only effect is through v omega, it
    # turned a at full rate one way or the other as v changed sign, and a stood still,
    # flipping between (a, omega) = (1, -2) and (-1, 2) every tick, for as long as it ran.
    normal = np.array([-0.5, math.sqrt(3) / 2])  # the wall's face, towards the robots
    wall = Obstacles((Box("wall", tuple(-0.654 * normal), (12.0, 0.2), yaw=math.pi / 6),))
    goal = 4.0 * np.array([0.374, 0.927])  # a's path leaves the wall at 52 degrees
    states = np.array([[0.0, 0.0, 0.431, 0.023], [-1.538, 0.388, 2.625, 0.0]])
    controller = ClusterCbfController(("a", "b"), wall, rate_hz=20.0)
    paths = FleetPaths((RobotPath("a", PATH_OK, frozen_array([[0.0, 0.0], goal])),
                        RobotPath("b", PATH_OK, frozen_array([states[1, :2]] * 2))))
    slack_ticks, yaw_rates, trace = 0, [], [states]
    for tick in range(200):  # 10 s
        u, telemetry = controller.control(0.05 * tick, states, paths)
        slack_ticks += telemetry.max_slack > SLACK_TOLERANCE
        yaw_rates.append(u[0, 1])
        states = predict_states(states, np.c_[states[:, 3] + 0.05 * u[:, 0], u[:, 1]],
                                controller.params.nominal, 0.05)
        trace.append(states)
    yaw_rates = np.array(yaw_rates)
    reversals = yaw_rates[1:] * yaw_rates[:-1] < -1.0  # full rate one way, then the other
    assert not np.any(reversals[1:] & reversals[:-1])  # never back and forth, tick after tick
    assert slack_ticks <= 10
    assert np.linalg.norm(states[0, :2] - goal) < 0.1
    assert _min_wall_distance(np.array(trace), wall) >= RADIUS


def test_a_person_in_the_lane_is_passed_where_there_is_room():
    # Issue 15 (seed 105 of the soak, an earlier controller), rebuilt small: a robot stands
    # at a corridor's corner, the corner 0.6 m from it (its wall safety distance) at -60
    # degrees, and a person shuffles in its lane 1.1 m ahead (0.12 m/s), waiting for it.
    # Passing on the right, as the passing rule says, heads into the corner's barrier: the
    # robot stood there for good, turning to and fro. There is room on the left.
    corner = np.array([0.3, -0.52])
    wall = Obstacles((Box("south", (corner[0] + 4.0, corner[1] - 0.5), (8.0, 1.0)),
                      Box("north", (4.0, 3.1), (10.0, 0.2))))
    path = RobotPath("a", PATH_OK, frozen_array([[0.0, 0.0], [8.0, 0.5]]))
    person = HumanStates(("p",), frozen_array([[1.12, 0.0]]), frozen_array([[0.12, -0.02]]),
                         frozen_array([0.25]))
    controller = ClusterCbfController(("a",), wall, rate_hz=20.0)
    states = np.array([[0.0, 0.0, -0.17, 0.0]])
    for tick in range(300):  # 15 s
        u, _ = controller.control(0.05 * tick, states, FleetPaths((path,)), person)
        states = predict_states(states, np.c_[states[:, 3] + 0.05 * u[:, 0], u[:, 1]],
                                controller.params.nominal, 0.05)
    assert states[0, 0] > 2.5  # past the person


def test_the_passing_side_has_room():
    params = NominalParams()
    path = RobotPath("r", PATH_OK, frozen_array([(0.0, 0.0), (8.0, 0.0)]))  # east
    state = [0.0, 0.0, 0.0, 0.0]
    person = [(1.1, 0.0, 0.1)]
    walls_right = [(x, -0.6) for x in np.arange(-1.0, 3.0, 0.5)]
    walls_both = walls_right + [(x, 0.6) for x in np.arange(-1.0, 3.0, 0.5)]
    assert nominal_control(state, path, params, bodies=person)[1] < -0.1  # right, by rule
    assert nominal_control(state, path, params, bodies=person, walls=walls_right)[1] > 0.1
    # No more room on the left than on the right: the rule stands.
    assert nominal_control(state, path, params, bodies=person, walls=walls_both)[1] < -0.1


def test_a_robot_sent_aside_leads_its_cluster():
    # Issue 15 (seeds 103 and 106 of the soak): the watchdog sent a robot aside, but in its
    # cluster it was a follower in the leader's way, got the slow-down and stood, the
    # leader standing behind it, for as long as the order lasted (three orders in a row).
    states = np.array([[0.0, 0.0, 0.0, 0.0], [0.9, 0.0, math.pi, 0.0]])
    controller = ClusterCbfController(("a", "b"), Obstacles(()), rate_hz=20.0)

    def paths(yielding):
        return FleetPaths((RobotPath("a", PATH_OK, frozen_array([[0.0, 0.0], [4.0, 0.0]])),
                           RobotPath("b", PATH_OK, frozen_array([[0.9, 0.0], [0.9, 1.5]]),
                                     yielding=yielding)))

    u, _ = controller.control(0.0, states, paths(False))
    assert u[1, 0] <= 0.0  # b, in a's way, waits as a follower
    plan = controller.plan(states, paths(True))
    assert plan.clusters == ((1, 0),)  # b leads
    u, _ = controller.control(0.0, states, paths(True))
    assert abs(u[1, 1]) > 0.5 or u[1, 0] > 0.0  # b turns or drives off to its spot
    # b stood as a blocked leader before the order (its stall time past stall_time): that
    # lost lead does not keep it a follower (office seed 1: a robot sent aside stood 13 s).
    stall_times = np.array([0.0, 2 * controller.params.coordination.stall_time])
    assert controller.plan(states, paths(True), stall_times=stall_times).clusters == ((1, 0),)
