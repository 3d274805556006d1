"""Kinematic differential-drive robots: the fast default robot block."""

import math
from dataclasses import dataclass

import numba
import numpy as np
from pydrake.common.value import Value
from pydrake.systems.framework import BasicVector, EventStatus, LeafSystem

from mrta_drake.payloads import (
    PLANAR_POSITION_SIZE,
    ROBOT_COMMAND_SIZE,
    ROBOT_STATE_SIZE,
    Relocations,
)
from mrta_drake.robots.relocation import Applied


@dataclass(frozen=True)
class UnicycleParams:
    """Limits of every robot. Defaults: the original stack's controller limits (it drove
    TurtleBot3 Waffles in Gazebo at up to 1.5 m/s)."""

    max_speed: float = 1.5  # |v| <= max_speed, m/s
    max_reverse_speed: float = 0.3  # v >= -max_reverse_speed, m/s
    max_acceleration: float = 1.0  # |dv/dt|, m/s^2
    max_yaw_rate: float = 2.0  # |omega|, rad/s


class UnicycleRobots(LeafSystem):
    """N kinematic unicycles, stepped at ``rate_hz``.

    .. pydrake_system::

        name: UnicycleRobots
        input_ports:
        - commands (optional)
        - relocations (optional)
        output_ports:
        - state
        - plant_positions

    Each step (dt = 1 / rate_hz) the commanded speed is reached as far as the acceleration
    limit allows, the commanded yaw rate is clipped, and the pose advances exactly along the
    circular arc driven at the step's mean speed and that yaw rate (a straight line when the
    yaw rate is zero).

    Input ``commands`` (2N): [v, omega] per robot in ``robot_names`` order, m/s and rad/s;
    unconnected: all zero.
    Input ``relocations``: abstract ``Relocations`` (a lift ride's end): a robot whose
    sequence number is new is put on its pose, at rest, in an unrestricted update at the
    same rate (before that instant's step); each pose is applied once. With ``relocations``
    False (a run without lifts, whose stack leaves the input unconnected) the block has no
    such update and never reads the input: an update that changes nothing still costs its
    dispatch at every step (Drake copies the block's state for it and calls the handler;
    ~4 us a step of 25 robots).
    Output ``state`` (4N): [x, y, theta, v] per robot, world frame, m, rad, m/s.
    Output ``plant_positions`` (3N): [x, y, theta] per robot, the planar joints' positions.
    """

    def __init__(self, robot_names, starts, params: UnicycleParams = UnicycleParams(), *,
                 rate_hz: float, relocations: bool = True):
        super().__init__()
        starts = np.asarray(starts, dtype=float).reshape(len(robot_names), 3)
        self._n = len(robot_names)
        self._params = params
        self._dt = 1.0 / rate_hz
        self.robot_names = tuple(robot_names)
        initial = np.zeros((self._n, ROBOT_STATE_SIZE))
        initial[:, :3] = starts
        state = self.DeclareDiscreteState(initial.ravel())
        self._commands = self.DeclareVectorInputPort("commands", ROBOT_COMMAND_SIZE * self._n)
        self._relocations = self.DeclareAbstractInputPort("relocations",
                                                          Value[object](Relocations()))
        if relocations:
            self._applied = self.DeclareAbstractState(
                Value[object](Applied((0,) * self._n)))
        self.DeclareStateOutputPort("state", state)
        self.DeclareVectorOutputPort(
            "plant_positions", PLANAR_POSITION_SIZE * self._n, self._calc_plant_positions,
            prerequisites_of_calc={self.xd_ticket()})
        self.DeclarePeriodicDiscreteUpdateEvent(self._dt, 0.0, self._step)
        if relocations:
            self.DeclarePeriodicUnrestrictedUpdateEvent(self._dt, 0.0, self._relocate)

    @property
    def num_robots(self) -> int:
        return self._n

    def set_initial_states(self, context, states) -> None:
        """Overwrite the robots' [x, y, theta, v] rows (N, 4) in ``context``."""
        context.SetDiscreteState(np.asarray(states, dtype=float).ravel())

    def _step(self, context, discrete_state) -> None:
        p, dt = self._params, self._dt
        x = context.get_discrete_state_vector().value().reshape(self._n, ROBOT_STATE_SIZE)
        if self._commands.HasValue(context):
            u = self._commands.Eval(context).reshape(self._n, ROBOT_COMMAND_SIZE)
        else:
            u = np.zeros((self._n, ROBOT_COMMAND_SIZE))
        discrete_state.set_value(unicycle_step(x, u, p, dt).ravel())

    def _relocate(self, context, state) -> EventStatus:
        # Nothing to apply: DidNothing lets Drake skip applying the update (and invalidating
        # what depends on the state) when no other block updates at this instant.
        if not self._relocations.HasValue(context):
            return EventStatus.DidNothing()
        applied = context.get_abstract_state(self._applied).get_value()
        moves = applied.new_moves(self._relocations.Eval(context))
        if not any(moves):
            return EventStatus.DidNothing()
        x = context.get_discrete_state_vector().value().reshape(self._n, ROBOT_STATE_SIZE).copy()
        for k, move in enumerate(moves):
            if move is not None:
                x[k] = (*move[1], 0.0)
        state.get_mutable_discrete_state().get_mutable_vector(0).SetFromVector(x.ravel())
        state.get_mutable_abstract_state(self._applied).set_value(applied.after(moves))
        return EventStatus.Succeeded()

    def _calc_plant_positions(self, context, output: BasicVector) -> None:
        x = context.get_discrete_state_vector().value().reshape(self._n, ROBOT_STATE_SIZE)
        output.SetFromVector(x[:, :3].ravel())


def unicycle_step(states: np.ndarray, commands: np.ndarray, params: UnicycleParams,
                  dt: float) -> np.ndarray:
    """Advance unicycle ``states`` (N, 4) [x, y, theta, v] by ``dt`` s under ``commands``
    (N, 2) [v, omega], applying ``params``' limits. Returns the new (N, 4) states."""
    # Writable copies: a read-only array (a context's value) would compile a second _step.
    return _step(np.array(states, dtype=float).reshape(-1, ROBOT_STATE_SIZE),
                 np.array(commands, dtype=float).reshape(-1, ROBOT_COMMAND_SIZE),
                 params.max_reverse_speed, params.max_speed, params.max_yaw_rate,
                 params.max_acceleration * dt, dt)


@numba.njit(cache=True)
def _step(states, commands, max_reverse_speed, max_speed, max_yaw_rate, dv_max, dt):
    new = np.empty_like(states)
    for i in range(len(states)):
        x, y, theta, v = states[i, 0], states[i, 1], states[i, 2], states[i, 3]
        v_cmd = min(max(commands[i, 0], -max_reverse_speed), max_speed)
        omega = min(max(commands[i, 1], -max_yaw_rate), max_yaw_rate)
        v_new = v + min(max(v_cmd - v, -dv_max), dv_max)
        distance = 0.5 * (v + v_new) * dt
        turn = omega * dt
        # Chord of the arc: length 2 R sin(turn / 2) = distance * sinc(turn / 2), along the
        # mean heading; exact for a circular arc and well conditioned as turn -> 0.
        # Below 1e-8 the series 1 - h^2/6 equals sin(h)/h to double precision, and it
        # cannot divide by a half-turn that underflowed to zero (numba raises on x / 0).
        half = 0.5 * turn
        chord = distance * (math.sin(half) / half if abs(half) > 1e-8
                            else 1.0 - half * half / 6.0)
        mid = theta + 0.5 * turn
        new[i, 0], new[i, 1] = x + chord * math.cos(mid), y + chord * math.sin(mid)
        new[i, 2] = (theta + turn + math.pi) % (2.0 * math.pi) - math.pi
        new[i, 3] = v_new
    return new
