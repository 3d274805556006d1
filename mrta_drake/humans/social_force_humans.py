"""All humans of a run in one discrete system: the Helbing-Molnar social force model."""

import math
from collections.abc import Sequence

import numba
import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, LeafSystem

from mrta_drake.humans.people import Person
from mrta_drake.humans.social_force_params import SocialForceParams
from mrta_drake.payloads import (
    PLANAR_POSITION_SIZE,
    ROBOT_STATE_SIZE,
    HumanStates,
    frozen_array,
)
from mrta_drake.stack.compiled_helper import compiled_helper
from mrta_drake.world.obstacles import Obstacles, cast_rays_into, closest_points_of

ELLIPSE_TIME = 2.0  # s: the elliptical potential stretches along the other's next 2 s of walk
FIELD_OF_VIEW = np.deg2rad(100.0)  # half angle of the field of view
OUT_OF_VIEW_WEIGHT = 0.5  # weight of repulsion from someone behind (c in Helbing-Molnar)
KEEP_RIGHT = 1.0  # sidestep to the right per unit of repulsion against the walking direction
GRADIENT_CAP = 2.0  # cap on |grad b|, which diverges on the ellipse's degenerate axis
STOPPED_SPEED = 0.05  # m/s: below it the heading is held
ENTRY_GAP = 0.1  # m: surface gap to everyone else a waiting person needs to enter
ROBOT_STANDOFF = 0.05  # m: a person's own step never takes it closer to a robot's surface
PROJECTION_ITERATIONS = 3
TAKEN_REACH = 1.0  # m: a target covered by someone else's body counts as reached this close
PARKING_GAP = 1.0  # m: distance of the parking row from the world's bounds


class SocialForceHumans(LeafSystem):
    """Moves M people with the social force model (``SocialForceParams``) at ``rate_hz``.

    .. pydrake_system::

        name: SocialForceHumans
        input_ports:
        - robot_state (optional)
        output_ports:
        - human_states
        - plant_positions
        - active

    Each update (period ``1 / rate_hz`` s, first at t = 0), for every person present:

    1. Waypoint: within ``waypoint_tolerance`` of its target (or within ``TAKEN_REACH`` of a
       target covered by a robot's or another person's body), the person targets the next
       waypoint of its loop (wrapping around).
    2. Acceleration, m/s^2: relaxation to the desired velocity with ``relaxation_time``:
       ``desired_speed`` toward the target, or, with a robot in the way, slower and aside
       (yielding, ``SocialForceParams``: urgency from the robot's gap and the closing
       speed; aside to the right, or to the left when only the left has room to pass beside
       the robot, by a ray cast from the robot's centre; a stand when neither has);
       repulsion from other
       people and from robots (robots count as pedestrians, moving with ``v (cos theta,
       sin theta)``, with ``V0`` times ``robot_repulsion_gain``) with the elliptical
       potential ``V0 exp(-b'/sigma)``, ``V0 = repulsion_strength``, ``sigma =
       repulsion_range``, ``b'`` the ellipse's semi-minor axis minus both body radii (so
       bodies, not centres, keep apart), stretched along the other's next ``ELLIPSE_TIME`` s
       of motion and weighted ``OUT_OF_VIEW_WEIGHT`` when the other is outside the
       ``FIELD_OF_VIEW``; repulsion from the nearest obstacle
       ``U0 exp(-d/R)`` (``U0 = wall_strength``, ``R = wall_range``, ``d`` the centre's
       distance to the obstacle) from ``Obstacles.closest_points``.
       A person's sidestep to the right, ``KEEP_RIGHT`` times the repulsion opposing its
       walking direction, breaks the symmetry of head-on encounters (which would deadlock);
       ``|grad b|`` is capped at ``GRADIENT_CAP`` where the ellipse degenerates.
    3. Semi-implicit Euler step, speed capped at ``max_speed``.
    4. Hard constraints on the step: overlapping people are pushed apart; nobody steps
       closer to a robot's surface than min(``ROBOT_STANDOFF``, the gap before the step),
       the robot taken both where it is and where its velocity takes it by the end of the
       step, so only a robot's own motion causes contact (robots are never pushed, and the
       people are not shoved out of a robot that drove into them: contacts stay visible to
       the metrics); everyone is pushed out to clearance ``radius`` from obstacles, and a
       step that would still lose clearance below ``radius`` (or break a robot gap) is
       cancelled and the person stops, so nobody ever enters a wall or steps into a
       robot.

    A person with ``entry_time`` > 0 waits until that time and until nobody is within
    ``ENTRY_GAP`` of its start. The number of people never changes: a waiting person is
    reported (and posed) at its parking spot outside the world, standing still, where it
    interacts with nobody; the ``active`` port tells who is present.

    Discrete state, one group of ``7M`` (world frame, m, m/s, rad): positions ``2M``,
    velocities ``2M``, target waypoint indices ``M``, headings ``M`` (from the velocity, held
    while slower than ``STOPPED_SPEED``), presence flags ``M`` (1 present, 0 waiting).

    Input ports:
        robot_state: vector ``4N``, ``[x, y, theta, v]`` per robot in ``robot_names`` order
            (radii ``robot_radii``, m); unconnected = no robots.
    Output ports:
        human_states: abstract ``HumanStates`` of all M people, in people order.
        plant_positions: vector ``3M``, ``[x, y, heading]`` per person. Parking spots form a
            row running west from ``parking`` (default: 1 m south-west of the obstacles' and
            people's bounds), 3 radii apart.
        active: vector ``M``, 1.0 for a person present, 0.0 for one still waiting.
    """

    def __init__(
        self,
        people: Sequence[Person],
        params: SocialForceParams,
        obstacles: Obstacles,
        robot_names: Sequence[str] = (),
        robot_radii: Sequence[float] = (),
        *,
        rate_hz: float,
        parking: tuple[float, float] | None = None,
    ):
        super().__init__()
        self._people = tuple(people)
        self._params = params
        self._obstacles = obstacles
        self._num_robots = len(robot_names)
        self._robot_radii = np.asarray(robot_radii, dtype=float).reshape(-1)
        if len(self._robot_radii) != self._num_robots:
            raise ValueError(f"robot_radii has {len(self._robot_radii)} entries, "
                             f"expected one per robot of robot_names ({self._num_robots})")
        if not rate_hz > 0:
            raise ValueError(f"rate_hz must be > 0, got {rate_hz}")
        self._dt = 1.0 / rate_hz
        m = len(self._people)
        if any(not p.waypoints for p in self._people):
            raise ValueError("every person needs at least one waypoint")

        self._names = tuple(p.name for p in self._people)
        self._radii = np.full(m, float(params.radius))
        self._frozen_radii = frozen_array(self._radii)
        self._speeds = np.array([p.desired_speed for p in self._people], dtype=float)
        self._entry = np.array([p.entry_time for p in self._people], dtype=float)
        self._late = bool(np.any(self._entry > 0.0))  # else everyone is present from the start
        self._all_present = np.ones(m)
        self._starts = np.array([p.start for p in self._people], dtype=float).reshape(m, 2)
        self._counts = np.array([len(p.waypoints) for p in self._people], dtype=int)
        self._waypoints = np.zeros((m, max(self._counts, default=1), 2))
        for i, p in enumerate(self._people):
            self._waypoints[i, : len(p.waypoints)] = p.waypoints
        self._parking = self._parking_spots(parking)
        self._constants = np.array([self._dt, params.waypoint_tolerance, params.relaxation_time,
                                    params.repulsion_strength, params.repulsion_range,
                                    params.wall_strength, params.wall_range, params.max_speed,
                                    params.robot_repulsion_gain, params.yield_distance,
                                    params.waiting_gap, params.yield_time, params.passing_gap,
                                    params.sidestep_ratio, float(params.yield_to_robots),
                                    params.negligible_force],
                                   dtype=float)

        first = self._waypoints[:, 0] - self._starts
        present = self._entry <= 0.0
        # One group: an update reads and writes it once (five groups cost more than the step).
        self.DeclareDiscreteState(np.concatenate([
            self._starts.reshape(-1), np.zeros(3 * m), np.arctan2(first[:, 1], first[:, 0]),
            present.astype(float)]))
        self.DeclarePeriodicDiscreteUpdateEvent(self._dt, 0.0, self._update)
        self._no_robots = (np.zeros((0, ROBOT_STATE_SIZE)), np.zeros(0), np.zeros(0),
                           np.zeros(0))

        self._robot_state = self.DeclareVectorInputPort(
            "robot_state", ROBOT_STATE_SIZE * self._num_robots)
        state = {self.xd_ticket()}
        self.DeclareAbstractOutputPort(
            "human_states", lambda: AbstractValue.Make(HumanStates()), self._calc_human_states,
            prerequisites_of_calc=state)
        self.DeclareVectorOutputPort(
            "plant_positions", BasicVector(PLANAR_POSITION_SIZE * m),
            self._calc_plant_positions, prerequisites_of_calc=state)
        self.DeclareVectorOutputPort(
            "active", BasicVector(m), self._calc_active, prerequisites_of_calc=state)

    @property
    def people(self) -> tuple[Person, ...]:
        return self._people

    @property
    def human_names(self) -> tuple[str, ...]:
        return self._names

    @property
    def human_radii(self) -> np.ndarray:
        """(M,) body radii, m."""
        return self._radii.copy()

    def _parking_spots(self, parking) -> np.ndarray:
        """(M, 2) places for waiting people: a row running west from ``parking``."""
        if parking is None:
            xy = [p.start for p in self._people] + [w for p in self._people for w in p.waypoints]
            if len(self._obstacles):
                x0, _, y0, _ = self._obstacles.bounds()
                xy.append((x0, y0))
            corner = np.min(xy, axis=0) if xy else np.zeros(2)
            parking = corner - PARKING_GAP
        spots = np.zeros((len(self._people), 2))
        spots[:, 0] = parking[0] - 3.0 * self._radii * np.arange(len(self._people))
        spots[:, 1] = parking[1]
        return spots

    # --- outputs -----------------------------------------------------------------------------

    def _state(self, context) -> np.ndarray:
        """The state (7M,), laid out as in the class docstring (a read-only view)."""
        return context.get_discrete_state_vector().value()

    def _calc_human_states(self, context, output):
        p, v = _placed(self._state(context), self._parking)
        p.flags.writeable = v.flags.writeable = False  # new arrays: frozen without a copy
        output.set_value(HumanStates(names=self._names, positions=p, velocities=v,
                                     radii=self._frozen_radii))

    def _calc_plant_positions(self, context, output):
        x, m = self._state(context), len(self._names)
        output.SetFromVector(np.column_stack([_placed(x, self._parking)[0],
                                              x[5 * m: 6 * m]]).reshape(-1))

    def _calc_active(self, context, output):
        if not self._late:
            output.SetFromVector(self._all_present)
            return
        output.SetFromVector((self._state(context)[6 * len(self._names):] > 0.5).astype(float))

    # --- update ------------------------------------------------------------------------------

    def _robots(self, context):
        """Robot states (N, 4), cosines and sines of their headings (N,), radii (N,); empty
        when unconnected."""
        if self._num_robots == 0 or not self._robot_state.HasValue(context):
            return self._no_robots
        x = self._robot_state.Eval(context).reshape(self._num_robots, ROBOT_STATE_SIZE)
        return x, np.cos(x[:, 2]), np.sin(x[:, 2]), self._robot_radii

    def _update(self, context, discrete_state):
        x, out = self._state(context), discrete_state.get_mutable_value()
        out[:] = x
        robots, cos, sin, robot_r = self._robots(context)
        time, m = context.get_time(), len(self._names)
        if self._late and np.any((x[6 * m:] <= 0.5) & (self._entry <= time + 1e-9)):
            _enter(time, out, robots, robot_r, self._radii, self._entry, self._starts)
        _step_people(out, robots, cos, sin, robot_r, self._radii, self._speeds, self._counts,
                     self._waypoints, self._obstacles.compiled, self._constants)


@numba.njit(cache=True)
def _placed(x, parking):
    """New arrays from the state ``x``: positions (M, 2), with waiting people at their
    ``parking`` spots (M, 2), and velocities (M, 2), zero for waiting people."""
    m = len(parking)
    p, v = np.empty((m, 2)), np.zeros((m, 2))
    for i in range(m):
        present = x[6 * m + i] > 0.5
        for c in range(2):
            p[i, c] = x[2 * i + c] if present else parking[i, c]
            if present:
                v[i, c] = x[2 * m + 2 * i + c]
    return p, v


# The update, compiled: indices of ``SocialForceHumans._constants``.
(_DT, _TOLERANCE, _RELAXATION, _STRENGTH, _RANGE, _WALL_STRENGTH, _WALL_RANGE, _MAX_SPEED,
 _ROBOT_GAIN, _YIELD_DISTANCE, _WAITING_GAP, _YIELD_TIME, _PASSING_GAP, _SIDESTEP,
 _YIELDS, _NEGLIGIBLE) = range(16)

# The kernels below copy arrays element by element: numba's array expressions, slice and
# fancy-index assignments (broadcasting, and error messages built from strings) take seconds
# to compile, and a sliced argument ('A' layout) compiles a second copy of its callee.


@numba.njit(cache=True)
def _enter(time, state, robots, robot_r, radii, entry, starts):
    """Lets waiting people whose ``entry`` time has come enter, in people order, when their
    start is at least ``ENTRY_GAP`` (surface to surface) from everyone present and from the
    ``robots`` (N, 4) (modifies ``state``, laid out as in the class docstring)."""
    m = len(radii)
    for i in range(m):
        if state[6 * m + i] > 0.5 or not entry[i] <= time + 1e-9:
            continue
        clear = True
        for j in range(m + len(robots)):
            if j < m:
                if not state[6 * m + j] > 0.5:
                    continue
                x, y, reach = state[2 * j], state[2 * j + 1], radii[j]
            else:
                x, y, reach = robots[j - m, 0], robots[j - m, 1], robot_r[j - m]
            dx, dy = x - starts[i, 0], y - starts[i, 1]
            if not math.sqrt(dx * dx + dy * dy) - reach - radii[i] >= ENTRY_GAP:
                clear = False
                break
        if clear:
            state[6 * m + i] = 1.0
            state[2 * i], state[2 * i + 1] = starts[i, 0], starts[i, 1]
            state[2 * m + 2 * i], state[2 * m + 2 * i + 1] = 0.0, 0.0


@numba.njit(cache=True)
def _step_people(state, robots, cos, sin, robot_r, radii_all, speeds_all, counts, waypoints,
                 obstacles, constants):
    """Steps 1-4 of the class docstring for the people present, in place on ``state`` (laid
    out as in the class docstring); ``robots`` (N, 4) robot states, ``cos`` and ``sin`` (N,)
    of their headings (numpy's, so that the result does not depend on the compiled math
    library); ``obstacles``: ``Obstacles.compiled``."""
    m, n = len(radii_all), len(robots)
    dt, tolerance = constants[_DT], constants[_TOLERANCE]
    robot_p, robot_v = np.empty((n, 2)), np.empty((n, 2))
    for j in range(n):
        robot_p[j, 0], robot_p[j, 1] = robots[j, 0], robots[j, 1]
        robot_v[j, 0], robot_v[j, 1] = robots[j, 3] * cos[j], robots[j, 3] * sin[j]
    a = np.empty(m, dtype=np.int64)
    k = 0
    for i in range(m):
        if state[6 * m + i] > 0.5:
            a[k] = i
            k += 1
    pa, va, goal = np.empty((k, 2)), np.empty((k, 2)), np.empty((k, 2))
    radii, speeds, targets = np.empty(k), np.empty(k), np.empty(k, dtype=np.int64)
    for j in range(k):
        i = a[j]
        radii[j], speeds[j], targets[j] = radii_all[i], speeds_all[i], int(state[4 * m + i])
        for c in range(2):
            pa[j, c], va[j, c] = state[2 * i + c], state[2 * m + 2 * i + c]
            goal[j, c] = waypoints[i, targets[j], c]
    reached = _taken(goal, pa, radii, robot_p, robot_r)
    direction, accel = np.zeros((k, 2)), np.empty((k, 2))
    for j in range(k):
        i = a[j]
        gx, gy = goal[j, 0] - pa[j, 0], goal[j, 1] - pa[j, 1]
        if reached[j] or math.sqrt(gx * gx + gy * gy) < tolerance:
            targets[j] = (targets[j] + 1) % counts[i]
        tx, ty = waypoints[i, targets[j], 0] - pa[j, 0], waypoints[i, targets[j], 1] - pa[j, 1]
        distance = math.sqrt(tx * tx + ty * ty)
        if distance > 1e-9 and not (counts[i] == 1 and distance < tolerance):
            direction[j, 0], direction[j, 1] = tx / distance, ty / distance
    desired = _yielding_velocities(pa, va, direction, speeds, radii, robot_p, robot_v,
                                   robot_r, obstacles, constants)
    for j in range(k):
        for c in range(2):
            accel[j, c] = (desired[j, c] - va[j, c]) / constants[_RELAXATION]
    force = np.zeros((k, 2))
    _add_repulsion(pa, direction, radii, pa, va, radii, constants[_STRENGTH],
                   constants[_RANGE], constants[_NEGLIGIBLE], force)
    _add_into(accel, force)
    force = np.zeros((k, 2))
    _add_repulsion(pa, direction, radii, robot_p, robot_v, robot_r,
                   constants[_STRENGTH] * constants[_ROBOT_GAIN], constants[_RANGE],
                   constants[_NEGLIGIBLE], force)
    _add_into(accel, force)
    closest, clearance = closest_points_of(pa, *obstacles)
    outward = _outward(pa, closest, clearance)
    for j in range(k):
        wall = constants[_WALL_STRENGTH] / constants[_WALL_RANGE] * np.exp(
            -max(clearance[j], 0.0) / constants[_WALL_RANGE])
        accel[j, 0] += wall * outward[j, 0]
        accel[j, 1] += wall * outward[j, 1]
    va_new, free_step = np.empty((k, 2)), np.empty((k, 2))
    for j in range(k):
        for c in range(2):
            va_new[j, c] = va[j, c] + dt * accel[j, c]
    va_new = _cap_speed(va_new, constants[_MAX_SPEED])
    for j in range(k):
        for c in range(2):
            free_step[j, c] = pa[j, c] + dt * va_new[j, c]
    # Each robot where it is and where its velocity takes it by the end of the step.
    bodies, body_r = np.empty((2 * n, 2)), np.empty(2 * n)
    for j in range(n):
        body_r[j], body_r[n + j] = robot_r[j], robot_r[j]
        for c in range(2):
            bodies[j, c], bodies[n + j, c] = robot_p[j, c], robot_p[j, c] + dt * robot_v[j, c]
    pa_new, blocked = _project(free_step, pa, closest, clearance, radii, bodies, body_r,
                               obstacles)
    for j in range(k):
        for c in range(2):
            va_new[j, c] = va_new[j, c] + (pa_new[j, c] - free_step[j, c]) / dt
    va_new = _cap_speed(va_new, constants[_MAX_SPEED])
    for j in range(k):
        i = a[j]
        if blocked[j]:
            va_new[j, 0], va_new[j, 1] = 0.0, 0.0
        for c in range(2):
            state[2 * i + c], state[2 * m + 2 * i + c] = pa_new[j, c], va_new[j, c]
        state[4 * m + i] = targets[j]
        if math.sqrt(va_new[j, 0] ** 2 + va_new[j, 1] ** 2) > STOPPED_SPEED:
            state[5 * m + i] = np.arctan2(va_new[j, 1], va_new[j, 0])


@compiled_helper
def _add_into(target, values):
    """``target += values`` for (k, 2) arrays, element by element."""
    for j in range(len(target)):
        target[j, 0] += values[j, 0]
        target[j, 1] += values[j, 1]


@compiled_helper
def _yielding_velocities(p, velocities, direction, speeds, radii, robot_p, robot_v, robot_r,
                         obstacles, constants) -> np.ndarray:
    """Desired velocities (a, 2), m/s, of people at ``p`` (a, 2) moving at ``velocities``
    (a, 2), walking in unit ``direction`` (a, 2) at ``speeds`` (a,), yielding to the robot
    in their way with the highest urgency (``SocialForceParams``; the gap counted less the
    closing speed, person's and robot's, times ``yield_time``):
    ``speed ((1 - u) e + u r s n)``, ``e`` the
    walking direction, ``n`` its right normal, ``u`` the urgency, ``r`` the sidestep ratio,
    ``s`` = +1 (right) when the robot has room to pass on the person's right, else -1 when
    on its left, else 0 (the person slows to a stand). People who do not yield
    (``yield_to_robots`` off) walk on at ``speed e``."""
    reach, wait = constants[_YIELD_DISTANCE], constants[_WAITING_GAP]
    desired = np.empty((len(p), 2))
    if constants[_YIELDS] == 0.0:
        for i in range(len(p)):
            desired[i, 0], desired[i, 1] = speeds[i] * direction[i, 0], speeds[i] * direction[i, 1]
        return desired
    for i in range(len(p)):
        ex, ey = direction[i, 0], direction[i, 1]
        nx, ny = ey, -ex  # the person's right
        urgency, robot = 0.0, -1
        for j in range(len(robot_p)):
            rx, ry = robot_p[j, 0] - p[i, 0], robot_p[j, 1] - p[i, 1]
            band = radii[i] + robot_r[j] + constants[_PASSING_GAP]
            if not (rx * ex + ry * ey > 0.0 and abs(rx * nx + ry * ny) < band):
                continue
            distance = math.sqrt(rx * rx + ry * ry)
            closing = max(((velocities[i, 0] - robot_v[j, 0]) * rx
                           + (velocities[i, 1] - robot_v[j, 1]) * ry) / max(distance, 1e-9), 0.0)
            gap = distance - radii[i] - robot_r[j] - closing * constants[_YIELD_TIME]
            u = min(max((reach - gap) / (reach - wait), 0.0), 1.0)
            if u > urgency:
                urgency, robot = u, j
        side = 0.0
        if robot >= 0:
            width = 2.0 * radii[i] + constants[_PASSING_GAP]
            for s in (1.0, -1.0):
                if _room(robot_p[robot, 0], robot_p[robot, 1], s * nx, s * ny, robot_r[robot],
                         width, obstacles):
                    side = s
                    break
        forward, aside = 1.0 - urgency, urgency * constants[_SIDESTEP] * side
        desired[i, 0] = speeds[i] * (forward * ex + aside * nx)
        desired[i, 1] = speeds[i] * (forward * ey + aside * ny)
    return desired


@compiled_helper
def _room(x, y, ux, uy, radius, width, obstacles) -> bool:
    """True when the obstacles leave at least ``width`` (m) beside a robot of ``radius`` at
    (``x``, ``y``), along the unit vector (``ux``, ``uy``)."""
    reach = radius + width
    hit, origin, dx, dy = np.empty((1, 1)), np.empty((1, 2)), np.empty((1, 1)), np.empty((1, 1))
    hit[0, 0], origin[0, 0], origin[0, 1], dx[0, 0], dy[0, 0] = reach, x, y, ux, uy
    cast_rays_into(origin, dx, dy, *obstacles, hit)
    return hit[0, 0] >= reach


@compiled_helper
def _project(new, old, old_closest, old_clearance, radii, robot_p, robot_r, obstacles):
    """Hard constraints on the step ``old`` -> ``new`` (positions (a, 2); ``old_closest``
    and ``old_clearance``: ``closest_points_of`` at ``old``; robots: discs at ``robot_p``
    (b, 2) of ``robot_r`` (b,)): overlapping people are pushed apart; nobody steps closer to
    a robot (surface to surface) than
    min(``ROBOT_STANDOFF``, its gap before the step), so only a robot's own motion can
    cause contact; everyone ends at clearance >= radius from obstacles. Returns the new
    positions and the mask of people blocked, who would still break a robot floor or lose
    clearance below min(radius, old clearance), and so stay at ``old``."""
    a, b = len(new), len(robot_p)
    new = new.copy()
    floor = np.empty((a, b))  # min(ROBOT_STANDOFF, gap before the step)
    for i in range(a):
        for j in range(b):
            floor[i, j] = min(ROBOT_STANDOFF, _gap_within(old, radii, robot_p, robot_r, i, j,
                                                          ROBOT_STANDOFF))
    known, closest, clearance = old.copy(), old_closest.copy(), old_clearance.copy()
    deep = False  # someone ends the iteration pushed out of an obstacle
    for _ in range(PROJECTION_ITERATIONS):
        apart, away = _apart(new, radii), _away(new, radii, robot_p, robot_r, floor)
        shifted = False
        for i in range(a):
            for c in range(2):
                shift = apart[i, c] + away[i, c]
                new[i, c] += shift
                shifted = shifted or shift != 0.0
        _refresh_closest(new, known, closest, clearance, obstacles)
        outward = _outward(new, closest, clearance)
        deep = False
        for i in range(a):
            depth = max(radii[i] - clearance[i], 0.0)
            deep = deep or depth != 0.0
            new[i, 0] += depth * outward[i, 0]
            new[i, 1] += depth * outward[i, 1]
        if not shifted and not deep:
            break
    if deep:
        _refresh_closest(new, known, closest, clearance, obstacles)
    blocked = np.zeros(a, dtype=np.bool_)
    for i in range(a):
        blocked[i] = clearance[i] < min(radii[i], old_clearance[i]) - 1e-9
        for j in range(b):
            least = floor[i, j] - 1e-9
            if _gap_within(new, radii, robot_p, robot_r, i, j, least) < least:
                blocked[i] = True
        if blocked[i]:
            new[i, 0], new[i, 1] = old[i, 0], old[i, 1]
    return new, blocked


@compiled_helper
def _refresh_closest(p, known, closest, clearance, obstacles):
    """``closest_points_of`` points ``p`` (n, 2) into ``closest`` (n, 2) and ``clearance``
    (n,), which hold it for the points ``known`` (n, 2): only the points that moved (bit
    for bit) are queried again; then ``known`` = ``p``."""
    moved = np.empty(len(p), dtype=np.int64)
    count = 0
    for i in range(len(p)):
        if not (_same(p[i, 0], known[i, 0]) and _same(p[i, 1], known[i, 1])):
            moved[count] = i
            count += 1
    if count == 0:
        return
    queried = np.empty((count, 2))
    for k in range(count):
        queried[k, 0], queried[k, 1] = p[moved[k], 0], p[moved[k], 1]
    q, d = closest_points_of(queried, *obstacles)
    for k in range(count):
        i = moved[k]
        closest[i, 0], closest[i, 1], clearance[i] = q[k, 0], q[k, 1], d[k]
        known[i, 0], known[i, 1] = p[i, 0], p[i, 1]


@compiled_helper
def _same(x, y) -> bool:
    """True when x and y are the same number, zeros of the same sign included."""
    return x == y and math.copysign(1.0, x) == math.copysign(1.0, y)


@compiled_helper
def _add_repulsion(p, direction, radii, q, q_velocity, q_radii, strength, reach, negligible,
                   force):
    """Adds to ``force`` (a, 2) the elliptical-potential force (m/s^2) of every other (q) on
    each person (p) walking in ``direction`` (a, 2) (q may be the people themselves: nobody
    repels a body at its own position); ``strength`` V0, ``reach`` sigma.

    Pairs whose force is surely below ``negligible`` (m/s^2; 0: none) are skipped. A pair's
    force is at most ``V0 / sigma GRADIENT_CAP (1 + KEEP_RIGHT) exp(-(b - r_i - r_j) /
    sigma)``, and the semi-minor axis ``b`` of the ellipse through the person, with the
    other's walk ``s`` (m) between its foci, is at least ``n - s`` at centre distance ``n``
    >= ``s``; so a pair with ``n > s + r_i + r_j + cutoff`` is skipped, ``cutoff = sigma
    ln(V0 GRADIENT_CAP (1 + KEEP_RIGHT) / (sigma negligible))``."""
    cos_view = math.cos(FIELD_OF_VIEW)
    ceiling = strength / reach * GRADIENT_CAP * (1.0 + KEEP_RIGHT)  # m/s^2, at b = r_i + r_j
    if negligible <= 0.0:
        cutoff = math.inf
    elif ceiling <= negligible:
        return  # every pair's force is below negligible
    else:
        cutoff = reach * math.log(ceiling / negligible)
    # Each other's next ELLIPSE_TIME s of walk (m) and walking direction, once per other.
    walk, ux, uy = np.empty(len(q)), np.empty(len(q)), np.empty(len(q))
    for j in range(len(q)):
        speed = math.sqrt(q_velocity[j, 0] ** 2 + q_velocity[j, 1] ** 2)
        walk[j] = speed * ELLIPSE_TIME
        ux[j], uy[j] = q_velocity[j, 0] / max(speed, 1e-12), q_velocity[j, 1] / max(speed, 1e-12)
    for i in range(len(p)):
        dx, dy = direction[i, 0], direction[i, 1]
        for j in range(len(q)):
            r1x, r1y = p[i, 0] - q[j, 0], p[i, 1] - q[j, 1]  # from the other to the person
            far = walk[j] + radii[i] + q_radii[j] + cutoff
            if r1x * r1x + r1y * r1y > far * far:
                continue
            n1 = math.sqrt(r1x * r1x + r1y * r1y)
            if n1 < 1e-9:
                continue
            s = walk[j]
            # From the other's position ELLIPSE_TIME s ahead.
            r2x, r2y = r1x - s * ux[j], r1y - s * uy[j]
            n2 = math.sqrt(r2x * r2x + r2y * r2y)
            b = 0.5 * math.sqrt(max((n1 + n2) ** 2 - s * s, 0.0))
            g = (n1 + n2) / (4.0 * max(b, 1e-9))
            gx = g * (r1x / max(n1, 1e-12) + r2x / max(n2, 1e-12))
            gy = g * (r1y / max(n1, 1e-12) + r2y / max(n2, 1e-12))
            cap = min(1.0, GRADIENT_CAP / max(math.sqrt(gx * gx + gy * gy), 1e-12))
            magnitude = strength / reach * math.exp(-max(b - radii[i] - q_radii[j], 0.0) / reach)
            fx, fy = magnitude * (gx * cap), magnitude * (gy * cap)
            # The other is in view when -force (pointing at it) is within FIELD_OF_VIEW of
            # the person's desired direction.
            if not -(dx * fx + dy * fy) >= math.sqrt(fx * fx + fy * fy) * cos_view:
                fx, fy = fx * OUT_OF_VIEW_WEIGHT, fy * OUT_OF_VIEW_WEIGHT
            # Keeping right breaks the symmetry of head-on encounters, which would deadlock.
            against = max(-(dx * fx + dy * fy), 0.0)
            force[i, 0] += fx + KEEP_RIGHT * against * dy
            force[i, 1] += fy - KEEP_RIGHT * against * dx


@compiled_helper
def _gap_within(p, radii, q, q_radii, i, j, limit) -> float:
    """The surface distance between the circles ``p[i]`` and ``q[j]`` where it is at most
    ``limit`` (m), else ``limit`` or more: a pair clearly further apart is not measured
    (``_CLEARLY_APART``), which gives every test against ``limit`` its exact answer."""
    dx, dy = p[i, 0] - q[j, 0], p[i, 1] - q[j, 1]
    near = limit + radii[i] + q_radii[j]
    if near > 0.0 and dx * dx + dy * dy > _CLEARLY_APART * near * near:
        return math.inf
    return math.sqrt(dx ** 2 + dy ** 2) - radii[i] - q_radii[j]


# Squared distances this far over a squared threshold are over it after the square root,
# rounding included: pairs clearly apart are skipped without one (the same results).
_CLEARLY_APART = 1.000001


@compiled_helper
def _apart(p, radii) -> np.ndarray:
    """Shifts (a, 2) that move each overlapping pair of people half the overlap apart."""
    shift = np.zeros((len(p), 2))
    for i in range(len(p)):
        for j in range(len(p)):
            ox, oy = p[i, 0] - p[j, 0], p[i, 1] - p[j, 1]
            if ox * ox + oy * oy > _CLEARLY_APART * (radii[i] + radii[j]) ** 2:
                continue  # no overlap, as the test below would find
            dist = math.sqrt(ox * ox + oy * oy)
            overlap = radii[i] + radii[j] - dist
            if i != j and overlap > 0 and dist > 1e-9:
                push = 0.5 * overlap / dist
                shift[i, 0] += push * ox
                shift[i, 1] += push * oy
    return shift


@compiled_helper
def _away(p, radii, q, q_radii, floor) -> np.ndarray:
    """Shifts (a, 2) that move people straight away from robots q until each gap >= floor."""
    shift = np.zeros((len(p), 2))
    for i in range(len(p)):
        for j in range(len(q)):
            ox, oy = p[i, 0] - q[j, 0], p[i, 1] - q[j, 1]
            near = floor[i, j] + radii[i] + q_radii[j]
            if near <= 0.0 or ox * ox + oy * oy > _CLEARLY_APART * near * near:
                continue  # no deficit, as the test below would find (it would add zeros)
            dist = math.sqrt(ox * ox + oy * oy)
            deficit = max(floor[i, j] - (dist - radii[i] - q_radii[j]), 0.0)
            if dist > 1e-9:
                shift[i, 0] += deficit / dist * ox
                shift[i, 1] += deficit / dist * oy
    return shift


@compiled_helper
def _taken(goal, p, radii, robot_p, robot_r) -> np.ndarray:
    """True for people within ``TAKEN_REACH`` of a target that someone else's body (a
    robot's or another person's) covers, so they cannot get closer."""
    taken = np.zeros(len(p), dtype=np.bool_)
    for i in range(len(p)):
        if not math.hypot(goal[i, 0] - p[i, 0], goal[i, 1] - p[i, 1]) < TAKEN_REACH:
            continue
        for j in range(len(p) + len(robot_p)):
            if j < len(p):
                x, y, reach = p[j, 0], p[j, 1], radii[j]
            else:
                x, y, reach = robot_p[j - len(p), 0], robot_p[j - len(p), 1], robot_r[j - len(p)]
            if j != i and math.sqrt((goal[i, 0] - x) ** 2
                                    + (goal[i, 1] - y) ** 2) < reach + radii[i]:
                taken[i] = True
                break
    return taken


@compiled_helper
def _outward(p, closest, clearance) -> np.ndarray:
    """Unit vectors (n, 2) pointing from the obstacle out to each point (zero if undefined)."""
    out = np.zeros((len(p), 2))
    for i in range(len(p)):
        sign = -1.0 if clearance[i] < 0 else 1.0
        ox, oy = sign * (p[i, 0] - closest[i, 0]), sign * (p[i, 1] - closest[i, 1])
        norm = math.sqrt(ox * ox + oy * oy)
        if norm > 1e-12:
            out[i, 0], out[i, 1] = ox / norm, oy / norm
    return out


@compiled_helper
def _cap_speed(v, max_speed: float) -> np.ndarray:
    out = np.empty((len(v), 2))
    for i in range(len(v)):
        scale = min(1.0, max_speed / max(math.sqrt(v[i, 0] ** 2 + v[i, 1] ** 2), 1e-12))
        out[i, 0], out[i, 1] = v[i, 0] * scale, v[i, 1] * scale
    return out
