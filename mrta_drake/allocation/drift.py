"""When a plan no longer holds: the drop-offs a robot's progress makes late or moves by more
than a margin from the time planned for them."""

from collections.abc import Sequence
from dataclasses import dataclass

from mrta_drake.allocation.problem import AllocationProblem
from mrta_drake.payloads import DROPOFF, RobotPlan

LATE = "late"  # a drop-off planned on time is now predicted after its deadline
DRIFT = "drift"  # a drop-off is now predicted more than the margin from its planned time


@dataclass(frozen=True)
class Drift:
    """Why to allocate again: ``kind`` (``LATE`` or ``DRIFT``), the ``tasks`` concerned and
    the largest change of a predicted drop-off time among them, ``seconds`` (s, positive =
    later)."""

    kind: str
    tasks: tuple[int, ...]
    seconds: float

    @property
    def reason(self) -> str:
        tasks = ", ".join(str(t) for t in self.tasks)
        plural = "s" if len(self.tasks) > 1 else ""
        return f"{self.kind}: task{plural} {tasks} ({self.seconds:+.0f} s)"


def find_drift(problem: AllocationProblem, plans: Sequence[RobotPlan],
               margin: float) -> Drift | None:
    """The drift of the drop-offs still planned, or None when every one stays within
    ``margin`` (s) of its planned time and none planned on time turns late.

    ``problem`` is the problem of a new allocation (robots free after their committed stop,
    each robot's ``planned`` actions the rest of its plan); ``plans[r]`` is problem robot
    ``r``'s current plan, whose stops hold the planned times."""
    late, drifted = {}, {}
    for r, (robot, plan) in enumerate(zip(problem.robots, plans, strict=True)):
        planned_times = {stop.key: stop.planned_time for stop in plan.stops}
        times = problem.completion_times(r, robot.planned)
        for action, time in zip(robot.planned, times, strict=True):
            planned = planned_times.get(action.key)
            if action.kind != DROPOFF or planned is None or not planned == planned:
                continue
            change = time - planned
            deadline = problem.task(action.task).deadline
            if time > deadline >= planned:
                late[action.task] = change
            elif abs(change) > margin:
                drifted[action.task] = change
    found, kind = (late, LATE) if late else (drifted, DRIFT)
    if not found:
        return None
    return Drift(kind, tuple(sorted(found)), max(found.values(), key=abs))
