"""Every departure's measured effect: the table of docs/fidelity.md, by one command.

Runs the fidelity sweep (``scenarios/sweeps/hospital_fidelity_seeds.yaml``: the busy
six-robot hospital, seeds 300-319, 300 s) once with this project's defaults, once per
switch of ``profile: paper`` with that switch alone at the paper's value, and once with
``profile: paper`` (every switch), each into ``RUNS/<configuration>/`` (a sweep folder: runs
already done are reused, so a stopped run resumes; default
``benchmarks/results/fidelity_runs``). Then writes ``benchmarks/results/fidelity.json`` (per
configuration its fields, the commit measured and its figures; configurations measured
before are kept) and prints one Markdown row per
configuration, over the seeds: tasks done / on time / released (summed), deadlock episodes
(summed), contacts robot-robot / robot-wall / robot-human (summed), the smallest clearances
robot-robot / robot-wall / robot-human (m, over the runs), the CBF slack-in-use time (s,
summed: the time some barrier row was relaxed) and the CPU time (s, summed).

    nice -n 5 python benchmarks/fidelity_table.py [--runs RUNS] [--workers 2]
    python benchmarks/fidelity_table.py --only defaults waypoints.door_wait   # these alone
"""

import argparse
import dataclasses
import json
import pathlib
import subprocess

from mrta_drake.scenario.profiles import PAPER_SWITCHES
from mrta_drake.tools.sweep import load_sweep, run_sweep

ROOT = pathlib.Path(__file__).resolve().parents[1]
SPEC = ROOT / "scenarios/sweeps/hospital_fidelity_seeds.yaml"
RESULTS = ROOT / "benchmarks" / "results"
HEADER = ("| configuration | runs | done / on time / released | deadlock episodes | "
          "contacts r-r / r-wall / r-human | min clearance r-r / r-wall / r-human (m) | "
          "slack in use (s) | CPU (s) |\n|---|---|---|---|---|---|---|---|")


def configurations() -> dict[str, dict]:
    """Configuration name -> the scenario fields it sets: the defaults, each switch alone
    (named by its field without ``blocks.`` and ``params.``, e.g. ``watchdog.enabled``) and
    the paper profile."""
    switches = {short_name(switch.field): {switch.field: switch.value}
                for switch in PAPER_SWITCHES}
    return {"defaults": {}, **switches, "profile_paper": {"profile": "paper"}}


def short_name(field: str) -> str:
    """A scenario field's name without ``blocks.`` and ``.params``."""
    return field.removeprefix("blocks.").replace(".params.", ".")


def run_configuration(fields: dict, out: pathlib.Path, workers: int) -> tuple[list[dict], int]:
    """The fidelity sweep with ``fields`` set in every run (into ``out``): its summaries
    (the runs that failed are left out and reported) and how many runs it made (not
    reused)."""
    spec = load_sweep(str(SPEC))
    spec = dataclasses.replace(spec, fixed=spec.fixed | fields)
    result = run_sweep(spec, str(out), workers=workers)
    for row in result.rows:
        if row["status"] != "ok":
            print(f"{out.name}: seed {row['seed']} failed: {row['error']}")
    summaries = [json.loads(path.read_text()) for path in sorted(out.glob("runs/*/summary.json"))]
    return summaries, result.ran


def figures(summaries: list[dict]) -> dict:
    """The table's figures over ``summaries`` (sums, or the smallest clearance)."""
    safety = [s["safety"] for s in summaries]
    kinds = ("robot", "wall", "human")
    return {
        "runs": len(summaries),
        "seeds": [s["seed"] for s in summaries],
        **{key: sum(s["tasks"][key] for s in summaries)
           for key in ("completed", "on_time", "released")},
        "deadlock_episodes": sum(s["deadlocks"]["count"] for s in summaries),
        "contacts": {kind: sum(x[f"robot_{kind}_contacts"] for x in safety) for kind in kinds},
        "min_clearance": {kind: min(x[f"min_robot_{kind}"] for x in safety) for kind in kinds},
        "slack_time": sum(x["cbf_slack_time"] for x in safety),
        "cpu_time": sum(s["cpu_time"] for s in summaries),
    }


def row(name: str, fields: dict, result: dict) -> str:
    """One Markdown row of the table."""
    label = ", ".join(f"`{short_name(key)}: {_as_yaml(value)}`" for key, value in fields.items())
    contacts = " / ".join(str(n) for n in result["contacts"].values())
    clearances = " / ".join(f"{d:.2f}" for d in result["min_clearance"].values())
    return (f"| {label or name} | {result['runs']} | {result['completed']} / "
            f"{result['on_time']} / {result['released']} | {result['deadlock_episodes']} | "
            f"{contacts} | {clearances} | {result['slack_time']:.1f} | "
            f"{result['cpu_time']:.0f} |")


def _as_yaml(value) -> str:
    """A switch's value as YAML writes it (``false``, not ``False``)."""
    return json.dumps(value) if isinstance(value, bool) else str(value)


def commit() -> str:
    """The commit checked out (with ``+changes`` when the work tree differs from it)."""
    def git(*args):
        return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True,
                              check=True).stdout.strip()
    dirty = git("status", "--porcelain", "--untracked-files=no")
    return git("rev-parse", "--short", "HEAD") + ("+changes" if dirty else "")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=pathlib.Path, default=RESULTS / "fidelity_runs",
                        help="folder for the sweeps (default benchmarks/results/fidelity_runs)")
    parser.add_argument("--json", type=pathlib.Path, default=RESULTS / "fidelity.json",
                        help="the figures (default benchmarks/results/fidelity.json)")
    parser.add_argument("--workers", type=int, default=2, help="processes (default 2)")
    parser.add_argument("--only", nargs="+", metavar="NAME",
                        help="run only these configurations, in this order (default: all)")
    args = parser.parse_args()
    chosen = configurations()
    unknown = set(args.only or ()) - set(chosen)
    if unknown:
        parser.error(f"unknown configuration(s) {sorted(unknown)}; one of {sorted(chosen)}")
    if args.only:
        chosen = {name: chosen[name] for name in args.only}
    table = args.json
    results = json.loads(table.read_text())["configurations"] if table.exists() else {}
    for name, fields in chosen.items():
        summaries, ran = run_configuration(fields, args.runs / name, args.workers)
        measured = commit() if ran or name not in results else results[name]["commit"]
        results[name] = {"fields": fields, "commit": measured, **figures(summaries)}
        table.write_text(json.dumps({"spec": str(SPEC.relative_to(ROOT)),
                                     "configurations": results}, indent=2))
    print(f"{table}; commits {sorted({r['commit'] for r in results.values()})}")
    print(HEADER)
    for name, result in results.items():
        print(row(name, result["fields"], result))


if __name__ == "__main__":
    main()
