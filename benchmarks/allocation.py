"""Allocation benchmark: seeded random instances like the SMrTa paper's.

Single batches: 65 locations, 10-30 tasks x 5-20 robots, all tasks at t = 0, deadlines
uniform in [1.5 x the longest travel time, 1000] s, capacity 2 and 3. Streams: 20 batches
of 10 tasks every 60 s for 20 robots, each batch's deadlines its arrival plus the same
range, executed exactly as planned between batches. Then the hard regime: single batches
with deadlines at most 250 s, and a stream overloaded with a batch every 10 s. First of all
the tight regime: the single batches of the 20 sizes (capacity 2, seed 0) with every deadline
scaled by 0.5 and by 0.35, for the SMT allocator (default budget), the greedy allocator and
OR-Tools routing (``routing_peer.py``, 10 s, if installed), on SMrTa's recipe (travel times
over a corridor graph, ``room_graph.py``) or, with ``--tight-recipe points``, on ours.

Our recipe ("points"): locations are random points on a floor of the hospital map's size
(25 x 56 m); travel times are the Manhattan distance at 0.7 m/s, rounded up (longest ~110 s).

    python benchmarks/allocation.py            # full run (takes long on 2 cores)
    python benchmarks/allocation.py --quick    # a few small instances
    python benchmarks/allocation.py --tight-only   # the tight regime alone (~15 min)
    python benchmarks/allocation.py --single-only  # the single batches alone, with CPU s

Prints tables and writes benchmarks/results/allocation.json (``--tight-only``:
benchmarks/results/allocation_tight.json, or ``allocation_tight_points.json`` with
``--tight-recipe points``; ``--single-only``: benchmarks/results/allocation_single.json).
"""

import argparse
import dataclasses
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

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import routing_peer  # noqa: E402
from room_graph import room_graph_travel  # noqa: E402

NUM_LOCATIONS = 65
FLOOR = (25.0, 56.0)  # m
SPEED = 0.7  # m/s
LATEST_DEADLINE = 1000.0  # s after the batch arrival
TIME_LIMIT = 60.0  # s per allocation
RESULTS = pathlib.Path(__file__).parent / "results" / "allocation.json"
TIGHT_RESULTS = {"smrta": pathlib.Path(__file__).parent / "results" / "allocation_tight.json",
                 "points": pathlib.Path(__file__).parent / "results" /
                 "allocation_tight_points.json"}
SINGLE_RESULTS = pathlib.Path(__file__).parent / "results" / "allocation_single.json"
TIGHT_SCALES = (0.5, 0.35)  # deadlines scaled: the tight regime
ROUTING_SECONDS = 10.0  # OR-Tools' guided local search per instance


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


TRAVEL_RECIPES = {"smrta": room_graph_travel, "points": hospital_travel}


def single_batch(seed, num_tasks, num_robots, capacity, latest=LATEST_DEADLINE, recipe="points"):
    """All tasks at t = 0 on the travel times of ``TRAVEL_RECIPES[recipe]``; deadlines uniform
    in whole seconds in [1.5 x the longest travel time, ``latest``]."""
    rng = np.random.default_rng(seed)
    travel = TRAVEL_RECIPES[recipe](rng)
    robots = tuple(RobotStart(f"robot{r}", int(rng.integers(NUM_LOCATIONS)), 0.0, capacity)
                   for r in range(num_robots))
    tasks = random_tasks(rng, travel, num_tasks, latest=latest)
    return AllocationProblem(travel, robots, tuple(tasks))


def scaled_deadlines(problem: AllocationProblem, scale: float) -> AllocationProblem:
    """``problem`` with every deadline moved to ``scale`` of its time after the release."""
    tasks = tuple(dataclasses.replace(task, deadline=task.release + scale * (
        task.deadline - task.release)) for task in problem.tasks)
    return dataclasses.replace(problem, tasks=tasks)


def tight_batch(num_tasks, num_robots, scale, seed=0, recipe="smrta"):
    """A single batch (capacity 2) of ``recipe`` with its deadlines scaled by ``scale``: the
    tight regime."""
    problem = single_batch(seed * 1000 + num_tasks * 31 + num_robots * 7 + 2, num_tasks,
                           num_robots, 2, recipe=recipe)
    return scaled_deadlines(problem, scale)


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
                    cpu = time.process_time()
                    allocation, seconds = solve(allocator, problem)
                    row[name] = {"status": allocation.status, "seconds": round(seconds, 3),
                                 "cpu_seconds": round(time.process_time() - cpu, 3),
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


def run_tight_regime(sizes, scales, routing_seconds, recipe):
    """The single batches of ``recipe`` (capacity 2, seed 0) with every deadline scaled by each
    of ``scales``: the SMT allocator with its default budget, searching every task
    (``defer_hopeless: false``, so that its proofs cover the whole problem), the greedy
    allocator and OR-Tools routing (``routing_seconds`` of guided local search), if
    installed. Per instance and allocator: late tasks, total tardiness (s), proven optimal
    (most tasks on time, then least tardiness; an answer with every task on time is), CPU
    and wall seconds."""
    allocators = {"smt": SmtAllocator(SmtAllocatorParams(defer_hopeless=False)),
                  "greedy": GreedyAllocator()}
    if routing_peer.available():
        allocators["ortools"] = _RoutingPeer(routing_seconds)
    rows = []
    for scale in scales:
        for num_tasks, num_robots in sizes:
            problem = tight_batch(num_tasks, num_robots, scale, recipe=recipe)
            row = {"scale": scale, "tasks": num_tasks, "robots": num_robots}
            for name, allocator in allocators.items():
                cpu = time.process_time()
                allocation, seconds = solve(allocator, problem)
                row[name] = {"late": len(allocation.late_tasks),
                             "tardiness": round(allocation.total_tardiness(problem), 3),
                             "proven": allocation.optimal or not allocation.late_tasks,
                             "cpu_seconds": round(time.process_time() - cpu, 3),
                             "seconds": round(seconds, 3), "work": allocation.work}
            row["smt_meets_target"] = _meets_target(row, [n for n in allocators if n != "smt"])
            rows.append(row)
            print(f"  scale {scale:4.2f} {num_tasks:3d} x {num_robots:2d} " + " | ".join(
                f"{name} late {row[name]['late']:2d} tard {row[name]['tardiness']:7.1f} "
                f"{'proven' if row[name]['proven'] else '      '} {row[name]['cpu_seconds']:5.2f}"
                f" s CPU" for name in allocators), flush=True)
    if not routing_peer.available():
        print("  ortools: not installed (pip install 'mrta-drake[benchmarks]')")
    return {"recipe": recipe, "allocators": list(allocators),
            "ortools_installed": routing_peer.available(), "routing_seconds": routing_seconds,
            "rows": rows,
            "totals": _tight_totals(rows, scales, list(allocators))}


class _RoutingPeer:
    """OR-Tools routing as an allocator (``allocate``) with a wall-clock limit."""

    def __init__(self, seconds: float):
        self.seconds = seconds

    def allocate(self, problem):
        return routing_peer.routing_allocation(problem, self.seconds)


def _meets_target(row, peers) -> bool:
    """The SMT answer is proven optimal, or no worse (late tasks, then tardiness) than the
    best peer's."""
    smt = row["smt"]
    if smt["proven"]:
        return True
    best = min((row[p]["late"], row[p]["tardiness"]) for p in peers)
    return (smt["late"], smt["tardiness"]) <= (best[0], best[1] + 1e-6)


def _tight_totals(rows, scales, names):
    totals = {}
    for scale in scales:
        mine = [row for row in rows if row["scale"] == scale]
        totals[str(scale)] = {name: {
            "late": sum(row[name]["late"] for row in mine),
            "tardiness": round(sum(row[name]["tardiness"] for row in mine), 1),
            "proven": sum(row[name]["proven"] for row in mine),
            "mean_cpu_seconds": round(float(np.mean([row[name]["cpu_seconds"] for row in mine])),
                                      3),
            "mean_seconds": round(float(np.mean([row[name]["seconds"] for row in mine])), 3),
        } for name in names} | {"smt_meets_target": sum(row["smt_meets_target"] for row in mine),
                                 "instances": len(mine)}
        print(f"  scale {scale}: {totals[str(scale)]}")
    return totals


def print_cpu_per_size(rows):
    """The most and the mean CPU seconds per allocate call of each size, per allocator."""
    names = ("smt", "smt_search_only", "greedy")
    print("CPU s per call: tasks robots | " + " | ".join(f"{n} max mean" for n in names))
    for size in dict.fromkeys((row["tasks"], row["robots"]) for row in rows):
        mine = [row for row in rows if (row["tasks"], row["robots"]) == size]
        cells = []
        for name in names:
            cpu = [row[name]["cpu_seconds"] for row in mine]
            cells.append(f"{max(cpu):6.3f} {float(np.mean(cpu)):6.3f}")
        print(f"  {size[0]:3d} {size[1]:3d} | " + " | ".join(cells))


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
    parser.add_argument("--tight-only", action="store_true",
                        help="only the tight regime (deadlines scaled by 0.5 and 0.35)")
    parser.add_argument("--single-only", action="store_true",
                        help="only the single batches (and their CPU seconds per size)")
    parser.add_argument("--tight-recipe", choices=sorted(TRAVEL_RECIPES), default="smrta",
                        help="the tight regime's instances: SMrTa's recipe or ours (points)")
    args = parser.parse_args()
    single_sizes = [(t, r) for t in (10, 15, 20, 25, 30) for r in (5, 10, 15, 20)]
    tight_regime = None
    if not args.single_only:
        print(f"tight regime ({args.tight_recipe}): deadlines scaled by {TIGHT_SCALES}, capacity "
              f"2, seed 0; smt default budget, greedy, ortools {ROUTING_SECONDS:g} s")
        tight_regime = run_tight_regime(single_sizes[:2] if args.quick else single_sizes,
                                        TIGHT_SCALES, 1.0 if args.quick else ROUTING_SECONDS,
                                        args.tight_recipe)
    if args.tight_only:
        write_results(TIGHT_RESULTS[args.tight_recipe], args.quick, tight_regime=tight_regime)
        return
    if args.quick:
        sizes = [(10, 5), (20, 20)]
        capacities, seeds, stream_batches, objective_sizes = (2,), (0,), 5, [(10, 5)]
        tight_sizes = [(10, 5)]
    else:
        sizes = single_sizes
        capacities, seeds, stream_batches = (2, 3), (0, 1), 20
        objective_sizes = [(t, r) for t in (10, 20, 30) for r in (5, 10, 20)]
        tight_sizes = [(t, r) for t in (10, 20, 30) for r in (5, 10)]

    print("single batch: tasks robots capacity | smt | smt (search only) | greedy")
    rows = run_single_batches(sizes, capacities, seeds)
    summary = summarize(rows)
    for name, values in summary.items():
        print(f"  {name:16s} {values}")
    if args.single_only:
        print_cpu_per_size(rows)
        write_results(SINGLE_RESULTS, args.quick, single_batch=rows,
                      single_batch_summary=summary)
        return

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
                  tight_single_batch=tight, streams=streams, tight_regime=tight_regime)


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
