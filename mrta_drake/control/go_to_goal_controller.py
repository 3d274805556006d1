"""Nominal path following without safety filter: the baseline for the CBF controllers."""

import numpy as np
from pydrake.systems.framework import LeafSystem

from mrta_drake.control.cbf_qp import CbfParams, WallRays, barrier_minima
from mrta_drake.control.cluster_cbf_controller import (
    controller_update,
    declare_controller_ports,
    input_bounds,
    rays_with_blockages,
    robot_paths_of,
)
from mrta_drake.control.nominal import nominal_control
from mrta_drake.payloads import (
    NO_HUMANS,
    ROBOT_STATE_SIZE,
    ControllerTelemetry,
    Disturbances,
    FleetPaths,
    HumanStates,
)


class GoToGoalController(LeafSystem):
    """Commands for N robots that follow their paths with the nominal control of
    ``mrta_drake.control.nominal`` (gains, lookahead, stop at the path end, heading gate for a
    lone robot; no passing), clipped to the hard input limits, and nothing else: robots ignore
    walls, humans and each other. Same ports, parameters and 20 Hz fixed-step behaviour as
    ``ClusterCbfController``; the CBF parameters only set how the telemetry's barrier values
    are measured (safety distances, wall rays against ``obstacles``; None: no walls).

    Input ``robot_state`` (4N): [x, y, theta, v] per robot, world frame, m, rad, m/s.
    Input ``paths`` (FleetPaths): one path per robot, in robot order.
    Input ``humans`` (HumanStates): optional; only measured, for the telemetry.
    Input ``disturbances`` (Disturbances): optional; broken-down robots get [0, 0], blockages
    are measured as walls.
    Output ``commands`` (2N): [v, omega] per robot, m/s and rad/s (as ClusterCbfController's).
    Output ``telemetry`` (ControllerTelemetry): barrier values of the last tick; no clusters,
    no slack, no solver.
    """

    def __init__(self, names, obstacles=None, params: CbfParams | None = None,
                 rate_hz: float = 20.0):
        super().__init__()
        params = params or CbfParams()
        self.names = tuple(names)
        self._n = len(self.names)
        self._rays = WallRays(obstacles, params)
        self._params = params
        self._dt = 1.0 / rate_hz
        declare_controller_ports(self, self._n, self._dt, self._update)

    @property
    def params(self) -> CbfParams:
        return self._params

    def control(self, time: float, states, paths: FleetPaths,
                humans: HumanStates | None = None, disturbances: Disturbances | None = None
                ) -> tuple[np.ndarray, ControllerTelemetry]:
        """One tick without the systems framework: inputs ``[a, omega]`` (N, 2) for robots in
        ``states`` (N, 4), and the tick's telemetry (``humans``, ``disturbances`` None:
        none)."""
        humans = humans or NO_HUMANS
        p = self._params
        states = np.asarray(states, dtype=float).reshape(self._n, ROBOT_STATE_SIZE)
        u = np.array([nominal_control(s, path, p)
                      for s, path in zip(states, robot_paths_of(paths, self._n), strict=True)])
        lower, upper = input_bounds(states, p, self._dt)
        u = np.clip(u.reshape(self._n, 2), lower, upper)
        hits, mask = self._rays(states)
        if disturbances is not None and disturbances.blockages:
            hits, mask = rays_with_blockages(states, hits, mask, disturbances.blockages, p)
        wall, human, robot = barrier_minima(states, hits, mask, humans.positions, p)
        return u, ControllerTelemetry(time=float(time), min_barrier_wall=wall,
                                      min_barrier_human=human, min_barrier_robot=robot)

    def _update(self, context, discrete_state) -> None:
        controller_update(self, context, discrete_state, self.control, self._params, self._dt,
                          self._n)
