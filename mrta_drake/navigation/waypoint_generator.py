"""Turns each robot's plan into waypoints: roadway legs, room queues, entries and service."""

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from operator import attrgetter

import networkx as nx
import numpy as np
from pydrake.common.value import Value
from pydrake.systems.framework import BasicVector, EventStatus, LeafSystem

from mrta_drake.errors import require_positive
from mrta_drake.navigation.roadways import Roadways
from mrta_drake.navigation.single_file import (
    NOTHING,
    Need,
    SingleFileParams,
    need,
    route_runs,
    segment_lanes,
    standing,
    stands_in,
)
from mrta_drake.payloads import (
    NO_BACK_OFFS,
    NO_DISTURBANCES,
    ROBOT_STATE_SIZE,
    ROBOT_STOPPED_SPEED,
    BackOffOrders,
    Detour,
    Disturbances,
    FleetPlan,
    LiftRequest,
    LiftState,
    QueueRequest,
    QueueState,
    RobotMode,
    RobotProgress,
    Stop,
    Visit,
    WaypointTarget,
)
from mrta_drake.world.segment_distances import distance_to_polyline

# The phases in which a robot asks the room queues for its stop's room.
_ASKING_PHASES = (RobotMode.QUEUE, RobotMode.ENTER, RobotMode.SERVE)


@dataclass(frozen=True)
class WaypointParams:
    """Parameters of a ``WaypointPolicy`` (kinds ``roadway`` and ``roadway_per_robot``);
    distances in m, times in s."""

    waypoint_tolerance: float = 1.0  # a waypoint is reached within this distance
    reach_tolerance: float = 1.0  # a location's point is reached within this distance
    service_time: float = 1.0  # standing at the point, holding the room, to finish a stop
    request_distance: float = 3.0  # ask for a place in the queue this close to its tail slot
    release_distance: float = 5.0  # give a room back this far from its point
    parking_clearance: float = 0.8  # a parking spot is taken with another robot this close
    door_clearance: float = 1.0  # a holder waits at its slot while another robot moves this
    # close to the room's entry path or point, or stands this close to its doorway
    door_wait: bool = True  # that wait at all (off: the holder enters at once, as in the paper)
    door_patience: float = 30.0  # but for the doorway no longer than this at a time (s): then
    # it enters as without the wait
    parking: bool = True  # a robot with nothing to do parks off the point: on a parking spot
    # of the location, or where it has none, back on its start spot (off: it stays there)
    overflow_spacing: float = 1.0  # robots beyond a queue's last slot wait this far apart
    lift_request_distance: float = 4.0  # ask for a lift this close to its cabin's point
    lift_wait_distance: float = 3.0  # wait for it this far back along the route from the
    # cabin's point, one more metre per robot ahead in its queue
    single_file: SingleFileParams = SingleFileParams()  # holding single-file segments
    on_lane: float = 0.05  # a start spot this near a lane is on it (``initial_state``)

    def __post_init__(self):
        require_positive(self, "door_clearance", "overflow_spacing", "on_lane", unit=" m")
        require_positive(self, "door_patience", unit=" s")


@dataclass(frozen=True)
class _Drive:
    """The generator's whole state. ``index`` is the route waypoint being driven to (drive,
    enter) or the queue slot being waited at (queue); ``since`` the time service began;
    ``release`` the room the robot asks to release; ``closed`` the blockages (names) in
    force at the last update; ``detours`` the route changes they forced; ``waiting``: to
    serve at a point whose room another robot still holds (e.g. parked in that room), so
    standing still rather than driving onto the holder; ``began`` when the robot set off
    for its stop (s). ``lift_slot``: waiting for a lift, the robot's place in its queue; -1
    once it rides, standing at ``berth`` in the cabin (world frame, m). ``lanes``: the
    single-file segments it needs now, and whether it stands until it holds them.
    ``door_since``: holding the room and not yet through its door, since when the doorway
    has been taken (``WaypointPolicy._door_busy``; s), else None; ``door``: while it so
    waits, the robots standing in the doorway (``WaypointPolicy._doorway_takers``).
    ``giving_way``: a ``releases`` order of the deadlock watchdog is in force for the
    robot."""

    phase: RobotMode = RobotMode.IDLE
    stop: Stop | None = None
    route: tuple[tuple[float, float], ...] = ()
    index: int = 0
    since: float | None = None
    release: int | None = None
    visits: tuple[Visit, ...] = ()
    last_location: int | None = None
    closed: tuple[str, ...] = ()
    detours: tuple[Detour, ...] = ()
    waiting: bool = False
    began: float | None = None
    lift_slot: int = -1
    berth: tuple[float, float] | None = None
    lanes: Need = NOTHING
    door_since: float | None = None
    door: tuple[str, ...] = ()
    giving_way: bool = False

    def __deepcopy__(self, memo):
        return self  # immutable: Drake's copies of the state can share it


@dataclass(frozen=True)
class _FleetState:
    """The fleet waypoints block's state: every robot's policy state, in robot order, and
    the policy's ``outputs`` of each (made once per state, for every output port)."""

    robots: tuple
    outputs: tuple

    def __deepcopy__(self, memo):
        return self  # immutable (so are the policies' states): Drake's copies can share it


@dataclass(frozen=True)
class _Outputs:
    """The output payloads made from one state, ``drive``."""

    drive: _Drive
    target: WaypointTarget
    queue_request: QueueRequest
    progress: RobotProgress
    lift_request: LiftRequest


class WaypointInputs:
    """What the waypoint policies read at one update, read once for all of them: the time
    ``t`` (s), ``plan`` (``FleetPlan``), ``queues`` (``QueueState``), ``disturbances``
    (``Disturbances``), ``back_offs`` (``BackOffOrders``, the deadlock watchdog's), and,
    read from their ports only when first needed (a parked or idle
    robot's update mostly needs neither), ``states``: (N, 4) ``[x, y, theta, v]`` per robot
    in ``robot_names`` order (world frame, m, rad, m/s), and ``lifts`` (``LiftState``)."""

    def __init__(self, ports: "_InputPorts", context):
        self._ports, self._context = ports, context
        self.t = context.get_time()
        self.plan = ports.plan.Eval(context)
        self.queues = ports.queue_state.Eval(context)
        self.disturbances = (ports.disturbances.Eval(context)
                             if ports.disturbances.HasValue(context) else NO_DISTURBANCES)
        self.back_offs: BackOffOrders = (ports.back_offs.Eval(context)
                                         if ports.back_offs.HasValue(context) else NO_BACK_OFFS)
        self._states: np.ndarray | None = None
        self._lifts: LiftState | None = None

    @property
    def states(self) -> np.ndarray:
        if self._states is None:
            self._states = self._ports.robot_state.Eval(self._context).reshape(
                -1, ROBOT_STATE_SIZE)
        return self._states

    @property
    def lifts(self) -> LiftState:
        if self._lifts is None:
            port = self._ports.lift_state
            self._lifts = port.Eval(self._context) if port.HasValue(self._context) \
                else LiftState()
        return self._lifts


@dataclass(frozen=True)
class _InputPorts:
    """The input ports of a waypoints system (``_declare_inputs``)."""

    plan: object
    robot_state: object
    queue_state: object
    lift_state: object
    disturbances: object
    back_offs: object


def _declare_inputs(system: LeafSystem, robots: int) -> _InputPorts:
    """Declares the waypoints inputs ``plan``, ``robot_state`` (4 x ``robots``),
    ``queue_state``, ``lift_state``, ``disturbances`` and ``back_offs`` on ``system``."""
    return _InputPorts(
        system.DeclareAbstractInputPort("plan", Value[object](FleetPlan(()))),
        system.DeclareVectorInputPort("robot_state", BasicVector(ROBOT_STATE_SIZE * robots)),
        system.DeclareAbstractInputPort("queue_state", Value[object](QueueState())),
        system.DeclareAbstractInputPort("lift_state", Value[object](LiftState())),
        system.DeclareAbstractInputPort("disturbances", Value[object](Disturbances())),
        system.DeclareAbstractInputPort("back_offs", Value[object](NO_BACK_OFFS)))


class _Robots:
    """The fleet's ``states`` (from ``WaypointInputs``) and ``xy``, robot ``index``'s
    position (world frame, m), read when first needed; ``broken``: the indices of the
    robots broken down now."""

    def __init__(self, inputs: WaypointInputs, index: int):
        self._inputs, self._index = inputs, index
        self._xy: tuple[float, float] | None = None

    @property
    def states(self) -> np.ndarray:
        return self._inputs.states

    @property
    def xy(self) -> tuple[float, float]:
        if self._xy is None:
            self._xy = _point(self._inputs.states[self._index])
        return self._xy

    @property
    def broken(self) -> tuple[int, ...]:
        return self._inputs.disturbances.broken


def _changed(s: _Drive, **changes) -> _Drive:
    """``replace(s, **changes)``, or ``s`` itself when they change nothing (the hot path:
    most updates change nothing)."""
    for name, value in changes.items():
        current = getattr(s, name)
        if current is not value and current != value:
            return replace(s, **changes)
    return s


def _first_to_do(stops: tuple[Stop, ...], visits: tuple[Visit, ...]) -> Stop | None:
    """The first of ``stops`` no visit completed."""
    if not visits:
        return stops[0] if stops else None
    done = {visit.key for visit in visits}
    return next((stop for stop in stops if stop.key not in done), None)


def _point(xy) -> tuple[float, float]:
    return (float(xy[0]), float(xy[1]))


def _points(array) -> tuple[tuple[float, float], ...]:
    return tuple(_point(xy) for xy in np.asarray(array))


def _points_or_none(array) -> tuple[tuple[float, float], ...] | None:
    return None if array is None else _points(array)


def _leads_to(lanes, a, b, node) -> bool:
    """Whether the lane ``a`` -> ``b`` leads on along ``lanes`` (start, end pairs: one
    single-file segment's) to ``node`` without turning back."""
    came, here = a, b
    seen = set()
    while here != node:
        if here in seen:
            return False
        seen.add(here)
        ahead = [end for start, end in lanes if start == here and end != came]
        if len(ahead) != 1:
            return False  # a dead end, or a fork: no one way on
        came, here = here, ahead[0]
    return True


def _distance(a, b) -> float:
    return math.hypot(a[0] - b[0], a[1] - b[1])


def _nearest(points: np.ndarray, spots) -> np.ndarray:
    """(N,) distance (m) from each of ``points`` (N, 2) to the nearest of ``spots``."""
    spots = np.asarray(spots, dtype=float).reshape(-1, 2)
    return np.linalg.norm(points[:, None, :] - spots[None, :, :], axis=-1).min(axis=1)


def _back_along(points, distance: float) -> tuple[float, float]:
    """The point ``distance`` m back from the last of ``points`` along their polyline (the
    first point if it is shorter)."""
    for k in range(len(points) - 1, 0, -1):
        a, b = points[k - 1], points[k]
        step = _distance(a, b)
        if step >= distance:
            f = distance / step
            return (b[0] + f * (a[0] - b[0]), b[1] + f * (a[1] - b[1]))
        distance -= step
    return points[0]


class WaypointPolicy:
    """Drives robot ``robot_names[index]`` through its plan's stops, one waypoint at a time:
    the per-robot behaviour the waypoints systems (``FleetWaypoints``, one for the fleet, or
    ``WaypointGenerator``, one per robot) call at each of their updates. Plain Python, no
    Drake system: ``initial_state()`` is the robot's state at the start (an immutable
    value), ``update(state, inputs)`` the state after one update from ``inputs``
    (``WaypointInputs``; the same object when nothing changes) and ``outputs(state)`` the
    payloads made from a state (``target``: ``WaypointTarget``, world frame, m;
    ``queue_request``: ``QueueRequest``; ``progress``: ``RobotProgress``, visit times are
    simulation times, s; ``lift_request``: ``LiftRequest``).

    This robot's ``RobotPlan`` is the one of the fleet plan named after it.

    Each update (``update``) takes the current stop through these phases:

    - drive: follow ``roadways.leg`` from the last location (or, away from any location, a
      route from the nearest roadway node) to the tail slot of the stop's queue; waypoints
      count as reached within ``waypoint_tolerance``. Within ``request_distance`` of the
      tail slot, on the last segment, go to queue. A robot that still holds the stop's room
      (sent back to it) drives straight to the point instead.
    - queue: request the room and wait at slot ``place`` (0 the head slot), moving up as
      the queue advances; one slot further back while the holder stands at the head slot
      (within ``waypoint_tolerance``: it waits there, for single-file segments or its
      doorway, and the first robot waiting would stand in its way in); robots beyond the
      last slot wait on the location's overflow spots where it has them, else
      ``overflow_spacing`` apart back from the tail slot towards the approach node
      (``_queue_spot``; before, they all drove to the tail slot and stood
      round it: office seed 2, coe's one slot, whose holder, waiting at it, was boxed in).
    - lift: a route through a lift (``Roadways.lift_edge``: its cabin's node on this level,
      then on the next) is cut there. Within ``lift_request_distance`` of the cabin's point
      the robot requests the lift and waits ``lift_wait_distance`` back along its route
      (one metre more per robot ahead of it in the queue of the lift of the bank the lift
      bank chose); a rider drives to its berth in that lift's cabin and stands until the
      lift bank relocates it to the cabin on the next level, then takes the lanes from
      there to its stop.
    - single file: while driving or entering, the robot asks the room queues for the
      single-file segments of the stretch ahead (``single_file.need``) from
      ``single_file.request_distance`` before it, and stands (target inactive) within
      ``single_file.hold_distance`` of it, or in it, until it holds them all; while it so
      waits, it gives up (for one update) those it holds but does not stand in
      (``single_file.stands_in``), so that it never holds part of a stretch while waiting
      for the rest; it gives them up ``single_file.clear_distance`` past the stretch.
      Queueing or serving, it
      holds the segments it stands in or at its slot or point (``single_file.standing``)
      and no others, standing still until it holds those at its slot or point; but not
      while it waits at a point for a room another robot holds (that robot must come in).
    - enter: once holding the room, drive through the remaining slots and the entry path;
      but while the doorway is taken, wait at the slot (until past the first slot, so also
      a robot granted the room on its way there: at the slot ahead of it, or where it
      stands while it holds single-file segments of its way in, so as to keep them), as
      two robots in a doorway cannot pass: while another robot moves within
      ``door_clearance`` of the entry path or the point (e.g. one that had parked in the
      room, leaving), or stands within ``door_clearance`` of the doorway, from the first
      slot along the entry path to the point, unless it waits for the holder or stands
      there for good (``_doorway_takers``; those it waits for so, standing, it names in
      its queue request's ``door``). After ``door_patience`` s of one such wait the
      holder drives in all the same; with ``door_wait`` off, at once. The mirror: a robot
      about to leave the room it stands in (on its point or a parking spot) while another
      robot holds the room and moves there waits, target inactive, until it stops moving.
    - serve: within ``reach_tolerance`` of the point and holding the room, stand for
      ``service_time``; the stop is then done (a ``Visit`` at that time) and the next begins.
      A stop at the location the robot is already at starts here (requesting the room);
      until it holds the room its target is inactive, so a robot parked in the room does not
      drive onto the holder standing at the point.

    The robot's stops are the plan's stops whose keys it has not completed, re-read every
    update: a new plan with the same first stop location changes nothing (only the stop);
    one with another location re-routes from the next roadway node ahead on the leg, from
    the exit node of the queue it waited in, or out of the room it entered. A completed stop
    is never redone. Without stops the robot parks (unless ``parking`` is off): at a location
    with parking spots it drives to the first one no other robot is within
    ``parking_clearance`` of (park), off the point; at a location without any (a dead end
    of an imported building, where an idle robot would box in the next one), or where
    every one is taken and it has a home (idle robots would pile up round the point), it
    drives back along the lanes to ``home``, its start spot (world frame, m; home: asking for
    single-file segments on the way as when driving), and waits there; where that is on
    another level, to the nearest free parking spot on its level, else the nearest free one
    of ``spots`` (the other robots' start spots) there (``_home_spot``); elsewhere, or with
    no such spot (it started on a location), the target is inactive and it stands still.
    A robot without a home (it started on a location) whose location's spots are all taken
    drives likewise to the nearest free parking spot elsewhere on its level, else another
    robot's free start spot; only with none free does it park on the last spot, beside the
    robot there. A robot parking, or driving to wait at a spot not its home, that another
    robot stands nearer chooses again from where it is (``_keep_spot``): two robots that
    chose one free spot at once would otherwise circle each other round it
    (docs/worlds.md, "Unseen seeds 3-7 of airport_terminal, battle_royale and campus").
    A parked robot given a stop starts it as if standing on the location's point. A robot
    whose start spot is off the lanes starts as one back home (``initial_state``).
    Idle, or back at the spot it drove to wait at, a robot holds the single-file segments
    it stands in; once another robot waits for one of them or holds it (to drive through
    it), it drives out of the way (``_make_way``): out of the segment's end away from that
    robot, to the nearest spot in no segment another robot waits for or holds
    (``_refuge``; boxed inside a corridor with no other, a dead end by a queue slot),
    keeping the segment it drives out of until out of it (``_leaving``).

    Release: the robot asks to release a room it holds (per ``queue_state``) once its
    current stop is elsewhere and it is more than ``release_distance`` from the room's
    point or waits at a slot of that stop's queue (within ``waypoint_tolerance``: out of the
    room, it must not keep it from the robots queueing for it while it queues nearby), or,
    with no stop left, once it is more than ``reach_tolerance`` from the point
    (at once where there is no parking spot, or where another robot stands on the spot it
    drives to: every spot was taken). It keeps naming that room in ``release`` until the
    queues no longer show it as the holder.

    Optional input ``disturbances`` (abstract ``Disturbances``):

    - blockages close the lanes that touch their boxes (``Roadways.closed``): legs and
      routes made while they are in force go around them. When the set of blockages
      changes, a robot driving (or waiting, below) takes the route ahead again: it keeps
      its route if that touches no newly closed box and none has opened, else it goes on to
      the first roadway node ahead it can reach without touching a closed box and from which
      lanes lead to its stop, else to the nearest such node it can reach in a straight line
      (turning back). Each change of route is a ``Detour`` in ``progress``. With no lane
      left to the stop the robot waits (wait, target inactive) until the blockages change.
    - a breakdown of this robot makes it drop its stop and stand (idle): it leaves any
      queue, gives up any room it holds and ignores the plan until it is repaired.

    Optional input ``back_offs`` (abstract ``BackOffOrders``, the deadlock watchdog's):
    while a ``releases`` order is in force for the robot (it gives way to break a gridlock
    of waits) it asks for no room (leaving the queue it waits in) and only for the
    single-file segments it stands in, and stands (the planner drives it to the order's
    spot); after the order it asks again as before, joining the queues' tails.
    """

    def __init__(
        self,
        robot_names: Sequence[str],
        index: int,
        roadways: Roadways,
        start_location: int | None = None,
        params: WaypointParams = WaypointParams(),
        home: tuple[float, float] | None = None,
        spots: Sequence[tuple[float, float]] = (),
    ):
        self._robot = robot_names[index]
        self._names = tuple(robot_names)
        self._home = home
        self._spots = tuple(spot for spot in spots if spot != home)
        self._starts = (*self._spots, *([] if home is None else [home]))  # every robot's
        self._parking = tuple(  # the locations' parking spots that are no robot's start
            _point(spot) for i in roadways.location_ids for spot in roadways.place(i).parking
            if all(_distance(spot, start) > params.parking_clearance for start in self._starts))
        self._index = index
        self._roadways = roadways
        self._params = params
        self._start_location = start_location
        self._spots_cache: dict[tuple, tuple[bool, tuple]] = {}  # ``_spots_reached``'s
        self._refuges: tuple | None = None  # ``_refuge``'s candidate spots, made when needed
        # The outputs of the state last read: most updates keep the state object as it is.
        self._last_outputs: _Outputs | None = None

    @property
    def robot(self) -> str:
        return self._robot

    def initial_state(self) -> _Drive:
        """At the start: a robot whose home (its start spot) is off the lanes (farther than
        ``on_lane`` from every lane: a corridor's centre line between its two lanes, a
        spot beside them) starts as one back home, so that pushed off it with nothing to
        do it drives back rather than standing wherever the others pushed it (onto a lane
        of the corridor across). A robot starting on a lane stays idle: pushed off it, it
        stands off the lane, out of the way (driving back, it would block that lane
        again). docs/worlds.md, "Junction standoffs", has the runs behind the rule."""
        if (self._home is not None and self._params.parking
                and self._roadways.distance_to_lanes(self._home) > self._params.on_lane):
            return _Drive(phase=RobotMode.HOME, route=(self._home,),
                          last_location=self._start_location)
        return _Drive(last_location=self._start_location)

    # --- Outputs -----------------------------------------------------------------------------

    def outputs(self, s: _Drive) -> _Outputs:
        outputs = self._last_outputs
        if outputs is None or outputs.drive is not s:
            outputs = self._last_outputs = _Outputs(
                s, self._target(s),
                QueueRequest(self._robot, s.stop.location if s.phase in _ASKING_PHASES
                             and not s.giving_way else None, s.release, s.lanes.segments,
                             s.lanes.stops, s.lanes.standing, s.door),
                RobotProgress(self._robot, s.visits, s.last_location, s.stop, s.detours),
                self._lift_request(s))
        return outputs

    def _lift_request(self, s: _Drive) -> LiftRequest:
        if s.phase != RobotMode.LIFT:
            return LiftRequest(self._robot)
        ride = self._roadways.lift_edge(s.route[s.index], s.route[s.index + 1])
        return LiftRequest(self._robot, ride.lift, ride.from_level, ride.to_level)

    def _target(self, s: _Drive) -> WaypointTarget:
        if s.phase == RobotMode.PARK:
            parking = _point(self._roadways.place(s.last_location).parking[s.index])
            return WaypointTarget(self._robot, True, parking, None, True)
        if s.phase == RobotMode.HOME and not s.lanes.hold:
            return self._along_route(s)
        if s.stop is None or s.phase == RobotMode.WAIT or s.waiting or s.lanes.hold:
            return WaypointTarget(self._robot)
        if s.phase == RobotMode.LIFT:
            if s.lift_slot < 0:
                berth = s.route[s.index] if s.berth is None else s.berth
                return WaypointTarget(self._robot, True, berth, None, True)
            wait = _back_along(s.route[:s.index + 1],
                               self._params.lift_wait_distance + s.lift_slot)
            return WaypointTarget(self._robot, True, wait, None, True)
        if s.phase in (RobotMode.DRIVE, RobotMode.ENTER):
            return self._along_route(s)
        place = self._roadways.place(s.stop.location)
        spot = self._queue_spot(place, s.index) if s.phase == RobotMode.QUEUE else place.point
        return WaypointTarget(self._robot, True, _point(spot), None, True)

    def _along_route(self, s: _Drive) -> WaypointTarget:
        """Route waypoint ``s.index`` and the one after it; the robot stops at the last."""
        last = len(s.route) - 1
        return WaypointTarget(self._robot, True, s.route[s.index],
                              s.route[s.index + 1] if s.index < last else None,
                              s.index == last)

    # --- Update ------------------------------------------------------------------------------

    def update(self, s: _Drive, inputs: WaypointInputs) -> _Drive:
        old = s
        t = inputs.t
        robots = _Robots(inputs, self._index)
        queues = inputs.queues
        lifts = inputs.lifts if self._roadways.has_lifts else LiftState()
        disturbances = inputs.disturbances
        lanes, closed = self._roadways, ()
        if disturbances.blockages:
            lanes = self._roadways.closed([b.box for b in disturbances.blockages])
            closed = tuple(b.name for b in disturbances.blockages)
        if closed != s.closed:
            s = self._reroute(s, robots.xy, lanes, closed, t)
        if disturbances.breakdowns and any(b.robot == self._index
                                           for b in disturbances.breakdowns):
            s = _changed(s, phase=RobotMode.IDLE, stop=None, route=(), index=0, since=None,
                         door_since=None)
        else:
            stops = self._stops(inputs.plan)
            s = self._follow_plan(s, _first_to_do(stops, s.visits), robots, lanes, queues, t)
            s = self._advance(s, robots, t, queues, stops, lanes, lifts)
        s = _changed(s, release=self._release(s, robots, queues))
        order = inputs.back_offs.of(self._robot) if inputs.back_offs.active else None
        giving_way = order is not None and order.releases
        s = _changed(s, lanes=self._standing_in(robots, queues) if giving_way
                     else self._lanes(s, robots, queues), giving_way=giving_way)
        if s.stop is not None and (old.stop is None or old.stop.key != s.stop.key):
            s = replace(s, began=t)
        return s

    def _stops(self, plan: FleetPlan) -> tuple[Stop, ...]:
        plans = plan.plans
        if self._index < len(plans) and plans[self._index].robot == self._robot:
            return plans[self._index].stops
        return next((plan.stops for plan in plans if plan.robot == self._robot), ())

    def _follow_plan(self, s: _Drive, stop: Stop | None, robots: _Robots, lanes: Roadways,
                     queues: QueueState, t: float) -> _Drive:
        if stop is None:
            if lanes.segment_count and (away := self._make_way(s, robots, lanes, queues)):
                return away
            if s.phase in (RobotMode.PARK, RobotMode.HOME):
                return self._keep_spot(s, robots, lanes)
            place = None if s.last_location is None else self._roadways.place(s.last_location)
            if (not self._params.parking or place is None
                    or _distance(robots.xy, place.point) > self._params.reach_tolerance):
                return _changed(s, phase=RobotMode.IDLE, stop=None, route=(), index=0,
                                since=None)
            others = np.delete(robots.states[:, :2], self._index, axis=0)
            spot = self._free_parking(place, others)
            if spot is None and (self._home is not None or not len(place.parking)
                                 or self._home_spot(place, lanes, others) is not None):
                return self._go_home(s, place, lanes, others)
            return replace(s, phase=RobotMode.PARK, stop=None, route=(), since=None,
                           index=len(place.parking) - 1 if spot is None else spot)
        xy = robots.xy
        if s.stop is None:
            return self._start(s, stop, xy, lanes, t)
        if stop.location == s.stop.location or (s.phase == RobotMode.LIFT and s.lift_slot < 0):
            return _changed(s, stop=stop)  # a rider takes the lanes again once out
        old = self._roadways.place(s.stop.location)
        if s.phase == RobotMode.LIFT:
            def route(roadways):
                return _points_or_none(roadways.route_from_point(xy, stop.location))
        elif s.phase == RobotMode.DRIVE:
            def route(roadways):
                return self._splice(s.route[s.index:], xy, old.exit_node, stop.location,
                                    roadways)
        elif s.phase == RobotMode.WAIT:
            route = self._way_from(s, stop, xy)
        elif s.phase == RobotMode.QUEUE:
            def route(roadways):
                return _points_or_none(roadways.route_from_node(old.exit_node, stop.location))
        else:
            def route(roadways):
                return _points_or_none(roadways.leg(old.id, stop.location))
        return self._drive_to(s, stop, route, lanes, t)

    def _go_home(self, s: _Drive, place, lanes: Roadways, others: np.ndarray) -> _Drive:
        """With nothing to do at ``place`` and no parking spot free there: back along the
        lanes to the start spot (``_home_spot``), unless there is none or it is by the
        point; else stand (idle)."""
        home = self._home_spot(place, lanes, others)
        if home is None or _distance(home, place.point) <= self._params.reach_tolerance:
            return _changed(s, phase=RobotMode.IDLE, stop=None, route=(), index=0, since=None)
        route = _points(lanes.leg_to_spot(place.id, home))
        return replace(s, phase=RobotMode.HOME, stop=None, route=route, index=0, since=None)

    def _keep_spot(self, s: _Drive, robots: _Robots, lanes: Roadways) -> _Drive:
        """Parking, or driving to wait at a spot that is not its home: where another robot
        stands nearer that spot (as near and first in robot order), within
        ``parking_clearance`` of it (it chose the spot too, seeing it free), choose again
        as when done at the location, from where the robot is: another free parking spot
        there, else ``_home_spot``'s; with none, keep the spot."""
        spot = (_point(self._roadways.place(s.last_location).parking[s.index])
                if s.phase == RobotMode.PARK else _point(s.route[-1]))
        if spot == self._home or s.last_location is None:  # None: a spot it drove to from
            return s  # standing away from any location, out of other robots' way (_make_way)
        gaps = np.linalg.norm(robots.states[:, :2] - np.asarray(spot), axis=1)
        mine = (gaps[self._index], self._index)
        if not any(gap <= self._params.parking_clearance and (gap, j) < mine
                   for j, gap in enumerate(gaps) if j != self._index):
            return s
        others = np.delete(robots.states[:, :2], self._index, axis=0)
        place = self._roadways.place(s.last_location)
        if s.phase == RobotMode.PARK:
            index = self._free_parking(place, others)
            if index is not None:
                return replace(s, index=index)
        new = self._home_spot(place, lanes, others)
        if new is None or new == spot:
            return s
        return replace(s, phase=RobotMode.HOME, route=_points(lanes.route_to_spot(robots.xy, new)),
                       index=0, since=None)

    def _make_way(self, s: _Drive, robots: _Robots, lanes: Roadways, queues: QueueState
                  ) -> _Drive | None:
        """A robot without a stop standing (idle, or back at the spot it drove to wait at)
        in a single-file segment that another robot waits for or holds (to drive through
        it) drives out of the way to ``_refuge``'s spot (phase home: it asks for the
        segments of its way there as when driving, and waits there until given a stop);
        None where it need not or finds no such spot (docs/worlds.md, "Robots without a
        task in single-file segments")."""
        xy = robots.xy
        if s.phase == RobotMode.HOME:
            if not s.route or _distance(xy, s.route[-1]) > \
                    self._params.single_file.stand_distance:
                return None
        elif s.phase != RobotMode.IDLE:
            return None
        wanted = {k for k, hold in enumerate(queues.segments)
                  if any(robot != self._robot for robot in (*hold.waiting, *hold.holders))}
        here = stands_in(self._roadways, xy, self._params.single_file)
        if not wanted or wanted.isdisjoint(here):
            return None
        askers = {robot for k in wanted.intersection(here) for robot in
                  (*queues.segments[k].waiting, *queues.segments[k].holders)} - {self._robot}
        route = self._refuge(xy, here, robots.states, lanes, queues, wanted,
                             robots.states[[self._names.index(r) for r in sorted(askers)], :2])
        if route is None:
            return None
        return replace(s, phase=RobotMode.HOME, stop=None, route=route, index=0, since=None)

    def _refuge(self, xy, here: tuple[int, ...], states: np.ndarray, lanes: Roadways,
                queues: QueueState, wanted: set[int], askers: np.ndarray
                ) -> tuple[tuple[float, float], ...] | None:
        """The shortest way along the lanes (without lift rides) from ``xy``, standing in
        the single-file segments ``here``, to a spot
        where a robot without a stop may wait out of the way (``_refuge_spots``; a dead
        end by a queue slot only for a robot inside a corridor (``_inside_segments``) where no
        other will do: there it may be in the way of a robot queueing or bound for that
        dead end, inside a segment another robot drives through it is in its way for
        certain): in none of
        the single-file segments other robots wait for or hold (``wanted``), no other robot
        within ``parking_clearance`` of it, through no segment another robot holds but those
        the robot stands in (it leaves them the way their holders drive), and
        passing no other robot nearer than ``parking_clearance`` (but those that near the
        robot already); leaving by an end node of the segments the robot stands in that is
        nearer it than every robot that holds or waits for those of them it must leave
        (``askers``, (n, 2), m): out of the end away from them. None if there is none."""
        params = self._params
        others = np.delete(states[:, :2], self._index, axis=0)
        ahead = others[np.linalg.norm(others - np.asarray(xy), axis=1) > params.parking_clearance]
        taken = {k for k, hold in enumerate(queues.segments)
                 if any(robot != self._robot for robot in hold.holders)}
        avoid = wanted | taken
        starts = {n for n in lanes.graph.nodes if not set(here).isdisjoint(
            stands_in(self._roadways, self._roadways.node_position(n), params.single_file))}
        inside = self._inside_segments(xy, here)
        spots = [(spot, node, by_slot) for spot, node, segments, by_slot in self._refuge_spots()
                 if (inside or not by_slot) and avoid.isdisjoint(segments)
                 and self._free(spot, others)]
        best, best_length = None, (True, math.inf)
        for start in sorted(starts, key=str):
            end = lanes.node_position(start)
            if len(askers) and np.linalg.norm(askers - end, axis=1).min() <= _distance(xy, end):
                continue
            paths = lanes.paths_from(start)
            for spot, node, by_slot in spots:
                if node not in paths:
                    continue
                route = tuple(_point(lanes.node_position(n)) for n in paths[node])
                route += () if route[-1] == spot else (spot,)
                length = (by_slot, _distance(xy, route[0]) + sum(
                    _distance(a, b) for a, b in zip(route[:-1], route[1:], strict=True)))
                if length >= best_length:
                    continue
                way = np.array([xy, *route], dtype=float)
                if len(ahead) and distance_to_polyline(ahead, way).min() <= \
                        params.parking_clearance:
                    continue
                runs = route_runs(lanes, route, params.single_file.chain_gap)
                if any(k in taken and k not in here for run in runs for k, _ in run.segments):
                    continue
                best, best_length = route, length
        return best

    def _inside_segments(self, xy, here: tuple[int, ...]) -> bool:
        """Whether a robot at ``xy``, standing in the single-file segments ``here``, is
        inside them: farther than ``single_file.stand_distance`` from each one's ends
        (the nodes joined to one other node of it). In a corridor the only ways out are
        its ends; at an end (a room, a junction) a robot driving through may pass it."""
        reach = self._params.single_file.stand_distance
        for k in here:
            joined: dict = {}
            for a, b in segment_lanes(self._roadways, k):
                joined.setdefault(a, set()).add(b)
                joined.setdefault(b, set()).add(a)
            if any(len(others) == 1 and _distance(xy, end) <= reach
                   for end, others in joined.items()):
                return False
        return bool(here)

    def _refuge_spots(self) -> tuple:
        """Where a robot without a stop may wait out of the way (``_refuge``): the roadway
        nodes but those of lift cabins, the start spots and the parking spots, less those
        within ``reach_tolerance`` of a location's point, and those within
        ``parking_clearance`` of its queue slots or overflow spots but at dead ends (their
        nearest node joins one other); each as (spot, its nearest roadway node, the
        single-file segments it stands in, whether it is by a queue slot or overflow
        spot). Made once, when first needed."""
        if self._refuges is None:
            roadways, params = self._roadways, self._params
            cabins = {n for a, b, lift in roadways.graph.edges(data="lift") if lift
                      for n in (a, b)}
            nodes = [n for n in roadways.graph.nodes if n not in cabins]
            spots = [_point(roadways.node_position(n)) for n in nodes]
            spots += [spot for spot in (*self._starts, *self._parking) if spot not in spots]
            places = [roadways.place(i) for i in roadways.location_ids]
            points = np.array([place.point for place in places], dtype=float).reshape(-1, 2)
            slots = np.array([xy for place in places for xy in (*place.queue,
                                                                  *place.overflow)],
                             dtype=float).reshape(-1, 2)
            by_slots = _nearest(np.array(spots), slots) <= params.parking_clearance
            positions = np.array([roadways.node_position(n) for n in nodes], dtype=float)
            nearest = [nodes[int(np.argmin(np.linalg.norm(positions - spot, axis=1)))]
                       for spot in spots]
            keep = (_nearest(np.array(spots), points) > params.reach_tolerance) & ~(
                by_slots & ~np.array([len(set(nx.all_neighbors(roadways.graph, n))) == 1
                                      for n in nearest]))
            self._refuges = tuple(
                (spot, node, stands_in(roadways, spot, params.single_file), bool(by_slot))
                for spot, node, ok, by_slot in zip(spots, nearest, keep, by_slots, strict=True)
                if ok)
        return self._refuges

    def _home_spot(self, place, lanes: Roadways, others: np.ndarray
                   ) -> tuple[float, float] | None:
        """Where a robot with nothing to do at ``place`` waits: its own start spot (home)
        where the lanes lead there without a lift ride (taken or not: a robot waiting on
        another's start spot would box in its owner coming home, as on the one-level
        office); else the nearest of the locations' parking spots the lanes lead to
        without a lift ride and no other robot (``others``, (N - 1, 2)) stands within
        ``parking_clearance`` of; else the nearest such of the other robots' start spots
        (``spots``); else None. A robot that rode a lift away from home (a building's
        levels) would otherwise drive for a home on another level and stand at the lift
        (the two-floor clinic, 10 robots, seed 0: robot7 from 200 s to the end, in
        robot2's way)."""
        home, here = self._spots_reached(place, lanes)
        if home:
            return self._home
        return next((spot for spot in here if self._free(spot, others)), None)

    def _spots_reached(self, place, lanes: Roadways) -> tuple[bool, tuple]:
        """Whether the lanes lead from ``place`` to the robot's home without a lift ride;
        if not, the parking spots and then the other robots' start spots they so lead to,
        each nearest ``place`` first (``_home_spot``). A function of the roadways alone
        (``lanes``, identified by their ``closures``), kept per roadways and place: each
        costs a search of the lanes and a nearest-node scan per spot, and an idle robot
        that sees another nearer its spot asks again at every update."""
        key = (lanes.closures, place.id)
        reached = self._spots_cache.get(key)
        if reached is None:
            if self._home is not None and lanes.spots_reached(place.id, [self._home]):
                reached = (True, ())
            else:
                def nearest(spots):
                    return sorted(spots, key=lambda spot: _distance(spot, place.point))

                reached = (False, tuple(lanes.spots_reached(
                    place.id, nearest(self._parking) + nearest(self._spots))))
            self._spots_cache[key] = reached
        return reached

    def _drive_to(self, s: _Drive, stop: Stop, route, lanes: Roadways, t: float) -> _Drive:
        """Drive to ``stop`` along ``route(lanes)`` (a function of the roadways: waypoints,
        or None where no lane leads there), or wait without one. Under blockages, a route
        other than the open roadways' is a detour."""
        waypoints = route(lanes)
        if lanes.closures and waypoints != route(self._roadways):
            s = replace(s, detours=s.detours + (Detour(t, s.closed, waypoints is not None),))
        return replace(s, phase=RobotMode.DRIVE if waypoints else RobotMode.WAIT, stop=stop,
                       route=waypoints or (), index=0, since=None)

    def _reroute(self, s: _Drive, xy, lanes: Roadways, closed: tuple[str, ...],
                 t: float) -> _Drive:
        """Take the route ahead again after the blockages changed from ``s.closed`` to
        ``closed`` (see the class docstring)."""
        opened = set(s.closed) - set(closed)
        changed = tuple(sorted(opened | (set(closed) - set(s.closed))))
        s = replace(s, closed=closed)
        if s.phase == RobotMode.WAIT:
            route = self._way_from(s, s.stop, xy)(lanes)
        elif s.phase == RobotMode.DRIVE:
            ahead = s.route[s.index:]
            if not opened and not lanes.crosses_closure((xy, *ahead)):
                return s
            route = self._splice(ahead, xy, None, s.stop.location, lanes)
            if route == ahead:
                return s
        else:
            return s
        return replace(s, phase=RobotMode.DRIVE if route else RobotMode.WAIT,
                       route=route or (), index=0,
                       detours=s.detours + (Detour(t, changed, route is not None),))

    def _free_parking(self, place, others: np.ndarray) -> int | None:
        """Index of the first of ``place``'s parking spots with no other robot near it
        (None if all are taken, or it has none)."""
        return next((k for k, spot in enumerate(place.parking) if self._free(spot, others)),
                    None)

    def _free(self, spot, others: np.ndarray) -> bool:
        """Whether no other robot (``others``, (N - 1, 2), m) stands within
        ``parking_clearance`` of ``spot`` (m)."""
        return not len(others) or float(np.min(np.linalg.norm(
            others - np.asarray(spot, dtype=float), axis=1))) > self._params.parking_clearance

    def _start(self, s: _Drive, stop: Stop, xy, lanes: Roadways, t: float) -> _Drive:
        """Begin ``stop`` from standing (at the start, or after finishing a stop)."""
        roadways, tolerance = self._roadways, self._params.reach_tolerance
        parked = s.phase == RobotMode.PARK
        if (_distance(xy, roadways.place(stop.location).point) <= tolerance
                or (parked and s.last_location == stop.location)):
            return replace(s, phase=RobotMode.SERVE, stop=stop, route=(), index=0, since=None)
        return self._drive_to(s, stop, self._way_from(s, stop, xy), lanes, t)

    def _way_from(self, s: _Drive, stop: Stop, xy):
        """How to reach ``stop`` from standing at ``xy``, as a function of the roadways:
        the leg from the last location when on its point (or parked there), else the lanes
        from the nearest roadway node."""
        roadways, tolerance = self._roadways, self._params.reach_tolerance
        parked = s.phase == RobotMode.PARK
        last = s.last_location
        if last is None:  # e.g. a robot placed on a location's point without start_location
            last = next(
                (i for i in roadways.location_ids
                 if _distance(xy, roadways.place(i).point) <= tolerance),
                None,
            )
        if (
            last is not None
            and last != stop.location
            and (parked or _distance(xy, roadways.place(last).point) <= tolerance)
        ):
            def route(lanes):
                return _points_or_none(lanes.leg(last, stop.location))
        else:
            def route(lanes):
                return _points_or_none(lanes.route_from_point(xy, stop.location))
        return route

    @staticmethod
    def _splice(ahead, xy, exit_node: str | None, location: int, lanes: Roadways):
        """The rest of the route ``ahead`` up to its first roadway node that leads to
        ``location``, then the lanes from there, looking only as far ahead as the robot at
        ``xy`` gets without touching a closure. If no node ahead leads there: with
        ``exit_node`` (the robot is past the last node of its leg), the rest of the route
        and then the lanes from it; else the rest of the route as it is. If the way ahead
        touches a closure (or there is none): the lanes from the nearest node the robot
        reaches in a straight line; None if none leads there."""
        last = xy
        for j, point in enumerate(ahead):
            if lanes.crosses_closure((last, point)):
                break
            last = point
            node = lanes.node_at(point)
            route = None if node is None else lanes.route_from_node(node, location)
            if route is not None:
                return ahead[:j] + _points(route)
        else:
            if exit_node is not None:
                route = lanes.route_from_node(exit_node, location)
                if route is not None and not lanes.crosses_closure((last, route[0])):
                    return ahead + _points(route)
            elif ahead:
                return ahead
        return _points_or_none(lanes.route_from_point(xy, location))

    def _advance(self, s: _Drive, robots: _Robots, t: float, queues: QueueState,
                 stops: tuple[Stop, ...], lanes: Roadways, lifts: LiftState) -> _Drive:
        if s.stop is None:
            return _changed(s, index=self._reached(s, robots.xy)) \
                if s.phase == RobotMode.HOME else s
        xy = robots.xy
        params = self._params
        place = self._roadways.place(s.stop.location)
        queue = queues.room(place.id)
        holding = queue is not None and queue.holder == self._robot
        if s.phase == RobotMode.DRIVE and holding:
            s = replace(s, phase=RobotMode.ENTER, route=(_point(place.point),), index=0)
        if s.phase == RobotMode.DRIVE:
            s = _changed(s, index=self._reached(s, xy))
            s = self._to_lift(s, xy)
        if s.phase == RobotMode.LIFT:
            s = self._ride(s, xy, lanes, lifts)
        if s.phase == RobotMode.DRIVE:
            if (
                s.index == len(s.route) - 1
                and _distance(xy, s.route[-1]) <= params.request_distance
            ):
                s = replace(s, phase=RobotMode.QUEUE, route=(), index=len(place.queue) - 1)
        # Entering while another robot comes out of the room, or stands in its doorway, would
        # stand both in the doorway: the holder waits at its slot, or where it stands.
        slot = self._slot_ahead(s, place) if holding else None
        takers = () if slot is None else self._doorway_takers(place, robots, queues)
        s = _changed(s, door_since=None if slot is None
                     else self._door_since(s, place, robots, takers, t))
        waits = s.door_since is not None and t - s.door_since < params.door_patience
        s = _changed(s, door=takers if waits else ())
        if s.phase == RobotMode.ENTER and waits and not s.lanes.segments:
            s = replace(s, phase=RobotMode.QUEUE, route=(), index=slot)
        if s.phase == RobotMode.QUEUE:
            if holding and not waits:
                route = _points(place.queue[min(s.index, len(place.queue) - 1)::-1]) + \
                    _points(place.entry)
                s = replace(s, phase=RobotMode.ENTER, route=route + (_point(place.point),),
                            index=0)
            elif not holding and queue is not None and queue.slot_of(self._robot) is not None:
                s = _changed(s, index=queue.slot_of(self._robot) + self._holder_at_head(
                    queue, place, robots.states))
        if s.phase == RobotMode.ENTER:
            s = _changed(s, index=self._reached(s, xy))
            if s.index == len(s.route) - 1:
                s = replace(s, phase=RobotMode.SERVE, route=(), index=0)
        # Driving in on single-file segments, it stands where it is, keeping them (back in
        # the queue phase it would give them up to the robots behind it); elsewhere it waits
        # at the slot ahead (above), out of the corridor's way.
        s = _changed(s, waiting=(s.phase == RobotMode.SERVE and not holding)
                     or (s.phase == RobotMode.ENTER and waits)
                     or self._held_at_door(s, robots, queues))
        if (s.phase == RobotMode.SERVE and holding
                and _distance(xy, place.point) <= params.reach_tolerance):
            since = t if s.since is None else s.since
            if t - since < params.service_time - 1e-9:
                return _changed(s, since=since)
            stop = s.stop
            visit = Visit(stop.key, stop.location, t, stop.task, stop.action, s.began)
            s = replace(
                s, phase=RobotMode.IDLE, stop=None, since=None,
                visits=s.visits + (visit,), last_location=stop.location,
            )
            following = _first_to_do(stops, s.visits)
            if following is not None:
                s = self._start(s, following, xy, lanes, t)
        return s

    def _lanes(self, s: _Drive, robots: _Robots, queues: QueueState) -> Need:
        """The single-file segments the robot needs on its route (while driving it,
        entering a room or driving home), holding back until the room queues grant them
        all; queueing or serving, or back home (within ``single_file.stand_distance`` of
        the home route's end), those it stands in (``single_file.standing``): a robot home
        keeps no segment of the way it came by from the robots that need it."""
        if not self._roadways.segment_count:
            return NOTHING
        if s.phase == RobotMode.SERVE and s.waiting:
            return NOTHING  # on the point without its room: the holder comes (docstring)
        spot = None
        if s.phase in (RobotMode.QUEUE, RobotMode.SERVE):
            place = self._roadways.place(s.stop.location)
            spot = self._queue_spot(place, s.index) if s.phase == RobotMode.QUEUE \
                else place.point
        elif s.phase == RobotMode.HOME and s.route and _distance(
                robots.xy, s.route[-1]) <= self._params.single_file.stand_distance:
            spot = s.route[-1]
        elif s.phase == RobotMode.IDLE and self._index not in robots.broken:
            spot = robots.xy
        if spot is not None:
            return standing(self._roadways, robots.xy, spot, self._held(queues),
                            self._params.single_file)
        if s.phase not in (RobotMode.DRIVE, RobotMode.ENTER, RobotMode.HOME):
            return NOTHING
        wanted = need(self._roadways, s.route, s.index, robots.xy, self._params.single_file)
        if s.phase == RobotMode.HOME and s.index == 0:
            out = self._leaving(robots.xy, s.route[0], queues)
            if out:
                segments = out | dict(wanted.segments)
                wanted = replace(wanted, segments=tuple(sorted(segments.items())))
        if not wanted.hold:
            return wanted
        # Held back inside a lane (farther than stand_distance from every roadway node), it
        # keeps the segments it holds and stands in, whatever its route says: given up, a
        # robot granted one would drive in head-on. At a node, where segments meet, it
        # keeps only those of its route (docs/worlds.md, "Office seed 9's gridlock").
        held = self._held(queues)
        here = stands_in(self._roadways, robots.xy, self._params.single_file)
        if here and held and self._between_nodes(robots.xy):
            kept = {k: held[k] for k in here if k in held} | dict(wanted.segments)
            if len(kept) > len(wanted.segments):
                wanted = Need(tuple(sorted(kept.items())), True, wanted.stops)
        if queues.holds_segments(self._robot, wanted.segments):
            return Need(wanted.segments, stops=wanted.stops)
        # Held back, it holds none of the run's segments it does not stand in: it gives
        # them up for an update and then waits for them all (office seed 6: a robot served
        # beside a segment kept it from serving there into its next run, and waited for
        # the rest, held by the robot standing on its way that waited for that segment).
        # Only for a segment another robot holds: with the rest free it would be granted
        # the rest at once, give up those for the ones dropped, and so on, every update
        # (the campus, seed 10: robot1, served 0.58 m off room_3's point, so standing in
        # no segment, held segments 6 and 5 in turn from 262 s to the end).
        if all(set(queues.segments[k].holders) <= {self._robot} for k, _ in wanted.segments):
            return wanted
        dropped = {k for k, _ in wanted.segments if k in held}.difference(here)
        if dropped:
            return wanted.without(dropped)
        return wanted

    def _leaving(self, xy, first, queues: QueueState) -> dict[int, bool]:
        """Setting off to wait elsewhere (phase home) from inside single-file segments it
        holds, farther than ``single_file.stand_distance`` from the route's first point
        ``first`` (a roadway node): those segments, each the way it drives along them to
        ``first`` (index -> forward: the way of a lane it stands by that leads on along the
        segment to ``first``, through any number of its lanes), kept until it is there (its
        route begins at that node: without them it would give up the segment it drives out
        of, and a robot granted it would drive in head-on)."""
        reach = self._params.single_file.stand_distance
        held = self._held(queues)
        if not held or _distance(xy, first) <= reach:
            return {}
        out = {}
        for k in stands_in(self._roadways, xy, self._params.single_file):
            lanes = segment_lanes(self._roadways, k) if k in held else ()
            for a, b in lanes:
                if distance_to_polyline(np.array([xy], dtype=float),
                                        np.array([a, b], dtype=float))[0] <= reach \
                        and _leads_to(lanes, a, b, first):
                    out[k] = self._roadways.segment_of(a, b)[1]
        return out

    def _between_nodes(self, xy) -> bool:
        """Whether ``xy`` is farther than ``single_file.stand_distance`` from every roadway
        node (inside a lane, not where lanes meet)."""
        reach = self._params.single_file.stand_distance
        return all(_distance(xy, self._roadways.node_position(n)) > reach
                   for n in self._roadways.graph.nodes)

    def _standing_in(self, robots: _Robots, queues: QueueState) -> Need:
        """Giving way (a ``releases`` order): only the single-file segments the robot
        stands in, each the way it holds it (or forward), standing (the planner drives it
        to its spot)."""
        here = standing(self._roadways, robots.xy, robots.xy, self._held(queues),
                        self._params.single_file)
        return replace(here, hold=True)

    def _held(self, queues: QueueState) -> dict[int, bool]:
        """The single-file segments the robot holds, each with the way it holds it
        (``SegmentHold.forward``)."""
        return {k: hold.forward for k, hold in enumerate(queues.segments)
                if self._robot in hold.holders}

    def _to_lift(self, s: _Drive, xy) -> _Drive:
        """Into the lift phase within ``lift_request_distance`` of the cabin where the
        route ahead next takes a lift."""
        roadways = self._roadways
        if not roadways.has_lifts:
            return s
        for j in range(s.index, len(s.route) - 1):
            if roadways.lift_edge(s.route[j], s.route[j + 1]) is not None:
                if j == s.index or _distance(xy, s.route[j]) <= \
                        self._params.lift_request_distance:
                    return replace(s, phase=RobotMode.LIFT, index=j)
                break
        return s

    def _ride(self, s: _Drive, xy, lanes: Roadways, lifts: LiftState) -> _Drive:
        """Wait for a lift of the bank, drive to the berth the bank gives, and drive on
        from the cabin once relocated to the next level."""
        status = lifts.serving(self._robot)
        if status is None or self._robot not in status.riders:
            slot = (status.waiting.index(self._robot) if status is not None else 0)
            return _changed(s, lift_slot=slot, berth=None)
        berth = status.berth(self._robot)
        if status.phase == "out" and _distance(xy, berth) <= \
                self._params.lift_request_distance:
            route = _points_or_none(lanes.route_from_point(xy, s.stop.location))
            return replace(s, phase=RobotMode.DRIVE if route else RobotMode.WAIT,
                           route=route or (), index=0, lift_slot=-1, berth=None)
        return _changed(s, lift_slot=-1, berth=berth)

    def _spot_taken(self, spot, states: np.ndarray) -> bool:
        """Whether another robot stands within ``parking_clearance`` of parking ``spot``
        (every spot taken: this robot waits beside the point, not holding its room)."""
        others = np.delete(states[:, :2], self._index, axis=0)
        return bool((np.linalg.norm(others - np.asarray(spot), axis=1)
                     <= self._params.parking_clearance).any())

    def _held_at_door(self, s: _Drive, robots: _Robots, queues: QueueState) -> bool:
        """Whether the robot, about to leave the room it stands in (within
        ``reach_tolerance`` of its point or a parking spot, driving to the first waypoint of
        its leg), waits for the room's holder, another robot, moving in the doorway
        (``_door_busy``): the mirror of an entering holder's wait (with ``door_wait``)."""
        if (not self._params.door_wait or s.phase != RobotMode.DRIVE or s.index != 0
                or s.last_location is None):
            return False
        queue = queues.room(s.last_location)
        if queue is None or queue.holder in (None, self._robot):
            return False
        place = self._roadways.place(s.last_location)
        if min(_distance(robots.xy, spot) for spot in (place.point, *place.parking)) > \
                self._params.reach_tolerance:
            return False
        return self._door_busy(place, robots.states)

    def _slot_ahead(self, s: _Drive, place) -> int | None:
        """The queue slot of ``place`` the robot waits at or drives to next, as long as it
        has not passed the first one on the way in (the route made at the queue: the slots
        back to the first, the entry path, the point); None otherwise."""
        if s.phase == RobotMode.QUEUE:
            return s.index
        first = len(s.route) - len(place.entry) - 2  # the first slot's index in the route
        if s.phase == RobotMode.ENTER and s.index <= first:
            return first - s.index
        return None

    def _door_since(self, s: _Drive, place, robots: _Robots, takers: tuple[str, ...],
                    t: float) -> float | None:
        """Since when ``place``'s doorway has been taken for the holder before its door
        (``s.door_since``, or now, ``t``), or None while it is free (or without
        ``door_wait``): another robot moves near the door (``_door_busy``) or stands in
        the doorway (``takers``, ``_doorway_takers``)."""
        if not self._params.door_wait or not (
                takers or self._door_busy(place, robots.states)):
            return None
        return t if s.door_since is None else s.door_since

    def _doorway_takers(self, place, robots: _Robots, queues: QueueState
                        ) -> tuple[str, ...]:
        """The other robots that stand (no faster than ``ROBOT_STOPPED_SPEED``) within
        ``door_clearance`` of ``place``'s doorway, the polyline from its first queue slot
        through the entry path to the point: one cannot pass it there (soak seed 115: robot2,
        the holder, drove past robot6 standing in the door on its way out, 2.4 cm from the
        jamb). Left out are the robots that stand there for good or wait for the holder,
        since waiting for them would deadlock: within ``reach_tolerance`` of the point or
        a parking spot (waiting to serve, parked, or held to leave: ``_held_at_door``),
        within ``parking_clearance`` of a start spot (at home), in the room's queue, waiting
        for single-file segments, and broken down."""
        states = robots.states
        near = np.abs(states[:, 3]) <= ROBOT_STOPPED_SPEED
        near[self._index] = False
        if not near.any():
            return ()
        params, xy = self._params, states[:, :2]
        near &= distance_to_polyline(xy, place.doorway) <= params.door_clearance
        if not near.any():
            return ()
        near &= _nearest(xy, [place.point, *place.parking]) > params.reach_tolerance
        if self._starts:
            near &= _nearest(xy, self._starts) > params.parking_clearance
        queue = queues.room(place.id)
        waiting = {*queues.segment_waiting, *(() if queue is None else queue.waiting)}
        broken = robots.broken
        return tuple(self._names[k] for k in np.flatnonzero(near)
                     if self._names[k] not in waiting and k not in broken)

    def _door_busy(self, place, states: np.ndarray) -> bool:
        """Whether another robot is moving (faster than ``ROBOT_STOPPED_SPEED``) within
        ``door_clearance`` of ``place``'s entry path or point."""
        others = np.delete(states, self._index, axis=0)
        moving = others[np.abs(others[:, 3]) > ROBOT_STOPPED_SPEED, :2]
        if not len(moving):
            return False
        return bool((_nearest(moving, [*place.entry, place.point])
                     <= self._params.door_clearance).any())

    def _reached(self, s: _Drive, xy) -> int:
        """The first route index not yet reached, at most the last."""
        index, route = s.index, s.route
        while index < len(route) - 1 and (
            _distance(xy, route[index]) <= self._params.waypoint_tolerance
        ) and not (self._roadways.has_lifts
                   and self._roadways.lift_edge(route[index], route[index + 1])):
            index += 1
        return index

    def _release(self, s: _Drive, robots: _Robots, queues: QueueState) -> int | None:
        for queue in queues.rooms:
            if queue.holder != self._robot:
                continue
            if s.stop is None:  # parked: keeps only the room it parked in (its index)
                place = self._roadways.place(queue.room)
                if (s.phase != RobotMode.PARK or queue.room != s.last_location
                        or _distance(robots.xy, place.point) > self._params.reach_tolerance
                        or self._spot_taken(place.parking[s.index], robots.states)):
                    return queue.room
                continue
            point = self._roadways.place(queue.room).point
            if s.stop.location != queue.room and (
                _distance(robots.xy, point) > self._params.release_distance
                or self._at_slot(s, robots.xy)
            ):
                return queue.room
        return None

    def _at_slot(self, s: _Drive, xy) -> bool:
        """Whether the robot waits at its queue slot (within ``waypoint_tolerance``)."""
        return s.phase == RobotMode.QUEUE and _distance(
            xy, self._queue_spot(self._roadways.place(s.stop.location), s.index)) <= \
            self._params.waypoint_tolerance

    def _holder_at_head(self, queue, place, states: np.ndarray) -> int:
        """1 if another robot holds ``place``'s room and stands within
        ``waypoint_tolerance`` of its head slot (waiting there), else 0."""
        if queue.holder is None or queue.holder == self._robot:
            return 0
        holder = states[self._names.index(queue.holder), :2]
        return int(_distance(holder, place.queue[0]) <= self._params.waypoint_tolerance)

    def _queue_spot(self, place, index: int) -> tuple[float, float]:
        """Where the robot at place ``index`` of ``place``'s queue waits (world frame, m):
        that slot; beyond the last, the place's overflow spots in order (the last shared),
        else ``overflow_spacing`` m apart from the tail slot towards the approach node, at
        most as far as that node."""
        last = len(place.queue) - 1
        if index <= last:
            return _point(place.queue[index])
        if len(place.overflow):
            return _point(place.overflow[min(index - last, len(place.overflow)) - 1])
        tail = place.tail
        towards = self._roadways.node_position(place.approach_node) - tail
        length = float(np.linalg.norm(towards))
        if length == 0.0:
            return _point(tail)
        back = min((index - last) * self._params.overflow_spacing, length)
        return _point(tail + towards * (back / length))


_OUTPUTS = ("target", "queue_request", "progress", "lift_request")  # _Outputs' payloads


def _model(payload):
    """An output port's model value allocator: ``Value[object](payload)``."""
    return lambda: Value[object](payload)


class WaypointGenerator(LeafSystem):
    """One robot's waypoints as a system of its own: ``rate_hz`` times a second an
    unrestricted update calls the robot's ``WaypointPolicy`` (the behaviour is described
    there). ``FleetWaypoints`` does the same for every robot in one system (the default);
    this one is the per-robot waypoints kind ``roadway_per_robot``.

    .. pydrake_system::

        name: WaypointGenerator
        input_ports:
        - plan
        - robot_state
        - queue_state
        - lift_state (optional)
        - disturbances (optional)
        - back_offs (optional)
        output_ports:
        - target
        - queue_request
        - progress
        - lift_request

    Inputs: see ``WaypointInputs`` (``robot_state``: vector 4N, ``[x, y, theta, v]`` per
    robot in ``robot_names`` order, world frame, m, rad, m/s; the others abstract).
    Outputs (from the state; no direct feedthrough): the policy's ``outputs``.
    The arguments but ``rate_hz`` are the ``WaypointPolicy``'s.
    """

    def __init__(self, robot_names: Sequence[str], *policy_args, rate_hz: float,
                 **policy_kwargs):
        super().__init__()
        self._policy = WaypointPolicy(robot_names, *policy_args, **policy_kwargs)
        self._state_index = self.DeclareAbstractState(
            Value[object](self._policy.initial_state()))
        self._inputs = _declare_inputs(self, len(robot_names))
        state_ticket = {self.abstract_state_ticket(self._state_index)}
        initial = self._policy.outputs(self._policy.initial_state())
        for name in _OUTPUTS:
            self.DeclareAbstractOutputPort(
                name, _model(getattr(initial, name)),
                lambda context, output, name=name: output.set_value(
                    getattr(self._policy.outputs(self._drive(context)), name)),
                prerequisites_of_calc=state_ticket)
        self.DeclarePeriodicUnrestrictedUpdateEvent(1.0 / rate_hz, 0.0, self._update)

    def _drive(self, context) -> _Drive:
        return context.get_abstract_state(self._state_index).get_value()

    def _update(self, context, state) -> EventStatus:
        old = self._drive(context)
        s = self._policy.update(old, WaypointInputs(self._inputs, context))
        if s is old:  # unchanged: Drake applies an instant's updates only if one changed
            return EventStatus.DidNothing()
        state.get_mutable_abstract_state(self._state_index).set_value(s)
        return EventStatus.Succeeded()


class FleetWaypoints(LeafSystem):
    """Every robot's waypoints in one system: ``rate_hz`` times a second one unrestricted
    update reads the inputs once (``WaypointInputs``) and calls each robot's policy in
    robot order; the robots' states are one abstract state, their tuple in robot order
    (``_FleetState``: Drake copies it at each update, as itself). ``policies`` (one per
    robot, in ``robot_names`` order) are ``WaypointPolicy`` objects (the behaviour is
    described there) or any objects with the same ``robot``, ``initial_state``, ``update``
    and ``outputs`` (a state must be an immutable value and ``update`` must return the very
    same object when nothing changes).

    .. pydrake_system::

        name: FleetWaypoints
        input_ports:
        - plan
        - robot_state
        - queue_state
        - lift_state (optional)
        - disturbances (optional)
        - back_offs (optional)
        output_ports:
        - target_<robot>
        - queue_request_<robot>
        - progress_<robot>
        - lift_request_<robot>
        - fleet_targets
        - fleet_queue_requests
        - fleet_progress

    Inputs: see ``WaypointInputs`` (``robot_state``: vector 4N, ``[x, y, theta, v]`` per
    robot, world frame, m, rad, m/s; the others abstract). Outputs (from the robots' states;
    no direct feedthrough): per robot, its policy's ``outputs``; and the ``fleet_`` outputs,
    each one tuple of every robot's ``target``, ``queue_request`` or ``progress`` in robot
    order, for the blocks that read all robots' (``stack.fleet_inputs``: one port evaluation
    instead of one per robot).
    """

    def __init__(self, policies: Sequence[WaypointPolicy], *, rate_hz: float):
        super().__init__()
        self._policies = tuple(policies)
        initial = self._state(tuple(policy.initial_state() for policy in self._policies))
        self._state_index = self.DeclareAbstractState(Value[object](initial))
        self._inputs = _declare_inputs(self, len(self._policies))
        tickets = {self.abstract_state_ticket(self._state_index)}
        for k, policy in enumerate(self._policies):
            for name in _OUTPUTS:
                self.DeclareAbstractOutputPort(
                    f"{name}_{policy.robot}",
                    _model(getattr(initial.outputs[k], name)),
                    lambda context, output, name=name, k=k:
                        output.set_value(getattr(self._fleet_state(context).outputs[k], name)),
                    prerequisites_of_calc=tickets)
        for fleet, name in (("targets", "target"), ("queue_requests", "queue_request"),
                            ("progress", "progress")):
            self.DeclareAbstractOutputPort(
                f"fleet_{fleet}", _model(tuple(map(attrgetter(name), initial.outputs))),
                lambda context, output, name=attrgetter(name): output.set_value(
                    tuple(map(name, self._fleet_state(context).outputs))),
                prerequisites_of_calc=tickets)
        self.DeclarePeriodicUnrestrictedUpdateEvent(1.0 / rate_hz, 0.0, self._update)

    def _state(self, robots: tuple) -> _FleetState:
        """The block's state of the robots' policy states ``robots``, with their outputs."""
        return _FleetState(robots, tuple(
            policy.outputs(s) for policy, s in zip(self._policies, robots, strict=True)))

    def _fleet_state(self, context) -> _FleetState:
        return context.get_abstract_state(self._state_index).get_value()

    def _update(self, context, state) -> EventStatus:
        inputs = WaypointInputs(self._inputs, context)
        old = self._fleet_state(context).robots
        new = tuple(policy.update(s, inputs)
                    for policy, s in zip(self._policies, old, strict=True))
        if all(a is b for a, b in zip(new, old, strict=True)):
            return EventStatus.DidNothing()  # Drake applies an instant's updates only if one
            # changed
        state.get_mutable_abstract_state(self._state_index).set_value(self._state(new))
        return EventStatus.Succeeded()
