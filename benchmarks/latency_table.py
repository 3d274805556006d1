"""The effect of network latency on the six-robot hospital: the table of docs/fidelity.md.

Reads the runs of the latency sweep (``scenarios/sweeps/hospital_latency.yaml``) and prints
one Markdown row per latency, over the sweep's seeds: tasks done of released and on time
(summed), mean task time (s, release to drop-off, over the tasks done), the smallest
robot-robot, robot-wall and robot-human clearances (m, over the runs), contacts (summed),
deadlock episodes (summed), and, over a network, the age of information (mean and largest,
s), the time the robots' views of a cluster disagreed and the robot-time followers braked
for want of a fresh command (s, mean per run).

    mrta-sim sweep scenarios/sweeps/hospital_latency.yaml --workers 2 --out sweeps/latency
    python benchmarks/latency_table.py sweeps/latency
"""

import argparse
import collections
import json
import pathlib
import statistics

HEADER = ("| latency (s) | runs | done / released | on time | mean task time (s) | "
          "min clearance robot-robot / wall / human (m) | contacts | deadlock episodes | "
          "age of information mean / max (s) | leaders disagree (s per run) | "
          "followers braking for want of a command (robot-s per run) |\n"
          "|---|---|---|---|---|---|---|---|---|---|---|")


def _runs(out: pathlib.Path) -> dict[float, list[dict]]:
    """The sweep's summaries by latency (s)."""
    by_latency = collections.defaultdict(list)
    for path in sorted(out.glob("runs/*/summary.json")):
        run = json.loads(path.with_name("run.json").read_text())
        latency = float(run["settings"]["communication.latency"])
        by_latency[latency].append(json.loads(path.read_text()))
    return dict(sorted(by_latency.items()))


def _row(latency: float, summaries: list[dict]) -> str:
    tasks = [s["tasks"] for s in summaries]
    done = [t for s in summaries for t in s["tasks"]["per_task"]
            if t["actual_dropoff"] is not None]
    safety = [s["safety"] for s in summaries]
    clearances = " / ".join(f"{min(x[f'min_robot_{kind}'] for x in safety):.2f}"
                            for kind in ("robot", "wall", "human"))
    contacts = sum(x[f"robot_{kind}_contacts"] for x in safety
                   for kind in ("robot", "wall", "human"))
    comms = [s["communication"] for s in summaries if s["communication"]]
    network = ("ideal | - | -" if not comms else
               f"{statistics.mean(c['age_of_information']['mean'] for c in comms):.2f} / "
               f"{max(c['age_of_information']['max'] for c in comms):.2f} | "
               f"{statistics.mean(c['leader_disagreement_time'] for c in comms):.1f} | "
               f"{statistics.mean(c['stale_command_time'] for c in comms):.1f}")
    mean_time = statistics.mean(t["actual_dropoff"] - t["arrival"] for t in done)
    return (f"| {latency:g} | {len(summaries)} | "
            f"{sum(t['completed'] for t in tasks)} / {sum(t['released'] for t in tasks)} | "
            f"{sum(t['on_time'] for t in tasks)} | {mean_time:.1f} | {clearances} | "
            f"{contacts} | {sum(s['deadlocks']['count'] for s in summaries)} | {network} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=pathlib.Path, help="the sweep's --out folder")
    args = parser.parse_args()
    print(HEADER)
    for latency, summaries in _runs(args.out).items():
        print(_row(latency, summaries))


if __name__ == "__main__":
    main()
