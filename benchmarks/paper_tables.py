"""The MRTA-Sim paper's Tables II and III, from runs of its six-robot hospital case.

The case: ``scenarios/hospital_6_robots.yaml`` with the original's task stream of three
tasks at 0 s and three at 180 s (``scenarios/tasks/paper_3_plus_3.json``), its people, and
the first 2, 4 or 6 robots (each starting on its own room's point), for this project's
defaults (``profile: mrta_drake``) and for ``profile: paper``. One run each.

- Table II, CBF-QP time per call by cluster size, from the run's own controller telemetry
  (``ControllerTelemetry.qp_calls``, recorded every control tick): a call is one QP handed
  to the solver (Clarabel through Drake's ``MathematicalProgram``), its size the number of
  robots solved together. Each run is in a fresh process, after a throwaway run of the
  same case for 2 s and one QP solve (they load the compiled kernels from numba's cache,
  or compile them, and the solver), so no window and no call is charged for loading code.
  "First" is the first call of that size in a run (it builds the program: the counterpart
  of the paper's JAX compilation), averaged over the runs that had one; "steady" the mean of
  every later call.
  The rows of all QPs of a tick are made before, in one compiled call, and are not in
  these times; ticks whose clipped nominal inputs already satisfy every row make no call.
- Table III, the lowest real-time factor over 10 s windows of simulated time (simulated
  time / wall-clock time per window, and the same with the process's CPU time, the
  steadier figure on a shared machine). Start-up (loading, building, the first
  allocation) is timed apart.

    python benchmarks/paper_tables.py [--robots 2,4,6] [--duration 300]
                                      [--profiles mrta_drake,paper]

Prints both tables beside the paper's figures and writes
benchmarks/results/paper_tables.json.
"""

import argparse
import dataclasses
import json
import multiprocessing
import os
import pathlib
import platform
import statistics
import time
from concurrent.futures import ProcessPoolExecutor

from pydrake.systems.analysis import Simulator
from realtime import warm_up_qp  # benchmarks/realtime.py

from mrta_drake import load_scenario
from mrta_drake.results.timing import task_rows, task_totals
from mrta_drake.stack.diagram import build_diagram

ROOT = pathlib.Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks/results/paper_tables.json"
SCENARIO = ROOT / "scenarios/hospital_6_robots.yaml"
TASKS = "tasks/paper_3_plus_3.json"  # relative to the scenario
WINDOW = 10.0  # s of simulated time per real-time-factor window
WARM_UP = 2.0  # s simulated of a throwaway copy of each case first (see the docstring)
# MRTA-Sim paper (Gazebo, ROS 2, JAX; i9-9900X): Table II, s per call (first, steady) by
# cluster size; Table III, the lowest real-time factor by number of robots.
PAPER_QP = {1: (0.0126, 0.00854), 2: (1.50, 0.0143), 3: (1.54, 0.0123)}
PAPER_RTF = {2: 0.73, 4: 0.56, 6: 0.42}


def paper_case(profile: str, robots: int, duration: float):
    """The paper's case for ``profile`` with the first ``robots`` robots, logging every
    control tick."""
    base = load_scenario(SCENARIO, overrides={"profile": profile, "tasks.file": TASKS,
                                              "duration": duration})
    rates = dataclasses.replace(base.rates, logging=base.rates.controller)
    return dataclasses.replace(base, robots=base.robots[:robots], rates=rates)


def _run_case(case: tuple[str, int, float]) -> dict:
    scenario = paper_case(*case)
    warm_up = Simulator(build_diagram(scenario).diagram)
    warm_up.AdvanceTo(WARM_UP)
    warm_up_qp()
    return run_case(scenario)


def run_case(scenario) -> dict:
    """Run ``scenario`` in ``WINDOW`` s steps: start-up, each window's wall and CPU time,
    the QP calls and the tasks done."""
    start_wall, start_cpu = time.perf_counter(), time.process_time()
    stack = build_diagram(scenario)
    simulator = Simulator(stack.diagram)
    simulator.Initialize()
    startup = (time.perf_counter() - start_wall, time.process_time() - start_cpu)
    windows, t = [], 0.0
    while t < scenario.duration - 1e-9:
        end = min(scenario.duration, t + WINDOW)
        wall, cpu = time.perf_counter(), time.process_time()
        simulator.AdvanceTo(end)
        windows.append({"start": t, "end": end, "wall": time.perf_counter() - wall,
                        "cpu": time.process_time() - cpu})
        t = end
    calls = [call for tick in _ticks(stack.recorder.telemetry) for call in tick.qp_calls]
    tasks = task_totals(task_rows(scenario.tasks.stream, stack.recorder.events, t))
    return {"robots": len(scenario.robots), "duration": scenario.duration,
            "startup_wall": startup[0], "startup_cpu": startup[1], "windows": windows,
            "rtf_min_wall": min(w["end"] - w["start"] for w in windows) / max(
                w["wall"] for w in windows),
            "rtf_min_cpu": min(w["end"] - w["start"] for w in windows) / max(
                w["cpu"] for w in windows),
            "qp_by_size": _by_size(calls), "tasks_done": tasks["completed"],
            "tasks_on_time": tasks["on_time"]}


def _ticks(telemetry) -> list:
    """The recorded telemetry, one entry per control tick (the recorder may sample a tick
    twice)."""
    seen, ticks = set(), []
    for tick in telemetry:
        if tick.time not in seen:
            seen.add(tick.time)
            ticks.append(tick)
    return ticks


def _by_size(calls) -> dict:
    """Per QP size (robots): calls, the first call's time and the later calls' mean and
    median (s)."""
    sizes = {}
    for size, seconds in calls:
        sizes.setdefault(size, []).append(seconds)
    return {str(size): {"calls": len(times), "first": times[0],
                        "steady_mean": statistics.fmean(times[1:]) if len(times) > 1 else None,
                        "steady_median": statistics.median(times[1:]) if len(times) > 1
                        else None}
            for size, times in sorted(sizes.items())}


def qp_table(runs: list[dict], profiles: list[str]) -> list[dict]:
    """Table II rows: per cluster size, the paper's figures and each profile's first call
    (mean over runs) and steady state (mean over all later calls, weighted by calls)."""
    sizes = sorted({int(size) for run in runs for size in run["qp_by_size"]} | set(PAPER_QP))
    rows = []
    for size in sizes:
        row = {"size": size, "paper_first": PAPER_QP.get(size, (None, None))[0],
               "paper_steady": PAPER_QP.get(size, (None, None))[1]}
        for profile in profiles:
            stats = [run["qp_by_size"][str(size)] for run in runs
                     if run["profile"] == profile and str(size) in run["qp_by_size"]]
            later = [(s["calls"] - 1, s["steady_mean"]) for s in stats if s["calls"] > 1]
            count = sum(n for n, _ in later)
            row[profile] = {
                "calls": sum(s["calls"] for s in stats),
                "first": statistics.fmean(s["first"] for s in stats) if stats else None,
                "steady": sum(n * m for n, m in later) / count if count else None}
        rows.append(row)
    return rows


def _ms(seconds) -> str:
    return "-" if seconds is None else f"{1000.0 * seconds:.2f}"


def print_tables(result: dict) -> None:
    profiles = result["profiles"]
    print("Table II: CBF-QP time per call (ms), by cluster size")
    header = "| size | MRTA-Sim first | MRTA-Sim steady |" + "".join(
        f" {p} first | {p} steady | {p} calls |" for p in profiles)
    print(header)
    print("|" + "---:|" * (3 + 3 * len(profiles)))
    for row in result["table_2"]:
        cells = [str(row["size"]), _ms(row["paper_first"]), _ms(row["paper_steady"])]
        for p in profiles:
            cells += [_ms(row[p]["first"]), _ms(row[p]["steady"]), str(row[p]["calls"])]
        print("| " + " | ".join(cells) + " |")
    print()
    print("Table III: lowest real-time factor over 10 s windows (wall clock; CPU)")
    print("| robots | MRTA-Sim |" + "".join(f" {p} wall | {p} CPU | {p} tasks done |"
                                         for p in profiles))
    print("|" + "---:|" * (2 + 3 * len(profiles)))
    for robots in result["robots"]:
        cells = [str(robots), f"{PAPER_RTF.get(robots, float('nan')):.2f}"]
        for p in profiles:
            run = next(r for r in result["runs"] if r["profile"] == p and r["robots"] == robots)
            cells += [f"{run['rtf_min_wall']:.1f}", f"{run['rtf_min_cpu']:.1f}",
                      str(run["tasks_done"])]
        print("| " + " | ".join(cells) + " |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", default="2,4,6", help="comma-separated robot counts")
    parser.add_argument("--duration", type=float, default=300.0, help="simulated s per run")
    parser.add_argument("--profiles", default="mrta_drake,paper", help="comma-separated")
    args = parser.parse_args()
    robots = [int(n) for n in args.robots.split(",")]
    profiles = args.profiles.split(",")
    runs = []
    cases = [(profile, n, args.duration) for profile in profiles for n in robots]
    # Each run in a fresh process, so that every run's first calls load the solver anew.
    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn"),
                             max_tasks_per_child=1) as pool:
        for (profile, n, _), run in zip(cases, pool.map(_run_case, cases), strict=True):
            runs.append({"profile": profile, **run})
            print(f"{profile}, {n} robots: lowest real-time factor {run['rtf_min_wall']:.1f} "
                  f"(CPU {run['rtf_min_cpu']:.1f}), {run['tasks_done']} tasks done", flush=True)
    result = {"machine": {"cpus": os.cpu_count(), "platform": platform.platform(),
                          "python": platform.python_version()},
              "scenario": str(SCENARIO.relative_to(ROOT)), "tasks": TASKS,
              "window": WINDOW, "robots": robots, "profiles": profiles, "runs": runs,
              "table_2": qp_table(runs, profiles)}
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps(result, indent=2) + "\n")
    print()
    print_tables(result)


if __name__ == "__main__":
    main()
