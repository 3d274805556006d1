"""Calibration of the SMT allocator's budget: z3 resource units per second of solving.

The allocator's limit is a budget of z3 resource units (``rlimit``), so that answers do not
depend on the host. This script measures how many units z3 spends per second on instances
hard enough to use up a 10 s limit (the wall-clock default the budget replaced), so that the
default budget takes about that long here:

1. each instance runs with a wall-clock ``time_limit`` of ``REFERENCE_SECONDS`` and no budget
   to speak of (``MAX_BUDGET``): the rate is the units it spent over the CPU seconds it took
   (the machine is shared: CPU time is what an unloaded machine would take in wall time);
2. the suggested budget is the median rate (over the instances that ran at least a tenth of
   that in CPU time) times ``REFERENCE_SECONDS``, to two significant digits;
3. each instance runs again with the budget in the code (``DEFAULT_BUDGET``) and no time
   limit: how long it takes (CPU and wall seconds), and whether the budget ran out.

Instances (``benchmarks/allocation.py``'s generator: 65 random points on the hospital's floor,
capacity 2): the hard regime (deadlines at most 250 s) with and without the greedy start, and
the makespan objective with deadlines up to 1000 s.

    python benchmarks/allocation_budget.py            # 9 instances, ~3 min
    python benchmarks/allocation_budget.py --quick    # 2 instances, 2 s reference

Prints the table and writes benchmarks/results/allocation_budget.json. Seconds vary from run
to run (wall clock more, on a shared machine); the units do not.
"""

import argparse
import json
import pathlib
import platform
import statistics
import time

from allocation import LATEST_DEADLINE, single_batch

from mrta_drake.allocation import SmtAllocator, SmtAllocatorParams, verify_allocation
from mrta_drake.allocation.smt_allocator import DEFAULT_BUDGET, MAX_BUDGET

REFERENCE_SECONDS = 10.0  # the wall-clock limit the default budget stands for
TIGHT_DEADLINE = 250.0  # s: the hard regime of benchmarks/allocation.py
RESULTS = pathlib.Path(__file__).parent / "results" / "allocation_budget.json"


def instances(quick: bool) -> list[dict]:
    """Each instance: a name, its problem and the allocator parameters it runs with."""
    sizes = [(20, 5)] if quick else [(20, 5), (30, 5), (30, 10)]
    found = []
    for num_tasks, num_robots in sizes:
        tight = single_batch(num_tasks * 31 + num_robots * 7, num_tasks, num_robots, 2,
                             TIGHT_DEADLINE)
        loose = single_batch(num_tasks * 31 + num_robots * 7 + 2, num_tasks, num_robots, 2,
                             LATEST_DEADLINE)
        size = f"{num_tasks}x{num_robots}"
        found += [
            {"name": f"tight {size}", "problem": tight, "params": {}},
            {"name": f"tight {size} search only", "problem": tight,
             "params": {"greedy_start": False}},
            {"name": f"makespan {size}", "problem": loose, "params": {"objective": "makespan"}},
        ]
    return found[:2] if quick else found


def run(problem, **params) -> dict:
    """One allocation: its CPU and wall-clock seconds, z3 units, status, late tasks and
    note."""
    cpu, wall = time.process_time(), time.perf_counter()
    allocation = SmtAllocator(SmtAllocatorParams(**params)).allocate(problem)
    cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
    if verify_allocation(problem, allocation):
        raise AssertionError("invalid allocation")
    return {"cpu_seconds": round(cpu, 3), "wall_seconds": round(wall, 3),
            "work": allocation.work, "status": allocation.status,
            "late": len(allocation.late_tasks), "note": allocation.note}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="2 instances, 2 s reference")
    args = parser.parse_args()
    reference = 2.0 if args.quick else REFERENCE_SECONDS
    rows = []
    print(f"1. time limit {reference:g} s, budget {MAX_BUDGET}: z3 units per second")
    for instance in instances(args.quick):
        timed = run(instance["problem"], time_limit=reference, budget=MAX_BUDGET,
                    **instance["params"])
        timed["units_per_second"] = round(timed["work"] / timed["cpu_seconds"])
        rows.append({"instance": instance, "timed": timed})
        print(f"  {instance['name']:26s} {_seconds(timed)} {timed['work']:11d} units "
              f"{timed['units_per_second']:9d} /s CPU  {timed['note']}", flush=True)
    rates = [row["timed"]["units_per_second"] for row in rows
             if row["timed"]["cpu_seconds"] >= reference / 10]
    rate = statistics.median(rates)
    suggested = int(float(f"{rate * reference:.2g}"))
    print(f"median {rate:.0f} units per CPU second over {len(rates)} instances: budget for "
          f"{reference:g} s = {suggested} (DEFAULT_BUDGET in the code: {DEFAULT_BUDGET})")
    print(f"2. budget {DEFAULT_BUDGET}, no time limit")
    for row in rows:
        instance = row["instance"]
        budgeted = run(instance["problem"], budget=DEFAULT_BUDGET, **instance["params"])
        row["budgeted"] = budgeted
        print(f"  {instance['name']:26s} {_seconds(budgeted)} {budgeted['work']:11d} "
              f"units  {budgeted['status']:10s} late {budgeted['late']:2d}  {budgeted['note']}",
              flush=True)
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps({
        "quick": args.quick,
        "machine": {"python": platform.python_version(), "cpus": __import__("os").cpu_count()},
        "reference_seconds": reference,
        "median_units_per_second": rate,
        "suggested_budget": suggested,
        "default_budget": DEFAULT_BUDGET,
        "rows": [{"instance": row["instance"]["name"], "params": row["instance"]["params"],
                  "timed": row["timed"], "budgeted": row["budgeted"]} for row in rows],
    }, indent=1))
    print(f"wrote {RESULTS}")


def _seconds(result: dict) -> str:
    return f"{result['cpu_seconds']:6.2f} s CPU {result['wall_seconds']:6.2f} s wall"


if __name__ == "__main__":
    main()
