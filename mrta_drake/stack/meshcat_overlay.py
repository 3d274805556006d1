"""Drawing the traffic layer in Meshcat: lanes, queue slots, locations, planned paths."""

import numpy as np
from pydrake.common.value import Value
from pydrake.geometry import Box, Cylinder, Meshcat, Rgba
from pydrake.math import RigidTransform
from pydrake.systems.framework import LeafSystem

from mrta_drake.payloads import PATH_OK, Disturbances, FleetPaths, QueueState
from mrta_drake.scenario.schema import Scenario
from mrta_drake.world.plant import ROBOT_COLORS

LANE_COLOR = Rgba(0.2, 0.45, 0.9, 1.0)
SLOT_COLOR = Rgba(0.3, 0.8, 0.4, 0.5)
HELD_COLOR = Rgba(0.9, 0.3, 0.2, 0.7)
LOCATION_COLOR = Rgba(0.95, 0.8, 0.1, 0.8)
BLOCKAGE_COLOR = Rgba(0.9, 0.1, 0.1, 0.35)
BLOCKAGE_HEIGHT = 1.0  # m
Z = 0.02  # m above the floor, so lines are not hidden by it


class MeshcatOverlay(LeafSystem):
    """Draws the scenario's roadway lanes (with arrowheads), rooms' queue slots and service
    points once, then each robot's planned path and which rooms are held, at ``rate_hz``
    (publish events only).

    .. pydrake_system::

        name: MeshcatOverlay
        input_ports:
        - paths
        - queue_state
        - disturbances (optional)

    Inputs: ``paths`` (FleetPaths), ``queue_state`` (QueueState), ``disturbances``
    (Disturbances): each of the scenario's blockages is a red translucent box, shown only
    while it is in force. ``view``, if given, maps the (3, K) points drawn (world frame, m)
    to where they are shown (the stacked levels' ``StackedView.points``)."""

    def __init__(self, meshcat: Meshcat, scenario: Scenario, *, rate_hz: float,
                 prefix: str = "traffic", view=None):
        super().__init__()
        self._meshcat = meshcat
        self._at = view or (lambda xyz: np.asarray(xyz, float))
        self._prefix = prefix
        self._robots = [r.name for r in scenario.robots]
        self._blockages = [b.name for b in scenario.disturbances.blockages]
        self.DeclareAbstractInputPort("paths", Value[object](FleetPaths(())))
        self.DeclareAbstractInputPort("queue_state", Value[object](QueueState()))
        self._disturbances = self.DeclareAbstractInputPort("disturbances",
                                                           Value[object](Disturbances()))
        self.DeclarePeriodicPublishEvent(1.0 / rate_hz, 0.0, self._draw)
        self._draw_static(scenario)

    def _draw_static(self, scenario: Scenario) -> None:
        nodes = scenario.roadways.nodes
        if scenario.roadways.edges:
            starts, ends = [], []
            for a, b in scenario.roadways.edges:
                p, q = np.array(nodes[a], float), np.array(nodes[b], float)
                starts.append(p)
                ends.append(q)
                # Arrowhead: two short strokes back from the edge's midpoint.
                d = q - p
                length = np.linalg.norm(d)
                if length > 1e-9:
                    d /= length
                    tip = 0.5 * (p + q)
                    side = np.array([-d[1], d[0]])
                    for s in (1.0, -1.0):
                        starts.append(tip)
                        ends.append(tip - 0.35 * d + s * 0.2 * side)
            start = self._at(np.array([[x, y, Z] for x, y in starts]).T)
            end = self._at(np.array([[x, y, Z] for x, y in ends]).T)
            self._meshcat.SetLineSegments(f"{self._prefix}/lanes", start, end, 2.0, LANE_COLOR)
        for location in scenario.locations:
            if location.point:
                path = f"{self._prefix}/locations/{location.id}"
                self._meshcat.SetObject(path, Cylinder(0.3, 0.01), LOCATION_COLOR)
                self._meshcat.SetTransform(path, self._pose(*location.point, Z))
            for k, slot in enumerate(location.queue):
                path = f"{self._prefix}/queues/{location.id}/{k}"
                self._meshcat.SetObject(path, Cylinder(0.2, 0.01), SLOT_COLOR)
                self._meshcat.SetTransform(path, self._pose(*slot, Z))
        for blockage in scenario.disturbances.blockages:
            x_min, x_max, y_min, y_max = blockage.box
            path = f"{self._prefix}/blockages/{blockage.name}"
            self._meshcat.SetObject(path, Box(x_max - x_min, y_max - y_min, BLOCKAGE_HEIGHT),
                                    BLOCKAGE_COLOR)
            self._meshcat.SetTransform(path, self._pose(
                0.5 * (x_min + x_max), 0.5 * (y_min + y_max), 0.5 * BLOCKAGE_HEIGHT))
            self._meshcat.SetProperty(path, "visible", False)

    def _pose(self, x: float, y: float, z: float) -> RigidTransform:
        return RigidTransform(self._at(np.array([[x], [y], [z]]))[:, 0])

    def _draw(self, context) -> None:
        paths: FleetPaths = self.get_input_port(0).Eval(context)
        for k, path in enumerate(paths.paths):
            name = f"{self._prefix}/paths/{path.robot}"
            if path.status == PATH_OK and len(path.points) >= 2:
                vertices = self._at(np.column_stack([path.points,
                                                     np.full(len(path.points), Z)]).T)
                r, g, b = ROBOT_COLORS[k % len(ROBOT_COLORS)]
                self._meshcat.SetLine(name, np.asfortranarray(vertices), 3.0, Rgba(r, g, b, 1))
                self._meshcat.SetProperty(name, "visible", True)
            else:
                self._meshcat.SetProperty(name, "visible", False)
        queues: QueueState = self.get_input_port(1).Eval(context)
        for queue in queues.rooms:
            self._meshcat.SetProperty(f"{self._prefix}/locations/{queue.room}", "color",
                                      _rgba_list(HELD_COLOR if queue.holder else LOCATION_COLOR))
        if self._blockages:
            closed = ({b.name for b in self._disturbances.Eval(context).blockages}
                      if self._disturbances.HasValue(context) else set())
            for name in self._blockages:
                self._meshcat.SetProperty(f"{self._prefix}/blockages/{name}", "visible",
                                          name in closed)


def _rgba_list(rgba: Rgba) -> list[float]:
    return [rgba.r(), rgba.g(), rgba.b(), rgba.a()]
