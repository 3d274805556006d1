"""Every payload that travels on a port between mrta-drake blocks, in one place.

Numeric per-robot signals travel as plain vector ports; everything else as abstract ports
(``Value[object]``) holding one of the frozen dataclasses below. A block that is swapped for
another must read and write the same payloads.

Vector layouts (N robots in scenario order, M humans; world frame, metres, radians, seconds):

- robot state, ``4N``: ``[x, y, theta, v]`` per robot: position of the robot centre, heading
  (yaw about +z, 0 = east), forward speed (m/s).
- robot commands, ``2N``: ``[v, omega]`` per robot: commanded forward speed (m/s) and yaw
  rate (rad/s). The robot block applies its own acceleration and speed limits.
- plant positions, ``3N`` (robots) or ``3M`` (humans): ``[x, y, theta]`` per body, the
  generalized positions of the bodies' planar joints in the ``MultibodyPlant``.

Arrays inside payloads are read-only numpy arrays; never modify a payload, make a new one.
"""

from dataclasses import dataclass, field
from enum import IntEnum
from functools import cached_property

import numpy as np

ROBOT_STATE_SIZE = 4  # x, y, theta, v
ROBOT_COMMAND_SIZE = 2  # v, omega
ROBOT_STOPPED_SPEED = 0.05  # m/s: a robot slower than this is at rest
PLANAR_POSITION_SIZE = 3  # x, y, theta


def frozen_array(values, dtype=float, shape=None) -> np.ndarray:
    """A read-only copy of ``values`` as a numpy array (reshaped to ``shape`` if given)."""
    array = np.array(values, dtype=dtype)
    if shape is not None:
        array = array.reshape(shape)
    array.flags.writeable = False
    return array


# --- Allocation: allocator -> waypoint generators -------------------------------------------

PICKUP = "pickup"
DROPOFF = "dropoff"
VISIT = "visit"


@dataclass(frozen=True)
class Stop:
    """One visit a robot must make: go to ``location`` and do ``action`` there.

    ``key`` identifies the stop across re-plans (e.g. ``"t3/pickup"``): a waypoint generator
    never repeats a stop whose key it has completed. ``planned_time`` is the allocator's
    predicted completion time (s, simulation time; ``nan`` if the allocator makes none).
    """

    key: str
    location: int
    action: str = VISIT
    task: int | None = None
    planned_time: float = float("nan")


@dataclass(frozen=True)
class RobotPlan:
    """The ordered stops one robot is to make, first stop first. A new plan replaces the old
    one; stops already completed (by ``key``) are skipped."""

    robot: str
    stops: tuple[Stop, ...] = ()


@dataclass(frozen=True)
class FleetPlan:
    """The allocator's output: one plan per robot, in scenario robot order. ``revision``
    increases whenever any plan changes."""

    plans: tuple[RobotPlan, ...]
    revision: int = 0


# --- Progress: waypoint generators -> allocator, results ------------------------------------


@dataclass(frozen=True)
class Visit:
    """A completed stop: the robot reached ``location`` and finished ``key`` at ``time`` (s),
    having set off for it at ``began`` (s; None when unknown)."""

    key: str
    location: int
    time: float
    task: int | None = None
    action: str = VISIT
    began: float | None = None


@dataclass(frozen=True)
class Detour:
    """A robot's route ahead changed at ``time`` (s) because the blockages named in
    ``blockages`` closed or opened; ``found`` False: no lane led to its stop then, so it
    waits where it is until the blockages change again."""

    time: float
    blockages: tuple[str, ...]
    found: bool = True


@dataclass(frozen=True)
class RobotProgress:
    """What one robot has done so far: every completed visit, oldest first; the location it
    last completed (or its start location); the stop it is driving to now; every detour
    blockages forced on it, oldest first."""

    robot: str
    visits: tuple[Visit, ...] = ()
    last_location: int | None = None
    current_stop: Stop | None = None
    detours: tuple[Detour, ...] = ()


class RobotMode(IntEnum):
    """What a robot is doing. A ``WaypointPolicy`` takes each stop through these phases;
    a ``RunRecorder`` infers one of the first four for each robot at each sample from the
    ports (its ``mode_array``), so it counts a robot entering a room as ``DRIVE`` and one
    parking or waiting as ``IDLE``."""

    IDLE = 0  # no stop to do; the robot stands still
    DRIVE = 1  # along a roadway leg to the tail slot of the stop's queue
    QUEUE = 2  # requesting the stop's room, waiting at a queue slot
    SERVE = 3  # at the point: once holding the room, stand there for the service time
    ENTER = 4  # holding the room, driving through the queue slots and entry to its point
    PARK = 5  # no stop to do: wait on a free parking spot of the last location
    WAIT = 6  # blockages leave no lane to the stop: stand still until they change
    LIFT = 7  # at a lift on the way: queue for it, drive into the cabin, ride to the next level
    HOME = 8  # no stop to do, no parking spot at the last location: back to the start spot


# --- Waypoints: waypoint generator -> planner, controller -----------------------------------


@dataclass(frozen=True)
class WaypointTarget:
    """Where one robot is to drive now (world frame, m).

    ``current`` is the waypoint being driven to and ``next`` the one after it (or ``None``);
    the planner plans through both. ``stop_at_current`` says the robot must come to rest at
    ``current`` (a queue slot or room point) rather than pass through it. An inactive robot
    (``active`` False) has nothing to do and should stand still.
    """

    robot: str
    active: bool = False
    current: tuple[float, float] | None = None
    next: tuple[float, float] | None = None
    stop_at_current: bool = True


# --- Rooms: waypoint generators <-> room queues ---------------------------------------------


@dataclass(frozen=True)
class QueueRequest:
    """One robot's standing request to the room queues.

    ``room`` is the location the robot wants to be queued for (and later hold), or ``None``.
    ``release`` names a room the robot is done with; only the room's holder can release it.
    A robot that stops naming a room it is queued for (but does not hold) leaves that queue.
    ``segments``: the single-file segments the robot wants to hold now, all together, each
    with the way it drives through it (``Roadways.segment_of``: (index, forward)); it gives
    up each one as soon as it stops naming it. ``stops``: the indices of those it will
    stand in (its route ends there, or it stands), not only drive through; ``standing``:
    those it stands in now. ``door``: holding ``room`` and waiting at its door, the robots
    standing in its doorway that it waits for (the deadlock watchdog's cycles of waits).
    """

    robot: str
    room: int | None = None
    release: int | None = None
    segments: tuple[tuple[int, bool], ...] = ()
    stops: tuple[int, ...] = ()
    standing: tuple[int, ...] = ()
    door: tuple[str, ...] = ()


@dataclass(frozen=True)
class RoomQueue:
    """The robots waiting for one room, in order; ``holder`` (if any) has the room."""

    room: int
    holder: str | None = None
    waiting: tuple[str, ...] = ()

    def slot_of(self, robot: str) -> int | None:
        """0-based place of ``robot`` among the waiting robots, or None."""
        return self.waiting.index(robot) if robot in self.waiting else None


@dataclass(frozen=True)
class SegmentHold:
    """Who drives through one single-file segment: ``holders`` (robots, all one way), and
    that way, ``forward`` (along its nodes' order); ``waiting``: the robots waiting for
    segments that name this one, first come first."""

    holders: tuple[str, ...] = ()
    forward: bool = True
    waiting: tuple[str, ...] = ()


FREE_SEGMENT = SegmentHold()


@dataclass(frozen=True)
class QueueState:
    """All rooms' queues, keyed by room id; ``segments``: who holds each single-file
    segment; ``segment_waiting``: the robots waiting for segments, first come first."""

    rooms: tuple[RoomQueue, ...] = ()
    segments: tuple[SegmentHold, ...] = ()
    segment_waiting: tuple[str, ...] = ()

    def holds_segments(self, robot: str, segments: tuple[tuple[int, bool], ...]) -> bool:
        """Whether ``robot`` holds every one of ``segments`` ((index, forward) pairs)."""
        return all(robot in self.segments[k].holders for k, _ in segments)

    def room(self, room: int) -> RoomQueue | None:
        for queue in self.rooms:
            if queue.room == room:
                return queue
        return None

    def __deepcopy__(self, memo):
        return self  # immutable: Drake's copies of the room queues' state can share it


# --- Lifts: waypoint generators <-> lift bank -> robots -------------------------------------


@dataclass(frozen=True)
class LiftRequest:
    """One robot's standing request for a lift: to ride ``lift`` from level ``from_level``
    to level ``to_level`` (all ``None``: no request). A robot that stops asking while
    queued (not yet holding the cabin) leaves the queue; the holder keeps the cabin until
    it has driven out of it."""

    robot: str
    lift: str | None = None
    from_level: str | None = None
    to_level: str | None = None


@dataclass(frozen=True)
class LiftStatus:
    """One lift: the cabin's ``level``, the ``riders`` of its current trip (boarding,
    aboard or driving out), the robots ``waiting`` in request order, the cabin's ``phase``
    (``idle``, ``called``: coming empty to the riders' level, ``open``: waiting for the
    riders to board, ``closing``, ``travel``, ``out``: the riders driving out at the target
    level) and ``berths``, where each rider stands in the cabin on the level it boards at
    (or, ``out``, arrived at); world frame, m. ``trip``: while the cabin moves (``called``,
    ``travel``), (from level, to level, start s, end s), else None."""

    lift: str
    level: str
    riders: tuple[str, ...] = ()
    waiting: tuple[str, ...] = ()
    phase: str = "idle"
    berths: tuple[tuple[float, float], ...] = ()
    trip: tuple[str, str, float, float] | None = None

    def berth(self, robot: str) -> tuple[float, float] | None:
        """Where rider ``robot`` stands in the cabin, or None if it is no rider."""
        return self.berths[self.riders.index(robot)] if robot in self.riders else None


@dataclass(frozen=True)
class LiftState:
    """Every lift's ``LiftStatus``, in the building's order."""

    lifts: tuple[LiftStatus, ...] = ()

    def lift(self, name: str) -> LiftStatus | None:
        return next((status for status in self.lifts if status.lift == name), None)

    def serving(self, robot: str) -> LiftStatus | None:
        """The lift ``robot`` waits for or rides, or None."""
        return next((status for status in self.lifts
                     if robot in status.riders or robot in status.waiting), None)


@dataclass(frozen=True)
class Relocations:
    """Where to put robots, per robot in ``robot_names`` order: ``(sequence, (x, y, theta))``
    or ``None``. A robots block applies a pose once, when its sequence number is new (world
    frame, m, rad)."""

    moves: tuple[tuple[int, tuple[float, float, float]] | None, ...] = ()


# --- Standstills: deadlock watchdog -> planner, recorder ------------------------------------


@dataclass(frozen=True)
class BackOff:
    """An order of the deadlock watchdog: ``robot`` drives to ``point`` (x, y, world frame,
    m) and stands there, instead of following its target, until ``until`` (s); ordered at
    ``issued`` (s) to make way for ``blockers`` (robot names, or people's when it stood
    with people only; stalled since ``stalled_since``, s); ``arrived`` (s) once it reached
    the spot. ``releases``: an order that breaks a gridlock of waits: while it is in force
    the robot also gives up its place in a room's queue and the single-file segments it
    does not stand in (its waypoints block asks for neither), and asks again after it."""

    robot: str
    point: tuple[float, float]
    issued: float
    until: float
    blockers: tuple[str, ...] = ()
    stalled_since: float = 0.0
    arrived: float | None = None
    releases: bool = False


@dataclass(frozen=True)
class BackOffOrders:
    """The back-offs in force (at most one per robot), and every one ordered so far,
    oldest first (``history``, a growing log for the recorder)."""

    active: tuple[BackOff, ...] = ()
    history: tuple[BackOff, ...] = ()

    def of(self, robot: str) -> BackOff | None:
        return next((order for order in self.active if order.robot == robot), None)


NO_BACK_OFFS = BackOffOrders()


# --- Paths: planner -> controller ------------------------------------------------------------

PATH_OK = "ok"
PATH_IDLE = "idle"
PATH_FAILED = "failed"


@dataclass(frozen=True)
class RobotPath:
    """A planned path for one robot: ``points`` (k, 2) in the world frame from near the
    robot's position to its target, m. ``status`` is ``ok``, ``idle`` (nothing to do) or
    ``failed`` (no path; the robot waits and the planner retries). ``stop_at_end`` says the
    robot must come to rest at the last point; ``yielding`` that it leads to a spot the
    deadlock watchdog sent the robot to, out of the others' way."""

    robot: str
    status: str = PATH_IDLE
    points: np.ndarray = field(default_factory=lambda: frozen_array(np.zeros((0, 2))))
    stop_at_end: bool = True
    planned_at: float = 0.0
    yielding: bool = False


@dataclass(frozen=True)
class FleetPaths:
    """One path per robot, in scenario robot order, plus the planner's failure count."""

    paths: tuple[RobotPath, ...]
    failures: int = 0


# --- Humans: humans -> controllers, results --------------------------------------------------


@dataclass(frozen=True)
class HumanStates:
    """Positions (M, 2) and velocities (M, 2) of all humans, world frame, m and m/s, and
    their body radii (M,), m."""

    names: tuple[str, ...] = ()
    positions: np.ndarray = field(default_factory=lambda: frozen_array(np.zeros((0, 2))))
    velocities: np.ndarray = field(default_factory=lambda: frozen_array(np.zeros((0, 2))))
    radii: np.ndarray = field(default_factory=lambda: frozen_array(np.zeros(0)))


NO_HUMANS = HumanStates()


# --- Control telemetry: controller -> results -----------------------------------------------


@dataclass(frozen=True)
class ControllerTelemetry:
    """One control tick's account. Barrier values are the smallest h = |p - p_o|^2 - d^2
    per obstacle kind (m^2; inf when none). ``clusters`` lists robot index tuples, each
    led by its first member. ``qp_calls``: each QP handed to a solver this tick, as its
    number of robots and its wall-clock time (s; a program's first solve includes building
    it)."""

    time: float = 0.0
    min_barrier_wall: float = float("inf")
    min_barrier_human: float = float("inf")
    min_barrier_robot: float = float("inf")
    max_slack: float = 0.0
    control_deviation: float = 0.0  # max over robots of |u - u_nominal|
    clusters: tuple[tuple[int, ...], ...] = ()
    solve_time: float = 0.0  # s (wall clock) spent in solvers this tick
    failures: int = 0  # solver failures this tick (robots braked)
    qp_calls: tuple[tuple[int, float], ...] = ()  # per solver call: (robots in the QP, s)
    leader_disagreement: bool = False  # robots' views of a cluster differ (over a network)
    stale_commands: int = 0  # followers without a fresh command from their leader (braking)


# --- Network: robots -> network -> controller; controller -> network -> controller ------------


@dataclass(frozen=True)
class CommandMessages:
    """The commands cluster leaders sent their followers at one control tick, ``time`` (s):
    ``leaders[i]`` is the robot whose command follower i was sent (-1: none), ``inputs[i]``
    that command ``[a, omega]`` (m/s^2, rad/s; (N, 2))."""

    time: float = -np.inf
    leaders: tuple[int, ...] = ()
    inputs: np.ndarray = field(default_factory=lambda: frozen_array(np.zeros((0, 2))))

    @classmethod
    def from_vector(cls, vector) -> "CommandMessages":
        """The messages of ``as_vector``'s layout."""
        n = (len(vector) - 1) // 3
        return cls(float(vector[0]), tuple(int(k) for k in vector[1:n + 1]),
                   frozen_array(vector[n + 1:], shape=(n, 2)))

    def as_vector(self) -> np.ndarray:
        """``[time, leaders (N), inputs (2N)]``, for a block's discrete state."""
        return np.concatenate([[self.time], self.leaders, np.ravel(self.inputs)])


@dataclass(frozen=True)
class NetworkViews:
    """What each robot has received over the network by ``time`` (s). ``states[i, j]``
    (N, N, 4) is robot j's ``[x, y, theta, v]`` (world frame, m, rad, m/s) as robot i last
    received it, sent at ``sent_at[i, j]`` (s; row i, column i: robot i's own, as at its last
    broadcast). ``commands[i]`` (N, 2) is the last command ``[a, omega]`` robot i received,
    from leader ``command_from[i]`` (-1: none yet), sent at ``command_sent_at[i]`` (s); a
    command older than ``max_age`` s is stale."""

    time: float = 0.0
    states: np.ndarray = field(default_factory=lambda: frozen_array(np.zeros((0, 0, 4))))
    sent_at: np.ndarray = field(default_factory=lambda: frozen_array(np.zeros((0, 0))))
    commands: np.ndarray = field(default_factory=lambda: frozen_array(np.zeros((0, 2))))
    command_from: tuple[int, ...] = ()
    command_sent_at: np.ndarray = field(default_factory=lambda: frozen_array(np.zeros(0)))
    max_age: float = 0.0

    def fresh_command(self, robot: int, leader: int) -> bool:
        """Whether ``robot``'s last command came from ``leader`` and is not stale."""
        return (self.command_from[robot] == leader
                and self.time - self.command_sent_at[robot] <= self.max_age)

    def view_of(self, observer: int, own_state: np.ndarray) -> np.ndarray:
        """Every robot's state (N, 4) as robot ``observer`` knows it at ``time``: the
        others' as last received, carried on at their speed and heading for the state's
        age (dead reckoning), its own ``own_state`` (its own sensors)."""
        view = np.array(self.states[observer])
        travelled = view[:, 3] * (self.time - self.sent_at[observer])
        view[:, 0] += travelled * np.cos(view[:, 2])
        view[:, 1] += travelled * np.sin(view[:, 2])
        view[observer] = own_state
        return view


# --- Disturbances: disturbance schedule -> planner, waypoints, allocator, controller, results


@dataclass(frozen=True)
class Blockage:
    """A region closed to robots: ``box`` (x_min, x_max, y_min, y_max), world frame, m,
    scheduled from ``start`` to ``end`` (s; inf: the end of the run)."""

    name: str
    box: tuple[float, float, float, float]
    start: float
    end: float = float("inf")

    def contains(self, xy) -> np.ndarray:
        """True where world points ``xy`` (shape (..., 2)) lie in the box (edges included)."""
        xy = np.asarray(xy, dtype=float)
        x_min, x_max, y_min, y_max = self.box
        return ((xy[..., 0] >= x_min) & (xy[..., 0] <= x_max)
                & (xy[..., 1] >= y_min) & (xy[..., 1] <= y_max))


@dataclass(frozen=True)
class Breakdown:
    """Robot index ``robot`` (scenario order) is broken down, from ``start`` to ``end`` (s;
    inf: for good)."""

    robot: int
    start: float
    end: float = float("inf")


@dataclass(frozen=True, eq=False)
class Outage:
    """Robot index ``robot`` exchanges no cluster messages from ``start`` to ``end`` (s;
    inf: the end of the run). ``snapshot`` (N, 4) is every robot's ``[x, y, theta, v]`` at
    ``start``: the last states the robot and the others exchanged. (Compared by identity.)"""

    robot: int
    start: float
    end: float
    snapshot: np.ndarray


@dataclass(frozen=True)
class Disturbances:
    """The disturbances in force now: closed regions, broken-down robots, and robots cut
    off from messages (earliest outage first)."""

    blockages: tuple[Blockage, ...] = ()
    breakdowns: tuple[Breakdown, ...] = ()
    outages: tuple[Outage, ...] = ()

    @cached_property
    def broken(self) -> tuple[int, ...]:
        """Indices of the broken-down robots, ascending."""
        return tuple(sorted(b.robot for b in self.breakdowns))

    @cached_property
    def cut_off(self) -> tuple[int, ...]:
        """Indices of the robots cut off from messages, ascending."""
        return tuple(sorted(o.robot for o in self.outages))

    def seen_by(self, states: np.ndarray, observer: int | None = None) -> np.ndarray:
        """The robots' ``states`` (N, 4) as robot ``observer`` knows them (None: as the
        robots still in touch know them): a cut-off robot's state as of its outage's
        start; for a cut-off observer, everyone else's as of its own outage's start (or
        of the other's, if that began earlier). Its own state is always the true one."""
        if not self.outages:
            return states
        view = np.array(states, dtype=float)
        own = next((o for o in self.outages if o.robot == observer), None)
        if own is not None:
            view[:] = own.snapshot
        for outage in self.outages:
            if own is None or outage.start < own.start:
                view[outage.robot] = outage.snapshot[outage.robot]
        if observer is not None:
            view[observer] = states[observer]
        return view


NO_DISTURBANCES = Disturbances()
