"""Robots as bodies in a stepped ``MultibodyPlant``, driven by wheel-like forces."""

from dataclasses import dataclass

import numba
import numpy as np
from pydrake.common.value import Value
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import BasicVector, EventStatus, LeafSystem

from mrta_drake.payloads import (
    PLANAR_POSITION_SIZE,
    ROBOT_COMMAND_SIZE,
    ROBOT_STATE_SIZE,
    Relocations,
)
from mrta_drake.robots.relocation import Applied


@dataclass(frozen=True)
class PhysicsRobotParams:
    """The plant and the robots' drive. Defaults: a TurtleBot3 Waffle Pi's mass (1.8 kg,
    with computer, battery and sensors), and the kinematic block's limits (``UnicycleParams``:
    1.5 m/s, 0.3 m/s reverse, 2 rad/s, 1 m/s^2, so the traction force is 1.8 kg x 1 m/s^2),
    so that the two backends can be compared.

    The forces are computed from the plant state at the start of each step and held through
    it (explicit), so the servo and damping gains are checked against ``time_step``.
    """

    time_step: float = 1e-2  # s, the discrete plant's step (SAP contact solver)
    mass: float = 1.8  # kg; inertia: a solid cylinder of the robot's radius and height
    collision_shape: str = "sphere"  # "sphere" (of the robot's radius) or "cylinder"
    max_speed: float = 1.5  # m/s, forward speed commands are clipped to this
    max_reverse_speed: float = 0.3  # m/s, backward
    max_yaw_rate: float = 2.0  # rad/s
    max_traction_force: float = 1.8  # N, the most the wheels push along the heading
    max_traction_torque: float = 1.0  # N m, the most the wheels turn the robot
    response_time: float = 0.05  # s, time constant of the wheel speed servo
    lateral_damping: float = 90.0  # N s/m, no-slip force per m/s of sideways velocity
    max_lateral_force: float = 14.0  # N, wheels' side friction (~0.8 x 1.8 kg x 9.81 m/s^2)

    def __post_init__(self):
        for name in ("time_step", "mass", "max_speed", "max_yaw_rate", "max_traction_force",
                     "max_traction_torque", "response_time", "lateral_damping",
                     "max_lateral_force"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        if self.max_reverse_speed < 0:
            raise ValueError(f"max_reverse_speed must be >= 0, got {self.max_reverse_speed}")
        if self.collision_shape not in ("sphere", "cylinder"):
            raise ValueError(f"collision_shape must be 'sphere' or 'cylinder', got "
                             f"{self.collision_shape!r}")
        if self.response_time < self.time_step:
            raise ValueError(f"response_time ({self.response_time} s) must be >= time_step "
                             f"({self.time_step} s): the servo is explicit")
        if self.lateral_damping * self.time_step > self.mass:
            raise ValueError(f"lateral_damping x time_step / mass = "
                             f"{self.lateral_damping * self.time_step / self.mass:.2f} must "
                             f"be <= 1: the damping is explicit")


class PhysicsRobots(LeafSystem):
    """N robots that are bodies on planar joints of a stepped (discrete) plant.

    .. pydrake_system::

        name: PhysicsRobots
        input_ports:
        - commands (optional)
        - plant_state
        - relocations (optional)
        output_ports:
        - generalized_force
        - state
        - plant_positions
        - relocate

    Each robot is driven like a differential drive: the commanded forward speed v (clipped
    to [-max_reverse_speed, max_speed]) and yaw rate omega (clipped to +-max_yaw_rate) are
    servoed with time constant ``response_time`` by a force along the heading and a torque
    about +z, limited to ``max_traction_force`` and ``max_traction_torque``; a no-slip force
    opposes the sideways velocity (``lateral_damping``, limited to ``max_lateral_force``).
    Contact with walls, furniture, people and other robots is the plant's (SAP).

    Input ``commands`` (2N): [v, omega] per robot, m/s and rad/s; unconnected: all zero.
    Input ``plant_state``: the plant's state [q; v].
    Output ``generalized_force`` (the plant's nv): the drive forces, [f_x, f_y, tau_z] on
        each robot's planar joint (world frame, N, N m), zero for the plant's other joints;
        for the plant's applied generalized force input.
    Output ``state`` (4N): [x, y, theta, v] per robot, world frame, m, rad; v the forward
        speed (body-frame x velocity), m/s.
    Output ``plant_positions`` (3N): [x, y, theta] per robot, its planar joint's positions.

    Input ``relocations``: abstract ``Relocations`` (a lift ride's end). Output
    ``relocate``: abstract ``Relocations``, its moves whose sequence numbers are new (None
    for the other robots). The plant owns the bodies' state, so the plant applies them
    (``plant_stepping.add_plant_stepping``, when ``relocates``: its own unrestricted update
    at its step, before the step; ``relocated``); with ``relocations`` (a building run
    across levels) the block notes them applied in its unrestricted update at the same
    instants, so each pose is applied once. With ``relocations`` False (a run without
    lifts) the block has no such update and no state for it, and ``relocate`` is all None.
    """

    def __init__(self, plant: MultibodyPlant, robot_models, params: PhysicsRobotParams, *,
                 relocations: bool = False):
        super().__init__()
        self._n = len(robot_models)
        nq, nv = plant.num_positions(), plant.num_velocities()
        joints = [plant.get_joint(plant.GetJointIndices(m)[0]) for m in robot_models]
        bodies = [plant.GetBodyByName("base", m) for m in robot_models]
        # Indices (N, 3) of each robot's [x, y, theta] and [vx, vy, omega] in [q; v], and of
        # its generalized forces in the nv-vector.
        offsets = np.arange(3)
        self._q = np.array([j.position_start() + offsets for j in joints])
        self._v = np.array([nq + j.velocity_start() + offsets for j in joints])
        self._f = self._v - nq
        self._nv = nv
        self._mass = np.array([b.default_mass() for b in bodies])
        self._inertia = np.array([b.default_rotational_inertia().get_moments()[2]
                                  for b in bodies])
        self._limits = np.array([params.max_reverse_speed, params.max_speed,
                                 params.max_yaw_rate, params.response_time,
                                 params.max_traction_force, params.max_traction_torque,
                                 params.lateral_damping, params.max_lateral_force])
        self._no_commands = np.zeros(ROBOT_COMMAND_SIZE * self._n)
        self.robot_names = tuple(plant.GetModelInstanceName(m) for m in robot_models)
        self._commands = self.DeclareVectorInputPort("commands", ROBOT_COMMAND_SIZE * self._n)
        self._plant_state = self.DeclareVectorInputPort("plant_state", nq + nv)
        plant_state = {self._plant_state.ticket()}
        self.DeclareVectorOutputPort(
            "generalized_force", BasicVector(nv), self._calc_forces,
            prerequisites_of_calc={self._commands.ticket(), self._plant_state.ticket()})
        self.DeclareVectorOutputPort(
            "state", BasicVector(ROBOT_STATE_SIZE * self._n), self._calc_state,
            prerequisites_of_calc=plant_state)
        self.DeclareVectorOutputPort(
            "plant_positions", BasicVector(PLANAR_POSITION_SIZE * self._n),
            self._calc_plant_positions, prerequisites_of_calc=plant_state)
        self.relocates = relocations
        self._relocations = self.DeclareAbstractInputPort("relocations",
                                                          Value[object](Relocations()))
        relocate = {self._relocations.ticket()}
        if relocations:
            self._applied = self.DeclareAbstractState(Value[object](Applied((0,) * self._n)))
            relocate.add(self.abstract_state_ticket(self._applied))
            self.DeclarePeriodicUnrestrictedUpdateEvent(params.time_step, 0.0, self._applied_now)
        self.DeclareAbstractOutputPort("relocate", lambda: Value[object](Relocations()),
                                       self._calc_relocate, prerequisites_of_calc=relocate)

    @property
    def num_robots(self) -> int:
        return self._n

    def _read(self, context) -> tuple[np.ndarray, np.ndarray]:
        """Poses (N, 3) [x, y, theta] and velocities (N, 3) [vx, vy, omega], world frame."""
        x = self._plant_state.Eval(context)
        return x[self._q], x[self._v]

    def _calc_forces(self, context, output: BasicVector) -> None:
        commands = (self._commands.Eval(context) if self._commands.HasValue(context)
                    else self._no_commands)
        _drive_forces(self._plant_state.Eval(context), commands, self._q, self._v, self._f,
                      self._mass, self._inertia, self._limits, output.get_mutable_value())

    def _calc_state(self, context, output: BasicVector) -> None:
        pose, velocity = self._read(context)
        forward = np.cos(pose[:, 2]) * velocity[:, 0] + np.sin(pose[:, 2]) * velocity[:, 1]
        theta = np.mod(pose[:, 2] + np.pi, 2.0 * np.pi) - np.pi
        output.SetFromVector(np.column_stack([pose[:, :2], theta, forward]).ravel())

    def _calc_plant_positions(self, context, output: BasicVector) -> None:
        output.SetFromVector(self._read(context)[0].ravel())

    def relocated(self, plant_state: np.ndarray, moves: tuple) -> np.ndarray:
        """The plant's state [q; v] with every robot that has a move (``relocate``'s
        ``moves``, per robot ``(sequence, (x, y, theta))`` or None) on its pose, at rest."""
        x = np.array(plant_state, dtype=float)
        for k, move in enumerate(moves):
            if move is not None:
                x[self._q[k]] = move[1]
                x[self._v[k]] = 0.0
        return x

    def _new_moves(self, context) -> tuple:
        if not (self.relocates and self._relocations.HasValue(context)):
            return (None,) * self._n
        applied = context.get_abstract_state(self._applied).get_value()
        return applied.new_moves(self._relocations.Eval(context))

    def _calc_relocate(self, context, output) -> None:
        output.set_value(Relocations(self._new_moves(context)))

    def _applied_now(self, context, state) -> EventStatus:
        # Nothing new: DidNothing lets Drake skip applying the update.
        moves = self._new_moves(context)
        if not any(moves):
            return EventStatus.DidNothing()
        applied = context.get_abstract_state(self._applied).get_value()
        state.get_mutable_abstract_state(self._applied).set_value(applied.after(moves))
        return EventStatus.Succeeded()


@numba.njit(cache=True)
def _clip(value, low, high):
    """``np.clip`` of one float, to the bit: NaN is kept, and so is ``value`` when it equals
    a bound (+0.0 clipped to [-0.0, 1] stays +0.0)."""
    value = low if value < low else value
    return high if value > high else value


@numba.njit(cache=True)
def _drive_forces(x, commands, q, v, f, mass, inertia, limits, forces):
    """``PhysicsRobots``' drive forces into ``forces`` (the plant's nv): from the plant state
    ``x`` [q; v], the commands (2N) [v, omega] per robot (m/s, rad/s), the robots' indices
    ``q``, ``v`` (N, 3) in ``x`` and ``f`` (N, 3) in ``forces``, masses (kg), yaw inertias
    (kg m^2) and ``limits`` [max_reverse_speed, max_speed, max_yaw_rate, response_time,
    max_traction_force, max_traction_torque, lateral_damping, max_lateral_force]
    (``PhysicsRobotParams``); every other entry of ``forces`` zero."""
    max_reverse, max_speed, max_yaw, response = limits[0], limits[1], limits[2], limits[3]
    max_push, max_turn, damping, max_grip = limits[4], limits[5], limits[6], limits[7]
    forces[:] = 0.0
    for i in range(len(q)):
        c, s = np.cos(x[q[i, 2]]), np.sin(x[q[i, 2]])
        vx, vy, omega = x[v[i, 0]], x[v[i, 1]], x[v[i, 2]]
        forward = c * vx + s * vy
        sideways = -s * vx + c * vy
        v_cmd = _clip(commands[2 * i], -max_reverse, max_speed)
        omega_cmd = _clip(commands[2 * i + 1], -max_yaw, max_yaw)
        push = _clip(mass[i] * (v_cmd - forward) / response, -max_push, max_push)
        grip = _clip(-damping * sideways, -max_grip, max_grip)
        forces[f[i, 0]] = c * push - s * grip
        forces[f[i, 1]] = s * push + c * grip
        forces[f[i, 2]] = _clip(inertia[i] * (omega_cmd - omega) / response, -max_turn,
                                max_turn)
