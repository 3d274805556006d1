"""Allocation benchmark: seeded random instances like the SMrTa paper's.

Single batches: 65 locations, 10-30 tasks x 5-20 robots, all tasks at t = 0, deadlines
uniform in [1.5 x the longest travel time, 1000] s, capacity 2 and 3. Streams: 20 batches
of 10 tasks every 60 s for 20 robots, each batch's deadlines its arrival plus the same
range, executed exactly as planned between batches. Then the hard regime: single batches
with deadlines at most 250 s, and a stream overloaded with a batch every 10 s.

Locations are random points on a floor of the hospital map's size (25 x 56 m); travel
times are the Manhattan distance at 0.7 m/s, rounded up (longest ~110 s).

    python benchmarks/allocation.py            # full run (takes long on 2 cores)
    python benchmarks/allocation.py --quick    # a few small instances

Prints tables and writes benchmarks/results/allocation.json.
"""

import argparse
import json
import math
import pathlib
import platform
import sys
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))

from mrta_drake.allocation import (  # noqa: E402
    FEASIBLE,
    INFEASIBLE,
    Action,
    AllocationProblem,
    GreedyAllocator,
    RobotStart,
    RobotStatus,
    SmtAllocator,
    SmtAllocatorParams,
    Task,
    committed_start,
    verify_allocation,
)
from mrta_drake.allocation.smt_allocator import MAX_BUDGET  # noqa: E402
from mrta_drake.payloads import DROPOFF, PICKUP  # noqa: E402

NUM_LOCATIONS = 65
FLOOR = (25.0, 56.0)  # m
SPEED = 0.7  # m/s
LATEST_DEADLINE = 1000.0  # s after the batch arrival
TIME_LIMIT = 60.0  # s per allocation
RESULTS = pathlib.Path(__file__).parent / "results" / "allocation.json"


def timed_smt(**params) -> SmtAllocator:
    """An SMT allocator bounded by its ``time_limit`` alone (the budget of z3 work set out of
    the way): the figures here are times."""
    return SmtAllocator(SmtAllocatorParams(budget=MAX_BUDGET, **params))


def hospital_travel(rng) -> np.ndarray:
    points = rng.uniform((0.0, 0.0), FLOOR, size=(NUM_LOCATIONS, 2))
    distance = np.abs(points[:, None, :] - points[None, :, :]).sum(axis=-1)
    return np.ceil(distance / SPEED).astype(int)


def random_tasks(rng, travel, count, first_id=0, arrival=0.0, latest=LATEST_DEADLINE):
    earliest = math.ceil(1.5 * travel.max())
    tasks = []
    for k in range(count):
        pickup, dropoff = (int(x) for x in rng.choice(NUM_LOCATIONS, 2, replace=False))
        deadline = arrival + float(rng.integers(earliest, int(latest) + 1))
        tasks.append(Task(first_id + k, pickup, dropoff, deadline, arrival))
    return tasks


def single_batch(seed, num_tasks, num_robots, capacity, latest=LATEST_DEADLINE):
    rng = np.random.default_rng(seed)
    travel = hospital_travel(rng)
    robots = tuple(RobotStart(f"robot{r}", int(rng.integers(NUM_LOCATIONS)), 0.0, capacity)
                   for r in range(num_robots))
    tasks = random_tasks(rng, travel, num_tasks, latest=latest)
    return AllocationProblem(travel, robots, tuple(tasks))


def solve(allocator, problem):
    start = time.perf_counter()
    allocation = allocator.allocate(problem)
    seconds = time.perf_counter() - start
    violations = verify_allocation(problem, allocation)
    if violations:
        raise AssertionError(f"invalid allocation: {violations[:3]}")
    return allocation, seconds


def run_single_batches(sizes, capacities, seeds):
    allocators = {
        "smt": timed_smt(time_limit=TIME_LIMIT),
        "smt_search_only": timed_smt(time_limit=TIME_LIMIT, greedy_start=False),
        "greedy": GreedyAllocator(),
    }
    rows = []
    for num_tasks, num_robots in sizes:
        for capacity in capacities:
            for seed in seeds:
                problem = single_batch(seed * 1000 + num_tasks * 31 + num_robots * 7 + capacity,
                                       num_tasks, num_robots, capacity)
                row = {"tasks": num_tasks, "robots": num_robots, "capacity": capacity,
                       "seed": seed}
                for name, allocator in allocators.items():
                    allocation, seconds = solve(allocator, problem)
                    row[name] = {"status": allocation.status, "seconds": round(seconds, 3),
                                 "late": len(allocation.late_tasks),
                                 "makespan": allocation.makespan()}
                rows.append(row)
                print(format_single_row(row), flush=True)
    return rows


def run_objective(sizes, seeds, objective, time_limit):
    allocator = timed_smt(objective=objective, time_limit=time_limit)
    rows = []
    for num_tasks, num_robots in sizes:
        for seed in seeds:
            problem = single_batch(seed * 1000 + num_tasks * 31 + num_robots * 7 + 2,
                                   num_tasks, num_robots, 2)
            greedy, _ = solve(GreedyAllocator(), problem)
            allocation, seconds = solve(allocator, problem)
            value = {"makespan": lambda a: a.makespan(),
                     "lateness": lambda a, p=problem: a.total_lateness(p)}[objective]
            rows.append({"tasks": num_tasks, "robots": num_robots, "seed": seed,
                         "greedy": value(greedy), "smt": value(allocation),
                         "proven": allocation.optimal, "seconds": round(seconds, 3)})
            print(f"  {objective:8s} {num_tasks:3d} tasks {num_robots:3d} robots: greedy "
                  f"{value(greedy):8.0f}  smt {value(allocation):8.0f} "
                  f"({'proven' if allocation.optimal else 'time limit'}, {seconds:.2f} s)",
                  flush=True)
    return rows


def run_stream(allocator, seed, num_batches, batch_size, num_robots, capacity, interval,
               latest=LATEST_DEADLINE):
    """Allocates each batch on arrival; between batches robots do exactly what was planned."""
    rng = np.random.default_rng(seed)
    travel = hospital_travel(rng)
    fleet = [RobotStart(f"robot{r}", int(rng.integers(NUM_LOCATIONS)), 0.0, capacity)
             for r in range(num_robots)]
    timelines = [[] for _ in fleet]  # per robot: (action, location, completion s), in order
    tasks, seconds, statuses = {}, [], []
    for b in range(num_batches):
        now = b * interval
        for task in random_tasks(rng, travel, batch_size, len(tasks), now, latest):
            tasks[task.id] = task
        problem, kept = stream_problem(travel, fleet, timelines, tasks, now)
        start = time.perf_counter()
        allocation = allocator.allocate(problem)
        seconds.append(time.perf_counter() - start)
        if verify_allocation(problem, allocation):
            raise AssertionError("invalid allocation in the stream")
        statuses.append(allocation.status)
        for r in range(len(problem.robots)):
            planned = [(a, problem.location(a), t)
                       for a, t in zip(allocation.routes[r], allocation.times[r], strict=True)]
            timelines[r] = kept[r] + planned
    drops = {a.task: t for line in timelines for a, _, t in line if a.kind == DROPOFF}
    late = sum(1 for task in tasks.values() if drops[task.id] > task.deadline)
    return {"batches": num_batches, "tasks": len(tasks), "robots": num_robots,
            "capacity": capacity, "interval": interval, "latest_deadline": latest,
            "total_seconds": round(sum(seconds), 3), "max_seconds": round(max(seconds), 3),
            "late_tasks": late, "statuses": statuses}


def stream_problem(travel, fleet, timelines, tasks, now):
    """The problem at ``now``: what each robot finished and the leg it drives are kept."""
    robots, kept, finishing = [], [], set()
    done_keys = set()
    for robot, line in zip(fleet, timelines, strict=True):
        done = [entry for entry in line if entry[2] <= now]
        current = line[len(done)] if len(done) < len(line) else None
        on_board = []
        for action, _, _ in done:
            done_keys.add(action.key)
            if action.kind == PICKUP:
                on_board.append(action.task)
            else:
                on_board.remove(action.task)
        location, clock = (done[-1][1], done[-1][2]) if done else (robot.location, 0.0)
        status = RobotStatus(robot.name, location, clock, robot.capacity, tuple(on_board),
                             None if current is None else current[0])
        rest = tuple(entry[0] for entry in line[len(done) + 1:])
        start = committed_start(status, now, tasks, travel, 1.0, rest)
        robots.append(start)
        if current is not None:
            kept.append(done + [(current[0], start.location, start.ready_time)])
            if current[0].kind == DROPOFF:
                finishing.add(current[0].task)
        else:
            kept.append(done)
    open_tasks = tuple(task for task in tasks.values()
                       if Action(task.id, DROPOFF).key not in done_keys
                       and task.id not in finishing)
    return AllocationProblem(travel, tuple(robots), open_tasks), kept


def run_tight(sizes, latest, time_limit):
    """Single batches whose deadlines are at most ``latest`` s: the greedy answer often has
    late tasks, and the solver has to find a better one or prove there is none."""
    smt = timed_smt(time_limit=time_limit)
    rows = []
    for num_tasks, num_robots in sizes:
        problem = single_batch(num_tasks * 31 + num_robots * 7, num_tasks, num_robots, 2, latest)
        greedy, greedy_seconds = solve(GreedyAllocator(), problem)
        allocation, seconds = solve(smt, problem)
        rows.append({"tasks": num_tasks, "robots": num_robots, "latest_deadline": latest,
                     "greedy_late": len(greedy.late_tasks),
                     "greedy_seconds": round(greedy_seconds, 3),
                     "smt_status": allocation.status, "smt_late": len(allocation.late_tasks),
                     "smt_conflict": len(allocation.conflict), "smt_proven": allocation.optimal,
                     "smt_seconds": round(seconds, 3)})
        print(f"  {num_tasks:3d} tasks {num_robots:3d} robots: greedy late "
              f"{len(greedy.late_tasks):2d} | smt {allocation.status:10s} late "
              f"{len(allocation.late_tasks):2d} conflict {len(allocation.conflict):2d} "
              f"{'proven' if allocation.optimal else 'unproven'} {seconds:6.2f} s", flush=True)
    return rows


def format_single_row(row):
    cells = [f"{row['tasks']:3d} {row['robots']:3d} {row['capacity']:2d}"]
    for name in ("smt", "smt_search_only", "greedy"):
        result = row[name]
        cells.append(f"{result['status'][:6]:6s} {result['seconds']:7.2f} s "
                     f"late {result['late']:2d}")
    return " | ".join(cells)


def summarize(rows):
    summary = {}
    for name in ("smt", "smt_search_only", "greedy"):
        times = [row[name]["seconds"] for row in rows]
        decided = [row for row in rows if row[name]["status"] in (FEASIBLE, INFEASIBLE)
                   and row[name]["seconds"] <= TIME_LIMIT]
        summary[name] = {
            "decided_within_60s": f"{len(decided)}/{len(rows)}",
            "max_seconds": round(max(times), 3),
            "median_seconds": round(float(np.median(times)), 3),
            "all_on_time": sum(1 for row in rows if row[name]["late"] == 0),
        }
    return summary


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a few small instances")
    args = parser.parse_args()
    if args.quick:
        sizes = [(10, 5), (20, 20)]
        capacities, seeds, stream_batches, objective_sizes = (2,), (0,), 5, [(10, 5)]
        tight_sizes = [(10, 5)]
    else:
        sizes = [(t, r) for t in (10, 15, 20, 25, 30) for r in (5, 10, 15, 20)]
        capacities, seeds, stream_batches = (2, 3), (0, 1), 20
        objective_sizes = [(t, r) for t in (10, 20, 30) for r in (5, 10, 20)]
        tight_sizes = [(t, r) for t in (10, 20, 30) for r in (5, 10)]

    print("single batch: tasks robots capacity | smt | smt (search only) | greedy")
    rows = run_single_batches(sizes, capacities, seeds)
    summary = summarize(rows)
    for name, values in summary.items():
        print(f"  {name:16s} {values}")

    print("objective makespan (capacity 2, time limit 10 s):")
    makespan = run_objective(objective_sizes, (0,), "makespan", 10.0)

    print("tight deadlines (latest 250 s, capacity 2, time limit 20 s):")
    tight = run_tight(tight_sizes, 250.0, 20.0)

    print(f"streams: {stream_batches} batches x 10 tasks, 20 robots, every 60 s")
    streams = []
    for capacity in (2, 3):
        for name, allocator in (
            ("smt", timed_smt(time_limit=TIME_LIMIT)),
            ("smt_search_only", timed_smt(time_limit=TIME_LIMIT, greedy_start=False)),
            ("greedy", GreedyAllocator()),
        ):
            result = run_stream(allocator, 7, stream_batches, 10, 20, capacity, 60.0)
            result["allocator"] = name
            streams.append(result)
            counts = {s: result["statuses"].count(s) for s in sorted(set(result["statuses"]))}
            print(f"  capacity {capacity} {name:16s} total {result['total_seconds']:7.2f} s, "
                  f"max {result['max_seconds']:6.2f} s per batch, late {result['late_tasks']}, "
                  f"{counts}", flush=True)
    print("overloaded streams: every 10 s, deadlines at most 300 s after arrival, capacity 2, "
          "time limit 10 s")
    for name, allocator in (
        ("smt", timed_smt(time_limit=10.0)),
        ("greedy", GreedyAllocator()),
    ):
        result = run_stream(allocator, 7, stream_batches, 10, 20, 2, 10.0, 300.0)
        result["allocator"] = name
        streams.append(result)
        counts = {s: result["statuses"].count(s) for s in sorted(set(result["statuses"]))}
        print(f"  {name:16s} total {result['total_seconds']:7.2f} s, max "
              f"{result['max_seconds']:6.2f} s per batch, late {result['late_tasks']}, {counts}",
              flush=True)

    write_results(RESULTS, args.quick, time_limit=TIME_LIMIT, single_batch=rows,
                  single_batch_summary=summary, objective_makespan=makespan,
                  tight_single_batch=tight, streams=streams)


def write_results(path: pathlib.Path, quick: bool, **fields):
    """Write ``fields`` as JSON to ``path``, after whether the run was ``quick`` and the
    machine."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({
        "quick": quick,
        "machine": {"python": platform.python_version(), "cpus": __import__("os").cpu_count()},
        **fields,
    }, indent=1))
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
