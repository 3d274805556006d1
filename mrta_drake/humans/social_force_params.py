"""How people walk: the parameters of the social-force humans block (``blocks.humans.params``)."""

from dataclasses import dataclass

from mrta_drake.errors import InputError, require_non_negative, require_positive


@dataclass(frozen=True)
class SocialForceParams:
    """The Helbing-Molnar social force model shared by every person (defaults as in the
    original stack), and how people yield to robots (docs/humans.md). A walker's or group's
    own ``desired_speed`` overrides the default one.

    ``robot_repulsion_gain`` multiplies the repulsion of robots (``repulsion_strength``) and
    restores the original's: the original MRTA-Sim multiplies its pedestrian repulsion by 90
    (``F_ab * 90`` in its ``socialforce`` simulator, which counts the robot as a pedestrian)
    and measures the potential's ``b`` between centres, where this model measures it between
    bodies (``b`` minus both radii). At equal centre distance the two agree for a gain of
    ``90 exp(-(0.25 + 0.22) / 0.3) = 90 x 0.209 = 18.8`` with the default person radius
    0.25 m, the robots' 0.22 m and sigma 0.3 m (exactly so for a robot standing still; for a
    moving one the ellipses differ: 2 s of walk here, one 0.05 s step there).

    A person yields to a robot *in its way*: ahead (in front of the person's walking
    direction) and nearer sideways than both radii plus ``passing_gap``. Its urgency grows
    from 0 at surface gap ``yield_distance`` to 1 at ``waiting_gap``, the gap counted less
    the closing speed (the person's and the robot's velocities towards each other) times
    ``yield_time``, so that yielding starts by time to contact (a person walking at a
    standing robot at 1 m/s slows from a 2.5 m gap); the person slows in proportion and
    walks aside (at ``sidestep_ratio`` of its speed at full urgency) to its right, or to its
    left when only that side has room to pass, or stands when neither has.

    ``negligible_force`` (m/s^2) cuts the pair repulsions off: the repulsion of a person or
    robot so far away that it cannot reach this value (a bound from the centre distance,
    the other's next 2 s of walk and both radii: ``SocialForceHumans``) is not computed.
    0 computes every pair.
    """

    radius: float = 0.25  # m, body radius
    desired_speed: float = 1.0  # m/s, walking speed towards the next waypoint
    max_speed: float = 1.5  # m/s
    relaxation_time: float = 0.5  # s, to reach the desired velocity
    repulsion_strength: float = 0.3  # V0, m^2/s^2, of other people
    repulsion_range: float = 0.3  # sigma, m
    robot_repulsion_gain: float = 18.8  # robots repel V0 times this: the original's x90
    wall_strength: float = 10.0  # U0, m^2/s^2, of the nearest obstacle
    wall_range: float = 0.2  # R, m
    waypoint_tolerance: float = 0.3  # m, a waypoint is reached this close
    yield_distance: float = 1.5  # m, surface gap to a robot in the way where yielding begins
    waiting_gap: float = 0.3  # m, surface gap where a person with no room to pass stands
    yield_time: float = 1.0  # s, of the closing speed counted off the gap
    passing_gap: float = 0.3  # m, surface gap kept sideways from a robot passed
    sidestep_ratio: float = 0.5  # sideways speed at full urgency, per unit of desired speed
    yield_to_robots: bool = True  # off: people walk on into a robot's way (the original)
    negligible_force: float = 1e-9  # m/s^2: pair repulsions surely below it are left out

    def __post_init__(self):
        require_positive(self, "radius", "desired_speed", "max_speed", "relaxation_time",
                         "repulsion_range", "wall_range", "waypoint_tolerance",
                         "yield_distance", "waiting_gap", "passing_gap")
        require_non_negative(self, "repulsion_strength", "robot_repulsion_gain",
                             "wall_strength", "yield_time", "sidestep_ratio",
                             "negligible_force")
        if self.desired_speed > self.max_speed:
            raise InputError(None, "desired_speed", f"must be <= max_speed {self.max_speed}, "
                             f"got {self.desired_speed}")
        if self.waiting_gap >= self.yield_distance:
            raise InputError(None, "waiting_gap", f"must be < yield_distance "
                             f"{self.yield_distance}, got {self.waiting_gap}")

