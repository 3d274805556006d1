"""How people walk: the parameters of the social-force humans block (``blocks.humans.params``)."""

import math
from dataclasses import dataclass

from mrta_drake.errors import InputError


@dataclass(frozen=True)
class SocialForceParams:
    """The Helbing-Molnar social force model shared by every person (defaults as in the
    original stack). A walker's or group's own ``desired_speed`` overrides the default one."""

    radius: float = 0.25  # m, body radius
    desired_speed: float = 1.0  # m/s, walking speed towards the next waypoint
    max_speed: float = 1.5  # m/s
    relaxation_time: float = 0.5  # s, to reach the desired velocity
    repulsion_strength: float = 0.3  # V0, m^2/s^2, of other people and robots
    repulsion_range: float = 0.3  # sigma, m
    wall_strength: float = 10.0  # U0, m^2/s^2, of the nearest obstacle
    wall_range: float = 0.2  # R, m
    waypoint_tolerance: float = 0.3  # m, a waypoint is reached this close

    def __post_init__(self):
        for name in ("radius", "desired_speed", "max_speed", "relaxation_time",
                     "repulsion_range", "wall_range", "waypoint_tolerance"):
            _check(name, getattr(self, name), "> 0", lambda value: value > 0)
        for name in ("repulsion_strength", "wall_strength"):
            _check(name, getattr(self, name), ">= 0", lambda value: value >= 0)
        if self.desired_speed > self.max_speed:
            raise InputError(None, "desired_speed", f"must be <= max_speed {self.max_speed}, "
                             f"got {self.desired_speed}")


def _check(name: str, value, bound: str, holds) -> None:
    """Raise ``InputError`` for field ``name`` unless ``value`` is a finite number for which
    ``holds(value)``."""
    if not (isinstance(value, int | float) and not isinstance(value, bool)
            and math.isfinite(value) and holds(value)):
        raise InputError(None, name, f"must be a number {bound}, got {value!r}")
