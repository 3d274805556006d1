"""Per-robot inputs of a block, read in one go when a fleet port feeds them.

A block that reads one abstract value per robot (a planner's targets, the room queues'
requests, the recorder's progress) declares them with ``PerRobotInputs``: one input
``<prefix>_<robot>`` per robot, as any block may send them, and an optional input
``fleet_<name>``, one tuple of the values in robot order, as the fleet waypoints block
(``FleetWaypoints``) sends them. ``add_stack`` connects the fleet input when the waypoints
block has the fleet output, else the per-robot ones: one port evaluation a read instead of
one per robot.
"""

from collections.abc import Callable, Sequence

from pydrake.common.value import Value
from pydrake.systems.framework import LeafSystem


class PerRobotInputs:
    """Inputs ``<prefix>_<robot>`` for each of ``robot_names`` (model value
    ``example(robot)``) and the optional ``fleet_<fleet>`` (their tuple) on ``system``."""

    def __init__(self, system: LeafSystem, prefix: str, fleet: str,
                 robot_names: Sequence[str], example: Callable[[str], object]):
        self.ports = [system.DeclareAbstractInputPort(f"{prefix}_{robot}",
                                                      Value[object](example(robot)))
                      for robot in robot_names]
        self.fleet = system.DeclareAbstractInputPort(
            f"fleet_{fleet}", Value[object](tuple(example(robot) for robot in robot_names)))

    def values(self, context) -> tuple:
        """Each robot's value, in robot order: the fleet input's if connected."""
        if self.fleet.HasValue(context):
            return self.fleet.Eval(context)
        return tuple(port.Eval(context) for port in self.ports)
