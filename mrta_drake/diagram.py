"""Wiring a scenario's blocks into one Drake diagram.

``add_stack`` adds every block of a scenario to a ``DiagramBuilder`` as a named subsystem
and connects the fixed ports (see ``blocks.py``); ``build_diagram`` does that and builds.
Users who want to add their own systems call ``add_stack`` on their own builder, connect
what they like to the returned handles, then build.
"""

from dataclasses import dataclass, field

from pydrake.geometry import Meshcat, MeshcatVisualizer, MeshcatVisualizerParams, Role
from pydrake.systems.framework import Diagram, DiagramBuilder, LeafSystem

from mrta_drake.blocks import BuildContext, resolve_block
from mrta_drake.scenario_schema import Scenario
from mrta_drake.systems.meshcat_overlay import MeshcatOverlay
from mrta_drake.systems.run_recorder import RunRecorder
from mrta_drake.world import (
    Body,
    World,
    add_plant_posing,
    build_world,
    load_floor_plan_of,
    resolve_locations,
)


@dataclass(eq=False)
class Stack:
    """Handles to the systems of one scenario's diagram (``diagram`` once built)."""

    scenario: Scenario
    world: World
    robots: LeafSystem
    controller: LeafSystem
    planner: LeafSystem
    queues: LeafSystem
    allocator: LeafSystem
    waypoint_generators: list[LeafSystem]
    humans: LeafSystem | None
    recorder: RunRecorder
    visualizer: MeshcatVisualizer | None = None
    diagram: Diagram | None = None
    extras: dict = field(default_factory=dict)


def add_stack(builder: DiagramBuilder, scenario: Scenario, *, meshcat: Meshcat | None = None,
              out_dir: str | None = None) -> Stack:
    """Add the scenario's world and blocks to ``builder`` and connect them. With ``meshcat``
    the scene, lanes, queues and paths are drawn there; with ``out_dir`` the recorder
    streams the timeline to files as the run goes."""
    floor_plan = load_floor_plan_of(scenario)
    scenario = resolve_locations(scenario, floor_plan)
    ctx = BuildContext(scenario, floor_plan, scenario.rates)
    names = ctx.robot_names

    humans = None
    has_humans = bool(scenario.humans.walkers or scenario.humans.groups)
    if has_humans:
        humans_type, humans_params = resolve_block(scenario, "humans")
        humans = builder.AddNamedSystem("humans", humans_type.make(ctx, humans_params))
    human_bodies = ([Body(n, r) for n, r in zip(humans.human_names, humans.human_radii,
                                                 strict=True)] if humans else [])
    world = build_world(builder, floor_plan,
                        robots=[Body(r.name, r.radius) for r in scenario.robots],
                        humans=human_bodies)

    def make(slot: str, *extra):
        block_type, params = resolve_block(scenario, slot)
        return block_type.make(ctx, params, *extra)

    robots = builder.AddNamedSystem("robots", make("robots"))
    controller = builder.AddNamedSystem("controller", make("controller"))
    planner = builder.AddNamedSystem("planner", make("planner"))
    queues = builder.AddNamedSystem("room_queues", make("queues"))
    allocator = builder.AddNamedSystem("allocator", make("allocator"))
    generators = [builder.AddNamedSystem(f"waypoints_{name}", make("waypoints", i))
                  for i, name in enumerate(names)]

    state = robots.GetOutputPort("state")
    builder.Connect(controller.GetOutputPort("commands"), robots.GetInputPort("commands"))
    builder.Connect(state, controller.GetInputPort("robot_state"))
    builder.Connect(planner.GetOutputPort("paths"), controller.GetInputPort("paths"))
    builder.Connect(state, planner.GetInputPort("robot_state"))
    for name, generator in zip(names, generators, strict=True):
        builder.Connect(allocator.GetOutputPort("plan"), generator.GetInputPort("plan"))
        builder.Connect(state, generator.GetInputPort("robot_state"))
        builder.Connect(queues.GetOutputPort("queue_state"),
                        generator.GetInputPort("queue_state"))
        builder.Connect(generator.GetOutputPort("target"),
                        planner.GetInputPort(f"target_{name}"))
        builder.Connect(generator.GetOutputPort("queue_request"),
                        queues.GetInputPort(f"request_{name}"))
        builder.Connect(generator.GetOutputPort("progress"),
                        allocator.GetInputPort(f"progress_{name}"))
    if humans is not None:
        builder.Connect(state, humans.GetInputPort("robot_state"))
        builder.Connect(humans.GetOutputPort("human_states"), controller.GetInputPort("humans"))
        add_plant_posing(builder, world, robots.GetOutputPort("plant_positions"),
                         humans.GetOutputPort("plant_positions"))
    else:
        add_plant_posing(builder, world, robots.GetOutputPort("plant_positions"))

    recorder = builder.AddNamedSystem("recorder", RunRecorder(
        names, human_bodies, scenario.rates.logging, out_dir))
    builder.Connect(state, recorder.GetInputPort("robot_state"))
    builder.Connect(controller.GetOutputPort("telemetry"), recorder.GetInputPort("telemetry"))
    builder.Connect(planner.GetOutputPort("paths"), recorder.GetInputPort("paths"))
    builder.Connect(queues.GetOutputPort("queue_state"), recorder.GetInputPort("queue_state"))
    builder.Connect(allocator.GetOutputPort("plan"), recorder.GetInputPort("plan"))
    for name, generator in zip(names, generators, strict=True):
        builder.Connect(generator.GetOutputPort("progress"),
                        recorder.GetInputPort(f"progress_{name}"))
    if humans is not None:
        builder.Connect(humans.GetOutputPort("human_states"),
                        recorder.GetInputPort("human_states"))

    visualizer = None
    if meshcat is not None:
        visualizer = MeshcatVisualizer.AddToBuilder(
            builder, world.scene_graph, meshcat,
            MeshcatVisualizerParams(publish_period=1.0 / scenario.rates.meshcat,
                                    role=Role.kIllustration, prefix="hospital"))
        overlay = builder.AddNamedSystem("meshcat_overlay", MeshcatOverlay(
            meshcat, scenario, publish_rate=scenario.rates.meshcat))
        builder.Connect(planner.GetOutputPort("paths"), overlay.GetInputPort("paths"))
        builder.Connect(queues.GetOutputPort("queue_state"), overlay.GetInputPort("queue_state"))
    return Stack(scenario, world, robots, controller, planner, queues, allocator, generators,
                 humans, recorder, visualizer)


def build_diagram(scenario: Scenario, *, meshcat: Meshcat | None = None,
                  out_dir: str | None = None) -> Stack:
    """The scenario's complete diagram (``stack.diagram``), with handles to its blocks."""
    builder = DiagramBuilder()
    stack = add_stack(builder, scenario, meshcat=meshcat, out_dir=out_dir)
    stack.diagram = builder.Build()
    stack.diagram.set_name("mrta_drake")
    return stack
