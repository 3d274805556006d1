"""Real-time factor of the full stack, headless, for 2 to 100 robots, both robot backends.

The whole stack of ``scenarios/hospital_6_robots.yaml`` (SMT allocator, waypoint generators,
room queues, shared grid planner, cluster CBF controller, social-force people, run recorder)
runs with N robots and a task load and crowd proportional to N:

- one hospital floor holds up to ``FLOOR_ROBOTS`` (25) robots: the paper's six at the six
  locations, the others on the roadway lanes (seeded spots at least 1.5 m from every
  location's point, queue and parking spot and 1.2 m from each other, heading along the
  lane);
- beyond that (50, 100 robots) the hospital has several identical floors of equal fleets
  (2 x 25, 4 x 25): every floor is a complete stack (its own allocator, planner, controller,
  people) and all floors are subsystems of one Drake diagram run by one ``Simulator``;
  robots never change floors (there are no lifts), so this is the same work as one building
  of several floors;
- people: 5/3 per robot (10 for 6 robots, as in the scenario): the scenario's 8 walkers
  (fewer for fewer robots), its 2 visitors, and more visitors walking between points in
  the lobby and the corridors;
- tasks: a generated stream (``tasks.generate``, the floor's seed): a batch of 2-3 tasks
  every 240/n s (every 40 s for 6 robots, as the paper's stream of 5 tasks in 40 s), from
  t = 0 to the end, deadlines 2-4 x the estimated travel time.

Start-up (loading, building the diagram, ``Simulator.Initialize``, which runs the first
allocation) is timed apart from the simulation of ``--duration`` s. Real-time factor =
simulated time / time spent simulating, for CPU time (``time.process_time``, the main figure
on a shared machine) and wall-clock time; each figure is the best of ``--repeats`` runs.
First, the quickstart command (``mrta-sim run scenarios/hospital_6_robots.yaml --duration
60``) runs twice in fresh processes, timed whole (start-up included): with an empty
``NUMBA_CACHE_DIR`` (the first run after installing, which compiles the kernels) and then
warm (``--no-first-run`` skips it), each with the load average of the minute before it ended
and the compile time the command announced. Each row, and the quickstart, names its scenario
variant.

A warm-up run and one CBF-QP solve first load the compiled (numba) kernels from their cache.
A fixed calibration workload (``calibration``), timed before and after the runs, records how
fast the shared host ran, so that figures taken at different hours can be compared.

With pyinstrument installed (the ``dev`` extra), the runs with ``--profile-robots`` robots
go on for ``--profile-duration`` s more under the sampling profiler, and the time is split
by the module of ``mrta_drake`` whose code the simulator called (a block's event handler,
named after its module, or a compiled kernel sampled on its own); "framework"
is what Drake's simulator and systems framework spend outside the blocks' Python code;
``qp_solver_share`` is the part of the controller's time inside Drake's ``Solve``
(Clarabel).

    python benchmarks/realtime.py [--robots 2,4,6] [--backend kinematic,physics]
                                  [--duration 60] [--repeats 1] [--quick] [--no-first-run]
                                  [--qp-solver active_set]

``--qp-solver`` runs every row with that controller ``qp.solver`` (named in the rows'
variants) instead of the default.

Prints a table and writes benchmarks/results/realtime.json.
"""

import argparse
import importlib.metadata
import json
import math
import os
import pathlib
import platform
import re
import resource
import subprocess
import sys
import tempfile
import threading
import time

import numpy as np
import yaml
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from mrta_drake import load_scenario
from mrta_drake.control.qp_solver import SOLVERS
from mrta_drake.stack.diagram import build_diagram

ROOT = pathlib.Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "mrta_drake"
RESULTS = ROOT / "benchmarks/results/realtime.json"
SCENARIO = ROOT / "scenarios/hospital_6_robots.yaml"
NAVIGATION = ROOT / "models/hospital/navigation.yaml"
FLOOR_PLAN = ROOT / "models/hospital/floor_plan.yaml"
ROBOTS = (2, 4, 6, 12, 25, 50, 100)
FLOOR_ROBOTS = 25
PEOPLE_PER_ROBOT = 10 / 6
TASK_PERIOD = 240.0  # s x robots between task batches
# Where the extra visitors walk: the lobby and the corridors.
VISITOR_POINTS = [[-3.0, 9.0], [3.0, 9.0], [-5.0, 3.0], [0.0, 12.0], [5.0, -5.0],
                  [-5.0, -5.0], [5.0, -18.0], [-5.0, -18.0], [0.0, -14.6], [0.0, -8.5]]
GOALS = {6: 88.0, 25: 40.0, 50: 5.0, 100: 10.0}  # the issues' real-time factor goals
PAPER = {2: 0.73, 4: 0.56, 6: 0.42}  # MRTA-Sim (Gazebo, ROS 2), Table III
QUICKSTART = ["run", "scenarios/hospital_6_robots.yaml", "--duration", "60", "--quiet"]
QUICKSTART_GOALS = {"cold": 15.0, "warm": 4.0}  # issue 18: wall s of the whole command


def lane_spots(roadways: dict, locations: list, people: list, count: int,
               seed: int) -> list[list[float]]:
    """``count`` start poses [x, y, theta] on the roadway lanes (see the module docstring),
    also 1.5 m clear of the points ``people`` may start at."""
    nodes = {name: np.array(xy, dtype=float) for name, xy in roadways["nodes"].items()}
    candidates = []
    for a, b in roadways["edges"]:
        step = nodes[b] - nodes[a]
        length = float(np.hypot(*step))
        heading = math.atan2(step[1], step[0])
        for s in np.arange(0.75, length - 0.5, 1.5):
            candidates.append([*(nodes[a] + step * (s / length)), heading])
    keep_out = people + [p for loc in locations for p in
                         [loc["point"], *loc.get("queue", []), *loc.get("parking", [])]]
    chosen: list[list[float]] = []
    for k in np.random.default_rng(seed).permutation(len(candidates)):
        if len(chosen) == count:
            return chosen
        xy = np.array(candidates[k][:2])
        if (min(np.hypot(*(xy - np.array(p))) for p in keep_out) >= 1.5
                and all(np.hypot(*(xy - np.array(c[:2]))) >= 1.2 for c in chosen)):
            chosen.append([round(float(v), 3) for v in candidates[k]])
    if len(chosen) < count:
        raise SystemExit(f"only {len(chosen)} lane spots for {count} robots")
    return chosen


def floor_scenario(robots: int, backend: str, seed: int, duration: float, folder: str,
                   qp_solver: str | None = None):
    """The scenario of one floor with ``robots`` robots (see the module docstring);
    ``qp_solver``: the controller's ``qp.solver`` (None: the default)."""
    base = yaml.safe_load(SCENARIO.read_text())
    navigation = yaml.safe_load(NAVIGATION.read_text())
    fleet = [dict(r) for r in base["robots"][:robots]]
    starts = [w["waypoints"][0] for w in base["humans"]["walkers"]] + VISITOR_POINTS + [
        p for g in base["humans"]["groups"] for p in g["points"]]
    spots = lane_spots(navigation["roadways"], navigation["locations"], starts,
                       max(0, robots - len(fleet)), seed)
    fleet += [{"name": f"robot{len(fleet) + k + 1}", "start": spot}
              for k, spot in enumerate(spots)]
    people = round(PEOPLE_PER_ROBOT * robots)
    walkers = base["humans"]["walkers"][:people]
    groups = [dict(g) for g in base["humans"]["groups"]]
    groups[0]["count"] = min(groups[0]["count"], people - len(walkers))
    extra = people - len(walkers) - groups[0]["count"]
    if extra > 0:
        groups.append({"kind": "visitors", "count": extra, "points": VISITOR_POINTS})
    groups = [g for g in groups if g["count"] > 0]
    period = TASK_PERIOD / robots
    raw = {
        "world": {"floor_plan": str(FLOOR_PLAN)}, "locations": str(NAVIGATION),
        "roadways": str(NAVIGATION), "robots": fleet,
        "humans": {"walkers": walkers, "groups": groups},
        "tasks": {"generate": {"times": [round(k * period, 3) for k in
                                         range(math.ceil(duration / period))],
                               "batch_size": [2, 3]}},
        "seed": seed, "duration": duration,
    }
    blocks = {}
    if backend != "kinematic":
        blocks["robots"] = {"kind": backend}
    if qp_solver is not None:
        blocks["controller"] = {"params": {"qp": {"solver": qp_solver}}}
    if blocks:
        raw["blocks"] = blocks
    solver = "" if qp_solver is None else f"_{qp_solver}"
    path = os.path.join(folder, f"floor_{robots}_{backend}_{seed}{solver}.yaml")
    with open(path, "w") as f:
        yaml.safe_dump(raw, f, sort_keys=False)
    return load_scenario(path)


def build(robots: int, backend: str, duration: float, seed: int, folder: str,
          qp_solver: str | None = None):
    """(simulator, stacks, floors, people) of ``robots`` robots on as many floors as needed
    (``qp_solver`` as for ``floor_scenario``)."""
    floors = math.ceil(robots / FLOOR_ROBOTS)
    if robots % floors:
        raise SystemExit(f"{robots} robots do not split evenly over {floors} floors")
    scenarios = [floor_scenario(robots // floors, backend, seed + k, duration, folder,
                                qp_solver) for k in range(floors)]
    stacks = [build_diagram(s) for s in scenarios]
    if floors == 1:
        diagram = stacks[0].diagram
    else:
        builder = DiagramBuilder()
        for k, stack in enumerate(stacks):
            builder.AddNamedSystem(f"floor_{k}", stack.diagram)
        diagram = builder.Build()
    simulator = Simulator(diagram)
    simulator.Initialize()
    people = sum(len(s.humans.walkers) + sum(g.count for g in s.humans.groups)
                 for s in scenarios)
    tasks = sum(len(batch.tasks) for s in scenarios for batch in s.tasks.stream)
    return simulator, stacks, floors, people, tasks


def variant(robots: int, floors: int, backend: str, qp_solver: str | None = None) -> str:
    """The scenario variant behind a row, in words."""
    per_floor = robots // floors
    fleet = "the scenario's robots" if per_floor <= 6 else "the scenario's 6 + lane spots"
    where = "1 hospital floor" if floors == 1 else f"{floors} copies of the hospital floor"
    solver = "" if qp_solver is None else f", qp.solver {qp_solver}"
    return f"{where}, {fleet}, {backend} robots{solver}"


def quickstart(cache: str) -> dict:
    """Wall and CPU s of the whole quickstart command (``mrta-sim run
    scenarios/hospital_6_robots.yaml --duration 60``) in a fresh process, start-up included;
    ``cache`` is the numba cache folder (empty: the first run after installing)."""
    env = dict(os.environ, NUMBA_CACHE_DIR=cache, PYTHONPATH=os.pathsep.join(
        [str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])]))
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    wall = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "mrta_drake.tools.cli", *QUICKSTART],
                          cwd=ROOT, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - wall
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode:
        raise SystemExit(f"quickstart failed: {done.stderr.strip()}")
    cpu = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
    announced = re.search(r"compiling kernels, once, ~(\d+) s", done.stderr)
    return {"wall_s": wall, "cpu_s": cpu, "load_average": os.getloadavg()[0],
            "announced_s": int(announced.group(1)) if announced else None}


def first_run() -> dict:
    """The quickstart command cold (an empty numba cache) and then warm (the same cache)."""
    with tempfile.TemporaryDirectory() as cache:
        cold = quickstart(cache)
        warm = quickstart(cache)
    for label, row in (("cold", cold), ("warm", warm)):
        row["goal_wall_s"] = QUICKSTART_GOALS[label]
        said = "nothing" if row["announced_s"] is None else f"~{row['announced_s']} s"
        print(f"quickstart {label:<5} wall {row['wall_s']:6.1f} s  CPU {row['cpu_s']:6.1f} s"
              f"  (goal <= {row['goal_wall_s']:.0f} s wall; announced {said}; load average "
              f"{row['load_average']:.1f})", flush=True)
    return {"command": "mrta-sim " + " ".join(QUICKSTART),
            "variant": "the scenario as written: " + variant(6, 1, "kinematic"),
            "cold": cold, "warm": warm}


def run(robots: int, backend: str, duration: float, seed: int, folder: str,
        profile_duration: float = 0.0, qp_solver: str | None = None) -> dict:
    cpu, wall = time.process_time(), time.perf_counter()
    simulator, stacks, floors, people, tasks = build(robots, backend, duration, seed, folder,
                                                     qp_solver)
    for thread in threading.enumerate():  # start-up work in the background (the planner's
        if thread is not threading.main_thread():  # landmark searches) counts as start-up
            thread.join(timeout=60.0)
    startup = (time.process_time() - cpu, time.perf_counter() - wall)
    cpu, wall = time.process_time(), time.perf_counter()
    simulator.AdvanceTo(duration)
    cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
    arrivals = sum(1 for stack in stacks for e in stack.recorder.events
                   if e["type"] == "arrival")
    result = {"robots": robots, "backend": backend, "floors": floors,
              "variant": variant(robots, floors, backend, qp_solver), "people": people,
              "tasks_released": tasks, "stops_completed": arrivals,
              "startup_cpu_s": startup[0], "startup_wall_s": startup[1],
              "sim_cpu_s": cpu, "sim_wall_s": wall,
              "rtf_cpu": duration / cpu, "rtf_wall": duration / wall}
    if profile_duration > 0:
        result["profile"] = profile(simulator, duration + profile_duration)
    return result


def profile(simulator, until: float) -> dict:
    """Seconds (wall, under the profiler) per block from ``simulator``'s time to ``until``."""
    from pyinstrument import Profiler

    profiler = Profiler(interval=0.001)
    start = simulator.get_context().get_time()
    profiler.start()
    simulator.AdvanceTo(until)
    profiler.stop()
    root = profiler.last_session.root_frame()
    blocks: dict[str, float] = {}
    functions: dict[str, float] = {}

    def walk(frame):
        path = pathlib.Path(frame.file_path or "")
        if PACKAGE in path.parents:
            block = path.stem
            blocks[block] = blocks.get(block, 0.0) + frame.time
            return
        for child in frame.children:
            walk(child)

    def leaves(frame):
        if not frame.is_synthetic and frame.total_self_time > 0:
            key = f"{frame.function} ({pathlib.Path(frame.file_path or '?').name})"
            functions[key] = functions.get(key, 0.0) + frame.total_self_time
        for child in frame.children:
            leaves(child)

    def solver(frame) -> float:
        if frame.function.rsplit(".", 1)[-1] == "Solve":  # Drake's Solve (PyCapsule.Solve)
            return frame.time
        return sum(solver(child) for child in frame.children)

    walk(root)
    leaves(root)
    total = root.time
    blocks["framework"] = total - sum(blocks.values())
    top = sorted(functions.items(), key=lambda kv: -kv[1])[:15]
    return {"simulated_s": until - start, "profiled_s": total,
            "share": {k: v / total for k, v in sorted(blocks.items(), key=lambda kv: -kv[1])},
            "qp_solver_share": solver(root) / total,
            "top_self": [{"function": k, "share": v / total} for k, v in top]}


def warm_up_qp(qp_solver: str | None = None) -> None:
    """One CBF-QP that needs the solver (the short warm-up run may solve none), so that its
    kernels are loaded before the timed runs (``qp_solver``'s; None: the default
    ``qp.solver``'s)."""
    from mrta_drake.control.qp_solver import CbfQp, QpParams

    solution = CbfQp(qp_solver or QpParams().solver).solve([[1.0, 0.0]], [[-1.0, 0.0]], [0.5],
                                              [[-1.0, -2.0]], [[1.0, 2.0]])
    assert solution.solved and solution.success


def calibration() -> float:
    """CPU ms of a fixed workload of small Python and numpy steps, like the stack's own
    (best of 5): how fast the shared host runs right now, so that figures taken at
    different hours can be compared (lower: faster host)."""
    a = np.arange(8.0)

    def work():
        total = 0.0
        for k in range(20000):
            total += float(np.dot(a, a)) * 1e-9 + k % 7
        return total

    best = math.inf
    for _ in range(5):
        start = time.process_time()
        work()
        best = min(best, time.process_time() - start)
    return best * 1e3


def machine() -> dict:
    model = ""
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    import numba

    return {"cpu_model": model, "cpus": os.cpu_count(), "python": platform.python_version(),
            "drake": importlib.metadata.version("drake"), "numpy": np.__version__,
            "numba": numba.__version__, "platform": platform.platform()}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--robots", default=",".join(map(str, ROBOTS)))
    parser.add_argument("--backend", default="kinematic,physics")
    parser.add_argument("--duration", type=float, default=60.0)
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--profile-robots", default="6,50")
    parser.add_argument("--profile-duration", type=float, default=20.0)
    parser.add_argument("--quick", action="store_true",
                        help="2 and 6 robots, kinematic, 20 s, no profile")
    parser.add_argument("--no-first-run", action="store_true",
                        help="skip the quickstart command cold and warm")
    parser.add_argument("--qp-solver", choices=SOLVERS, default=None,
                        help="the controller's qp.solver (default: the scenario's)")
    parser.add_argument("--out", type=pathlib.Path, default=RESULTS)
    args = parser.parse_args()
    if args.quick:
        args.robots, args.backend, args.duration, args.profile_robots = "2,6", "kinematic", \
            20.0, ""
    counts = [int(n) for n in args.robots.split(",") if n]
    backends = [b for b in args.backend.split(",") if b]
    profiled = {int(n) for n in args.profile_robots.split(",") if n}
    try:
        import pyinstrument  # noqa: F401
    except ImportError:
        print("pyinstrument is not installed: no profile")
        profiled = set()

    rows = []
    calibration_before = calibration()
    print(f"host calibration workload: {calibration_before:.1f} ms CPU", flush=True)
    first = None if args.no_first_run else first_run()
    with tempfile.TemporaryDirectory() as folder:
        run(2, "kinematic", 1.0, args.seed, folder)  # warm-up: compiled kernels, imports
        warm_up_qp(args.qp_solver)
        for backend in backends:
            for n in counts:
                runs = [run(n, backend, args.duration, args.seed, folder,
                            qp_solver=args.qp_solver) for _ in range(args.repeats)]
                best = max(runs, key=lambda r: r["rtf_cpu"])
                best["rtf_wall"] = max(r["rtf_wall"] for r in runs)
                if n in profiled:
                    best["profile"] = run(n, backend, args.duration, args.seed, folder,
                                          args.profile_duration, args.qp_solver)["profile"]
                best["goal"] = GOALS.get(n)
                best["paper"] = PAPER.get(n)
                rows.append(best)
                print(f"{backend:<10}{n:>5} robots {best['floors']} floor(s) "
                      f"{best['people']:>4} people  start-up {best['startup_cpu_s']:5.1f} s  "
                      f"RTF cpu {best['rtf_cpu']:6.2f}  wall {best['rtf_wall']:6.2f}  "
                      f"stops {best['stops_completed']}", flush=True)

    calibration_after = calibration()
    print(f"\n{args.duration:.0f} s simulated; real-time factor = simulated / spent "
          "(CPU; wall in brackets); host calibration workload "
          f"{calibration_before:.1f} ms before, {calibration_after:.1f} ms after")
    print(f"{'backend':<10}{'robots':>7}{'floors':>7}{'people':>7}{'start-up s':>11}"
          f"{'RTF':>9}{'(wall)':>9}{'goal':>7}{'paper':>7}")
    for r in rows:
        print(f"{r['backend']:<10}{r['robots']:>7}{r['floors']:>7}{r['people']:>7}"
              f"{r['startup_cpu_s']:>11.1f}{r['rtf_cpu']:>9.2f}{r['rtf_wall']:>9.2f}"
              f"{r['goal'] or '':>7}{r['paper'] or '':>7}  {r['variant']}")
    for r in rows:
        if "profile" in r:
            share = ", ".join(f"{k} {v:.0%}" for k, v in r["profile"]["share"].items())
            print(f"where the time goes, {r['backend']} {r['robots']} robots: {share}")

    args.out.parent.mkdir(parents=True, exist_ok=True)
    report = {"duration": args.duration, "repeats": args.repeats, "seed": args.seed,
              "qp_solver": args.qp_solver,
              "floor_robots": FLOOR_ROBOTS, "machine": machine(),
              "calibration_ms": {"before": calibration_before, "after": calibration_after},
              "first_run": first, "results": rows}
    args.out.write_text(json.dumps(report, indent=2) + "\n")
    print(f"wrote {args.out.relative_to(ROOT) if args.out.is_relative_to(ROOT) else args.out}")


if __name__ == "__main__":
    main()
