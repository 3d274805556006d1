"""The "no allocator" block: every robot visits its configured route, once, in order."""

from collections.abc import Sequence

from pydrake.common.value import Value
from pydrake.systems.framework import LeafSystem

from mrta_drake.payloads import VISIT, FleetPlan, RobotPlan, RobotProgress, Stop


class FixedSequenceAllocator(LeafSystem):
    """Outputs a constant ``FleetPlan``: robot ``robot_names[r]`` visits the locations of
    ``routes[r]`` (location ids) in order, stop ``k`` keyed ``"<robot>/visit<k>"`` (action
    ``visit``, no task).

    .. pydrake_system::

        name: FixedSequenceAllocator
        input_ports:
        - progress_<robot> (optional)
        output_ports:
        - plan

    It has the ports of the task allocator so that either can be used: inputs
    ``progress_<robot>`` (abstract ``RobotProgress``, one per robot, not read) and output
    ``plan`` (abstract ``FleetPlan``, revision 0).
    """

    def __init__(self, robot_names: Sequence[str], routes: Sequence[Sequence[int]]):
        super().__init__()
        self._fleet_plan = FleetPlan(
            tuple(
                RobotPlan(
                    name,
                    tuple(
                        Stop(f"{name}/visit{k}", location, VISIT)
                        for k, location in enumerate(route)
                    ),
                )
                for name, route in zip(robot_names, routes, strict=True)
            )
        )
        for name in robot_names:
            self.DeclareAbstractInputPort(f"progress_{name}", Value[object](RobotProgress(name)))
        self.DeclareAbstractOutputPort(
            "plan",
            lambda: Value[object](self._fleet_plan),
            self._calc_plan,
            prerequisites_of_calc={self.nothing_ticket()},
        )

    def _calc_plan(self, context, output):
        output.set_value(self._fleet_plan)
