"""Nominal path following without safety filter: the baseline for the CBF controllers."""

from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
from pydrake.systems.framework import LeafSystem

from mrta_drake.control.barrier_minima import barrier_minima
from mrta_drake.control.barriers import SafetyDistances
from mrta_drake.control.controller_common import controller_update, declare_controller_ports
from mrta_drake.control.input_limits import input_bounds
from mrta_drake.control.nominal import NominalParams, nominal_control
from mrta_drake.control.param_groups import moved_from_flat
from mrta_drake.control.paths import robot_paths_of
from mrta_drake.control.wall_rays import SensingParams, WallRays, rays_with_blockages
from mrta_drake.payloads import (
    NO_HUMANS,
    ROBOT_STATE_SIZE,
    ControllerTelemetry,
    Disturbances,
    FleetPaths,
    HumanStates,
)


@dataclass(frozen=True)
class GoToGoalParams:
    """The parameters of ``GoToGoalController``: its nominal control and limits, and how the
    telemetry's barrier values are measured (the safety distances, the wall rays).
    ``predict_latency``: as ``CbfParams.predict_latency``."""

    nominal: NominalParams = field(default_factory=NominalParams)
    safety_distances: SafetyDistances = field(default_factory=SafetyDistances)
    sensing: SensingParams = field(default_factory=SensingParams)
    predict_latency: bool = True

    moved_fields: ClassVar[dict[str, str]] = moved_from_flat(
        {"nominal": NominalParams, "sensing": SensingParams},
        {"safety_distance_wall": "safety_distances.wall",
         "safety_distance_human": "safety_distances.human",
         "safety_distance_robot": "safety_distances.robot"})


class GoToGoalController(LeafSystem):
    """Commands for N robots that follow their paths with the nominal control of
    ``mrta_drake.control.nominal`` (gains, lookahead, stop at the path end, heading gate for a
    lone robot; no passing), clipped to the hard input limits, and nothing else: robots ignore
    walls, humans and each other.

    .. pydrake_system::

        name: GoToGoalController
        input_ports:
        - robot_state
        - paths
        - human_states (optional)
        - disturbances (optional)
        output_ports:
        - commands
        - telemetry

    Ports, fixed-step behaviour and commands as ``ClusterCbfController``'s (see
    ``mrta_drake.control.controller_common``); robots in ``robot_names`` order. The humans
    and blockages are only measured, for the telemetry: barrier values of the last tick
    (wall rays against ``obstacles``, None: no walls); no clusters, no slack, no solver.
    Broken-down robots get [0, 0].
    """

    def __init__(self, robot_names, obstacles=None, params: GoToGoalParams | None = None, *,
                 rate_hz: float):
        super().__init__()
        params = params or GoToGoalParams()
        self.robot_names = tuple(robot_names)
        self._n = len(self.robot_names)
        self._rays = WallRays(obstacles, params.sensing)
        self._params = params
        self._dt = 1.0 / rate_hz
        self._ports = declare_controller_ports(self, self._n, self._dt, self._update)
        (self.robot_state_port, self.paths_port, self.human_states_port,
         self.disturbances_port, self.commands_port, self.telemetry_port) = self._ports.handles

    @property
    def params(self) -> GoToGoalParams:
        return self._params

    def control(self, time: float, states, paths: FleetPaths,
                human_states: HumanStates | None = None,
                disturbances: Disturbances | None = None
                ) -> tuple[np.ndarray, ControllerTelemetry]:
        """One tick without the systems framework: inputs ``[a, omega]`` (N, 2) for robots in
        ``states`` (N, 4), and the tick's telemetry (``human_states``, ``disturbances`` None:
        none)."""
        humans = human_states or NO_HUMANS
        p = self._params
        states = np.asarray(states, dtype=float).reshape(self._n, ROBOT_STATE_SIZE)
        u = np.array([nominal_control(s, path, p.nominal)
                      for s, path in zip(states, robot_paths_of(paths, self._n), strict=True)])
        lower, upper = input_bounds(states, p.nominal, self._dt)
        u = np.clip(u.reshape(self._n, 2), lower, upper)
        hits, mask = self._rays(states)
        if disturbances is not None and disturbances.blockages:
            hits, mask = rays_with_blockages(states, hits, mask, disturbances.blockages,
                                             p.sensing)
        wall, human, robot = barrier_minima(states, hits, mask, humans.positions,
                                            p.safety_distances)
        return u, ControllerTelemetry(time=float(time), min_barrier_wall=wall,
                                      min_barrier_human=human, min_barrier_robot=robot)

    def _update(self, context, discrete_state) -> None:
        controller_update(self._ports, context, discrete_state, self.control,
                          self._params.nominal, self._params.predict_latency)
