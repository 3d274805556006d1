"""Soak: the busy six-robot hospital for an hour of simulated time, over several seeds.

Each seed runs in a fresh process (``mrta-sim``'s own ``simulate``, files written to
``--out``), while this script samples the child's resident memory (VmRSS) against the
simulated time it has reached (the last row of its ``timeline.csv``). It reports, per seed:
deadlock episodes, contacts of every kind, time with CBF slack in use, the smallest
robot-wall, robot-robot and robot-person gaps, and the memory growth from minute 10 to
minute 60 of simulated time. One more run is killed with SIGKILL halfway through, and its
files are checked: every complete timeline row and event line parses, and the rows reach
the time of the kill (a long run never loses its results).

    python benchmarks/soak.py [--seeds 101 102 103 104 105] [--duration 3600] [--workers 2]

Prints a table and writes ``benchmarks/results/soak.json``. The stream is the busy one of
``scenarios/sweeps/hospital_20_seeds.yaml`` (Poisson batches at 0.02 /s of 1-3 tasks) on top
of ``scenarios/hospital_6_robots.yaml``, with its people, arriving over the whole run; the
seeds are ones the sweeps do not use.
"""

import argparse
import concurrent.futures
import json
import os
import pathlib
import signal
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "hospital_6_robots.yaml"
RESULTS = ROOT / "benchmarks" / "results" / "soak.json"
BUSY_STREAM = {
    "tasks.generate": {
        "rate": 0.02,
        "batch_size": [1, 3],
        "slack": [2.0, 4.0],
        "pickup_weights": {"lobby": 3, "room_1": 1, "room_2": 1, "south_hall": 1, "room_4": 1,
                           "room_5": 1},
    },
}
SAMPLE_PERIOD = 1.0  # s of wall time between memory samples


def child(seed: int, duration: float, out_dir: str) -> None:
    """The run itself (in the child process): the busy hospital for ``duration`` s."""
    from mrta_drake.scenario.loading import load_scenario
    from mrta_drake.stack.simulate import simulate

    scenario = load_scenario(SCENARIO, overrides=BUSY_STREAM | {"seed": seed,
                                                               "duration": duration})
    simulate(scenario, out_dir=out_dir, plots=False)


def _start(seed: int, duration: float, out_dir: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, __file__, "--child", str(seed), "--duration",
                             str(duration), "--out", out_dir],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)


def _rss_mib(pid: int) -> float | None:
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        return None
    return None


def _sim_time(out_dir: str) -> float:
    """The simulated time of the last complete row of ``timeline.csv`` (0 before any)."""
    path = os.path.join(out_dir, "timeline.csv")
    try:
        with open(path, "rb") as f:
            f.seek(max(0, os.path.getsize(path) - 4096))
            lines = f.read().decode(errors="replace").splitlines()
    except OSError:
        return 0.0
    for line in reversed(lines[:-1] if lines else []):
        try:
            return float(line.split(",", 1)[0])
        except ValueError:
            continue
    return 0.0


def _watch(process: subprocess.Popen, out_dir: str, kill_at: float | None = None):
    """Memory samples [(sim time s, RSS MiB)] until the child ends (or is killed once its
    simulated time passes ``kill_at``)."""
    samples = []
    while process.poll() is None:
        sim, rss = _sim_time(out_dir), _rss_mib(process.pid)
        if rss is not None:
            samples.append((sim, rss))
        if kill_at is not None and sim >= kill_at:
            process.send_signal(signal.SIGKILL)
            process.wait()
            break
        time.sleep(SAMPLE_PERIOD)
    return samples


def _growth(samples, start: float, end: float) -> float | None:
    """RSS growth (%) from the first sample at or after ``start`` s to the last before ``end``
    s of simulated time: samples at ``end`` are taken after the simulation, while the run
    writes its summary (the whole timeline in memory at once, ~40 MiB for an hour), which
    is not growth of the running stack."""
    first = next((rss for t, rss in samples if t >= start), None)
    last = next((rss for t, rss in reversed(samples) if t < end), None)
    if first is None or last is None:
        return None
    return 100.0 * (last - first) / first


def soak_one(seed: int, duration: float, root: str) -> dict:
    out_dir = os.path.join(root, f"seed_{seed}")
    started = time.perf_counter()
    process = _start(seed, duration, out_dir)
    samples = _watch(process, out_dir)
    wall = time.perf_counter() - started
    if process.returncode != 0:
        return {"seed": seed, "error": process.stderr.read().strip().splitlines()[-1:]}
    with open(os.path.join(out_dir, "summary.json")) as f:
        summary = json.load(f)
    safety = summary["safety"]
    contacts = {kind: safety[f"{kind}_contacts"]
                for kind in ("robot_robot", "robot_wall", "robot_human")}
    return {
        "seed": seed,
        "wall_time": wall,
        "tasks_released": summary["tasks"]["released"],
        "tasks_completed": summary["tasks"]["completed"],
        "deadlock_episodes": summary["deadlocks"]["count"],
        "contacts": contacts,
        "cbf_slack_time": safety["cbf_slack_time"],
        "cbf_slack_fraction": safety["cbf_slack_time"] / duration,
        "min_robot_wall": safety["min_robot_wall"],
        "min_robot_robot": safety["min_robot_robot"],
        "min_robot_human": safety["min_robot_human"],
        "rss_growth_10_to_60_min_percent": _growth(samples, 600.0, 3600.0),
        "max_rss_mib": max((rss for _, rss in samples), default=None),
    }


def kill_check(duration: float, root: str, seed: int) -> dict:
    """Kill a run with SIGKILL halfway and check what it left on disk."""
    out_dir = os.path.join(root, "killed")
    process = _start(seed, duration, out_dir)
    _watch(process, out_dir, kill_at=duration / 2)
    rows, bad_rows, last_time = _check_lines(os.path.join(out_dir, "timeline.csv"), _row_time)
    events, bad_events, _ = _check_lines(os.path.join(out_dir, "events.jsonl"), _event_time)
    return {"killed_at": duration / 2, "timeline_rows": rows, "bad_timeline_rows": bad_rows,
            "last_row_time": last_time, "events": events, "bad_events": bad_events,
            "intact": bad_rows == 0 and bad_events == 0 and last_time >= duration / 2 - 1.0}


def _row_time(line: str) -> float:
    fields = line.split(",")
    if len(fields) != 6:
        raise ValueError(line)
    time_s, *_pose = (float(v) for v in (fields[0], *fields[2:]))
    return time_s


def _event_time(line: str) -> float:
    return float(json.loads(line).get("time", 0.0))


def _check_lines(path: str, parse) -> tuple[int, int, float]:
    """(complete lines, complete lines that do not parse, largest time): a last line without
    its newline was being written at the kill and is not counted."""
    with open(path, encoding="utf-8") as f:
        text = f.read()
    lines = text.split("\n")[:-1]  # the piece after the last newline is incomplete
    good, bad, last = 0, 0, 0.0
    for line in lines[1:] if path.endswith(".csv") else lines:
        try:
            last = max(last, parse(line))
            good += 1
        except (ValueError, KeyError):
            bad += 1
    return good, bad, last


def _table(rows: list[dict], killed: dict) -> str:
    header = (f"{'seed':>5} {'tasks':>9} {'deadlocks':>9} {'contacts r-r/w/h':>16} "
              f"{'slack %':>8} {'min wall m':>10} {'min robot m':>11} {'min human m':>11} "
              f"{'RSS +% 10-60':>12} {'wall s':>7}")
    lines = [header]
    for r in rows:
        if "error" in r:
            lines.append(f"{r['seed']:>5} error: {r['error']}")
            continue
        c = r["contacts"]
        growth = r["rss_growth_10_to_60_min_percent"]
        lines.append(
            f"{r['seed']:>5} {r['tasks_completed']:>4}/{r['tasks_released']:<4} "
            f"{r['deadlock_episodes']:>9} "
            f"{c['robot_robot']:>6}/{c['robot_wall']}/{c['robot_human']:<5} "
            f"{100 * r['cbf_slack_fraction']:>8.2f} {r['min_robot_wall']:>10.3f} "
            f"{r['min_robot_robot']:>11.3f} {_num(r['min_robot_human']):>11} "
            f"{_num(growth):>12} {r['wall_time']:>7.0f}")
    lines.append(f"killed at {killed['killed_at']:.0f} s: {killed['timeline_rows']} rows to "
                 f"{killed['last_row_time']:.1f} s, {killed['events']} events, "
                 f"{'intact' if killed['intact'] else 'DAMAGED'}")
    return "\n".join(lines)


def _num(value) -> str:
    return "-" if value is None else f"{value:.3f}" if abs(value) < 10 else f"{value:.1f}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[101, 102, 103, 104, 105])
    parser.add_argument("--duration", type=float, default=3600.0)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", default="")
    parser.add_argument("--child", type=int, default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child is not None:
        child(args.child, args.duration, args.out)
        return
    root = args.out or tempfile.mkdtemp(prefix="soak_")
    with concurrent.futures.ThreadPoolExecutor(args.workers) as pool:
        rows = list(pool.map(lambda s: soak_one(s, args.duration, root), args.seeds))
    killed = kill_check(min(args.duration, 600.0), root, args.seeds[0])
    print(_table(rows, killed))
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps({"duration": args.duration, "runs": rows, "kill": killed,
                                   "run_files": root}, indent=2))
    print(f"wrote {RESULTS.relative_to(ROOT)}; run files in {root}")


if __name__ == "__main__":
    main()
