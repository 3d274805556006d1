"""The building, robots and people in a ``MultibodyPlant`` + ``SceneGraph``.

The floor plan's ``Obstacles`` become welded collision and visual geometry. Each robot and
each human is a body on a ``PlanarJoint`` (x, y, yaw) to the world, robots first, in scenario
order, so the plant's generalized positions are the robots' ``plant_positions`` followed by
the humans'. The kinematic blocks do not step the plant: a
``MultibodyPositionToGeometryPose`` poses its geometry for queries and Meshcat. A physics
robots block (``PlantPhysics``) has the plant made discrete and added to the diagram, where
it is stepped; see ``mrta_drake.robots.plant_stepping``.
"""

import dataclasses
from dataclasses import dataclass

import numpy as np
from pydrake.geometry import Box as BoxShape
from pydrake.geometry import CollisionFilterDeclaration, SceneGraph
from pydrake.geometry import Cylinder as CylinderShape
from pydrake.geometry import Sphere as SphereShape
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.plant import (
    AddMultibodyPlant,
    CoulombFriction,
    MultibodyPlant,
    MultibodyPlantConfig,
)
from pydrake.multibody.tree import ModelInstanceIndex, PlanarJoint, SpatialInertia
from pydrake.systems.primitives import Multiplexer
from pydrake.systems.rendering import MultibodyPositionToGeometryPose

from mrta_drake.errors import InputError
from mrta_drake.scenario.schema import Scenario
from mrta_drake.world.floor_plan import FloorPlan, load_floor_plan
from mrta_drake.world.ros_map import load_ros_map

WALL_COLOR = np.array([0.82, 0.82, 0.80, 1.0])
FURNITURE_COLOR = np.array([0.55, 0.42, 0.30, 1.0])
HUMAN_COLOR = np.array([0.95, 0.65, 0.25, 1.0])
ROBOT_HEIGHT = 0.2  # m
HUMAN_HEIGHT = 1.7  # m
ROBOT_MASS = 20.0  # kg, of a robot in a plant that is not stepped
HUMAN_MASS = 70.0  # kg
# Distinct robot colours (Tableau 10), cycled.
ROBOT_COLORS = np.array([
    [0.12, 0.47, 0.71], [0.84, 0.15, 0.16], [0.17, 0.63, 0.17], [0.58, 0.40, 0.74],
    [0.55, 0.34, 0.29], [0.89, 0.47, 0.76], [0.50, 0.50, 0.50], [0.74, 0.74, 0.13],
    [0.09, 0.75, 0.81], [1.00, 0.50, 0.05],
])


@dataclass(frozen=True)
class Body:
    """A moving body in the plant: a robot or a human, a cylinder of ``radius`` m, starting
    at ``pose`` [x, y, theta] (world frame, m, rad; its planar joint's default position)."""

    name: str
    radius: float
    pose: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class PlantPhysics:
    """How ``build_world`` makes a plant that is stepped: discrete, ``time_step`` s, SAP
    contact solver, point contact; robots of ``robot_mass`` kg (a solid cylinder's inertia)
    colliding as a ``robot_shape`` ("sphere" of their radius at half their height, or
    "cylinder", their full body).

    The plant's output ports are not sampled: it steps in a discrete update, at the same
    instant as the blocks' discrete updates (the controller's, the people's), so every
    block that ticks at an instant reads the plant's state at that instant; its ``state``
    output is its state, and its contact results are those of the step it takes next from
    there (the ``ContactRecorder`` reads them after each step). A sampled plant steps in
    an unrestricted update, before the instant's discrete updates (which then read the
    state after its step), and that marks the whole diagram's state changed and copies it
    at every step: 15-20 % of a 6-robot stack's CPU time (docs/benchmarks.md)."""

    time_step: float
    robot_mass: float
    robot_shape: str = "sphere"


@dataclass(frozen=True, eq=False)
class World:
    """What ``build_world`` made: the plant and scene graph (already in the builder), the
    floor plan they came from, and the model instances of the robots and humans."""

    plant: MultibodyPlant
    scene_graph: SceneGraph
    floor_plan: FloorPlan
    robots: tuple[ModelInstanceIndex, ...]
    humans: tuple[ModelInstanceIndex, ...]

    @property
    def obstacles(self):
        return self.floor_plan.obstacles


def load_floor_plan_of(scenario: Scenario, *, objects: bool = True) -> FloorPlan:
    """The scenario's floor plan, from our format, a ROS map or an Open-RMF building; with
    ``objects``, its obstacles include those its Scenic program (``world.scenic``) places
    for its seed."""
    if scenario.world.kind == "ros_map":
        floor_plan = load_ros_map(scenario.world.floor_plan)
    elif scenario.world.kind == "rmf_building":
        from mrta_drake.world.rmf_scenario import building_floor_plan

        floor_plan = building_floor_plan(scenario)
    else:
        floor_plan = load_floor_plan(scenario.world.floor_plan)
    if objects and scenario.world.scenic:
        from mrta_drake.world.scenic_objects import add_scenic_objects

        floor_plan = add_scenic_objects(floor_plan, resolve_locations(scenario, floor_plan))
    return floor_plan


def resolve_locations(scenario: Scenario, floor_plan: FloorPlan) -> Scenario:
    """Fill location points left out of the scenario from the floor plan's named places."""
    locations = []
    for i, location in enumerate(scenario.locations):
        if not location.point:
            if location.name not in floor_plan.places:
                raise InputError(scenario.source, f"locations[{i}].point",
                                 f"missing, and the floor plan has no place named "
                                 f"{location.name!r}")
            location = dataclasses.replace(location,
                                           point=list(floor_plan.places[location.name]))
        locations.append(location)
    return dataclasses.replace(scenario, locations=locations)


def check_robot_starts(scenario: Scenario, floor_plan: FloorPlan) -> None:
    """Every robot must start clear of walls and furniture."""
    if not scenario.robots:
        return
    starts = np.array([r.start[:2] for r in scenario.robots], dtype=float)
    clearance = floor_plan.obstacles.signed_distance(starts)
    x_min, x_max, y_min, y_max = floor_plan.bounds
    for i, (robot, gap) in enumerate(zip(scenario.robots, clearance, strict=True)):
        x, y = robot.start[:2]
        if not (x_min <= x <= x_max and y_min <= y <= y_max):
            raise InputError(scenario.source, f"robots[{i}].start",
                             f"{robot.name} at {[x, y]} is outside the floor plan")
        if gap < robot.radius:
            raise InputError(scenario.source, f"robots[{i}].start",
                             f"{robot.name} at {[x, y]} is inside a wall or furniture "
                             f"(clearance {gap:.2f} m < radius {robot.radius} m)")


def build_world(builder, floor_plan: FloorPlan, robots=(), humans=(),
                physics: PlantPhysics | None = None) -> World:
    """Add a scene graph to ``builder`` and make a plant registered with it: the floor
    plan's obstacles as welded geometry, then one planar body per robot and per human
    (``Body`` lists). People collide with robots only, not with the building or each
    other. Without ``physics`` the plant is finalized but not added to the diagram: the
    kinematic blocks never step it, and ``add_plant_posing`` poses its geometry from their
    outputs. With ``physics`` it is a discrete plant in the diagram, connected to the scene
    graph (``mrta_drake.robots.plant_stepping.add_plant_stepping`` closes the loop)."""
    if physics is None:
        scene_graph = builder.AddNamedSystem("scene_graph", SceneGraph())
        plant = MultibodyPlant(0.0)
        plant.set_name("plant")
        plant.RegisterAsSourceForSceneGraph(scene_graph)
    else:
        plant, scene_graph = AddMultibodyPlant(MultibodyPlantConfig(
            time_step=physics.time_step, contact_model="point",
            discrete_contact_approximation="sap", use_sampled_output_ports=False), builder)
    _add_obstacles(plant, floor_plan)
    robot_mass = ROBOT_MASS if physics is None else physics.robot_mass
    robot_shape = "cylinder" if physics is None else physics.robot_shape
    robot_models = tuple(
        _add_body(plant, body, ROBOT_HEIGHT, np.append(ROBOT_COLORS[k % len(ROBOT_COLORS)], 1),
                  heading_marker=True, mass=robot_mass, shape=robot_shape)
        for k, body in enumerate(robots))
    human_models = tuple(
        _add_body(plant, body, HUMAN_HEIGHT, HUMAN_COLOR, heading_marker=False,
                  mass=HUMAN_MASS, shape="cylinder")
        for body in humans)
    plant.Finalize()
    if human_models:
        passive = [plant.world_body()] + [plant.GetBodyByName("base", m) for m in human_models]
        scene_graph.collision_filter_manager().Apply(
            CollisionFilterDeclaration().ExcludeWithin(plant.CollectRegisteredGeometries(
                passive)))
    return World(plant, scene_graph, floor_plan, robot_models, human_models)


def _add_obstacles(plant: MultibodyPlant, floor_plan: FloorPlan) -> None:
    world = plant.world_body()
    friction = CoulombFriction(0.5, 0.5)
    tall = floor_plan.wall_height - 1e-6
    for k, box in enumerate(floor_plan.obstacles.boxes):
        pose = RigidTransform(RotationMatrix.MakeZRotation(box.yaw),
                              [box.center[0], box.center[1], 0.5 * box.height])
        shape = BoxShape(box.size[0], box.size[1], box.height)
        color = WALL_COLOR if box.height >= tall else FURNITURE_COLOR
        name = f"{box.name}_{k}"
        plant.RegisterCollisionGeometry(world, pose, shape, name, friction)
        plant.RegisterVisualGeometry(world, pose, shape, name, color)
    for k, cyl in enumerate(floor_plan.obstacles.cylinders):
        pose = RigidTransform([cyl.center[0], cyl.center[1], 0.5 * cyl.height])
        shape = CylinderShape(cyl.radius, cyl.height)
        name = f"{cyl.name}_{k}"
        plant.RegisterCollisionGeometry(world, pose, shape, name, friction)
        plant.RegisterVisualGeometry(world, pose, shape, name, FURNITURE_COLOR)


def _add_body(plant: MultibodyPlant, body: Body, height: float, color,
              heading_marker: bool, mass: float, shape: str) -> ModelInstanceIndex:
    model = plant.AddModelInstance(body.name)
    inertia = SpatialInertia.SolidCylinderWithMass(mass, body.radius, height, [0, 0, 1])
    link = plant.AddRigidBody("base", model, inertia)
    joint = plant.AddJoint(PlanarJoint(f"{body.name}_planar", plant.world_frame(),
                                       link.body_frame(), [0.0, 0.0, 0.0]))
    joint.set_default_pose(body.pose[:2], body.pose[2])
    cylinder = CylinderShape(body.radius, height)
    pose = RigidTransform([0, 0, 0.5 * height])
    collision = SphereShape(body.radius) if shape == "sphere" else cylinder
    plant.RegisterCollisionGeometry(link, pose, collision, "body", CoulombFriction(0.5, 0.5))
    plant.RegisterVisualGeometry(link, pose, cylinder, "body", color)
    if heading_marker:
        # A bright wedge on top, pointing along the body's +x (its heading).
        marker = BoxShape(body.radius, 0.25 * body.radius, 0.02)
        plant.RegisterVisualGeometry(
            link, RigidTransform([0.5 * body.radius, 0, height + 0.01]), marker, "heading",
            [1.0, 1.0, 1.0, 1.0])
    return model



def add_plant_posing(builder, world: World, robot_positions, human_positions=None) -> None:
    """Pose the plant's geometry in the scene graph from the robots' (and humans')
    ``plant_positions`` output ports (3 per body, robots first)."""
    to_pose = builder.AddNamedSystem("plant_posing", MultibodyPositionToGeometryPose(
        world.plant))
    builder.Connect(to_pose.get_output_port(),
                    world.scene_graph.get_source_pose_port(world.plant.get_source_id()))
    if human_positions is None:
        builder.Connect(robot_positions, to_pose.get_input_port())
        return
    mux = builder.AddNamedSystem("plant_positions", Multiplexer(
        [3 * len(world.robots), 3 * len(world.humans)]))
    builder.Connect(robot_positions, mux.get_input_port(0))
    builder.Connect(human_positions, mux.get_input_port(1))
    builder.Connect(mux.get_output_port(), to_pose.get_input_port())
