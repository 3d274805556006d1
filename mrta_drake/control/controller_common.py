"""What every controller block shares: its ports and state, the periodic update that reads the
inputs, plans from the state the new commands will act on and zeroes broken-down robots'
commands, and the telemetry kept as numbers in the state.

A controller block for N robots ticking every dt s has:

- input ``robot_state`` (4N): ``[x, y, theta, v]`` per robot, world frame, m, rad, m/s;
- input ``paths`` (``FleetPaths``): one path per robot, in robot order;
- input ``human_states`` (``HumanStates``), optional: none;
- input ``disturbances`` (``Disturbances``), optional: none;
- output ``commands`` (2N): ``[v, omega]`` per robot, m/s and rad/s, ``v = v' + a dt`` with
  v' the speed when the command takes effect;
- output ``telemetry`` (``ControllerTelemetry``): the last tick's account.
"""

import functools
from dataclasses import dataclass

import numpy as np
from pydrake.common.value import Value
from pydrake.systems.framework import InputPort, LeafSystem, OutputPort

from mrta_drake.control.nominal import NominalParams
from mrta_drake.payloads import (
    NO_DISTURBANCES,
    NO_HUMANS,
    ROBOT_COMMAND_SIZE,
    ROBOT_STATE_SIZE,
    ControllerTelemetry,
    Disturbances,
    FleetPaths,
    HumanStates,
)
from mrta_drake.robots.unicycle_robots import UnicycleParams, unicycle_step

_TELEMETRY_FIELDS = ("time", "min_barrier_wall", "min_barrier_human", "min_barrier_robot",
                     "max_slack", "control_deviation", "solve_time", "failures",
                     "leader_disagreement", "stale_commands")


@dataclass(frozen=True, eq=False)
class ControllerPorts:
    """The ports and state of a controller block for ``robots`` robots ticking every ``dt``
    s (``declare_controller_ports``): discrete state group ``commands_state`` holds the
    commands, ``telemetry_state`` the telemetry."""

    robot_state: InputPort
    paths: InputPort
    human_states: InputPort
    disturbances: InputPort
    commands: OutputPort
    telemetry: OutputPort
    commands_state: int
    telemetry_state: int
    robots: int
    dt: float

    @property
    def handles(self) -> tuple[InputPort | OutputPort, ...]:
        """The ports in declaration order: robot_state, paths, human_states, disturbances,
        commands, telemetry."""
        return (self.robot_state, self.paths, self.human_states, self.disturbances,
                self.commands, self.telemetry)


def declare_controller_ports(system: LeafSystem, robots: int, dt: float,
                             update) -> ControllerPorts:
    """Declare on ``system`` the ports and state of a controller for ``robots`` robots (see
    the module docstring) and its ``update`` event every ``dt`` s."""
    commands = system.DeclareDiscreteState(ROBOT_COMMAND_SIZE * robots)
    telemetry = system.DeclareDiscreteState(_telemetry_vector(ControllerTelemetry(), robots))
    inputs = (system.DeclareVectorInputPort("robot_state", ROBOT_STATE_SIZE * robots),
              system.DeclareAbstractInputPort("paths", Value[object](FleetPaths(()))),
              system.DeclareAbstractInputPort("human_states", Value[object](HumanStates())),
              system.DeclareAbstractInputPort("disturbances", Value[object](Disturbances())))
    outputs = (system.DeclareStateOutputPort("commands", commands),
               system.DeclareAbstractOutputPort(
                   "telemetry", lambda: Value[object](ControllerTelemetry()),
                   lambda context, output: output.set_value(_telemetry_from_vector(
                       context.get_discrete_state(telemetry).value(), robots)),
                   prerequisites_of_calc={system.discrete_state_ticket(telemetry)}))
    system.DeclarePeriodicDiscreteUpdateEvent(dt, 0.0, update)
    return ControllerPorts(*inputs, *outputs, commands, telemetry, robots, dt)


def controller_update(ports: ControllerPorts, context, discrete_state, control,
                      limits: NominalParams, predict_latency: bool) -> None:
    """The periodic update of a controller with ``ports``: read the inputs,
    ``control(time, states, paths, human_states, disturbances) -> (u, telemetry)``, store
    the commands (zero for broken-down robots) and the telemetry. With ``predict_latency``
    ``control`` gets the states predicted for when the new commands act, one tick on under
    the commands in force (``predict_states`` with the ``limits``)."""
    n, dt = ports.robots, ports.dt
    states = ports.robot_state.Eval(context).reshape(n, ROBOT_STATE_SIZE)
    paths = ports.paths.Eval(context)
    humans = (ports.human_states.Eval(context) if ports.human_states.HasValue(context)
              else NO_HUMANS)
    disturbances = (ports.disturbances.Eval(context) if ports.disturbances.HasValue(context)
                    else NO_DISTURBANCES)
    if predict_latency:
        states = predict_states(
            states, context.get_discrete_state(ports.commands_state).value(), limits, dt)
    u, telemetry = control(context.get_time(), states, paths, humans, disturbances)
    commands = np.empty((n, ROBOT_COMMAND_SIZE))
    commands[:, 0] = states[:, 3] + u[:, 0] * dt
    commands[:, 1] = u[:, 1]
    if disturbances.broken:
        commands[list(disturbances.broken)] = 0.0
    discrete_state.set_value(ports.commands_state, commands.ravel())
    discrete_state.set_value(ports.telemetry_state, _telemetry_vector(telemetry, n))


def predict_states(states, commands, limits: NominalParams, dt: float) -> np.ndarray:
    """Robot ``states`` (N, 4) one tick of ``dt`` s later under ``commands`` (N, 2)
    ``[v, omega]``, by the robot block's own exact arc step with the controller's
    ``limits``."""
    return unicycle_step(np.asarray(states, dtype=float).reshape(-1, ROBOT_STATE_SIZE),
                         np.asarray(commands, dtype=float).reshape(-1, ROBOT_COMMAND_SIZE),
                         _robot_limits(limits), dt)


@functools.cache
def _robot_limits(limits: NominalParams) -> UnicycleParams:
    """The controller's limits as a robot block's parameters (``predict_states``)."""
    return UnicycleParams(max_speed=limits.max_speed,
                          max_reverse_speed=max(0.0, -limits.min_speed),
                          max_acceleration=limits.max_accel, max_yaw_rate=limits.max_yaw_rate)


def _telemetry_vector(telemetry: ControllerTelemetry, n: int) -> np.ndarray:
    """Telemetry as numbers: the scalar fields, then the clusters' members one cluster after
    the other, then where each cluster ends in that list, then the QP calls' robot counts
    and their times (each padded with -1 to n: a tick has at most n QPs)."""
    k = len(_TELEMETRY_FIELDS)
    vector = np.full(k + 4 * n, -1.0)
    vector[:k] = [getattr(telemetry, name) for name in _TELEMETRY_FIELDS]
    members, ends = [], []
    for cluster in telemetry.clusters:
        members.extend(cluster)
        ends.append(len(members))
    vector[k:k + len(members)] = members
    vector[k + n:k + n + len(ends)] = ends
    calls = len(telemetry.qp_calls)
    vector[k + 2 * n:k + 2 * n + calls] = [size for size, _ in telemetry.qp_calls]
    vector[k + 3 * n:k + 3 * n + calls] = [seconds for _, seconds in telemetry.qp_calls]
    return vector


def _telemetry_from_vector(vector, n: int) -> ControllerTelemetry:
    k = len(_TELEMETRY_FIELDS)
    fields = dict(zip(_TELEMETRY_FIELDS, vector[:k].tolist(), strict=True))
    fields["failures"] = int(fields["failures"])
    fields["leader_disagreement"] = bool(fields["leader_disagreement"])
    fields["stale_commands"] = int(fields["stale_commands"])
    members = vector[k:k + n].astype(int).tolist()
    clusters, first = [], 0
    for end in vector[k + n:k + 2 * n].astype(int).tolist():
        if end < 0:
            break
        clusters.append(tuple(members[first:end]))
        first = end
    sizes = vector[k + 2 * n:k + 3 * n].astype(int).tolist()
    calls = tuple((size, float(seconds))
                  for size, seconds in zip(sizes, vector[k + 3 * n:].tolist(), strict=True)
                  if size > 0)
    return ControllerTelemetry(clusters=tuple(clusters), qp_calls=calls, **fields)
