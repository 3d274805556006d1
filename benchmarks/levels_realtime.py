"""Real-time factor of a building run across levels: the two-floor clinic with 10 robots and
10 people over 600 s, kinematic robots. The goal: >= 20x real time.

The scenario is what ``mrta-sim import models/two_floor_clinic/two_floor_clinic.building.yaml
--robots 10 --people 10`` writes (seed 0: robots and people shared out over both floors, a
generated task stream over every location, many tasks changing floors through the two
lifts), run for ``--duration`` s. Start-up (loading, building the diagram,
``Simulator.Initialize``) is timed apart. The run advances in slices of ``--slice`` s;
each slice's CPU time (``time.process_time``, the main figure on a shared machine) and
wall-clock time are recorded, so the table shows how the rate holds up over the run
(real-time factor = simulated s / s spent). Numba's compiled kernels are loaded from their
cache by a short warm-up run first. A fixed calibration workload (``realtime.calibration``)
records how fast the shared host ran.

With ``--profile FILE`` the run goes under cProfile (slower) and the stack's own functions
with the most cumulative time are printed; FILE keeps the pstats.

    python benchmarks/levels_realtime.py [--robots 10] [--people 10] [--duration 600]
                                         [--slice 60] [--profile FILE]

Prints a table and writes benchmarks/results/levels_realtime.json.
"""

import argparse
import cProfile
import json
import pathlib
import platform
import pstats
import sys
import tempfile
import time

from pydrake.systems.analysis import Simulator

from mrta_drake import load_scenario
from mrta_drake.results.summary import summarize
from mrta_drake.stack.diagram import build_diagram
from mrta_drake.tools.building_import import ImportOptions, import_building

ROOT = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))
from realtime import calibration, machine  # noqa: E402

RESULTS = ROOT / "benchmarks/results/levels_realtime.json"
BUILDING = ROOT / "models/two_floor_clinic/two_floor_clinic.building.yaml"


def run(scenario, duration: float, slice_s: float) -> dict:
    """Run ``scenario`` ``duration`` s in slices: start-up and per-slice CPU and wall s, and
    the run's summary figures."""
    cpu0, wall0 = time.process_time(), time.perf_counter()
    stack = build_diagram(scenario)
    simulator = Simulator(stack.diagram)
    simulator.Initialize()
    startup = {"cpu_s": time.process_time() - cpu0, "wall_s": time.perf_counter() - wall0}
    slices, t = [], 0.0
    while t < duration - 1e-9:
        end = min(duration, t + slice_s)
        cpu, wall = time.process_time(), time.perf_counter()
        simulator.AdvanceTo(end)
        slices.append({"from": t, "to": end, "cpu_s": time.process_time() - cpu,
                       "wall_s": time.perf_counter() - wall})
        t = end
    stack.recorder.close()
    summary = summarize(stack, duration, sum(s["wall_s"] for s in slices),
                        sum(s["cpu_s"] for s in slices))
    tasks, safety = summary["tasks"], summary["safety"]
    return {"startup": startup, "slices": slices, "released": tasks["released"],
            "completed": tasks["completed"], "robot_robot_contacts":
            safety["robot_robot_contacts"], "robot_wall_contacts": safety["robot_wall_contacts"],
            "deadlocks": summary["deadlocks"]["count"], "lifts": summary["lifts"]}


def factors(slices: list[dict], until: float) -> dict:
    """Real-time factors (CPU and wall) of the slices up to ``until`` s."""
    chosen = [s for s in slices if s["to"] <= until + 1e-9]
    simulated = chosen[-1]["to"] - chosen[0]["from"]
    return {"until": until, "cpu": simulated / sum(s["cpu_s"] for s in chosen),
            "wall": simulated / sum(s["wall_s"] for s in chosen)}


def format_table(result: dict) -> str:
    lines = [f"{'slice s':>12s} {'CPU s':>7s} {'x (CPU)':>8s} {'wall s':>7s} {'x (wall)':>8s}"]
    for s in result["slices"]:
        span = s["to"] - s["from"]
        lines.append(f"{s['from']:5.0f}-{s['to']:<6.0f} {s['cpu_s']:7.2f} "
                     f"{span / s['cpu_s']:8.1f} {s['wall_s']:7.2f} {span / s['wall_s']:8.1f}")
    for f in result["factors"]:
        lines.append(f"first {f['until']:4.0f} s: {f['cpu']:.1f}x CPU, {f['wall']:.1f}x wall")
    lifts = ", ".join(f"{name} {entry['rides']} rides" for name, entry in
                      result["lifts"].items())
    lines.append(f"start-up {result['startup']['cpu_s']:.1f} s CPU; tasks "
                 f"{result['completed']}/{result['released']}; contacts "
                 f"{result['robot_robot_contacts']} robot-robot, {result['robot_wall_contacts']}"
                 f" robot-wall; deadlocks {result['deadlocks']}; {lifts}")
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--robots", type=int, default=10)
    parser.add_argument("--people", type=int, default=10)
    parser.add_argument("--duration", type=float, default=600.0)
    parser.add_argument("--slice", type=float, default=60.0, help="s per timed slice")
    parser.add_argument("--profile", help="run under cProfile, keeping the stats here")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        import_building(str(BUILDING), folder, ImportOptions(
            robots=args.robots, people=args.people, duration=args.duration))
        scenario = load_scenario(f"{folder}/scenario.yaml")
        run(scenario, 2.0, 2.0)  # loads the compiled kernels
        before = calibration()
        profiler = cProfile.Profile() if args.profile else None
        if profiler is not None:
            profiler.enable()
        result = run(scenario, args.duration, args.slice)
        if profiler is not None:
            profiler.disable()
            profiler.dump_stats(args.profile)
    result["factors"] = [factors(result["slices"], until) for until in
                         sorted({min(120.0, args.duration), args.duration})]
    result.update(scenario={"building": str(BUILDING.relative_to(ROOT)), "robots": args.robots,
                            "people": args.people, "duration": args.duration,
                            "robots_kind": "kinematic", "seed": 0},
                  calibration_ms=[before, calibration()], machine=machine(),
                  profiled=bool(args.profile), python=platform.python_version())
    print(format_table(result))
    if profiler is not None:
        pstats.Stats(args.profile).sort_stats("cumulative").print_stats("mrta_drake", 25)
        return  # a profiled run's times are not the benchmark's
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    with open(RESULTS, "w") as f:
        json.dump(result, f, indent=1)
        f.write("\n")
    print(f"written to {RESULTS.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
