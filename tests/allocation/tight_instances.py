"""Seeded problems with tight deadlines, for tests: several tasks per robot and deadlines short
enough that some must be late."""

import numpy as np

from mrta_drake.allocation import AllocationProblem, RobotStart, Task


def tight_problem(seed: int, num_tasks: int, num_robots: int, same_start: bool = False,
                  latest: int = 160, capacity: int = 2) -> AllocationProblem:
    """``num_tasks`` tasks on ``num_robots`` robots of ``capacity`` over 12 random points on a
    40 x 40 s Manhattan grid (travel in whole seconds); deadlines uniform in [40, ``latest``]
    s. With ``same_start`` every robot starts at location 0."""
    rng = np.random.default_rng(seed)
    points = rng.integers(0, 40, size=(12, 2))
    travel = np.abs(points[:, None, :] - points[None, :, :]).sum(axis=-1)
    tasks = []
    for i in range(num_tasks):
        pickup, dropoff = (int(x) for x in rng.choice(12, 2, replace=False))
        tasks.append(Task(i, pickup, dropoff, float(rng.integers(40, latest + 1))))
    robots = tuple(RobotStart(f"r{r}", 0 if same_start else int(rng.integers(12)), 0.0, capacity)
                   for r in range(num_robots))
    return AllocationProblem(travel, robots, tuple(tasks))
