"""The physics robot backend: robots as bodies in a stepped plant, contacts, swapping."""

import dataclasses
import pathlib

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

from mrta_drake import load_scenario, simulate
from mrta_drake.errors import InputError
from mrta_drake.payloads import Relocations
from mrta_drake.robots.physics_robots import PhysicsRobotParams, PhysicsRobots
from mrta_drake.robots.plant_stepping import add_plant_stepping
from mrta_drake.stack.blocks import replace_block
from mrta_drake.stack.diagram import build_diagram
from mrta_drake.world.floor_plan import FloorPlan
from mrta_drake.world.obstacles import Box, Obstacles
from mrta_drake.world.plant import Body, PlantPhysics, build_world

ROOT = pathlib.Path(__file__).resolve().parents[2]
RADIUS = 0.22  # m
WALL_FACE = 1.9  # m, the west face of the test wall (x)


def _world(robot_poses, commands, human_poses=(), human_targets=None, relocations=False):
    """A 6 m x 6 m floor with one wall (x from 1.9 to 2.1 m), robots ``r0``, ``r1``, ...
    under constant ``commands`` (N, 2) and people ``h0``, ... moved to ``human_targets``;
    default physics parameters; with ``relocations``, the robots block's relocations input
    (left for the test to fix)."""
    params = PhysicsRobotParams()
    floor_plan = FloorPlan("test", (-3.0, 3.0, -3.0, 3.0), 2.5, Obstacles(
        (Box("wall", (WALL_FACE + 0.1, 0.0), (0.2, 4.0), height=2.5),)))
    builder = DiagramBuilder()
    world = build_world(
        builder, floor_plan,
        robots=[Body(f"r{k}", RADIUS, tuple(p)) for k, p in enumerate(robot_poses)],
        humans=[Body(f"h{k}", 0.25, tuple(p)) for k, p in enumerate(human_poses)],
        physics=PlantPhysics(params.time_step, params.mass, params.collision_shape))
    robots = builder.AddSystem(PhysicsRobots(world.plant, world.robots, params,
                                             relocations=relocations))
    source = builder.AddSystem(ConstantVectorSource(np.ravel(commands)))
    builder.Connect(source.get_output_port(), robots.GetInputPort("commands"))
    human_positions = None
    if human_poses:
        targets = builder.AddSystem(ConstantVectorSource(np.ravel(human_targets)))
        human_positions = targets.get_output_port()
    contacts = add_plant_stepping(builder, world, robots, human_positions)
    simulator = Simulator(builder.Build())
    return simulator, world, robots, contacts


def _drive(simulator, robots, duration: float) -> np.ndarray:
    """Robot states (steps, N, 4) after every plant step up to ``duration``."""
    step = PhysicsRobotParams().time_step
    context = robots.GetMyContextFromRoot(simulator.get_context())
    states = []
    for k in range(1, round(duration / step) + 1):
        simulator.AdvanceTo(k * step)
        states.append(robots.GetOutputPort("state").Eval(context).reshape(-1, 4))
    return np.array(states)


def test_robot_driven_into_a_wall_stops_at_it():
    # From rest 1.5 m away, it reaches 1 m/s (1 m/s^2) and hits the wall at that speed.
    simulator, _, robots, contacts = _world([(0.0, 0.0, 0.0)], [[1.0, 0.0]])
    states = _drive(simulator, robots, 3.0)
    front = states[:, 0, 0] + RADIUS
    assert states[:, 0, 3].max() == pytest.approx(1.0, abs=1e-3)
    assert front.max() < WALL_FACE + 0.01  # no tunnelling, penetration under 1 cm
    assert front[-1] == pytest.approx(WALL_FACE, abs=2e-3)  # still pushing, at rest on it
    assert abs(states[-1, 0, 3]) < 0.01
    assert abs(states[-1, 0, 1]) < 1e-9 and abs(states[-1, 0, 2]) < 1e-9  # head-on: no turn
    summary = contacts.summary()
    assert summary["count"] == 1 and summary["count_by_kind"]["robot_obstacle"] == 1
    (pair,) = summary["pairs"]
    assert pair["between"] == ["r0", "wall_0"] and pair["kind"] == "robot_obstacle"
    assert 0 < pair["max_penetration"] < 0.01 and pair["impulse"] > 1.0  # ~ m v = 1.8 N s
    assert pair["first_time"] > 1.0


def test_two_robots_pushed_together_register_a_contact():
    # Face to face 1 m apart, both driving forward at 0.5 m/s.
    simulator, _, robots, contacts = _world([(-1.0, 0.0, 0.0), (0.0, 0.0, np.pi)],
                                            [[0.5, 0.0], [0.5, 0.0]])
    states = _drive(simulator, robots, 2.5)
    gap = states[:, 1, 0] - states[:, 0, 0] - 2 * RADIUS
    assert gap.min() > -0.01
    assert gap[-1] == pytest.approx(0.0, abs=2e-3)  # pressed together, neither gets through
    np.testing.assert_allclose(states[-1, :, 3], 0.0, atol=0.01)
    summary = contacts.summary()
    assert summary["count_by_kind"] == {"robot_robot": 1, "robot_human": 0,
                                        "robot_obstacle": 0}
    (pair,) = summary["pairs"]
    assert pair["between"] == ["r0", "r1"] and pair["kind"] == "robot_robot"
    assert pair["max_force"] > 0 and pair["duration"] > 0.5


def test_people_are_moved_onto_their_targets_and_push_robots_aside():
    # A person whose target is 0.3 m into a standing robot: the person gets there in one
    # step and stays (kinematic), the robot is pushed out of the way.
    simulator, world, robots, contacts = _world(
        [(0.0, 0.0, 0.0)], [[0.0, 0.0]], human_poses=[(-1.0, 0.0, 0.0)],
        human_targets=[(-0.2, 0.0, 0.5)])
    states = _drive(simulator, robots, 1.0)
    plant_context = world.plant.GetMyContextFromRoot(simulator.get_context())
    person = world.plant.GetPositions(plant_context, world.humans[0])
    np.testing.assert_allclose(person, [-0.2, 0.0, 0.5], atol=1e-3)
    assert states[-1, 0, 0] > -0.2 + 0.25 + RADIUS - 0.01
    (pair,) = contacts.summary()["pairs"]
    assert pair["between"] == ["h0", "r0"] and pair["kind"] == "robot_human"


def test_the_plant_applies_a_relocation_once_when_its_sequence_number_is_new():
    # r0 drives east at 0.5 m/s; r1 stands. Each move puts a robot on its pose, at rest, at
    # the next step; a move already applied is not applied again.
    simulator, world, robots, _ = _world([(-2.0, 0.0, 0.0), (-2.0, 2.0, 0.0)],
                                         [[0.5, 0.0], [0.0, 0.0]], relocations=True)
    context = robots.GetMyContextFromRoot(simulator.get_context())
    relocations = robots.GetInputPort("relocations")
    relocations.FixValue(context, Relocations((None, (1, (-2.0, -2.0, 1.0)))))
    states = _drive(simulator, robots, 1.0)
    np.testing.assert_allclose(states[-1, 1], [-2.0, -2.0, 1.0, 0.0], atol=1e-9)
    assert states[-1, 0, 3] == pytest.approx(0.5, abs=1e-3)  # r0 untouched
    # r0, moving, is put on a pose: at rest there, then it speeds up again.
    relocations.FixValue(context, Relocations(((1, (1.0, -1.0, np.pi / 2)),
                                               (1, (-2.0, -2.0, 1.0)))))
    simulator.AdvanceTo(1.0 + PhysicsRobotParams().time_step)
    state = robots.GetOutputPort("state").Eval(context).reshape(-1, 4)
    np.testing.assert_allclose(state[0, :3], [1.0, -1.0, np.pi / 2], atol=0.01)
    assert state[0, 3] < 0.05  # one step's acceleration from rest
    np.testing.assert_allclose(state[1], [-2.0, -2.0, 1.0, 0.0], atol=1e-9)
    # The same sequence numbers: r0 drives north from the pose, not put back on it.
    simulator.AdvanceTo(3.0)
    state = robots.GetOutputPort("state").Eval(context).reshape(-1, 4)
    assert state[0, 1] > -0.5
    relocations.FixValue(context, Relocations(((2, (0.0, 1.0, 0.0)), None)))
    simulator.AdvanceTo(3.0 + PhysicsRobotParams().time_step)
    state = robots.GetOutputPort("state").Eval(context).reshape(-1, 4)
    np.testing.assert_allclose(state[0, :2], [0.0, 1.0], atol=0.01)


def test_without_relocations_the_plant_has_no_relocation_update_and_steps_alike():
    # A run without lifts: neither the block nor the plant has a relocation update, the
    # plant no relocations input; a block built with them, nothing to relocate, steps alike.
    poses, commands = [(-2.0, 0.0, 0.0), (0.0, 1.0, 2.0)], [[1.0, 0.3], [0.5, -0.2]]
    simulator, world, robots, _ = _world(poses, commands)
    assert not robots.relocates and not world.plant.HasInputPort("relocations")
    assert robots.num_abstract_states() == 0
    without = _drive(simulator, robots, 2.0)
    simulator, world, robots, _ = _world(poses, commands, relocations=True)
    assert world.plant.HasInputPort("relocations")
    np.testing.assert_array_equal(without, _drive(simulator, robots, 2.0))


def test_parameters_are_checked():
    with pytest.raises(ValueError, match="response_time"):
        PhysicsRobotParams(time_step=0.02, response_time=0.01)
    with pytest.raises(ValueError, match="lateral_damping"):
        PhysicsRobotParams(mass=0.5)
    scenario = load_scenario(ROOT / "scenarios/hospital_routes_6_robots.yaml")
    with pytest.raises(InputError, match="collision_shape"):
        simulate(replace_block(scenario, "robots", "physics", collision_shape="box"),
                 duration=0.1)


@pytest.fixture(scope="module")
def two_robot_routes():
    """robot2 and robot6 of the fixed-route hospital, one stop each (done by ~31 s and
    ~40 s with the kinematic robots)."""
    scenario = load_scenario(ROOT / "scenarios/hospital_routes_6_robots.yaml")
    robots = [dataclasses.replace(r, route=r.route[:1]) for r in scenario.robots[1::4]]
    return dataclasses.replace(scenario, robots=robots)


def _arrivals(result) -> dict:
    return {e["robot"]: e["at"] for e in result.events if e["type"] == "arrival"}


def test_both_backends_finish_the_same_stops_and_physics_runs_are_bit_identical(
        two_robot_routes):
    physics = replace_block(two_robot_routes, "robots", "physics")
    kinematic_run = simulate(two_robot_routes, duration=45.0)
    physics_run = simulate(physics, duration=45.0)
    for result in (kinematic_run, physics_run):
        assert [r["stops_completed"] for r in result.summary["robots"].values()] == [1, 1]
    kinematic_at, physics_at = _arrivals(kinematic_run), _arrivals(physics_run)
    assert kinematic_at.keys() == physics_at.keys() == {"robot2", "robot6"}
    for robot, at in kinematic_at.items():
        assert physics_at[robot] == pytest.approx(at, abs=3.0)
    assert kinematic_run.summary["physics_contacts"] is None
    contacts = physics_run.summary["physics_contacts"]
    assert contacts["time_step"] == PhysicsRobotParams().time_step
    assert contacts["count"] == len(contacts["pairs"]) == 0

    again = simulate(physics, duration=45.0)
    assert np.array_equal(again.robot_states, physics_run.robot_states)
    assert again.summary["physics_contacts"] == contacts


def test_people_bodies_follow_the_humans_block_in_the_hospital():
    scenario = load_scenario(ROOT / "scenarios/hospital_6_robots.yaml")
    scenario = replace_block(dataclasses.replace(scenario, robots=scenario.robots[:2]),
                             "robots", "physics")
    stack = build_diagram(scenario)
    simulator = Simulator(stack.diagram)
    # Between the humans block's updates (20 Hz) and the plant's steps: the plant has moved
    # every person onto the position the block gives since its last update.
    simulator.AdvanceTo(4.975)
    plant, humans = stack.world.plant, stack.humans
    plant_context = plant.GetMyContextFromRoot(simulator.get_context())
    targets = humans.GetOutputPort("plant_positions").Eval(
        humans.GetMyContextFromRoot(simulator.get_context())).reshape(-1, 3)
    bodies = np.array([plant.GetPositions(plant_context, m) for m in stack.world.humans])
    assert len(bodies) == len(humans.human_names) > 0
    np.testing.assert_allclose(bodies[:, :2], targets[:, :2], atol=1e-6)
    turn = np.angle(np.exp(1j * (bodies[:, 2] - targets[:, 2])))
    np.testing.assert_allclose(turn, 0.0, atol=1e-6)


def test_the_compiled_clip_is_numpys_to_the_bit():
    from mrta_drake.robots.physics_robots import _clip

    values = [-2.0, -1.0, -0.0, 0.0, 0.5, 1.0, 3.0, np.inf, -np.inf, np.nan]
    for low, high in [(-1.0, 1.0), (-0.0, 1.5), (0.0, 0.0), (-0.0, -0.0), (0.0, 2.0)]:
        for value in values:
            expected = np.clip(value, low, high)
            got = _clip(value, low, high)
            assert np.array_equal(got, expected, equal_nan=True), (value, low, high)
            assert np.signbit(got) == np.signbit(expected), (value, low, high)
