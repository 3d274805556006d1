"""The scenario file's schema: frozen dataclasses, one per YAML section.

Units: metres, radians, seconds, Hz; world frame x east, y north. Every field has a default
unless a scenario cannot do without it. ``load_scenario`` (in ``loading.py``) reads a YAML
file into ``Scenario`` and validates it; docs/scenario.md describes every field.
"""

from dataclasses import dataclass, field

from mrta_drake.errors import InputError, require_non_negative


@dataclass(frozen=True)
class WorldConfig:
    """The building. ``floor_plan`` is a floor-plan YAML (``FloorPlanFile``), a ROS
    ``map_server`` YAML (``kind: ros_map``) or an Open-RMF ``.building.yaml``
    (``kind: rmf_building``: its ``level``, or, left out with several levels, all of them
    side by side joined by the lifts (docs/worlds.md); and navigation ``graph``; locations
    and roadways left out are derived from it, see ``world/rmf_scenario.py``); paths are
    relative to the scenario file. ``levels_view``: how Meshcat shows a building run across
    levels: ``stacked`` (each level at its elevation) or ``side_by_side`` (as simulated, in
    one plane).
    ``scenic``: a Scenic 3 program placing objects (beds, carts...) for the scenario's seed,
    with ``scenic_params`` overriding its ``param`` values (see ``scenic_objects.py``)."""

    floor_plan: str = ""
    kind: str = "floor_plan"  # floor_plan | ros_map | rmf_building
    level: str = ""
    graph: int = 0
    levels_view: str = "stacked"  # stacked | side_by_side
    scenic: str = ""
    scenic_params: dict = field(default_factory=dict)


@dataclass(frozen=True)
class RobotConfig:
    """One robot. ``start`` is [x, y] or [x, y, theta]; ``priority``: smaller leads
    (default: the robot's place in the list); ``route``: location ids visited in order
    by the ``fixed`` allocator; ``capacity``: items carried at once."""

    name: str = ""
    start: list[float] = field(default_factory=list)
    radius: float = 0.22
    priority: int | None = None
    capacity: int = 2
    start_location: int | None = None
    route: list[int] = field(default_factory=list)


@dataclass(frozen=True)
class LocationConfig:
    """A place robots serve (a room, the lobby).

    ``point``: where the robot stands to serve it. ``queue``: waiting slots in the corridor,
    head (nearest the door) first. ``entry``: the path from the head slot through the door to
    ``point`` (intermediate points only). ``exit_node``: the roadway node robots join when
    leaving; ``approach_node``: the roadway node from which robots drive to the queue's tail.
    ``parking``: optional spots [x, y] off the point where a robot that has nothing more to do
    waits, leaving the point (and the room) free for the next robot. ``overflow``: optional
    spots [x, y] where robots beyond the last queue slot wait, the first robot beyond it on
    the first spot (further robots share the last); without them they wait
    ``overflow_spacing`` apart from the tail slot towards ``approach_node``. ``point`` may be
    omitted when the floor plan names a place with this location's ``name``.
    """

    id: int = -1
    name: str = ""
    point: list[float] = field(default_factory=list)
    queue: list[list[float]] = field(default_factory=list)
    entry: list[list[float]] = field(default_factory=list)
    exit_node: str = ""
    approach_node: str = ""
    parking: list[list[float]] = field(default_factory=list)
    overflow: list[list[float]] = field(default_factory=list)


@dataclass(frozen=True)
class LiftEdgeConfig:
    """A ride in ``lift`` from roadway node ``from_node`` (its cabin on level
    ``from_level``) to ``to_node`` (its cabin on ``to_level``), costing ``length`` m: the
    ride's time at the nominal speed ``tasks.estimate_speed``."""

    lift: str = ""
    from_node: str = ""
    to_node: str = ""
    from_level: str = ""
    to_level: str = ""
    length: float = 0.0


@dataclass(frozen=True)
class RoadwaysConfig:
    """A directed lane graph: ``nodes`` name -> [x, y]; ``edges`` [from, to] one-way;
    ``lift_edges``: rides between levels (a building with lifts); ``single_file``: segments
    driven both ways on one lane, each the roadway node names along it in order, which
    robots drive one way at a time (reserved like a room)."""

    nodes: dict[str, list[float]] = field(default_factory=dict)
    edges: list[list[str]] = field(default_factory=list)
    lift_edges: list[LiftEdgeConfig] = field(default_factory=list)
    single_file: list[list[str]] = field(default_factory=list)


@dataclass(frozen=True)
class TaskConfig:
    """Carry an item from location ``pickup`` to ``dropoff`` by absolute time ``deadline``."""

    pickup: int = -1
    dropoff: int = -1
    deadline: float = 0.0


@dataclass(frozen=True)
class TaskBatch:
    """Tasks released together at ``arrival`` (s)."""

    arrival: float = 0.0
    tasks: list[TaskConfig] = field(default_factory=list)


@dataclass(frozen=True)
class TaskGenerationConfig:
    """Seeded random task batches, drawn by ``load_scenario`` with the scenario's ``seed``
    (see ``task_generation.py``).

    Arrivals: a Poisson process of ``rate`` batches per s over [``start``, ``end``) s
    (``end`` 0: the scenario's duration), or the fixed ``times`` (s). ``batch_size``:
    [min, max] tasks per batch, uniform. ``pickup_weights``, ``dropoff_weights``: relative
    weights keyed by location name or id (locations left out: weight 0; empty: all
    locations equally); a task's drop-off differs from its pickup. Deadline: arrival +
    ``slack`` [min, max] (uniform) x the allocator's travel time pickup -> drop-off
    (``tasks.travel_times``, or its estimate at ``tasks.estimate_speed``); or, when
    ``deadline_range`` [min, max] s is given, arrival + a uniform draw from it.
    ``whole_seconds``: arrivals rounded down and deadlines up to whole seconds, as in
    MRTA-Sim task streams."""

    rate: float = 0.0
    times: list[float] = field(default_factory=list)
    start: float = 0.0
    end: float = 0.0
    batch_size: list[int] = field(default_factory=lambda: [1, 1])
    pickup_weights: dict[str, float] = field(default_factory=dict)
    dropoff_weights: dict[str, float] = field(default_factory=dict)
    slack: list[float] = field(default_factory=lambda: [2.0, 4.0])
    deadline_range: list[float] = field(default_factory=list)
    whole_seconds: bool = True


@dataclass(frozen=True)
class TasksConfig:
    """The task stream: inline ``stream`` batches and/or a ``file`` (this format or an
    original MRTA-Sim ``tasks_stream`` JSON/YAML) and/or seeded random batches
    (``generate``), merged in arrival order; ``travel_times``: a matrix file (YAML/CSV,
    integer s) for the allocator, estimated from roadway lengths at ``estimate_speed`` m/s
    when empty; ``service_time``: s per pickup or drop-off."""

    file: str = ""
    stream: list[TaskBatch] = field(default_factory=list)
    generate: TaskGenerationConfig | None = None
    travel_times: str = ""
    estimate_speed: float = 0.6
    service_time: float = 1.0


@dataclass(frozen=True)
class HumanConfig:
    """A named person walking a loop through ``waypoints`` ([x, y] each)."""

    name: str = ""
    waypoints: list[list[float]] = field(default_factory=list)
    desired_speed: float | None = None


@dataclass(frozen=True)
class HumanGroupConfig:
    """Seeded generated people. ``kind``: ``visitors`` (walk between random ``points``),
    ``crowd`` (mill around ``center`` within ``spread``), ``stream`` (enter at ``center``
    every ``interval`` s and walk to random ``points``)."""

    kind: str = "visitors"
    count: int = 0
    points: list[list[float]] = field(default_factory=list)
    center: list[float] = field(default_factory=list)
    spread: float = 1.5
    interval: float = 10.0
    desired_speed: float | None = None


@dataclass(frozen=True)
class HumansConfig:
    """People in the building: named walkers and generated groups. How they walk (body
    radius, speeds, social forces) is the humans block's ``blocks.humans.params``."""

    walkers: list[HumanConfig] = field(default_factory=list)
    groups: list[HumanGroupConfig] = field(default_factory=list)


@dataclass(frozen=True)
class BlockageConfig:
    """A region closed to robots from ``start`` to ``end`` s (no ``end``: to the end of the
    run). ``box`` [x_min, x_max, y_min, y_max] (m, inside the floor plan) is lethal in the
    planner's costmap, roadway lanes crossing it are closed (robots driving through it are
    re-routed), and the controllers' wall rays see it. People are not affected."""

    name: str = ""
    box: list[float] = field(default_factory=list)
    start: float = 0.0
    end: float | None = None


@dataclass(frozen=True)
class BreakdownConfig:
    """``robot`` breaks down at ``start`` s: it brakes to a stop where it is (an obstacle the
    others' paths go around), gives up its rooms and drops out of the fleet; the items it
    carries are lost (their tasks fail) and its other tasks go to the others. With ``end``
    (s) it is repaired then and rejoins the fleet."""

    robot: str = ""
    start: float = 0.0
    end: float | None = None


@dataclass(frozen=True)
class OutageConfig:
    """``robot``'s cluster messages are lost from ``start`` to ``end`` s (no ``end``: to the
    end of the run): the others' controllers see its state as last broadcast at
    ``start``; it brakes and stands, solving its own QP alone against their states as they
    were then, until the messages return."""

    robot: str = ""
    start: float = 0.0
    end: float | None = None


@dataclass(frozen=True)
class DisturbancesConfig:
    """Scheduled disturbances (see ``mrta_drake/scenario/disturbances.py``); none by default."""

    blockages: list[BlockageConfig] = field(default_factory=list)
    breakdowns: list[BreakdownConfig] = field(default_factory=list)
    outages: list[OutageConfig] = field(default_factory=list)


@dataclass(frozen=True)
class BlockConfig:
    """Which implementation of a block to use (``kind``) and its parameters (``params``,
    checked against that implementation's own parameter dataclass)."""

    kind: str = ""
    params: dict = field(default_factory=dict)


@dataclass(frozen=True)
class BlocksConfig:
    allocator: BlockConfig = field(default_factory=lambda: BlockConfig("smt"))
    waypoints: BlockConfig = field(default_factory=lambda: BlockConfig("roadway"))
    queues: BlockConfig = field(default_factory=lambda: BlockConfig("fifo"))
    planner: BlockConfig = field(default_factory=lambda: BlockConfig("grid_astar"))
    controller: BlockConfig = field(default_factory=lambda: BlockConfig("cluster_cbf"))
    robots: BlockConfig = field(default_factory=lambda: BlockConfig("kinematic"))
    humans: BlockConfig = field(default_factory=lambda: BlockConfig("social_force"))
    lifts: BlockConfig = field(default_factory=lambda: BlockConfig("fifo"))
    watchdog: BlockConfig = field(default_factory=lambda: BlockConfig("back_off"))


@dataclass(frozen=True)
class RatesConfig:
    """Update rates of the blocks, Hz, the only place blocks take their rates from. The
    planner re-plans every robot at ``planner`` and looks for changed targets at
    ``planner_target_check``; ``logging`` is the recorder's sampling rate, ``meshcat`` the
    drawing rate."""

    allocator: float = 1.0
    waypoints: float = 10.0
    queues: float = 10.0
    planner: float = 2.0
    planner_target_check: float = 10.0
    controller: float = 20.0
    robots: float = 20.0
    humans: float = 20.0
    lifts: float = 10.0
    watchdog: float = 2.0
    logging: float = 10.0
    meshcat: float = 20.0
    network: float = 20.0  # robots' broadcasts (communication:, unless ideal)


@dataclass(frozen=True)
class CommunicationConfig:
    """The network the robots' cluster messages travel over (docs/fidelity.md). Every
    message (a robot's state broadcast to each other robot, a leader's command to a
    follower) is lost with probability ``loss``, independently, or arrives ``latency`` s
    plus a delay uniform in [0, ``jitter``] s after it is sent. A follower whose leader's
    last command is older than ``latency + jitter + stale_after`` s brakes on its own QP.
    ``kind``: the registered network block (``stack.blocks.register_block("network",
    ...)``). With no latency, jitter or loss (the default) the network is ideal: no network
    block, the controller forms clusters from the true states every tick."""

    latency: float = 0.0
    jitter: float = 0.0
    loss: float = 0.0
    stale_after: float = 0.1
    kind: str = "broadcast"

    def __post_init__(self):
        require_non_negative(self, "latency", "jitter", "stale_after", unit=" s")
        if not 0.0 <= self.loss < 1.0:
            raise InputError(None, "loss", f"must be in [0, 1), got {self.loss!r}")

    @property
    def ideal(self) -> bool:
        """No latency, jitter or loss: messages arrive at once, every one."""
        return self.latency == 0.0 and self.jitter == 0.0 and self.loss == 0.0


@dataclass(frozen=True)
class Scenario:
    """A complete runnable scenario. ``source`` is the file it was loaded from (set by
    ``load_scenario``; relative paths inside resolve against its folder). ``profile``:
    ``mrta_drake`` (this project's behaviour) or ``paper`` (every switch of
    docs/fidelity.md at the MRTA-Sim paper's value where the scenario leaves it unset; see
    ``profiles.py``)."""

    world: WorldConfig = field(default_factory=WorldConfig)
    robots: list[RobotConfig] = field(default_factory=list)
    locations: list[LocationConfig] = field(default_factory=list)
    roadways: RoadwaysConfig = field(default_factory=RoadwaysConfig)
    humans: HumansConfig = field(default_factory=HumansConfig)
    tasks: TasksConfig = field(default_factory=TasksConfig)
    blocks: BlocksConfig = field(default_factory=BlocksConfig)
    rates: RatesConfig = field(default_factory=RatesConfig)
    disturbances: DisturbancesConfig = field(default_factory=DisturbancesConfig)
    communication: CommunicationConfig = field(default_factory=CommunicationConfig)
    seed: int = 0
    duration: float = 60.0
    profile: str = "mrta_drake"
    source: str = ""
