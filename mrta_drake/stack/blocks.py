"""Which implementations exist for each block, and how to make one from a scenario.

A scenario picks an implementation per block slot (``blocks.controller.kind``) and gives its
parameters (``blocks.controller.params``, checked against the implementation's own frozen
``Params`` dataclass). Researchers add their own with ``register_block``; the new system
must have the slot's ports (docs/architecture.md lists them):

=========== ===================================== ============================================
slot        inputs                                outputs
=========== ===================================== ============================================
allocator   progress_<robot> (RobotProgress)      plan (FleetPlan)
waypoints   plan, robot_state, queue_state        target_<robot>, queue_request_<robot>,
                                                  progress_<robot>, lift_request_<robot>,
                                                  fleet_targets, fleet_queue_requests,
                                                  fleet_progress
                                                  (one system for the fleet; a ``per_robot``
                                                  kind: target, queue_request, progress,
                                                  lift_request of one system per robot)
queues      request_<robot> (QueueRequest; or     queue_state (QueueState)
            fleet_queue_requests)
planner     robot_state, target_<robot> (or       paths (FleetPaths)
            fleet_targets)
controller  robot_state, paths, human_states      commands (2N), telemetry
robots      commands (2N)                         state (4N), plant_positions (3N)
humans      robot_state (4N)                      human_states (HumanStates), plant_positions
lifts       request_<robot> (LiftRequest),        lift_state (LiftState), relocations,
            robot_state (4N)                      events (only with lifts: a building run
                                                  across levels)
watchdog    robot_state (4N), target_<robot> (or  back_offs (BackOffOrders; not in the
            fleet_targets), human_states,         diagram when its ``enabled`` is off)
            queue_state, queue_request_<robot>
            (or fleet_queue_requests), lift_state
            (optional)
network     robot_state (4N), leader_commands     views (NetworkViews) (only when the
            (CommandMessages)                     ``communication:`` is not ideal)
=========== ===================================== ============================================

The network's kind and parameters are the scenario's ``communication:`` section
(``CommunicationConfig``: its ``kind``, the rest its parameters), not a ``blocks:`` entry.

A robots block that steps the plant (``BlockType.physics``, e.g. kind ``physics``) also has
an input ``plant_state`` and an output ``generalized_force`` (see
``mrta_drake.robots.plant_stepping``).
Any block may also have an input ``disturbances`` (``payloads.Disturbances``): ``add_stack``
connects it when the scenario schedules disturbances (see ``mrta_drake.scenario.disturbances``).
Each block's class docstring lists its ports in a ``.. pydrake_system::`` block, and takes its
rate (``rate_hz``) from the scenario's ``rates:`` section only.
"""

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from mrta_drake.errors import InputError
from mrta_drake.payloads import ROBOT_STATE_SIZE
from mrta_drake.scenario.schema import BlockConfig, Scenario
from mrta_drake.scenario.section_files import start_locations
from mrta_drake.scenario.typed_yaml import load_typed


@dataclass(frozen=True, eq=False)
class BuildContext:
    """What a block factory may use: the scenario, the world geometry, derived data."""

    scenario: Scenario
    floor_plan: object  # FloorPlan
    rates: object  # RatesConfig
    world: object = None  # World, for the blocks made after it (all but humans)

    @classmethod
    def for_scenario(cls, scenario: Scenario) -> "BuildContext":
        """The context of ``scenario`` before its world is built: its floor plan (with any
        Scenic objects) loaded, its location points filled in from the floor plan."""
        from mrta_drake.world.plant import load_floor_plan_of, resolve_locations

        floor_plan = load_floor_plan_of(scenario)
        return cls(resolve_locations(scenario, floor_plan), floor_plan, scenario.rates)

    @property
    def robot_names(self) -> list[str]:
        return [r.name for r in self.scenario.robots]

    @property
    def robot_starts(self) -> np.ndarray:
        """(N, 3) [x, y, theta] start poses."""
        return np.array([(list(r.start) + [0.0])[:3] for r in self.scenario.robots])

    def home(self, index: int) -> tuple[float, float] | None:
        """Robot ``index``'s start spot (x, y), m, where it waits with nothing to do when
        its last location has no parking spot; None when it started on a location."""
        if self.start_locations[index] is not None:
            return None
        x, y = self.robot_starts[index][:2]
        return (float(x), float(y))

    @property
    def homes(self) -> tuple[tuple[float, float], ...]:
        """Every robot's start spot that is not on a location (``home``), in robot order."""
        return tuple(home for home in map(self.home, range(len(self.scenario.robots)))
                     if home is not None)

    @property
    def obstacles(self):
        return self.floor_plan.obstacles

    @cached_property
    def roadways(self):
        from mrta_drake.navigation.roadways import Roadways

        return Roadways(self.scenario.roadways, self.scenario.locations, self.scenario.source)

    @cached_property
    def lifts(self) -> tuple:
        """The lifts (``LiftSpec``) robots ride: those of a building run across levels,
        else none."""
        if self.scenario.world.kind != "rmf_building":  # no building: no import of one
            return ()
        from mrta_drake.world.rmf_scenario import building_lifts

        return building_lifts(self.scenario)

    @cached_property
    def travel_times(self) -> np.ndarray:
        """The allocator's (L, L) integer travel times (s): the scenario's file, else an
        estimate from roadway leg lengths at ``tasks.estimate_speed``, the one the loader
        drew a generated stream's deadlines with (``allocator_travel_times``)."""
        from mrta_drake.scenario.travel_times import allocator_travel_times

        return allocator_travel_times(self.scenario, self.roadways)

    @cached_property
    def start_locations(self) -> list[int | None]:
        """Each robot's start location: as given, else the location whose point is within
        1 m of its start position, else None."""
        return start_locations(self.scenario.robots, self.scenario.locations)


@dataclass(frozen=True)
class BlockType:
    """An implementation of a block slot: its parameter dataclass and a factory
    ``make(context, params) -> LeafSystem``. A waypoints block with ``per_robot`` set is
    one system per robot, ``make(context, params, robot_index)``. A robots block that steps
    the plant gives ``physics(params) -> world.PlantPhysics``, how the world makes the
    plant."""

    params: type
    make: Callable
    physics: Callable | None = None
    per_robot: bool = False


NETWORK = "network"  # the slot whose kind and parameters are the ``communication:`` section
_REGISTRY: dict[str, dict[str, Callable[[], BlockType]]] = {
    "allocator": {}, "waypoints": {}, "queues": {}, "planner": {}, "controller": {},
    "robots": {}, "humans": {}, "lifts": {}, "watchdog": {}, NETWORK: {},
}


def register_block(slot: str, kind: str, block_type: "BlockType | Callable[[], BlockType]"):
    """Make ``kind`` available for ``slot`` in scenarios. ``block_type`` may be a function
    returning the BlockType, so heavy imports happen only when the kind is used."""
    if slot not in _REGISTRY:
        raise ValueError(f"unknown block slot {slot!r}; slots: {', '.join(_REGISTRY)}")
    _REGISTRY[slot][kind] = block_type if callable(block_type) and not isinstance(
        block_type, BlockType) else (lambda: block_type)


def block_kinds(slot: str) -> list[str]:
    return sorted(_REGISTRY[slot])


def block_type(slot: str, kind: str) -> BlockType:
    """The registered implementation ``kind`` of ``slot``."""
    return _REGISTRY[slot][kind]()


def resolve_block(scenario: Scenario, slot: str) -> tuple[BlockType, object]:
    """The chosen implementation of ``slot`` and its parameters, checked."""
    if slot == NETWORK:
        return _network_block(scenario), scenario.communication
    config: BlockConfig = getattr(scenario.blocks, slot)
    kinds = _REGISTRY[slot]
    if config.kind not in kinds:
        raise InputError(scenario.source, f"blocks.{slot}.kind",
                         f"unknown kind {config.kind!r} (known: {', '.join(sorted(kinds))})")
    chosen = kinds[config.kind]()
    path = f"blocks.{slot}.params"
    _refuse_moved_fields(config.params, chosen.params, scenario.source, path)
    params = load_typed(config.params, chosen.params, scenario.source, path)
    return chosen, params


def _network_block(scenario: Scenario) -> BlockType:
    """The network block the scenario's ``communication.kind`` names."""
    kinds = _REGISTRY[NETWORK]
    kind = scenario.communication.kind
    if kind not in kinds:
        raise InputError(scenario.source, "communication.kind",
                         f"unknown kind {kind!r} (known: {', '.join(sorted(kinds))})")
    return kinds[kind]()


def _refuse_moved_fields(raw: dict, params_class: type, file: str, path: str) -> None:
    """An old field of a regrouped params class (listed in its ``moved_fields``: old name ->
    new dotted place) is refused with its new place. A name that is now a group's may
    still hold the group (a mapping)."""
    moved = getattr(params_class, "moved_fields", {})
    for key, value in (raw or {}).items():
        if key in moved and not isinstance(value, dict):
            raise InputError(file, f"{path}.{key}", f"moved to {path}.{moved[key]}")


def check_blocks(scenario: Scenario) -> None:
    """Resolve every block slot once, so bad kinds or parameters fail at load time."""
    for slot in _REGISTRY:
        resolve_block(scenario, slot)


# --- The built-in implementations ------------------------------------------------------------


def _kinematic_robots() -> BlockType:
    from mrta_drake.robots.unicycle_robots import UnicycleParams, UnicycleRobots

    return BlockType(UnicycleParams, lambda ctx, params: UnicycleRobots(
        ctx.robot_names, ctx.robot_starts, params, rate_hz=ctx.rates.robots,
        relocations=bool(ctx.lifts)))


def _physics_robots() -> BlockType:
    from mrta_drake.robots.physics_robots import PhysicsRobotParams, PhysicsRobots
    from mrta_drake.world.plant import PlantPhysics

    return BlockType(
        PhysicsRobotParams,
        lambda ctx, params: PhysicsRobots(ctx.world.plant, ctx.world.robots, params,
                                          relocations=bool(ctx.lifts)),
        physics=lambda params: PlantPhysics(params.time_step, params.mass,
                                            params.collision_shape))


@dataclass(frozen=True)
class NoParams:
    """For implementations without parameters."""


def task_allocator_block(allocator_class, params_class) -> BlockType:
    """An allocator block: a ``TaskAllocator`` around ``allocator_class(params)``, any class
    with ``allocate(AllocationProblem) -> Allocation`` (like ``GreedyAllocator``), whose
    parameters are ``params_class`` (e.g. ``NoParams``). The block's parameters are those
    plus the feedback switches (``allocation.feedback_params.FeedbackParams``)."""
    from mrta_drake.allocation.feedback_params import (
        FeedbackParams,
        allocator_params,
        with_feedback,
    )

    def make(ctx: BuildContext, params):
        from mrta_drake.allocation.task_allocator import TaskAllocator

        # A robot that does not start on a location is planned from the nearest one.
        points = np.array([loc.point for loc in ctx.scenario.locations])
        ids = [loc.id for loc in ctx.scenario.locations]
        starts = [
            location if location is not None
            else ids[int(np.argmin(np.linalg.norm(points - start[:2], axis=1)))]
            for location, start in zip(ctx.start_locations, ctx.robot_starts, strict=True)]
        return TaskAllocator(
            ctx.scenario.tasks.stream, ctx.robot_names, starts,
            [r.capacity for r in ctx.scenario.robots], ctx.travel_times,
            allocator_class(allocator_params(params)), ctx.scenario.tasks.service_time,
            rate_hz=ctx.rates.allocator, source=ctx.scenario.source,
            feedback=FeedbackParams.of(params))

    return BlockType(with_feedback(params_class), make)


def _smt_allocator() -> BlockType:
    from mrta_drake.allocation import SmtAllocator, SmtAllocatorParams

    return task_allocator_block(SmtAllocator, SmtAllocatorParams)


def _greedy_allocator() -> BlockType:
    from mrta_drake.allocation import GreedyAllocator, GreedyAllocatorParams

    return task_allocator_block(GreedyAllocator, GreedyAllocatorParams)


def _fixed_allocator() -> BlockType:
    from mrta_drake.allocation.fixed_sequence_allocator import FixedSequenceAllocator

    return BlockType(NoParams, lambda ctx, params: FixedSequenceAllocator(
        ctx.robot_names, [r.route for r in ctx.scenario.robots]))


def _waypoint_params(ctx: BuildContext, params):
    """``params`` (``WaypointParams``) with the scenario's ``tasks.service_time``."""
    if ctx.scenario.blocks.waypoints.params.get("service_time") is not None:
        raise InputError(ctx.scenario.source, "blocks.waypoints.params.service_time",
                         "set tasks.service_time instead (the allocator uses it too)")
    return dataclasses.replace(params, service_time=ctx.scenario.tasks.service_time)


def _roadway_waypoints() -> BlockType:
    from mrta_drake.navigation.waypoint_generator import (
        FleetWaypoints,
        WaypointParams,
        WaypointPolicy,
    )

    def make(ctx: BuildContext, params: WaypointParams):
        params = _waypoint_params(ctx, params)
        return FleetWaypoints([
            WaypointPolicy(ctx.robot_names, k, ctx.roadways, location, params, ctx.home(k),
                           ctx.homes)
            for k, location in enumerate(ctx.start_locations)], rate_hz=ctx.rates.waypoints)

    return BlockType(WaypointParams, make)


def _roadway_per_robot_waypoints() -> BlockType:
    from mrta_drake.navigation.waypoint_generator import WaypointGenerator, WaypointParams

    def make(ctx: BuildContext, params: WaypointParams, index: int):
        return WaypointGenerator(ctx.robot_names, index, ctx.roadways,
                                 ctx.start_locations[index], _waypoint_params(ctx, params),
                                 ctx.home(index), ctx.homes, rate_hz=ctx.rates.waypoints)

    return BlockType(WaypointParams, make, per_robot=True)


def _fifo_queues() -> BlockType:
    from mrta_drake.navigation.room_queues import RoomQueues
    from mrta_drake.navigation.single_file import SingleFileParams, stop_segments

    def make(ctx: BuildContext, params):
        # Segments where robots stop are held by one robot at a time (single_file.py).
        lanes = getattr(resolve_block(ctx.scenario, "waypoints")[1], "single_file",
                        SingleFileParams())
        # A robot that starts on a location holds it until it leaves (first one per room).
        holders = {}
        for name, location in zip(ctx.robot_names, ctx.start_locations, strict=True):
            if location is not None:
                holders.setdefault(location, name)
        return RoomQueues(ctx.robot_names, ctx.roadways.location_ids, rate_hz=ctx.rates.queues,
                          holders=holders, segments=ctx.roadways.segment_count,
                          exclusive=stop_segments(ctx.roadways, lanes))

    return BlockType(NoParams, make)


def _fifo_lifts() -> BlockType:
    from mrta_drake.navigation.lift_bank import LiftBank, LiftParams

    return BlockType(LiftParams, lambda ctx, params: LiftBank(
        ctx.robot_names, ctx.lifts, params, rate_hz=ctx.rates.lifts,
        robot_radius=max((r.radius for r in ctx.scenario.robots), default=0.22)))


def _grid_astar_planner() -> BlockType:
    from mrta_drake.navigation.planner_service import PlannerService, PlannerServiceParams

    return BlockType(PlannerServiceParams, lambda ctx, params: PlannerService.from_obstacles(
        ctx.obstacles, ctx.floor_plan.bounds, ctx.robot_names, params,
        replan_rate_hz=ctx.rates.planner, target_check_rate_hz=ctx.rates.planner_target_check,
        floors=ctx.floor_plan.floors))


def _back_off_watchdog() -> BlockType:
    from mrta_drake.navigation.costmap import Costmap, CostmapParams
    from mrta_drake.navigation.deadlock_watchdog import DeadlockWatchdog, WatchdogParams

    def make(ctx: BuildContext, params: WatchdogParams):
        _, planner = resolve_block(ctx.scenario, "planner")
        costmap = Costmap.from_obstacles(ctx.obstacles, ctx.floor_plan.bounds,
                                         getattr(planner, "costmap", CostmapParams()),
                                         floors=ctx.floor_plan.floors)
        return DeadlockWatchdog(ctx.robot_names, [r.radius for r in ctx.scenario.robots],
                                costmap, params, _priorities(ctx), rate_hz=ctx.rates.watchdog,
                                roadways=ctx.roadways)

    return BlockType(WatchdogParams, make)


def _social_force_humans() -> BlockType:
    from mrta_drake.humans.people import scenario_people
    from mrta_drake.humans.social_force_humans import SocialForceHumans
    from mrta_drake.humans.social_force_params import SocialForceParams

    def make(ctx: BuildContext, params: SocialForceParams):
        people = scenario_people(ctx.scenario, params, ctx.obstacles, ctx.floor_plan.places)
        return SocialForceHumans(people, params, ctx.obstacles, ctx.robot_names,
                                 [r.radius for r in ctx.scenario.robots],
                                 rate_hz=ctx.rates.humans)

    return BlockType(SocialForceParams, make)


def _priorities(ctx: BuildContext) -> list[int]:
    """Robots' leader priorities (smaller leads); default: their place in the scenario."""
    return [k if r.priority is None else r.priority for k, r in enumerate(ctx.scenario.robots)]


def _cluster_cbf_controller() -> BlockType:
    from mrta_drake.control.cbf_params import CbfParams
    from mrta_drake.control.cluster_cbf_controller import ClusterCbfController

    return BlockType(CbfParams, lambda ctx, params: ClusterCbfController(
        ctx.robot_names, ctx.obstacles, params, _priorities(ctx),
        rate_hz=ctx.rates.controller))


def _go_to_goal_controller() -> BlockType:
    from mrta_drake.control.go_to_goal_controller import GoToGoalController, GoToGoalParams

    return BlockType(GoToGoalParams, lambda ctx, params: GoToGoalController(
        ctx.robot_names, ctx.obstacles, params, rate_hz=ctx.rates.controller))


def _broadcast_network() -> BlockType:
    from mrta_drake.network.broadcast_network import BroadcastNetwork
    from mrta_drake.scenario.schema import CommunicationConfig

    def make(ctx: BuildContext, config: CommunicationConfig):
        starts = np.zeros((len(ctx.robot_names), ROBOT_STATE_SIZE))
        starts[:, :3] = ctx.robot_starts
        return BroadcastNetwork(ctx.robot_names, starts, config, ctx.scenario.seed,
                                rate_hz=ctx.rates.network)

    return BlockType(CommunicationConfig, make)


register_block("robots", "kinematic", _kinematic_robots)
register_block("robots", "physics", _physics_robots)
register_block("controller", "cluster_cbf", _cluster_cbf_controller)
register_block("controller", "go_to_goal", _go_to_goal_controller)
register_block("humans", "social_force", _social_force_humans)
register_block(NETWORK, "broadcast", _broadcast_network)
register_block("planner", "grid_astar", _grid_astar_planner)
register_block("allocator", "fixed", _fixed_allocator)
register_block("allocator", "smt", _smt_allocator)
register_block("allocator", "greedy", _greedy_allocator)
register_block("waypoints", "roadway", _roadway_waypoints)
register_block("waypoints", "roadway_per_robot", _roadway_per_robot_waypoints)
register_block("queues", "fifo", _fifo_queues)
register_block("lifts", "fifo", _fifo_lifts)
register_block("watchdog", "back_off", _back_off_watchdog)


def replace_block(scenario: Scenario, slot: str, kind: str, **params) -> Scenario:
    """A copy of ``scenario`` using implementation ``kind`` for ``slot`` with ``params``."""
    blocks = dataclasses.replace(scenario.blocks, **{slot: BlockConfig(kind, dict(params))})
    return dataclasses.replace(scenario, blocks=blocks)
