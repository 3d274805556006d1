"""The SMT allocator's CPU per call, on the calls simulations make.

Cases: ``floor25``, the 25-robot hospital floor of ``benchmarks/realtime.py`` (kinematic,
seed 0) for 90 s; ``busy``, the six-robot hospital under the busy stream of
``scenarios/sweeps/hospital_20_seeds.yaml`` (seeds 200-209, 300 s each). Each simulation
records the problem of every ``SmtAllocator.allocate`` call and its answer; then the allocator
solves each problem again ``--repeat`` times, and the least CPU time counts (less noise on a
shared host). Every answer must equal the recorded one (wall-clock ``solve_time`` aside).

Per case: calls, calls where z3 searched (work > 0), CPU of all calls and of the costliest,
and a hash of the answers: the same hash on two commits means the same answers.

    python benchmarks/allocation_calls.py                  # both cases (~2 min CPU)
    python benchmarks/allocation_calls.py --cases floor25 --repeat 5

Prints a table and writes benchmarks/results/allocation_calls.json.
"""

import argparse
import dataclasses
import hashlib
import json
import pathlib
import sys
import tempfile
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))

from mrta_drake.allocation import SmtAllocator  # noqa: E402
from mrta_drake.stack.simulate import simulate  # noqa: E402
from mrta_drake.tools.sweep import load_sweep, sweep_scenario  # noqa: E402

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import realtime  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results" / "allocation_calls.json"
BUSY_SWEEP = ROOT / "scenarios" / "sweeps" / "hospital_20_seeds.yaml"
BUSY_SEEDS = range(200, 210)
FLOOR_ROBOTS, FLOOR_SECONDS = 25, 90.0


def scenarios(case: str, folder: str) -> list:
    """The scenarios of ``case`` (see the module docstring)."""
    if case == "floor25":
        return [realtime.floor_scenario(FLOOR_ROBOTS, "kinematic", 0, FLOOR_SECONDS, folder)]
    busy = load_sweep(str(BUSY_SWEEP))
    return [sweep_scenario(busy.scenario, dict(busy.fixed, seed=seed)) for seed in BUSY_SEEDS]


def recorded_calls(scenario) -> list:
    """(allocator, problem, answer) of every ``SmtAllocator.allocate`` call in a run of
    ``scenario``."""
    calls, allocate = [], SmtAllocator.allocate

    def recording(allocator, problem):
        answer = allocate(allocator, problem)
        calls.append((allocator, problem, answer))
        return answer

    SmtAllocator.allocate = recording
    try:
        simulate(scenario, plots=False)
    finally:
        SmtAllocator.allocate = allocate
    return calls


def without_wall_clock(answer):
    return dataclasses.replace(answer, solve_time=0.0)


def measure(case: str, repeat: int) -> dict:
    with tempfile.TemporaryDirectory() as folder:
        calls = [call for scenario in scenarios(case, folder)
                 for call in recorded_calls(scenario)]
    digest, seconds = hashlib.sha256(), []
    for allocator, problem, recorded in calls:
        best = None
        for _ in range(repeat):
            cpu = time.process_time()
            answer = allocator.allocate(problem)
            cpu = time.process_time() - cpu
            best = cpu if best is None else min(best, cpu)
            if without_wall_clock(answer) != without_wall_clock(recorded):
                raise AssertionError(f"{case}: a different answer to the same problem")
        seconds.append(best)
        digest.update(repr(without_wall_clock(recorded)).encode())
    return {"case": case, "calls": len(calls),
            "searched": sum(answer.work > 0 for _, _, answer in calls),
            "cpu_s": round(sum(seconds), 4), "max_cpu_s": round(max(seconds), 4),
            "answers": digest.hexdigest()[:16]}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="*", default=["floor25", "busy"],
                        choices=["floor25", "busy"])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--out", type=pathlib.Path, default=RESULTS)
    args = parser.parse_args()
    rows = []
    print(f"{'case':<9}{'calls':>6}{'searched':>9}{'CPU s':>9}{'max s':>8}  answers")
    for case in args.cases:
        row = measure(case, args.repeat)
        rows.append(row)
        print(f"{case:<9}{row['calls']:>6}{row['searched']:>9}{row['cpu_s']:>9.3f}"
              f"{row['max_cpu_s']:>8.3f}  {row['answers']}", flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"repeat": args.repeat, "rows": rows}, indent=2) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
