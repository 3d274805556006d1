"""Calibration of the SMT allocator's budget: z3 resource units per second of solving.

The allocator's limit is a budget of z3 resource units (``rlimit``), so that answers do not
depend on the host. This script measures how fast z3 spends them on instances hard enough
to use up a 10 s limit (the wall-clock default the budget replaced), so that the default
budget takes about that long here:

1. each instance is allocated ``--repeats`` times with a budget of ``CALIBRATION_UNITS`` and
   no time limit: every repeat must give the same allocation and spend the same units; the
   rate is those units over the least CPU time of the repeats (the machine is shared: CPU
   time, and its least over repeats, is what an unloaded machine takes);
2. the suggested budget is the median rate (over the instances that spent at least a tenth
   of ``CALIBRATION_UNITS``) times ``REFERENCE_SECONDS``, to two significant digits;
3. each instance is allocated once more with the budget in the code (``DEFAULT_BUDGET``):
   how long it takes (CPU and wall seconds), and whether the budget ran out.

Instances (``benchmarks/allocation.py``'s generator: 65 random points on the hospital's floor,
capacity 2): the hard regime (deadlines at most 250 s) with and without the greedy start, and
the makespan objective with deadlines up to 1000 s.

    python benchmarks/allocation_budget.py            # 9 instances, ~4 CPU minutes
    python benchmarks/allocation_budget.py --quick    # 2 instances, a few seconds

Prints the table and writes benchmarks/results/allocation_budget.json. Seconds vary from run
to run (wall clock more, on a shared machine); the units do not.
"""

import argparse
import dataclasses
import pathlib
import statistics
import time

from allocation import LATEST_DEADLINE, single_batch, write_results

from mrta_drake.allocation import SmtAllocator, SmtAllocatorParams, verify_allocation
from mrta_drake.allocation.smt_allocator import DEFAULT_BUDGET

REFERENCE_SECONDS = 10.0  # the wall-clock limit the default budget stands for
CALIBRATION_UNITS = 20_000_000  # z3 resource units per calibration run (a few CPU seconds)
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


def run(problem, **params) -> tuple[dict, dict]:
    """One allocation: its CPU and wall-clock seconds, z3 units, status, late tasks and note;
    and the allocation less its wall-clock field."""
    cpu, wall = time.process_time(), time.perf_counter()
    allocation = SmtAllocator(SmtAllocatorParams(**params)).allocate(problem)
    cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
    if verify_allocation(problem, allocation):
        raise AssertionError("invalid allocation")
    answer = {k: v for k, v in dataclasses.asdict(allocation).items() if k != "solve_time"}
    return {"cpu_seconds": round(cpu, 3), "wall_seconds": round(wall, 3),
            "work": allocation.work, "status": allocation.status,
            "late": len(allocation.late_tasks), "note": allocation.note}, answer


def calibrate(instance: dict, repeats: int, units: int) -> dict:
    """The instance's rate: units spent over the least CPU time of ``repeats`` runs, which
    must all give the same allocation."""
    results, answers = zip(*(run(instance["problem"], budget=units, **instance["params"])
                             for _ in range(repeats)), strict=True)
    if any(answer != answers[0] for answer in answers):
        raise AssertionError(f"{instance['name']}: repeats gave different allocations")
    best = min(results, key=lambda result: result["cpu_seconds"])
    return best | {"cpu_seconds_all": [result["cpu_seconds"] for result in results],
                   "units_per_second": round(best["work"] / best["cpu_seconds"])}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="2 instances, a smaller budget")
    parser.add_argument("--repeats", type=int, default=3, help="runs per instance in step 1")
    args = parser.parse_args()
    units = CALIBRATION_UNITS // 10 if args.quick else CALIBRATION_UNITS
    rows = []
    print(f"1. budget {units} units, best of {args.repeats}: z3 units per CPU second")
    for instance in instances(args.quick):
        calibration = calibrate(instance, args.repeats, units)
        rows.append({"instance": instance, "calibration": calibration})
        print(f"  {instance['name']:26s} {calibration['work']:10d} units in "
              f"{calibration['cpu_seconds']:6.2f} s CPU (of {calibration['cpu_seconds_all']}) "
              f"{calibration['units_per_second']:9d} /s", flush=True)
    rates = [row["calibration"]["units_per_second"] for row in rows
             if row["calibration"]["work"] >= units / 10]
    rate = statistics.median(rates)
    suggested = int(float(f"{rate * REFERENCE_SECONDS:.2g}"))
    print(f"median {rate:.0f} units per CPU second over {len(rates)} instances: budget for "
          f"{REFERENCE_SECONDS:g} s = {suggested} (DEFAULT_BUDGET in the code: "
          f"{DEFAULT_BUDGET})")
    print(f"2. budget {DEFAULT_BUDGET}")
    for row in rows:
        instance = row["instance"]
        row["default"], _ = run(instance["problem"], **instance["params"])
        result = row["default"]
        print(f"  {instance['name']:26s} {result['cpu_seconds']:6.2f} s CPU "
              f"{result['wall_seconds']:6.2f} s wall {result['work']:10d} units  "
              f"{result['status']:10s} late {result['late']:2d}  {result['note']}", flush=True)
    write_results(RESULTS, args.quick, reference_seconds=REFERENCE_SECONDS,
                  calibration_units=units, median_units_per_second=rate,
                  suggested_budget=suggested, default_budget=DEFAULT_BUDGET,
                  rows=[{"instance": row["instance"]["name"], "params": row["instance"]["params"],
                         "calibration": row["calibration"], "default": row["default"]}
                        for row in rows])


if __name__ == "__main__":
    main()
