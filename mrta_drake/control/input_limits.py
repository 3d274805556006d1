"""The hard input limits of a controller's robots, as bounds on ``[a, omega]`` per tick."""

import numba
import numpy as np

from mrta_drake.control.nominal import NominalParams
from mrta_drake.payloads import ROBOT_STATE_SIZE
from mrta_drake.stack.compiled_helper import compiled_helper


def input_bounds(states, params: NominalParams, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Hard bounds (N, 2) on ``[a, omega]`` for robots ``states`` (N, 4): |a| <= max_accel,
    |omega| <= max_yaw_rate, and the speed after one step of dt s within
    [min_speed, max_speed] as far as the acceleration limit allows."""
    states = np.ascontiguousarray(states, dtype=float).reshape(-1, ROBOT_STATE_SIZE)
    lower, upper = np.empty((len(states), 2)), np.empty((len(states), 2))
    _fill_input_bounds_entry(states, limits_of(params, dt), lower, upper)
    return lower, upper


def limits_of(params: NominalParams, dt: float) -> np.ndarray:
    """The limits ``fill_input_bounds`` takes: max_accel, max_speed, min_speed, max_yaw_rate
    and the tick dt (s)."""
    return np.array([params.max_accel, params.max_speed, params.min_speed,
                     params.max_yaw_rate, dt])


@numba.njit(cache=True)
def _fill_input_bounds_entry(states, limits, lower, upper):
    """``fill_input_bounds`` for Python, which cannot call a ``compiled_helper``."""
    fill_input_bounds(states, limits, lower, upper)


@compiled_helper
def fill_input_bounds(states, limits, lower, upper):
    """``input_bounds`` into ``lower``, ``upper`` (N, 2), compiled (``limits``: as from
    ``limits_of``)."""
    a_max, max_speed, min_speed, max_yaw_rate, dt = (limits[0], limits[1], limits[2],
                                                      limits[3], limits[4])
    for i in range(len(states)):
        v = states[i, 3]
        a_hi = min(max((max_speed - v) / dt, -a_max), a_max)
        lower[i, 0] = min(min(max((min_speed - v) / dt, -a_max), a_max), a_hi)
        upper[i, 0] = a_hi
        lower[i, 1], upper[i, 1] = -max_yaw_rate, max_yaw_rate
