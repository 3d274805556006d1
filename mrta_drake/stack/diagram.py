"""Wiring a scenario's blocks into one Drake diagram.

``add_stack`` adds every block of a scenario to a ``DiagramBuilder`` as a named subsystem
and connects the fixed ports (see ``blocks.py``); ``build_diagram`` does that and builds.
Users who want to add their own systems call ``add_stack`` on their own builder, connect
what they like to the returned handles, then build.
"""

import dataclasses
from dataclasses import dataclass, field

import numpy as np
from pydrake.geometry import Meshcat, MeshcatVisualizer, MeshcatVisualizerParams, Role
from pydrake.systems.framework import Diagram, DiagramBuilder, LeafSystem, OutputPort

from mrta_drake.errors import InputError
from mrta_drake.robots.plant_stepping import add_plant_stepping
from mrta_drake.scenario.disturbances import blockages, breakdowns, has_disturbances, outage_windows
from mrta_drake.scenario.schema import Scenario
from mrta_drake.stack.blocks import NETWORK, BuildContext, resolve_block
from mrta_drake.stack.contact_recorder import ContactRecorder
from mrta_drake.stack.disturbance_schedule import DisturbanceSchedule
from mrta_drake.stack.levels_view import LevelsView
from mrta_drake.stack.meshcat_overlay import MeshcatOverlay
from mrta_drake.stack.run_recorder import RunRecorder
from mrta_drake.world.plant import Body, World, add_plant_posing, build_world


@dataclass(eq=False)
class Stack:
    """Handles to the systems of one scenario's diagram (``diagram`` once built);
    ``contacts`` records the plant's contacts when a physics robots block steps it;
    ``disturbances`` is the schedule of a scenario with a ``disturbances:`` section;
    ``lifts`` the lift bank of a building run across levels; ``watchdog`` the deadlock
    watchdog unless the scenario turns it off; ``network`` the network of a
    scenario whose ``communication:`` is not ideal. ``waypoints`` is the waypoints block:
    one system for the fleet, or one per robot (a ``per_robot`` kind); ``waypoint_output``
    finds a robot's output in either."""

    scenario: Scenario
    world: World
    robots: LeafSystem
    controller: LeafSystem
    planner: LeafSystem
    queues: LeafSystem
    allocator: LeafSystem
    waypoints: list[LeafSystem]
    humans: LeafSystem | None
    recorder: RunRecorder
    visualizer: MeshcatVisualizer | None = None
    diagram: Diagram | None = None
    contacts: ContactRecorder | None = None
    disturbances: DisturbanceSchedule | None = None
    lifts: LeafSystem | None = None
    watchdog: LeafSystem | None = None
    network: LeafSystem | None = None
    extras: dict = field(default_factory=dict)

    def waypoint_output(self, index: int, port: str) -> OutputPort:
        """Robot ``index``'s waypoints output ``port`` (``target``, ``queue_request``,
        ``progress`` or ``lift_request``)."""
        return _waypoint_output(self.waypoints, self.scenario.robots[index].name, index, port)


def _waypoint_output(systems: list[LeafSystem], robot: str, index: int,
                     port: str) -> OutputPort:
    """Robot ``index`` (named ``robot``)'s output ``port`` of the waypoints block
    ``systems``: ``<port>_<robot>`` of the one fleet system, or ``port`` of its own."""
    if len(systems) == 1 and systems[0].HasOutputPort(f"{port}_{robot}"):
        return systems[0].GetOutputPort(f"{port}_{robot}")
    return systems[index].GetOutputPort(port)


def add_stack(builder: DiagramBuilder, scenario: Scenario, *, meshcat: Meshcat | None = None,
              out_dir: str | None = None) -> Stack:
    """Add the scenario's world and blocks to ``builder`` and connect them. With ``meshcat``
    the scene, lanes, queues and paths are drawn there; with ``out_dir`` the recorder
    streams the timeline to files as the run goes."""
    ctx = BuildContext.for_scenario(scenario)
    scenario, floor_plan = ctx.scenario, ctx.floor_plan
    names = ctx.robot_names

    humans = None
    has_humans = bool(scenario.humans.walkers or scenario.humans.groups)
    if has_humans:
        humans_type, humans_params = resolve_block(scenario, "humans")
        humans = builder.AddNamedSystem("humans", humans_type.make(ctx, humans_params))
    human_bodies = ([Body(n, r, tuple(p)) for n, r, p in zip(
        humans.human_names, humans.human_radii, _start_poses(humans), strict=True)]
        if humans else [])
    robots_type, robots_params = resolve_block(scenario, "robots")
    world = build_world(builder, floor_plan,
                        robots=[Body(r.name, r.radius, tuple(pose)) for r, pose in zip(
                            scenario.robots, ctx.robot_starts, strict=True)],
                        humans=human_bodies,
                        physics=robots_type.physics(robots_params) if robots_type.physics
                        else None)
    ctx = dataclasses.replace(ctx, world=world)

    def make(slot: str, *extra):
        block_type, params = resolve_block(scenario, slot)
        return block_type.make(ctx, params, *extra)

    robots = builder.AddNamedSystem("robots", make("robots"))
    controller = builder.AddNamedSystem("controller", make("controller"))
    planner = builder.AddNamedSystem("planner", make("planner"))
    queues = builder.AddNamedSystem("room_queues", make("queues"))
    allocator = builder.AddNamedSystem("allocator", make("allocator"))
    if resolve_block(scenario, "waypoints")[0].per_robot:
        generators = [builder.AddNamedSystem(f"waypoints_{name}", make("waypoints", i))
                      for i, name in enumerate(names)]
    else:
        generators = [builder.AddNamedSystem("waypoints", make("waypoints"))]

    def waypoints(port: str) -> list[OutputPort]:
        """Each robot's waypoints output ``port``, in robot order."""
        return [_waypoint_output(generators, name, k, port) for k, name in enumerate(names)]

    def per_robot(port: str, reader: LeafSystem, prefix: str, fleet: str) -> None:
        """Each robot's waypoints output ``port`` to ``reader``'s ``<prefix>_<robot>``, or
        the waypoints block's ``fleet_<fleet>`` to the reader's when both have it
        (``stack.fleet_inputs``)."""
        name = f"fleet_{fleet}"
        if (len(generators) == 1 and generators[0].HasOutputPort(name)
                and reader.HasInputPort(name)):
            builder.Connect(generators[0].GetOutputPort(name), reader.GetInputPort(name))
            return
        for robot, output in zip(names, waypoints(port), strict=True):
            builder.Connect(output, reader.GetInputPort(f"{prefix}_{robot}"))

    state = robots.GetOutputPort("state")
    builder.Connect(controller.GetOutputPort("commands"), robots.GetInputPort("commands"))
    builder.Connect(state, controller.GetInputPort("robot_state"))
    builder.Connect(planner.GetOutputPort("paths"), controller.GetInputPort("paths"))
    builder.Connect(state, planner.GetInputPort("robot_state"))
    for generator in generators:
        builder.Connect(allocator.GetOutputPort("plan"), generator.GetInputPort("plan"))
        builder.Connect(state, generator.GetInputPort("robot_state"))
        builder.Connect(queues.GetOutputPort("queue_state"),
                        generator.GetInputPort("queue_state"))
    per_robot("target", planner, "target", "targets")
    per_robot("queue_request", queues, "request", "queue_requests")
    per_robot("progress", allocator, "progress", "progress")
    lifts = (_add_lifts(builder, ctx, make, robots, planner, generators,
                        waypoints("lift_request")) if ctx.lifts else None)
    if humans is not None:
        builder.Connect(state, humans.GetInputPort("robot_state"))
        builder.Connect(humans.GetOutputPort("human_states"),
                        controller.GetInputPort("human_states"))
    watchdog = _add_watchdog(builder, scenario, make, state, planner, humans)
    if watchdog is not None:
        per_robot("target", watchdog, "target", "targets")
    if watchdog is not None and watchdog.HasInputPort("queue_state"):
        # Who waits for whom (gridlocks of waits); the waypoints drop a giving-way robot's
        # claims.
        builder.Connect(queues.GetOutputPort("queue_state"), watchdog.GetInputPort("queue_state"))
        per_robot("queue_request", watchdog, "queue_request", "queue_requests")
        if lifts is not None:
            builder.Connect(lifts.GetOutputPort("lift_state"), watchdog.GetInputPort("lift_state"))
        for generator in generators:
            builder.Connect(watchdog.GetOutputPort("back_offs"),
                            generator.GetInputPort("back_offs"))
    human_positions = humans.GetOutputPort("plant_positions") if humans is not None else None
    contacts = None
    if robots_type.physics is None:
        add_plant_posing(builder, world, robots.GetOutputPort("plant_positions"), human_positions)
    else:
        contacts = add_plant_stepping(builder, world, robots, human_positions)

    recorder = builder.AddNamedSystem("recorder", RunRecorder(
        names, human_bodies, rate_hz=scenario.rates.logging, out_dir=out_dir))
    builder.Connect(state, recorder.GetInputPort("robot_state"))
    builder.Connect(controller.GetOutputPort("telemetry"), recorder.GetInputPort("telemetry"))
    builder.Connect(planner.GetOutputPort("paths"), recorder.GetInputPort("paths"))
    builder.Connect(queues.GetOutputPort("queue_state"), recorder.GetInputPort("queue_state"))
    builder.Connect(allocator.GetOutputPort("plan"), recorder.GetInputPort("plan"))
    per_robot("progress", recorder, "progress", "progress")
    per_robot("target", recorder, "target", "targets")
    per_robot("queue_request", recorder, "queue_request", "queue_requests")
    if allocator.HasOutputPort("events"):
        builder.Connect(allocator.GetOutputPort("events"),
                        recorder.GetInputPort("allocator_events"))
    if humans is not None:
        builder.Connect(humans.GetOutputPort("human_states"),
                        recorder.GetInputPort("human_states"))
        if humans.HasOutputPort("active"):
            builder.Connect(humans.GetOutputPort("active"), recorder.GetInputPort("human_active"))

    network = None if scenario.communication.ideal else _add_network(
        builder, make, state, controller, recorder)
    if lifts is not None:
        builder.Connect(lifts.GetOutputPort("lift_state"), recorder.GetInputPort("lift_state"))
        builder.Connect(lifts.GetOutputPort("events"), recorder.GetInputPort("lift_events"))
    if watchdog is not None:
        builder.Connect(watchdog.GetOutputPort("back_offs"), recorder.GetInputPort("back_offs"))

    visualizer = None
    if meshcat is not None:
        view = None
        if lifts is not None and scenario.world.levels_view == "stacked":
            view = _add_levels_view(builder, ctx, meshcat, state, humans, lifts).view
        else:
            _look_at_floor_plan(meshcat, floor_plan.bounds)
            visualizer = MeshcatVisualizer.AddToBuilder(
                builder, world.scene_graph, meshcat,
                MeshcatVisualizerParams(publish_period=1.0 / scenario.rates.meshcat,
                                        role=Role.kIllustration, prefix="hospital"))
        overlay = builder.AddNamedSystem("meshcat_overlay", MeshcatOverlay(
            meshcat, scenario, rate_hz=scenario.rates.meshcat,
            view=None if view is None else view.points))
        builder.Connect(planner.GetOutputPort("paths"), overlay.GetInputPort("paths"))
        builder.Connect(queues.GetOutputPort("queue_state"), overlay.GetInputPort("queue_state"))

    schedule = None
    if has_disturbances(scenario.disturbances):
        schedule = builder.AddNamedSystem("disturbances", DisturbanceSchedule(
            names, blockages(scenario), breakdowns(scenario), outage_windows(scenario)))
        builder.Connect(state, schedule.GetInputPort("robot_state"))
        readers = [controller, planner, allocator, *generators, recorder]
        if watchdog is not None:
            readers.append(watchdog)
        if meshcat is not None:
            readers.append(overlay)
        for reader in readers:  # a swapped-in block without the input ignores disturbances
            if reader.HasInputPort("disturbances"):
                builder.Connect(schedule.GetOutputPort("disturbances"),
                                reader.GetInputPort("disturbances"))
    return Stack(scenario, world, robots, controller, planner, queues, allocator, generators,
                 humans, recorder, visualizer, contacts=contacts, disturbances=schedule,
                 lifts=lifts, watchdog=watchdog, network=network)


def _add_network(builder: DiagramBuilder, make, state, controller: LeafSystem,
                 recorder: RunRecorder) -> LeafSystem:
    """The network between the robots and the controller (and back to it): the robots'
    broadcasts and the leaders' commands reach the controller through it. A controller
    without the ``network`` input (``go_to_goal``) ignores it."""
    network = builder.AddNamedSystem("network", make(NETWORK))
    builder.Connect(state, network.GetInputPort("robot_state"))
    builder.Connect(network.GetOutputPort("views"), recorder.GetInputPort("network"))
    if controller.HasInputPort("network"):
        builder.Connect(network.GetOutputPort("views"), controller.GetInputPort("network"))
        builder.Connect(controller.GetOutputPort("leader_commands"),
                        network.GetInputPort("leader_commands"))
    return network


def _add_lifts(builder: DiagramBuilder, ctx: BuildContext, make, robots: LeafSystem,
               planner: LeafSystem, generators: list[LeafSystem],
               requests: list[OutputPort]) -> LeafSystem:
    """The lift bank, between the waypoints block (its systems ``generators``, each
    robot's ``lift_request`` output in ``requests``) and the robots block; its relocations
    also go to the planner (a swapped-in planner without that input ignores them)."""
    if not robots.HasInputPort("relocations"):
        raise InputError(ctx.scenario.source, "blocks.robots.kind",
                         f"{ctx.scenario.blocks.robots.kind!r} robots cannot ride lifts "
                         "(no relocations input): use kind kinematic or physics for a "
                         "building run across levels")
    bank = builder.AddNamedSystem("lift_bank", make("lifts"))
    builder.Connect(robots.GetOutputPort("state"), bank.GetInputPort("robot_state"))
    builder.Connect(bank.GetOutputPort("relocations"), robots.GetInputPort("relocations"))
    if planner.HasInputPort("relocations"):
        builder.Connect(bank.GetOutputPort("relocations"), planner.GetInputPort("relocations"))
    for name, request in zip(ctx.robot_names, requests, strict=True):
        builder.Connect(request, bank.GetInputPort(f"request_{name}"))
    for generator in generators:
        builder.Connect(bank.GetOutputPort("lift_state"), generator.GetInputPort("lift_state"))
    return bank


def _add_levels_view(builder: DiagramBuilder, ctx: BuildContext, meshcat: Meshcat, state,
                     humans: LeafSystem | None, lifts: LeafSystem) -> LevelsView:
    """The stacked levels' drawing (``world.levels_view: stacked``), camera on it."""
    from mrta_drake.world.rmf_scenario import imported_levels

    world = ctx.scenario.world
    layout = imported_levels(world.floor_plan, world.graph).layout
    people = ()
    if humans is not None:
        states = humans.GetOutputPort("human_states").Eval(humans.CreateDefaultContext())
        people = tuple(zip(states.names, map(float, states.radii), strict=True))
    view = builder.AddNamedSystem("levels_view", LevelsView(
        meshcat, ctx.floor_plan, layout, ctx.lifts,
        [(r.name, r.radius) for r in ctx.scenario.robots], people,
        rate_hz=ctx.scenario.rates.meshcat))
    builder.Connect(state, view.GetInputPort("robot_state"))
    builder.Connect(lifts.GetOutputPort("lift_state"), view.GetInputPort("lift_state"))
    if humans is not None:
        builder.Connect(humans.GetOutputPort("human_states"), view.GetInputPort("human_states"))
    x0 = min(p.bounds[0] - p.offset for p in layout.levels)
    x1 = max(p.bounds[1] - p.offset for p in layout.levels)
    top = max(p.elevation for p in layout.levels)
    _, _, y0, y1 = layout.bounds
    middle = np.array([0.5 * (x0 + x1), 0.5 * (y0 + y1), 0.5 * top])
    extent = max(x1 - x0, y1 - y0, top)
    meshcat.SetCameraPose(middle + [0.3 * extent, -0.8 * extent, 0.45 * extent], middle)
    return view


def _add_watchdog(builder: DiagramBuilder, scenario: Scenario, make, state,
                  planner: LeafSystem, humans: LeafSystem | None) -> LeafSystem | None:
    """The deadlock watchdog, before the planner (None when the scenario turns it off); the
    caller connects the waypoints block's targets to it."""
    _, params = resolve_block(scenario, "watchdog")
    if not getattr(params, "enabled", True):
        return None
    watchdog = builder.AddNamedSystem("watchdog", make("watchdog"))
    builder.Connect(state, watchdog.GetInputPort("robot_state"))
    if humans is not None and watchdog.HasInputPort("human_states"):
        builder.Connect(humans.GetOutputPort("human_states"),
                        watchdog.GetInputPort("human_states"))
    if planner.HasInputPort("back_offs"):  # a swapped-in planner without it ignores them
        builder.Connect(watchdog.GetOutputPort("back_offs"), planner.GetInputPort("back_offs"))
    return watchdog


def _look_at_floor_plan(meshcat: Meshcat, bounds) -> None:
    """Puts the camera south of and above the floor plan's middle, looking north and down
    at it, far enough back to see all of it."""
    x_min, x_max, y_min, y_max = bounds
    middle = np.array([0.5 * (x_min + x_max), 0.5 * (y_min + y_max), 0.0])
    extent = max(x_max - x_min, y_max - y_min)
    meshcat.SetCameraPose(middle + [0.0, -0.3 * extent, 0.75 * extent], middle)


def _start_poses(system) -> np.ndarray:
    """(K, 3) [x, y, theta] rows of ``system``'s ``plant_positions`` in a default context."""
    context = system.CreateDefaultContext()
    return system.GetOutputPort("plant_positions").Eval(context).reshape(-1, 3)


def build_diagram(scenario: Scenario, *, meshcat: Meshcat | None = None,
                  out_dir: str | None = None) -> Stack:
    """The scenario's complete diagram (``stack.diagram``), with handles to its blocks."""
    builder = DiagramBuilder()
    stack = add_stack(builder, scenario, meshcat=meshcat, out_dir=out_dir)
    stack.diagram = builder.Build()
    stack.diagram.set_name("mrta_drake")
    return stack
