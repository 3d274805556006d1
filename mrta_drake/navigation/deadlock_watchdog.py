"""A fleet manager's deadlock watchdog: robots standing blocked by each other are sent, one
at a time, to a free spot nearby to let the others pass."""

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from pydrake.common.value import Value
from pydrake.systems.framework import BasicVector, EventStatus, LeafSystem

from mrta_drake.errors import InputError, require_non_negative, require_positive
from mrta_drake.navigation.costmap import Costmap
from mrta_drake.navigation.roadways import Roadways
from mrta_drake.navigation.single_file import segment_lanes
from mrta_drake.navigation.standstills import (
    Anchor,
    Pose,
    back_off_spot,
    blocked_groups,
    gridlocks,
    in_ways,
    near_walls,
    next_anchor,
    next_pose,
    wait_cycles,
    waits_for,
    yield_order,
)
from mrta_drake.payloads import (
    NO_BACK_OFFS,
    NO_DISTURBANCES,
    NO_HUMANS,
    ROBOT_STATE_SIZE,
    ROBOT_STOPPED_SPEED,
    BackOff,
    BackOffOrders,
    HumanStates,
    LiftState,
    QueueRequest,
    QueueState,
    WaypointTarget,
)
from mrta_drake.results.deadlocks import stalled_waits
from mrta_drake.stack.fleet_inputs import PerRobotInputs


@dataclass(frozen=True)
class WatchdogParams:
    """When the watchdog steps in and what it orders; distances in m, times in s.

    A robot *has a goal* when its target is active and it is farther than
    ``goal_tolerance`` from the target's current waypoint; it is *stalled* once it has had
    one for ``standstill_time`` without getting farther than ``progress_distance`` from
    where it stood, or only backwards (against the way it faces: others push it back;
    outside single-file segments). A
    stalled robot is blocked by the robots within ``block_gap`` of it (surface to
    surface). The robot chosen to yield drives to the nearest spot within
    ``search_reach`` at least ``spot_clearance`` from every other robot and person and from
    its blockers' ways to their targets, its centre ``wall_clearance`` from walls, and
    stands there for ``yield_time``; never to a spot nearer than ``back_off_distance`` to
    where it stands: it counts as there within ``progress_distance`` of the spot (and the
    controller stops leading a robot within its ``arrival_radius``, 0.5 m, of its path's
    end), so a nearer spot makes no way (soak seed 107: a robot sent eleven times to spots
    0.51 m off moved 3.5 cm each time). An order is *missed* when its robot did not reach
    the spot in that time, or stood on its way there (got no farther than
    ``progress_distance`` from where it stood nor turned more than ``progress_angle``) for
    ``order_patience``: it is given up then; for ``retry_window`` after a miss, the robot is
    asked to yield only after robots that missed fewer orders, and never to a spot within
    ``progress_distance`` of the one it missed. A gridlock of waits (robots waiting for
    rooms or single-file segments, the waits leading to no robot that moves, serves or
    uses a lift) that lasts ``gridlock_time`` is broken by one of its robots giving way
    (``DeadlockWatchdog``, step 5), and a robot that gave way is not chosen again for
    ``gridlock_cooldown``: shorter than the run recorder's ``STUCK_TIME`` (30 s), it ends
    such a gridlock before it counts as a deadlock. A cycle of waits among robots standing
    still (a robot waiting for a room or segment another holds, or for a segment another
    stands in, and so on back to it) is a deadlock for certain: one that lasts
    ``cycle_time`` is broken at once (step 6). ``enabled`` off: no watchdog in the
    diagram (as in the paper)."""

    enabled: bool = True
    standstill_time: float = 15.0
    progress_distance: float = 0.5
    progress_angle: float = 0.5
    goal_tolerance: float = 1.0
    block_gap: float = 0.6
    search_reach: float = 8.0
    back_off_distance: float = 1.0
    wall_clearance: float = 0.8
    spot_clearance: float = 0.3
    yield_time: float = 15.0
    order_patience: float = 5.0
    retry_window: float = 120.0
    gridlock_time: float = 20.0
    gridlock_cooldown: float = 60.0
    cycle_time: float = 3.0

    def __post_init__(self):
        require_positive(self, "standstill_time", "yield_time", "order_patience",
                         "retry_window", "gridlock_time", "gridlock_cooldown", "cycle_time",
                         unit=" s")
        require_positive(self, "progress_angle", unit=" rad")
        require_positive(self, "progress_distance", "goal_tolerance", "search_reach",
                         "wall_clearance", "back_off_distance", unit=" m")
        require_non_negative(self, "block_gap", "spot_clearance", unit=" m")
        if not self.back_off_distance > self.progress_distance:
            raise InputError(None, "back_off_distance", f"must be > progress_distance "
                             f"({self.progress_distance!r} m), got {self.back_off_distance!r}")
        if not self.order_patience < self.yield_time:
            raise InputError(None, "order_patience", f"must be < yield_time "
                             f"({self.yield_time!r} s), got {self.order_patience!r}")


@dataclass(frozen=True)
class _WatchdogState:
    """Each robot's ``Anchor`` (None: no goal, or backing off), the orders, the orders
    missed within the retry window (each as ordered, ``until`` the time it ended), where
    and since when each robot has counted as in a gridlock of waits (an ``Anchor``; None:
    it is in none, step 5), since when in a cycle of waits (s; None: in none), and each
    robot's ``Pose`` on its way to its order's spot (None: no order, or at its spot; step
    4)."""

    anchors: tuple[Anchor | None, ...]
    orders: BackOffOrders = NO_BACK_OFFS
    misses: tuple[BackOff, ...] = ()
    gridlocked: tuple[Anchor | None, ...] = ()
    cycled: tuple[float | None, ...] = ()
    approaches: tuple[Pose | None, ...] = ()

    def __deepcopy__(self, memo):
        return self  # immutable: Drake's copies of the state can share it


@dataclass(frozen=True)
class _Waits:
    """What steps 5 and 6 read at one update: the robots' states (N, ROBOT_STATE_SIZE) and
    targets, their queue requests, the queues, the single-file segments each robot asks
    for (``asks``: name -> segment indices), who waits for whom (``waits``:
    ``standstills.waits_for``), the rooms' holders, the robots under an order in force
    (``backing``), the orders missed within ``retry_window`` and the robots broken down
    (names; time ``now``, s)."""

    context: object
    now: float
    states: np.ndarray
    targets: Sequence[WaypointTarget]
    requests: Sequence[QueueRequest]
    queues: QueueState
    asks: dict[str, set[int]]
    waits: dict[str, set[str]]
    holders: set[str]
    backing: set[str]
    misses: tuple[BackOff, ...]
    broken: set[str]

    @property
    def fixed(self) -> set[str]:
        """The robots no order may move: broken down, or one that missed an order within
        ``retry_window``."""
        return self.broken | {order.robot for order in self.misses}


class DeadlockWatchdog(LeafSystem):
    """Resolves standstills of robots blocked by each other, as a fleet manager would.

    .. pydrake_system::

        name: DeadlockWatchdog
        input_ports:
        - robot_state
        - target_<robot>
        - fleet_targets (optional)
        - human_states (optional)
        - disturbances (optional)
        - queue_state (optional)
        - queue_request_<robot> (optional)
        - fleet_queue_requests (optional)
        - lift_state (optional)
        output_ports:
        - back_offs

    Inputs: ``robot_state`` (vector, 4N: x, y, theta, v per robot, world frame, m, rad,
    m/s), ``target_<robot>`` (abstract ``WaypointTarget``, each waypoint generator's), one
    per robot in ``robot_names`` order (or instead ``fleet_targets``, their tuple in that
    order: ``stack.fleet_inputs``), and optionally ``human_states`` (``HumanStates``):
    back-off spots keep clear of people, and ``disturbances`` (``Disturbances``): a
    broken-down robot is never asked to yield; ``queue_state`` (``QueueState``) with each
    robot's ``queue_request_<robot>`` (``QueueRequest``, or instead ``fleet_queue_requests``,
    their tuple in robot order) and ``lift_state`` (``LiftState``): who waits for whom
    (step 5; without ``queue_state``, no step 5). Output: ``back_offs`` (abstract
    ``BackOffOrders``, from the state): the planner plans an ordered robot's path to its
    spot instead of its target; the waypoints block drops a ``releases`` order's robot's
    claims; the recorder notes each order.

    ``rate_hz`` times a second an unrestricted update (see ``WatchdogParams`` for the
    terms):

    1. Orders whose ``until`` has passed end (see 4).
    2. Each robot's anchor is renewed (``standstills.next_anchor``); a robot backing off
       has none; one pushed backwards keeps its time, unless it asks for or stands in
       single-file segments.
    3. Stalled robots and the robots within ``block_gap`` of them form groups
       (``standstills.blocked_groups``). In each group (in robot order) without a robot
       backing off, the first of ``standstills.yield_order`` (robots standing first in a
       stalled robot's way, or first in the doorway where a room's holder of the group
       waits at its door, ``standstills.in_ways``; then robots without a goal, then
       stalled ones, then those at their goal; the lowest priority first) that makes way
       for a stalled robot or such a holder (not the only one itself) and for which
       ``standstills.back_off_spot`` finds a spot clear of the others' ways is ordered
       there; every member's anchor starts again, so the group gets another
       ``standstill_time`` before the next order. A group with no spot for anyone is tried
       again at the next update; once its stalled robots have stood twice
       ``standstill_time`` with no spot clear of the others' ways, the spots need not be
       (``_order``): the robot backs off wherever it can, in a corridor back along the way
       it came, rather than the group being tried again for good. A stalled robot in
       no group but with people within ``block_gap`` of it backs off the same way, to a
       spot off their ways (a person waiting for a robot to pass and the robot waiting
       for the person); one with nobody near but nearer a wall than ``wall_clearance``
       backs off to a spot clear of walls (``_back_off_alone``).
    4. An order holds until ``yield_time`` after its robot reached its spot (within
       ``progress_distance``; an order without blockers ends there), or after the order
       if it has not reached it by then, or until its robot has stood ``order_patience``
       on its way there (a robot sent aside that stays put, e.g. kept off its way by the
       controller, holds step 3 off its group for nothing): then it is a miss, and the
       standstill it was to break goes on as before it: its robot and the robots it made
       way for that have stood since count as stalled since the order's
       ``stalled_since`` (``_stalled_again``), so the group's next order goes out at
       once. Robots with fewer
       misses within ``retry_window`` are asked first (a stable sort of ``yield_order``),
       and a robot's spots keep ``progress_distance`` from those it missed, so a
       standstill is never met with the same order again and again.
    5. Gridlocks of waits, from the facts the run recorder uses (``standstills.waits_for``:
       the robots waiting for a room wait for its holder; those waiting for single-file
       segments for the segments' holders, or the robots before them in the segments'
       queue): the waiting robots whose waits lead to no robot *live*, through every robot
       each waits for (``results.deadlocks.stalled_waits``: a robot asking for segments of
       a driving holder and of one standing for good is stalled, as the run recorder counts
       it; live: moving faster than ``ROBOT_STOPPED_SPEED``, at a lift (waiting for it or
       riding), or serving as the recorder counts it: holding a room, its target active,
       within ``goal_tolerance`` of its last waypoint, waiting for no segment) are joined
       with the robots they wait for (``standstills.gridlocks``). A robot is in a gridlock
       since the update it first was; a break while it still waits, within
       ``progress_distance`` of where it stood, does not end that but does not count (as
       the run recorder counts). A gridlock in which a robot has been for
       ``gridlock_time``, and no member backs off, is broken by robots giving way (orders
       with ``releases``); one whose members backing off each stand at their spots under a
       step 3 order, hold no room and are waited for, by those orders going on as
       ``releases`` orders (``_releasing``). A robot may give way if it holds no room (a
       holder serves, enters or leaves: undoing that costs a visit) and is not broken down
       (e.g. one waiting, or standing at home in a segment others wait for); it moves off
       only if it has not given way within ``gridlock_cooldown``. The members waiting for
       segments are taken in turn (first the holders of rooms other members wait for, then
       other holders, then by priority, highest first) until one can be freed: the robots
       holding segments it asks for go, each to the spot ``standstills.back_off_spot``
       finds clear of the other members' ways (their targets' ways and the lanes of the
       segments they ask for) and of the spots given before it, and where there is one, off
       every single-file segment's lane (standing on one it would hold it); the robots
       before it in the segments' line asking for one of them (holders too: they keep their
       rooms) stand where they are (else they would take the segments first and gridlock
       with it in turn); all at once, or none if one of those going has no spot. A gridlock
       of room waits only: the first robot that may give way, lowest priority first, goes
       to a spot. With no robot so given way, the last resort (``_make_way_for_boxed_in``):
       a member boxed in (no spot within ``search_reach`` even off everybody's way)
       standing in the way of members it waits for (ahead of them, on their way to their
       targets) is freed the other way round: those go (rooms' holders too, keeping their
       rooms), letting go of their segments, to spots off its way and the lanes it asks
       for, and the robots before it in the line stand; failing that
       (``_clear_round_boxed_in``), a member boxed in that others of the gridlock wait for
       has the members standing within ``back_off_distance`` of it (surface to surface;
       rooms' holders too, keeping their rooms) sent to spots off the others' ways (else
       the nearest), so it has room to be sent aside in turn. While its order is in force a
       robot asks for no room (it leaves the queue) and only for the segments it stands
       in, so the others get them; when it ends, it asks again, at the queues' tails.
       Every member's gridlock time starts again, so the others get another
       ``gridlock_time`` to move before the next orders.
    6. Cycles of waits, before step 5's gridlocks: among the robots standing still (at no
       lift, under no order, not serving (step 5), and not going: moving with a goal it got
       ``progress_distance`` nearer within ``cycle_time``; a robot rocking on the spot is
       still), robot A waits for robot B when B is one it waits for in step 5's sense or B
       stands in a single-file segment A asks for (a room's holder, granted its way, kept
       off it by a robot queueing for its room in it), or B stands in the doorway of the
       room A holds and waits at the door of (``QueueRequest.door``: A counts as standing
       still then, though the recorder counts it as serving); robots waiting for each
       other round a cycle (``standstills.wait_cycles``) wait for good, so a cycle that
       has lasted ``cycle_time`` (each robot's time in one counted as in step 5) is broken
       at once: for the first robot of the cycle (rooms' holders first, then by priority,
       highest first) that other robots of the cycle stand in the way of (in segments it
       asks for, or in the doorway it waits at), none of them a room's holder, broken
       down, or one that missed an order within ``retry_window``, those robots give way
       (``releases`` orders, as in step 5, to spots off the other members' ways, the lanes
       of the segments they ask for and the doorways they wait at, off every
       single-file lane where there is such a spot), all at once, or none if one of them
       has no spot; where those robots all queue for a room the freed robot holds (at
       their queue places in its way out) and have no such spot, to the nearest spots
       whatever the ways (on ahead along its way: they wait for it to leave, it for them
       to go, and no spot off its way will come); the robots before the freed one in the
       segments' line asking for one of its segments stand (as in step 5). Once the cycle
       has lasted ``gridlock_time`` with no robot so freed, rooms' holders may give way too
       (last: a holder in a cycle serves nothing, standing off its room's point, at a slot
       or on its way out; it keeps its room while it stands aside).

    ``costmap``: the static costmap the spots are checked against (the way to a spot
    keeps the robot ``standstills.PASS_WALL_GAP`` from walls). ``priorities``: per robot,
    smaller keeps its way (default: robot order, as the controller's cluster leaders).
    ``roadways``: where the single-file segments lie (step 5; None: no segments' lanes
    kept clear).
    """

    def __init__(self, robot_names: Sequence[str], radii: Sequence[float], costmap: Costmap,
                 params: WatchdogParams = WatchdogParams(), priorities=None, *,
                 rate_hz: float, roadways: Roadways | None = None):
        super().__init__()
        self._robots = tuple(robot_names)
        n = len(self._robots)
        self._radii = np.asarray(radii, dtype=float).reshape(n)
        self._costmap = costmap
        self._params = params
        self._priorities = (np.arange(n, dtype=float) if priorities is None
                            else np.asarray(priorities, dtype=float).reshape(n))
        self._roadways = roadways
        self._period = 1.0 / rate_hz
        # Every single-file segment's lane, as a way (radius 0) a spot keeps clear of.
        self._all_lanes = [] if roadways is None else [
            (np.asarray(lane, dtype=float), 0.0) for k in range(roadways.segment_count)
            for lane in segment_lanes(roadways, k)]
        self._state_index = self.DeclareAbstractState(
            Value[object](_WatchdogState((None,) * n, gridlocked=(None,) * n,
                                         cycled=(None,) * n, approaches=(None,) * n)))
        self._robot_state = self.DeclareVectorInputPort(
            "robot_state", BasicVector(ROBOT_STATE_SIZE * n))
        self._targets = PerRobotInputs(self, "target", "targets", self._robots, WaypointTarget)
        self._humans = self.DeclareAbstractInputPort("human_states", Value[object](NO_HUMANS))
        self._disturbances = self.DeclareAbstractInputPort(
            "disturbances", Value[object](NO_DISTURBANCES))
        self._queue_state = self.DeclareAbstractInputPort(
            "queue_state", Value[object](QueueState()))
        self._requests = PerRobotInputs(self, "queue_request", "queue_requests", self._robots,
                                        QueueRequest)
        self._lift_state = self.DeclareAbstractInputPort("lift_state", Value[object](LiftState()))
        self.DeclareAbstractOutputPort(
            "back_offs", lambda: Value[object](NO_BACK_OFFS), self._calc_back_offs,
            prerequisites_of_calc={self.abstract_state_ticket(self._state_index)})
        self.DeclarePeriodicUnrestrictedUpdateEvent(1.0 / rate_hz, 0.0, self._update)

    def _calc_back_offs(self, context, output):
        output.set_value(context.get_abstract_state(self._state_index).get_value().orders)

    def _update(self, context, state):
        old = context.get_abstract_state(self._state_index).get_value()
        now = context.get_time()
        states = self._robot_state.Eval(context).reshape(-1, ROBOT_STATE_SIZE)
        targets = self._targets.values(context)
        active, missed, approaches = self._in_force(old.orders.active, old.approaches,
                                                    states, now)
        misses = tuple(m for m in old.misses + missed
                       if m.until > now - self._params.retry_window + 1e-9)
        backing = {order.robot for order in active}
        single_file = self._in_single_file(context)
        anchors = [next_anchor(anchor, states[k, :2], self._has_goal(states[k], targets[k])
                               and self._robots[k] not in backing, now,
                               self._params.progress_distance,
                               None if k in single_file else float(states[k, 2]))
                   for k, anchor in enumerate(old.anchors)]
        for order in missed:
            self._stalled_again(order, anchors)
        stalled = np.array([a is not None and now - a.since >= self._params.standstill_time
                            - 1e-9 for a in anchors])
        history = old.orders.history
        groups = (blocked_groups(stalled, states[:, :2], self._radii, self._params.block_gap)
                  if stalled.any() else ())
        for group in groups:
            if any(self._robots[k] in backing for k in group):
                continue
            order = self._order(group, stalled, anchors, states, targets, context, now,
                                misses)
            if order is None:
                continue
            active, history = active + (order,), history + (order,)
            backing.add(order.robot)
            for k in group:
                anchors[k] = _restarted(anchors[k], now, self._robots[k] == order.robot)
        grouped = {k for group in groups for k in group}
        for k in np.flatnonzero(stalled):
            if k in grouped or self._robots[k] in backing:
                continue
            order = self._back_off_alone(k, anchors[k], states, context, now, misses)
            if order is not None:
                active, history = active + (order,), history + (order,)
                backing.add(order.robot)
                anchors[k] = None
        gridlocked, cycled = old.gridlocked, old.cycled
        if self._queue_state.HasValue(context):
            gridlocked, cycled, given = self._gridlocks(context, states, targets, old, anchors,
                                                        active, history, misses, now)
            ordered = {order.robot for order in given}  # a standstill order made releases
            active = tuple(order for order in active if order.robot not in ordered)
            for order in given:
                active, history = active + (order,), history + (order,)
                anchors[self._robots.index(order.robot)] = None
        orders = (old.orders if (active, history) == (old.orders.active, old.orders.history)
                  else BackOffOrders(active, history))
        if (tuple(anchors) == old.anchors and orders is old.orders and misses == old.misses
                and gridlocked == old.gridlocked and cycled == old.cycled
                and approaches == old.approaches):
            return EventStatus.DidNothing()
        state.get_mutable_abstract_state(self._state_index).set_value(
            _WatchdogState(tuple(anchors), orders, misses, gridlocked, cycled, approaches))
        return EventStatus.Succeeded()

    def _in_single_file(self, context) -> set[int]:
        """The indices of the robots asking for or standing in single-file segments (none
        without ``queue_state``): pushed back there by their own convoy or at a segment's
        end, where the queues order who goes, they count as moving (step 2)."""
        if not self._queue_state.HasValue(context):
            return set()
        return {k for k, request in enumerate(self._requests.values(context))
                if request.segments or request.standing}

    def _stalled_again(self, missed: BackOff, anchors: list[Anchor | None]) -> None:
        """A ``missed`` order freed nothing: the standstill it was to break goes on as it
        was, so it gets its next order at once. Its robot (which got nowhere) and the robots
        it made way for that have not got farther than ``progress_distance`` since (their
        anchors restarted by it, step 3) count as stalled since the order's
        ``stalled_since`` (``anchors`` updated in place)."""
        for k, robot in enumerate(self._robots):
            if anchors[k] is not None and (robot == missed.robot or (
                    robot in missed.blockers and abs(anchors[k].since - missed.issued) < 1e-9)):
                anchors[k] = Anchor(anchors[k].xy, min(anchors[k].since, missed.stalled_since,
                                                       missed.issued))

    def _gridlocks(self, context, states, targets, old: _WatchdogState, anchors, active,
                   history, misses, now
                   ) -> tuple[tuple[Anchor | None, ...], tuple[float | None, ...],
                              tuple[BackOff, ...]]:
        """Steps 5 and 6 (class docstring), ``active`` the orders in force: each robot's
        gridlock anchor and since when it has been in a cycle of waits after this update,
        and the orders that break one (none, or those of one gridlock or cycle per
        update)."""
        queues: QueueState = self._queue_state.Eval(context)
        requests = self._requests.values(context)
        waits = waits_for(queues, requests)
        asks = {request.robot: {k for k, _ in request.segments} for request in requests}
        backing = {order.robot for order in active}
        holders = {queue.holder for queue in queues.rooms} - {None}
        broken = {self._robots[k] for k in self._disturbances_now(context).broken}
        scene = _Waits(context, now, states, targets, requests, queues, asks, waits, holders,
                       backing, misses, broken)
        moving = {robot for k, robot in enumerate(self._robots)
                  if abs(states[k, 3]) > ROBOT_STOPPED_SPEED}
        serving = self._serving(states, targets, holders, queues.segment_waiting)
        live = moving | serving
        at_lifts = set()
        if self._lift_state.HasValue(context):
            for lift in self._lift_state.Eval(context).lifts:
                at_lifts.update(lift.waiting, lift.riders)
        live |= at_lifts
        going = {robot for robot, anchor in zip(self._robots, anchors, strict=True)
                 if robot in moving and anchor is not None
                 and now - anchor.since < self._params.cycle_time - 1e-9}
        cycled, given = self._cycles(scene, serving, going | at_lifts, old.cycled)
        groups = gridlocks(waits, stalled_waits(waits, live))
        since = self._gridlock_anchors(old.gridlocked, groups, waits, states, now)
        if given:  # the cycle's robots (each order's blockers) get time to move again
            freed = {robot for order in given for robot in (order.robot, *order.blockers)}
            return tuple(replace(a, since=now) if robot in freed and a is not None else a
                         for robot, a in zip(self._robots, since, strict=True)), cycled, given
        p = self._params
        for group in groups:
            index = [self._robots.index(robot) for robot in group]
            began = min(since[k].since for k in index)
            if now - began < p.gridlock_time - 1e-9:
                continue
            given = (self._releasing(group, active, waits, holders, now)
                     if backing.intersection(group) else
                     self._give_way(scene, group, history, began)
                     or self._make_way_for_boxed_in(scene, group, began)
                     or self._clear_round_boxed_in(scene, group, began))
            if given:
                for k in index:
                    since[k] = replace(since[k], since=now)
                return tuple(since), cycled, given
        return tuple(since), cycled, ()

    def _gridlock_anchors(self, old, groups, waits, states, now) -> list[Anchor | None]:
        """Each robot's gridlock anchor after this update (step 5): a robot in one of
        ``groups`` keeps its anchor (a new one, from ``now``, if it had none); one out of
        them that still waits (``waits``) within ``progress_distance`` of its anchor keeps
        it, moved on by the update's period (its time out of a gridlock does not count:
        the run recorder counts a robot standing through stalled waits with flowing ones
        between them stuck once the stalled stretches add up: office seed 13, a room's
        holder stepping about at the door every few seconds); others have none."""
        member = {robot for group in groups for robot in group}
        anchors = []
        for k, (robot, anchor) in enumerate(zip(self._robots, old, strict=True)):
            if robot in member:
                anchor = anchor or Anchor((float(states[k, 0]), float(states[k, 1])), now)
            elif (anchor is not None and waits.get(robot)
                  and math.dist(anchor.xy, states[k, :2]) <= self._params.progress_distance):
                anchor = replace(anchor, since=anchor.since + self._period)
            else:
                anchor = None
            anchors.append(anchor)
        return anchors

    def _cycles(self, scene: _Waits, serving, going, since
                ) -> tuple[tuple[float | None, ...], tuple[BackOff, ...]]:
        """Step 6 (class docstring): since when each robot has been in a cycle of waits
        among the robots standing still (``standstills.wait_cycles``; not ``serving``,
        ``going``, at a lift, or ``backing`` off), and the orders that break one cycle
        that lasted ``cycle_time`` (or none)."""
        doors = {request.robot: set(request.door) for request in scene.requests}
        still = [robot for robot in self._robots if robot not in going and robot not in
                 scene.backing and (robot not in serving or doors.get(robot))]
        stands = {request.robot: set(request.standing) for request in scene.requests}
        cycles = wait_cycles({robot: {*scene.waits.get(robot, ()), *doors.get(robot, ())}
                              for robot in self._robots}, scene.asks, stands, still)
        now = scene.now
        member = {robot for cycle in cycles for robot in cycle}
        since = tuple((s if s is not None else now) if robot in member else None
                      for robot, s in zip(self._robots, since, strict=True))
        for cycle in cycles:
            began = min(since[self._robots.index(robot)] for robot in cycle)
            if now - began < self._params.cycle_time - 1e-9:
                continue
            given = self._free_cycle(scene, cycle, stands, doors, began)
            if given:
                return tuple(now if robot in cycle else s
                             for robot, s in zip(self._robots, since, strict=True)), given
        return since, ()

    def _free_cycle(self, scene: _Waits, cycle, stands, doors, began
                    ) -> tuple[BackOff, ...]:
        """The ``releases`` orders that break ``cycle`` (class docstring, step 6), or ()
        when none of its robots can be freed: for the first of its robots (the rooms'
        holders first, then by priority, highest first) that the others stand in the way
        of (in single-file segments it asks for, or in the doorway it waits at: ``doors``,
        robot -> the robots it waits for there), and none of them a room's holder,
        broken down or one that missed an order within ``retry_window``, they all go
        to spots off the others' ways, and the robots before it in the segments' line
        asking for one of those segments stand (as in step 5); robots queueing for its
        room with no spot off the ways go to the nearest spots any way; with no such
        robot, once the cycle (since ``began``) has lasted ``gridlock_time``, the same
        with rooms' holders among those going."""
        holders, asks = scene.holders, scene.asks
        fixed = scene.fixed
        ranked = sorted(cycle, key=lambda r: (r not in holders, *self._priority_key(r)))
        late = scene.now - began >= self._params.gridlock_time - 1e-9
        for stay in (holders | fixed, fixed) if late else (holders | fixed,):
            for robot in ranked:
                blockers = [other for other in cycle if other != robot and (
                    not asks[robot].isdisjoint(stands[other]) or other in doors.get(robot, ()))]
                if not blockers or not stay.isdisjoint(blockers) or (
                        stay is fixed and holders.isdisjoint(blockers)):  # tried already
                    continue
                given = self._orders(scene, blockers, cycle, robot, began) or (
                    _queued_for(robot, blockers, scene.queues)
                    and self._orders(scene, blockers, cycle, robot, began, off_ways=False))
                if not given:
                    continue
                ahead = _before_in_line(scene.queues.segment_waiting, robot, asks) - set(
                    blockers) - scene.broken - scene.backing
                return given + self._stand(ahead, robot, scene.states, began, scene.now)
        return ()

    def _releasing(self, group, active, waits, holders, now) -> tuple[BackOff, ...]:
        """Step 5 for a gridlock ``group`` with robots backing off: when each of them
        stands at its spot under a standstill order (step 3: it keeps its claims), holds
        no room and is waited for by others of the group, those orders go on as
        ``releases`` orders (until they would have ended), so the segments they hold go
        to the robots waiting (office seed 1: a robot sent aside by the standstill rule
        stood its ``yield_time`` holding four segments the lounge's holder waited for);
        else ()."""
        orders = [order for order in active if order.robot in group]
        waited = {other for robot in group for other in waits.get(robot, ())}
        if not all(not order.releases and order.arrived is not None
                   and order.robot not in holders and order.robot in waited
                   for order in orders):
            return ()
        return tuple(replace(order, issued=now, releases=True, blockers=tuple(
            robot for robot in self._robots if order.robot in waits.get(robot, ())))
            for order in orders)

    def _give_way(self, scene: _Waits, group, history, stalled_since
                  ) -> tuple[BackOff, ...]:
        """The ``releases`` orders that break gridlock ``group`` (class docstring, step 5),
        or () when no robot may give way with a spot to go to (the robots already under an
        order, ``scene.backing``, given none)."""
        p = self._params
        now, waits, holders, queues = scene.now, scene.waits, scene.holders, scene.queues
        recent = {order.robot for order in history
                  if order.releases and order.issued > now - p.gridlock_cooldown + 1e-9}
        may = {robot for robot in self._robots
               if robot not in holders and robot not in scene.broken}
        waiting = {robot for robot in self._robots
                   if robot in waits and robot not in scene.broken}
        line = queues.segment_waiting
        awaited = {queue.holder for queue in queues.rooms
                   if not set(queue.waiting).isdisjoint(group)}
        rank = {robot: (robot not in awaited, robot not in holders, *self._priority_key(robot))
                for robot in group}
        for robot in sorted((r for r in group if r in line), key=rank.get):
            inside = {j for k in scene.asks[robot]
                      for j in queues.segments[k].holders} - {robot}
            ahead = _before_in_line(line, robot, scene.asks) - inside
            if (not (inside or ahead) or not inside <= may - recent or not ahead <= waiting
                    or not scene.backing.isdisjoint(inside | ahead)):
                continue
            given = self._orders(scene, sorted(inside, key=self._robots.index), group, robot,
                                 stalled_since)
            if inside and not given:
                continue
            return given + self._stand(ahead, robot, scene.states, stalled_since, now)
        for robot in sorted((may - recent).intersection(group),
                            key=lambda r: (-rank[r][2], rank[r][3])):
            given = self._orders(scene, [robot], group, None, stalled_since)
            if given:
                return given
        return ()

    def _make_way_for_boxed_in(self, scene: _Waits, group, stalled_since
                               ) -> tuple[BackOff, ...]:
        """Step 5's last resort for gridlock ``group`` (class docstring): for the first of
        its robots (by priority, highest first) that stands in the way of robots of the
        group it waits for (``_waiters_in_way``) and is boxed in (``_boxed_in``: no spot
        even off everybody's way, so no order can send it aside), those robots (rooms'
        holders too: they keep their rooms; not broken down, no miss within
        ``retry_window``) give way to it, to spots off its way and the lanes it asks for,
        letting go of their segments, and the robots before it in the segments' line
        asking for one of its segments stand; () if there is no such robot or one of them
        has no spot. The case: a holder of single-file segments (and of the room at a
        corridor's end) driving to its point, and a robot waiting for its segments
        standing in its way, target inactive, with the corridor's end behind it."""
        fixed = scene.fixed
        in_way = self._waiters_in_way(group, scene.waits, scene.states, scene.targets)

        def giving_way(robot):
            giving = [other for other in group if other in scene.waits.get(robot, ())
                      and robot in in_way.get(other, ())]
            return giving if fixed.isdisjoint(giving) else []

        for robot, giving in self._boxed_in_among(scene, group, giving_way):
            given = self._orders(scene, giving, group, robot, stalled_since)
            if given:
                ahead = _before_in_line(scene.queues.segment_waiting, robot, scene.asks) - set(
                    giving) - fixed
                return given + self._stand(ahead, robot, scene.states, stalled_since,
                                           scene.now)
        return ()

    def _clear_round_boxed_in(self, scene: _Waits, group, stalled_since
                              ) -> tuple[BackOff, ...]:
        """Step 5's last resort when ``_make_way_for_boxed_in`` has none (class
        docstring): for the first robot of gridlock ``group`` (by priority, highest
        first) that others of it wait for and that is boxed in (``_boxed_in``), orders
        sending the group's robots standing within ``back_off_distance`` of it (surface
        to surface; rooms' holders too: they keep their rooms; not broken down, no miss
        within ``retry_window``) to spots off the group's ways (else the nearest); () if
        there is none. The case: a robot queueing for a room inside the single-file
        corridor that the room's holder waits to leave through, a robot of the group
        beside it, no spot for it."""
        fixed = scene.fixed
        xy = scene.states[:, :2]

        def standing_near(robot):
            if robot in fixed or not any(robot in scene.waits.get(other, ()) for other in group):
                return []
            k = self._robots.index(robot)
            return [other for other in group if other != robot and other not in fixed
                    and self._gap(xy, k, self._robots.index(other))
                    < self._params.back_off_distance]

        for robot, near in self._boxed_in_among(scene, group, standing_near):
            given = (self._orders(scene, near, group, robot, stalled_since)
                     or self._orders(scene, near, group, robot, stalled_since, off_ways=False))
            if given:
                return given
        return ()

    def _priority_key(self, robot: str) -> tuple[float, int]:
        """``robot``'s place when robots are taken by priority, highest (smallest) first,
        then in the watchdog's order."""
        k = self._robots.index(robot)
        return self._priorities[k], k

    def _gap(self, xy, i: int, j: int) -> float:
        """The distance between robots ``i`` and ``j``'s surfaces (m)."""
        return math.dist(xy[i], xy[j]) - self._radii[i] - self._radii[j]

    def _waiters_in_way(self, robots, waits, states, targets) -> dict[str, set[str]]:
        """For each of ``robots`` (names) with an active target, the others of ``robots``
        that wait for it (``waits``) and stand in its way (``standstills.in_ways``: ahead
        of it, nearer its way to its target than their radii and ``spot_clearance``)."""
        xy = states[:, :2]
        ways = [_way(xy[k], target) for k, target in enumerate(targets)]
        blocks = {}
        for robot in robots:
            waiters = [other for other in robots if robot in waits.get(other, ())]
            if not waiters:
                continue
            k = self._robots.index(robot)
            near = (k, *(self._robots.index(other) for other in waiters))
            ahead = in_ways(near, np.arange(len(xy)) == k, xy, self._radii, ways,
                            self._params.spot_clearance)
            blocks[robot] = {self._robots[j] for j in near if ahead[j]}
        return blocks

    def _boxed_in_among(self, scene: _Waits, group, movers):
        """Each robot of ``group`` (by priority, highest first) with robots to move for it,
        ``movers(robot)`` (names; empty: none), that is boxed in (``_boxed_in``, tested last:
        it costs), with those robots."""
        for robot in sorted(group, key=self._priority_key):
            moving = movers(robot)
            if moving and self._boxed_in(scene.context, robot, scene.states):
                yield robot, moving

    def _boxed_in(self, context, robot: str, states) -> bool:
        """Whether ``robot`` has no spot to back off to (``standstills.back_off_spot``
        within ``search_reach``, off no robot's way): no order can send it aside."""
        return self._spot(self._people(context), self._robots.index(robot), states[:, :2],
                          []) is None

    def _humans_now(self, context) -> HumanStates:
        """The people now (``NO_HUMANS`` where ``human_states`` is not connected)."""
        return self._humans.Eval(context) if self._humans.HasValue(context) else NO_HUMANS

    def _people(self, context) -> tuple[np.ndarray, np.ndarray]:
        """The people's positions (M, 2), m, world frame, and radii (M,), m."""
        return _positions_and_radii(self._humans_now(context))

    def _spot(self, people, k: int, xy, ways, avoid=()) -> tuple[float, float] | None:
        """``standstills.back_off_spot`` for robot ``k`` at ``xy[k]`` with this watchdog's
        params: off ``ways`` and ``people`` (``_people``), within ``search_reach``, at least
        ``back_off_distance`` from where it stands and farther than ``progress_distance``
        from each of ``avoid`` (spots it missed)."""
        p = self._params
        return back_off_spot(k, xy, self._radii, ways, *people, self._costmap, p.search_reach,
                             p.spot_clearance, p.wall_clearance, avoid=avoid,
                             avoid_radius=p.progress_distance, min_move=p.back_off_distance)

    def _stand(self, robots, freed, states, stalled_since, now) -> tuple[BackOff, ...]:
        """``releases`` orders for ``robots`` (names) to stand where they are, asking for
        nothing, while ``freed`` gets the segments they wait for before it in the line."""
        return tuple(BackOff(robot, (float(states[k, 0]), float(states[k, 1])), now,
                             now + self._params.yield_time, (freed,), stalled_since,
                             releases=True)
                     for k, robot in enumerate(self._robots) if robot in robots)

    def _orders(self, scene: _Waits, robots, group, freed, stalled_since,
                off_ways: bool = True) -> tuple[BackOff, ...]:
        """Orders sending each of ``robots`` (names) to its own spot, off the ways of the
        other robots of ``group`` (and of ``freed``, the robot they make way for): their
        targets' ways, the lanes of the segments they ask for and the doorways they wait at
        (``QueueRequest.door``; not kept clear with ``off_ways`` off: the nearest spot
        any way); off every single-file segment's lane if there is such a spot (standing
        on one it would hold it); and off the spots given before. () if one of them has no
        spot."""
        p = self._params
        people = self._people(scene.context)
        xy = scene.states[:, :2]
        given = []
        for robot in robots:
            k = self._robots.index(robot)
            others = [self._robots.index(j) for j in {*group, *([freed] if freed else [])}
                      if j != robot]
            others.sort()
            ways = (self._ways_of(others, xy, scene.targets, scene.requests) if off_ways
                    else [])
            ways += [(np.asarray(order.point, dtype=float), self._radii[k]) for order in given]
            spot = None
            for extra in (self._all_lanes, []):
                spot = self._spot(people, k, xy, ways + extra)
                if spot is not None:
                    break
            if spot is None:
                return ()
            given.append(BackOff(robot, spot, scene.now, scene.now + p.yield_time,
                                 tuple(self._robots[j] for j in others), stalled_since,
                                 releases=True))
        return tuple(given)

    def _ways_of(self, robots, xy, targets, requests) -> list:
        """The ways (polyline, radius) of ``robots`` (indices) a spot keeps clear of: their
        targets' ways, the lanes of the segments they ask for and the doorways they wait
        at."""
        ways = [(_way(xy[j], targets[j]), self._radii[j]) for j in robots]
        ways += [(np.asarray(lane, dtype=float), self._radii[j]) for j in robots
                 for lane in self._lanes_asked(requests[j])]
        ways += [(self._roadways.place(requests[j].room).doorway, self._radii[j])
                 for j in robots if requests[j].door and requests[j].room is not None]
        return ways

    def _lanes_asked(self, request: QueueRequest) -> list:
        """The lanes (start, end) of the single-file segments ``request`` asks for."""
        if self._roadways is None:
            return []
        return [lane for k, _ in request.segments for lane in segment_lanes(self._roadways, k)]

    def _serving(self, states, targets, holders: set[str], segment_waiting) -> set[str]:
        """The robots serving, as the run recorder counts them (its ``SERVE`` mode): each
        one of the rooms' ``holders``, not in the segments' ``segment_waiting`` line, its
        target active with no waypoint after the current one, and within
        ``goal_tolerance`` of it. A holder standing with its target inactive (nothing to do
        for now) serves nothing: robots waiting for its room wait for one that stands."""
        return {robot for k, (robot, target) in enumerate(zip(self._robots, targets,
                                                                strict=True))
                if robot in holders and robot not in segment_waiting
                and target.active and target.current is not None and target.next is None
                and not self._has_goal(states[k], target)}

    def _has_goal(self, robot_state: np.ndarray, target: WaypointTarget) -> bool:
        return (target.active and target.current is not None
                and float(np.hypot(*(robot_state[:2] - target.current)))
                > self._params.goal_tolerance)

    def _in_force(self, orders: tuple[BackOff, ...], approaches: tuple[Pose | None, ...],
                  states: np.ndarray, now: float
                  ) -> tuple[tuple[BackOff, ...], tuple[BackOff, ...], tuple[Pose | None, ...]]:
        """The orders still in force at ``now``, each given its ``arrived`` time (and so its
        end) once its robot is within ``progress_distance`` of its spot; the orders that
        ended now without their robot reaching the spot (missed: at their ``until``, or
        given up, ``until`` now, once their robot has stood ``order_patience`` on its way,
        its ``Pose`` from ``approaches`` not renewed); and each ordered robot's ``Pose``
        after this update (step 4). Standing is judged by where the robot is and which way
        it faces, not by its distance to the spot, which a robot driving round a corner to
        it may not shorten for a while (office seed 8)."""
        p = self._params
        kept, missed = [], []
        after = [None] * len(self._robots)
        for order in orders:
            k = self._robots.index(order.robot)
            if (order.arrived is None and float(np.hypot(*(states[k, :2] - order.point)))
                    <= p.progress_distance):
                hold = p.yield_time if order.blockers else 0.0  # see _back_off_alone
                order = replace(order, arrived=now, until=now + hold)
            if order.arrived is None:
                before = approaches[k]  # the pose of an earlier order does not count
                if before is not None and before.since < order.issued - 1e-9:
                    before = None
                after[k] = next_pose(before, states[k], now, p.progress_distance,
                                     p.progress_angle)
                if now - after[k].since >= p.order_patience - 1e-9:
                    order, after[k] = replace(order, until=min(order.until, now)), None
            if order.until > now + 1e-9:
                kept.append(order)
            elif order.arrived is None:
                missed.append(order)
        return tuple(kept), tuple(missed), tuple(after)

    def _order(self, group, stalled, anchors, states, targets, context, now, misses
               ) -> BackOff | None:
        """The back-off of the first robot of ``group`` (in ``yield_order``, those with
        fewer ``misses`` first) with a free spot, away from the spots it missed, that frees
        the way of a stalled robot or of a room's holder waiting at its door, or None; the
        spot clear of the others' ways, or, with none such after the group's stalled robots
        stood twice ``standstill_time``, any (class docstring, step 3)."""
        people = self._people(context)
        xy = states[:, :2]
        p = self._params
        idle = np.array([not t.active or t.current is None for t in targets])
        stalled_here = [k for k in group if stalled[k]]
        broken = self._disturbances_now(context).broken
        missed_spots = {k: self._spots_to_avoid(k, misses) for k in group}
        all_ways = [_way(xy[j], targets[j]) for j in range(len(xy))]
        doors = self._door_waits(context, group)
        in_way = in_ways(group, stalled, xy, self._radii, all_ways, p.spot_clearance, doors)
        since = min(anchors[j].since for j in stalled_here)
        waiting = [k for k in group if stalled[k] or k in doors]
        candidates = [k for k in sorted(yield_order(group, idle, stalled, self._priorities,
                                                    in_way),
                                        key=lambda k: len(missed_spots[k]))
                      if waiting != [k] and k not in broken]  # else it frees nobody
        keep_ways = (True,) if now - since < 2 * p.standstill_time - 1e-9 else (True, False)
        for off_ways in keep_ways:
            for k in candidates:
                blockers = tuple(j for j in group if j != k)
                ways = [(all_ways[j], self._radii[j]) for j in blockers] if off_ways else []
                spot = self._spot(people, k, xy, ways, avoid=missed_spots[k])
                if spot is not None:
                    return BackOff(self._robots[k], spot, now, now + p.yield_time,
                                   tuple(self._robots[j] for j in blockers), since)
        return None

    def _door_waits(self, context, group) -> dict[int, tuple[int, ...]]:
        """The robots of ``group`` waiting at their room's door for others of it standing
        in the doorway (``QueueRequest.door``): robot index -> those robots' indices
        (none without ``queue_state``)."""
        if not self._queue_state.HasValue(context):
            return {}
        doors = {}
        for k, request in enumerate(self._requests.values(context)):
            takers = tuple(j for j in group if self._robots[j] in request.door)
            if k in group and takers:
                doors[k] = takers
        return doors

    def _disturbances_now(self, context):
        """The disturbances in force (``NO_DISTURBANCES`` where the input is not
        connected)."""
        return (self._disturbances.Eval(context) if self._disturbances.HasValue(context)
                else NO_DISTURBANCES)

    def _spots_to_avoid(self, k: int, misses: tuple[BackOff, ...]) -> np.ndarray:
        """(M, 2) the spots robot ``k`` missed, where it must not be sent again."""
        return np.array([m.point for m in misses if m.robot == self._robots[k]],
                        dtype=float).reshape(-1, 2)

    def _back_off_alone(self, k, anchor, states, context, now, misses) -> BackOff | None:
        """The back-off of robot ``k``, stalled with no robot within ``block_gap`` of it,
        or None:

        - with people within ``block_gap`` of it, to a spot off each such person's way
          (from the person on through where the robot stands, ``search_reach`` long): a
          person who waits for the robot to pass and a robot that waits for the person
          would stand there for good;
        - with nobody near but a wall nearer than ``wall_clearance`` to its centre, to the
          nearest spot clear of walls (no blockers; the order ends when it gets there):
          only the walls hold it, e.g. a robot pushed round a corner by a passing one to
          within the controller's wall distance, whose path runs on past the corner, where
          the controller will not drive it (triple_H, seed 0: 32 s); from the spot its
          path is planned again. Farther from walls, nothing holds it, and a robot cut off
          from messages stands by design: no order."""
        humans = self._humans_now(context)
        people, radii = _positions_and_radii(humans)
        xy = states[:, :2]
        with np.errstate(invalid="ignore"):  # people absent from the run are NaN
            near = np.flatnonzero(np.linalg.norm(people - xy[k], axis=-1) - radii
                                  - self._radii[k] <= self._params.block_gap)
        disturbances = self._disturbances_now(context)
        p = self._params
        if k in disturbances.broken or (len(near) == 0 and (
                k in disturbances.cut_off  # it stands until messages return
                or not near_walls(xy[k], self._costmap, p.wall_clearance))):
            return None
        ways = [(_way_through(people[j], xy[k], p.search_reach), radii[j]) for j in near]
        spot = self._spot((people, radii), k, xy, ways, avoid=self._spots_to_avoid(k, misses))
        if spot is None:
            return None
        return BackOff(self._robots[k], spot, now, now + p.yield_time,
                       tuple(humans.names[j] for j in near), anchor.since)


def _positions_and_radii(humans: HumanStates) -> tuple[np.ndarray, np.ndarray]:
    """``humans``' positions (M, 2), m, world frame, and radii (M,), m."""
    return np.asarray(humans.positions).reshape(-1, 2), np.asarray(humans.radii).reshape(-1)


def _way_through(start, through, length: float) -> np.ndarray:
    """(2, 2) the straight way from ``start`` on through ``through``, ``length`` long
    (m; just ``start`` and ``through`` when they coincide)."""
    start, through = np.asarray(start, dtype=float), np.asarray(through, dtype=float)
    step = through - start
    norm = float(np.hypot(*step))
    end = through if norm < 1e-9 else start + step * (length / norm)
    return np.array([start, end])


def _before_in_line(line, robot: str, asks) -> set[str]:
    """The robots before ``robot`` in the segments' waiting ``line`` (``QueueState``'s
    ``segment_waiting``) that ask for one of the segments it asks for (``asks``: robot ->
    segment indices); none when it is not in the line."""
    if robot not in line:
        return set()
    return {j for j in line[:line.index(robot)] if not asks[j].isdisjoint(asks[robot])}


def _queued_for(holder: str, robots, queues: QueueState) -> bool:
    """Whether each of ``robots`` (names) waits in the queue of a room ``holder`` holds:
    standing in the holder's way out at its queue place, it waits for the holder to
    leave and the holder for it to go."""
    waiting = {robot for queue in queues.rooms if queue.holder == holder
               for robot in queue.waiting}
    return set(robots) <= waiting


def _way(xy, target: WaypointTarget) -> np.ndarray:
    """(P, 2) the way a robot at ``xy`` will drive: to its target's current waypoint and
    on to the next (just where it stands without an active target)."""
    if not target.active or target.current is None:
        return np.asarray(xy, dtype=float).reshape(1, 2)
    return np.array([xy, target.current] + ([target.next] if target.next else []),
                    dtype=float)


def _restarted(anchor: Anchor | None, now: float, backing_off: bool) -> Anchor | None:
    """A group member's anchor after an order: none for the robot backing off; the others
    count their standstill again from ``now``."""
    if backing_off or anchor is None:
        return None
    return Anchor(anchor.xy, now)
