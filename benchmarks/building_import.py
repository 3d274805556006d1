"""Import time of Open-RMF buildings, and optionally a run of each single-level one.

For each ``*.building.yaml`` in a folder (e.g. the maps of a checkout of Open-RMF's
rmf_demos, which this repository does not hold): the time to read and check the file and
bring it to metres (``load_building``), then per level the world (``level_world``) and the
navigation of graph 0 (``level_navigation``; a level whose graph 0 gives no runnable
navigation is noted). The goal: the airport terminal, the largest demo, under 10 s.

With ``--run S``, each single-level building is also imported with ``--robots`` robots
(``mrta-sim import``) and run for S s: tasks completed of those released, contacts
(robot-robot, robot-wall) and deadlocks (robots stuck 30 s with somewhere to go).

Times are wall-clock seconds (``time.perf_counter``) of one import in a fresh process for
each building, numba's compiled code loaded from its cache. Run from the repository root:
``python benchmarks/building_import.py FOLDER [--run 600] [--robots 6]``; prints a table
and writes ``benchmarks/results/building_import.json``.
"""

import argparse
import json
import pathlib
import platform
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks/results/building_import.json"


def time_import(path: str) -> dict:
    """Import times (s) of the building in ``path``, in this process."""
    from mrta_drake.errors import InputError
    from mrta_drake.world.rmf_building import load_building
    from mrta_drake.world.rmf_navigation import level_navigation
    from mrta_drake.world.rmf_world import level_world

    tic = time.perf_counter()
    building = load_building(path)
    row = {"load_s": time.perf_counter() - tic, "levels": {}}
    for name, level in building.levels.items():
        tic = time.perf_counter()
        world = level_world(building, name)
        entry = {"world_s": time.perf_counter() - tic, "walls": len(level.walls),
                 "lanes": len(level.lanes), "obstacles": len(world.floor_plan.obstacles)}
        tic = time.perf_counter()
        try:
            navigation = level_navigation(building, name, world.floor_plan)
            entry["locations"] = len(navigation.locations)
        except InputError as error:
            entry["note"] = str(error).split(": ", 2)[-1]
        entry["navigation_s"] = time.perf_counter() - tic
        row["levels"][name] = entry
    row["total_s"] = row["load_s"] + sum(e["world_s"] + e["navigation_s"]
                                         for e in row["levels"].values())
    return row


def run_imported(path: str, robots: int, duration: float) -> dict:
    """Import ``path`` with ``robots`` robots and run it ``duration`` s: its results."""
    from mrta_drake import load_scenario, simulate
    from mrta_drake.tools.building_import import ImportOptions, import_building

    with tempfile.TemporaryDirectory() as folder:
        import_building(path, folder, ImportOptions(robots=robots))
        summary = simulate(load_scenario(f"{folder}/scenario.yaml"), duration=duration,
                           plots=False).summary
    tasks, safety = summary["tasks"], summary["safety"]
    return {"duration": duration, "robots": robots, "released": tasks["released"],
            "completed": tasks["completed"], "robot_robot_contacts":
            safety["robot_robot_contacts"], "robot_wall_contacts": safety["robot_wall_contacts"],
            "deadlocks": summary["deadlocks"]["count"], "wall_s": summary["wall_time"]}


def child(path: str, run: float, robots: int) -> None:
    """In a fresh process: one building's row as JSON on stdout."""
    row = time_import(path)
    if run > 0 and len(row["levels"]) == 1 and "note" not in next(iter(
            row["levels"].values())):
        row["run"] = run_imported(path, robots, run)
    print(json.dumps(row))


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("folder", type=pathlib.Path, help="folder of *.building.yaml files")
    parser.add_argument("--run", type=float, default=0.0, help="also run each single-level "
                        "building this many s (default: no runs)")
    parser.add_argument("--robots", type=int, default=6)
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(args.child, args.run, args.robots)
        return
    paths = sorted(args.folder.glob("*.building.yaml"))
    if not paths:
        raise SystemExit(f"{args.folder}: no *.building.yaml files")
    rows = {}
    for path in paths:
        result = subprocess.run([sys.executable, __file__, str(args.folder), "--child",
                                 str(path), "--run", str(args.run), "--robots",
                                 str(args.robots)], capture_output=True, text=True)
        if result.returncode != 0:
            raise SystemExit(f"{path}: {result.stderr.strip().splitlines()[-1]}")
        rows[path.name.removesuffix(".building.yaml")] = json.loads(
            result.stdout.strip().splitlines()[-1])
    print(format_table(rows))
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    with open(RESULTS, "w") as f:
        json.dump({"machine": platform.platform(), "processor": platform.processor(),
                   "maps": rows}, f, indent=1)
        f.write("\n")
    print(f"written to {RESULTS.relative_to(ROOT)}")


def format_table(rows: dict) -> str:
    lines = [f"{'map':18s} {'levels':>6s} {'load s':>7s} {'world s':>8s} {'nav s':>6s} "
             f"{'total s':>8s} {'locs':>5s}  run: completed/released, contacts, deadlocks"]
    for name, row in rows.items():
        levels = row["levels"].values()
        locations = "/".join(str(e.get("locations", "-")) for e in levels)
        run = row.get("run")
        ran = (f"  {run['completed']}/{run['released']}, {run['robot_robot_contacts']} + "
               f"{run['robot_wall_contacts']}, {run['deadlocks']}" if run else "")
        lines.append(f"{name:18s} {len(row['levels']):6d} {row['load_s']:7.2f} "
                     f"{sum(e['world_s'] for e in levels):8.2f} "
                     f"{sum(e['navigation_s'] for e in levels):6.2f} {row['total_s']:8.2f} "
                     f"{locations:>5s}{ran}")
    return "\n".join(lines)


if __name__ == "__main__":
    main()
