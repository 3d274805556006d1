"""The "no allocator" block: every robot visits its configured route, once, in order."""

from collections.abc import Sequence

from pydrake.common.value import Value
from pydrake.systems.framework import LeafSystem

from mrta_drake.payloads import VISIT, FleetPlan, RobotPlan, RobotProgress, Stop
from mrta_drake.scenario.schema import RobotConfig


class FixedSequenceAllocator(LeafSystem):
    """Outputs a constant ``FleetPlan``: robot ``name`` visits the locations of its
    ``route`` in order, stop ``k`` keyed ``"<name>/visit<k>"`` (action ``visit``, no task).

    It has the ports of the task allocator so that either can be used: inputs
    ``progress_<robot>`` (abstract ``RobotProgress``, one per robot, not read) and output
    ``plan`` (abstract ``FleetPlan``, revision 0).
    """

    def __init__(self, robots: Sequence[RobotConfig]):
        super().__init__()
        self._fleet_plan = FleetPlan(
            tuple(
                RobotPlan(
                    robot.name,
                    tuple(
                        Stop(f"{robot.name}/visit{k}", location, VISIT)
                        for k, location in enumerate(robot.route)
                    ),
                )
                for robot in robots
            )
        )
        for robot in robots:
            self.DeclareAbstractInputPort(
                f"progress_{robot.name}", Value[object](RobotProgress(robot.name))
            )
        self.DeclareAbstractOutputPort(
            "plan",
            lambda: Value[object](self._fleet_plan),
            self._calc_plan,
            prerequisites_of_calc={self.nothing_ticket()},
        )

    def _calc_plan(self, context, output):
        output.set_value(self._fleet_plan)
