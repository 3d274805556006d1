"""The cluster controller over a network: each robot's share of the cluster protocol."""

import math

import numpy as np
from pydrake.common.value import Value
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantValueSource, LogVectorOutput

from mrta_drake.control.cluster_cbf_controller import ClusterCbfController
from mrta_drake.network.broadcast_network import BroadcastNetwork
from mrta_drake.payloads import (
    PATH_OK,
    Disturbances,
    FleetPaths,
    HumanStates,
    NetworkViews,
    RobotPath,
    frozen_array,
)
from mrta_drake.robots.unicycle_robots import UnicycleRobots
from mrta_drake.scenario.schema import CommunicationConfig
from mrta_drake.world.obstacles import Box, Obstacles

RADIUS = 0.22  # robot body radius, m
NAMES = ["r0", "r1"]
CORRIDOR = Obstacles((Box("north", (7.0, 1.5), (18.0, 0.2)),
                      Box("south", (7.0, -1.5), (18.0, 0.2))))


def _paths(starts, goals) -> FleetPaths:
    return FleetPaths(tuple(RobotPath(name, PATH_OK, frozen_array([start[:2], goal]))
                            for name, start, goal in zip(NAMES, starts, goals, strict=True)))


def test_a_head_on_swap_over_a_lossy_network_with_latency_keeps_clear():
    starts = np.array([[1.0, 0.0, 0.0, 0.0], [13.0, 0.0, math.pi, 0.0]])
    goals = [[13.0, 0.0], [1.0, 0.0]]
    builder = DiagramBuilder()
    robots = builder.AddSystem(UnicycleRobots(NAMES, starts[:, :3], rate_hz=20.0))
    controller = builder.AddSystem(ClusterCbfController(NAMES, CORRIDOR, rate_hz=20.0))
    network = builder.AddSystem(BroadcastNetwork(
        NAMES, starts, CommunicationConfig(latency=0.2, loss=0.1), seed=0, rate_hz=20.0))
    paths = builder.AddSystem(ConstantValueSource(Value[object](_paths(starts, goals))))
    state = robots.GetOutputPort("state")
    builder.Connect(paths.get_output_port(), controller.GetInputPort("paths"))
    builder.Connect(state, controller.GetInputPort("robot_state"))
    builder.Connect(state, network.GetInputPort("robot_state"))
    builder.Connect(network.GetOutputPort("views"), controller.GetInputPort("network"))
    builder.Connect(controller.GetOutputPort("leader_commands"),
                    network.GetInputPort("leader_commands"))
    builder.Connect(controller.GetOutputPort("commands"), robots.GetInputPort("commands"))
    log = LogVectorOutput(state, builder, 0.05)
    simulator = Simulator(builder.Build())
    simulator.AdvanceTo(40.0)
    states = log.FindLog(simulator.get_context()).data().T.reshape(-1, 2, 4)
    gap = np.linalg.norm(states[:, 0, :2] - states[:, 1, :2], axis=1)
    assert gap.min() >= 2 * RADIUS
    np.testing.assert_allclose(states[-1, :, :2], goals, atol=0.1)


def _driving(gap: float, toward: bool):
    """Two robots ``gap`` m apart along the corridor at 0.5 m/s, driving at each other
    (``toward``) or one behind the other (east), each with a path 8 m on."""
    heading = np.pi if toward else 0.0
    states = np.array([[5.0, 0.0, 0.0, 0.5], [5.0 + gap, 0.0, heading, 0.5]])
    ends = [[13.0, 0.0], [5.0 + gap + 8.0 * np.cos(heading), 0.0]]
    return states, _paths(states, ends)


def _views(states, command_from, command=(0.0, 0.0), time=1.0) -> NetworkViews:
    """Each robot knows the other's true state, sent now; robot 1's last command
    ``command`` came from ``command_from[1]`` 0.2 s ago."""
    return NetworkViews(time, frozen_array(np.broadcast_to(states, (2, 2, 4))),
                        frozen_array(np.full((2, 2), time)),
                        frozen_array([[0.0, 0.0], command]), command_from,
                        frozen_array([-np.inf, time - 0.2]), 0.3)


def _tick(states, paths, views):
    controller = ClusterCbfController(NAMES, CORRIDOR, rate_hz=20.0)
    return controller.control_over_network(1.0, states, paths, HumanStates(), None,
                                           Disturbances(), views)


def test_a_follower_applies_its_leaders_fresh_safe_command_and_the_leader_sends_it():
    states, paths = _driving(3.0, toward=False)
    tick = _tick(states, paths, _views(states, (-1, 0), (0.1, 0.2)))
    np.testing.assert_allclose(tick.u[1], [0.1, 0.2])
    assert tick.messages.leaders == (-1, 0)
    assert tick.telemetry.stale_commands == 0 and tick.telemetry.clusters == ((0, 1),)
    assert not tick.telemetry.leader_disagreement


def test_a_follower_keeps_its_leaders_command_within_its_own_barriers():
    states, paths = _driving(1.2, toward=True)
    tick = _tick(states, paths, _views(states, (-1, 0), (0.5, 0.0)))
    assert tick.telemetry.stale_commands == 0
    assert tick.u[1, 0] < 0.0  # told to speed up at the other robot, it slows down


def test_a_follower_without_a_fresh_command_brakes_on_its_own_qp():
    states, paths = _driving(3.0, toward=False)
    tick = _tick(states, paths, _views(states, (-1, -1)))
    assert tick.telemetry.stale_commands == 1
    assert tick.u[1, 0] < 0.0  # decelerates
