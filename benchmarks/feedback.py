"""Feedback benchmark: the open loop against each way of closing it (docs/allocation.md).

The cases below, each run with every variant of the allocator's feedback switches
(``FeedbackParams``):

- busy: the six-robot hospital with people for 300 s under the generated task stream of
  ``scenarios/sweeps/hospital_20_seeds.yaml``, over 20 seeds the sweeps do not use
  (200-219); busy_check: the same on forty further seeds (220-259, ``--check-seeds``), to
  check a default chosen on the first twenty; busy_pooled: both together (printed and
  stored when both ran, with each block of 20 seeds' on-time change); busy_unseen: twenty
  more (260-279, ``--unseen-seeds``), run once a default is chosen, not pooled;
- paper: ``scenarios/hospital_6_robots.yaml`` as it is (its 3+2 stream, the ten people),
  600 s;
- six_plus_six: ``scenarios/hospital_6_plus_6.yaml`` (a 6+6 stream after the original's
  pattern, the ten people), 450 s;
- two_floor: ``scenarios/two_floor_6_robots.yaml`` (the two-level clinic with lifts, its
  generated stream), 600 s.

Each variant is one sweep (``mrta_drake.tools.sweep``: fresh processes), the variants'
sweeps side by side with ``--workers`` processes in all, resumable from
``benchmarks/results/feedback_runs/``. Per case and variant: tasks
completed, on time and late; broken promises (tasks planned on time at their last
allocation that missed their deadline); drop-off and leg prediction errors pooled over the
runs (median and p90 of the absolute error, mean signed error); re-plans on drift; and
each variant's change of on-time tasks and broken promises against the open loop.

    python benchmarks/feedback.py                 # everything (hours on 2 shared cores)
    python benchmarks/feedback.py --seeds 4 --variants "open loop" "learn only"
    python benchmarks/feedback.py --cases two_floor paper --variants "open loop"
    python benchmarks/feedback.py --cases busy_check --check-seeds 220 221 222
    python benchmarks/feedback.py --cases busy_unseen --variants "open loop"

Prints the tables and writes benchmarks/results/feedback.json, keeping the variants and
cases an earlier invocation wrote there and this one did not run.
"""

import argparse
import json
import pathlib
import sys
from concurrent.futures import ThreadPoolExecutor

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))

from mrta_drake.results.predictions import error_stats  # noqa: E402
from mrta_drake.results.report import text_table  # noqa: E402
from mrta_drake.tools.sweep import SweepSpec, load_sweep, run_sweep  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
RUNS = RESULTS / "feedback_runs"
BUSY_SWEEP = ROOT / "scenarios" / "sweeps" / "hospital_20_seeds.yaml"
PAPER = ROOT / "scenarios" / "hospital_6_robots.yaml"
SINGLE_RUNS = {"paper": PAPER, "six_plus_six": ROOT / "scenarios" / "hospital_6_plus_6.yaml",
               "two_floor": ROOT / "scenarios" / "two_floor_6_robots.yaml"}
SEEDS = list(range(200, 220))
CHECK_SEEDS = list(range(220, 260))
UNSEEN_SEEDS = list(range(260, 280))
PARAMS = "blocks.allocator.params."

OFF = {"earliest_drop_offs": False, "write_off_lateness": None,  # the switches a variant
       "replan_only_if_fewer_late": False, "travel_time_rounding": "up",  # leaves unless set
       "safety_slack": 0.0}
# Switches added after runs were cached, at the value those runs had: left out of a run
# directory's name at that value, so the cached runs stay valid.
IMPLIED = {"safety_slack": 0.0}
DRIFT_10 = OFF | {"learn_travel_times": True, "replan_on_delay": True, "retime_on_drift": False,
                  "drift_margin": 10.0}  # an earlier default: allocate again on a 10 s drift
LOOP = OFF | {"learn_travel_times": True, "replan_on_delay": True, "retime_on_drift": True,
              "drift_margin": 3.0}  # learn, re-plan when late, re-time on a 3 s drift
EARLIEST = LOOP | {"earliest_drop_offs": True}
PREVIOUS = EARLIEST | {"drift_margin": 1.0}  # the default before write-offs
PREVIOUS_DEFAULT = ("previous default: loop, earliest drop-offs, write off 5 s late, re-plan "
                    "only for fewer late, nearest-second travel times, no safety slack")
DEFAULT = ("default: loop, earliest drop-offs, write off 5 s late, re-plan only for fewer "
           "late, nearest-second travel times, 10 s safety slack")
BEFORE_SLACK = PREVIOUS | {"write_off_lateness": 5.0, "replan_only_if_fewer_late": True,
                           "travel_time_rounding": "nearest"}
VARIANTS = {  # name -> allocator params set (every switch the defaults could change)
    "open loop": OFF | {"learn_travel_times": False, "replan_on_delay": False},
    "learn only": OFF | {"learn_travel_times": True, "replan_on_delay": False},
    "re-plan only, 10 s drift": DRIFT_10 | {"learn_travel_times": False},
    "learn + re-plan, 10 s drift": DRIFT_10,
    "loop: learn + re-plan when late, re-time on 3 s drift": LOOP,
    "loop, quantile 0.8": LOOP | {"travel_time_estimator": "quantile"},
    "loop, recent-weighted": LOOP | {"travel_time_estimator": "recent"},
    "loop, 3 s margin": LOOP | {"planning_margin": 3.0},
    "loop, 6 s margin": LOOP | {"planning_margin": 6.0},
    "loop, smt objective lateness": LOOP | {"objective": "lateness"},
    "loop, earliest drop-offs": EARLIEST,
    "loop, earliest drop-offs, 3 s margin": EARLIEST | {"planning_margin": 3.0},
    "previous default: loop, earliest drop-offs, re-time on 1 s drift": PREVIOUS,
    "previous default, write off 5 s late": PREVIOUS | {"write_off_lateness": 5.0},
    "previous default, write off 5 s late, re-plan only for fewer late": PREVIOUS | {
        "write_off_lateness": 5.0, "replan_only_if_fewer_late": True},
    PREVIOUS_DEFAULT: BEFORE_SLACK,
    "previous default, write off 10 s late": BEFORE_SLACK | {"write_off_lateness": 10.0},
    "previous default, smt objective lateness": BEFORE_SLACK | {"objective": "lateness"},
    DEFAULT: BEFORE_SLACK | {"safety_slack": 10.0},
}


def run_case(name: str, spec: SweepSpec, variant: dict, workers: int) -> list[dict]:
    """The summaries of ``spec``'s runs with the allocator params ``variant``."""
    fixed = dict(spec.fixed) | {PARAMS + key: value for key, value in variant.items()}
    spec = SweepSpec(spec.scenario, spec.grid, fixed, spec.plugins, spec.source)
    slug = "_".join(f"{key}={value}" for key, value in sorted(variant.items())
                    if key not in IMPLIED or IMPLIED[key] != value)
    out = RUNS / name / slug
    result = run_sweep(spec, str(out), workers=workers)
    summaries = []
    for row in result.rows:
        path = out / "runs" / row["run_id"] / "summary.json"
        if row["status"] != "ok" or not path.is_file():
            raise RuntimeError(f"{name} {slug} {row['run_id']}: {row.get('error')}")
        summaries.append(json.loads(path.read_text()))
    return summaries


def figures(summaries: list[dict]) -> dict:
    """A variant's figures over its runs (see the module docstring)."""
    tasks = [t for s in summaries for t in s["tasks"]["per_task"]]
    done = [t for t in tasks
            if t["actual_dropoff"] is not None and t["predicted_dropoff"] is not None]
    legs = [leg for s in summaries for leg in s["legs"] if leg["predicted"] is not None]
    return {
        "runs": len(summaries),
        "seeds": [s["seed"] for s in summaries],
        "on_time_per_run": [s["tasks"]["on_time"] for s in summaries],
        "completed": sum(s["tasks"]["completed"] for s in summaries),
        "on_time": sum(s["tasks"]["on_time"] for s in summaries),
        "late": sum(s["tasks"]["late"] for s in summaries),
        "missed": sum(s["tasks"]["missed"] for s in summaries),
        "promised": sum(s["predictions"]["promised"] for s in summaries),
        "broken_promises": sum(len(s["predictions"]["broken_promises"]) for s in summaries),
        "replans": sum(s["predictions"]["replans"]["count"] for s in summaries),
        "dropoff_error": error_stats([t["actual_dropoff"] - t["predicted_dropoff"]
                                      for t in done]),
        "leg_error": error_stats([leg["actual"] - leg["predicted"] for leg in legs]),
    }


def table(results: dict) -> str:
    rows = []
    for variant, f in results.items():
        drop, leg = f["dropoff_error"], f["leg_error"]
        rows.append([variant, f["runs"], f["completed"], f["on_time"], f["late"], f["missed"],
                     f["broken_promises"], f"{drop['median_abs']:.1f}",
                     f"{drop['p90_abs']:.1f}", f"{drop['bias']:+.1f}",
                     f"{leg['median_abs']:.1f}", f"{leg['bias']:+.1f}", f["replans"]])
    return text_table(["variant", "runs", "completed", "on time", "late", "missed",
                       "broken promises", "drop |med| s", "drop |p90| s", "drop bias s",
                       "leg |med| s", "leg bias s", "re-plans"], rows)


def report(output: dict, case: str, results: dict):
    """Prints ``case``'s table, with each variant's on-time change against the open loop
    when it ran, and stores ``results`` in ``output``."""
    output["cases"][case] = output["cases"].get(case, {}) | results
    print(f"\n{case}\n{table(results)}", flush=True)
    base = results.get("open loop")
    for variant, f in results.items():
        if base is not None and variant != "open loop" and base["on_time"]:
            gain = 100.0 * (f["on_time"] / base["on_time"] - 1.0)
            promises = (f"{100.0 * (f['broken_promises'] / base['broken_promises'] - 1.0):+.0f} %"
                        if base["broken_promises"] else "none in the open loop")
            print(f"  {variant}: on time {gain:+.1f} %, broken promises {promises}"
                  + block_gains(base, f))


def block_gains(base: dict, figures: dict, size: int = 20) -> str:
    """The on-time change (%) of ``figures`` against ``base`` on each block of ``size``
    consecutive seeds, when the case has more than one block (e.g. ``; 200-219 +9.2 %``)."""
    if len(base["seeds"]) <= size or base["seeds"] != figures["seeds"]:
        return ""
    parts = []
    for k in range(0, len(base["seeds"]), size):
        seeds = base["seeds"][k:k + size]
        was, now = (sum(f["on_time_per_run"][k:k + size]) for f in (base, figures))
        parts.append(f"{seeds[0]}-{seeds[-1]} {100.0 * (now / was - 1.0):+.1f} %")
    return "; " + ", ".join(parts)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=len(SEEDS), help="busy seeds to run")
    parser.add_argument("--check-seeds", type=int, nargs="*", default=CHECK_SEEDS,
                        help="the busy_check case's seeds (default 220-259)")
    parser.add_argument("--unseen-seeds", type=int, nargs="*", default=UNSEEN_SEEDS,
                        help="the busy_unseen case's seeds (default 260-279)")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--variants", nargs="*", default=list(VARIANTS),
                        help="variant names (default: all)")
    parser.add_argument("--cases", nargs="*", default=["busy", "busy_check", *SINGLE_RUNS])
    args = parser.parse_args()
    busy = load_sweep(str(BUSY_SWEEP))
    cases = {
        "busy": SweepSpec(busy.scenario, {"seed": SEEDS[:args.seeds]},
                          {k: v for k, v in busy.fixed.items()}, busy.plugins, busy.source),
        "busy_check": SweepSpec(busy.scenario, {"seed": args.check_seeds}, dict(busy.fixed),
                                busy.plugins, busy.source),
        "busy_unseen": SweepSpec(busy.scenario, {"seed": args.unseen_seeds}, dict(busy.fixed),
                                 busy.plugins, busy.source),
    } | {name: SweepSpec(str(path), {"seed": [0]}, {}, [], str(path))
         for name, path in SINGLE_RUNS.items()}
    path = RESULTS / "feedback.json"
    output = json.loads(path.read_text()) if path.is_file() else {"variants": {}, "cases": {}}
    output["variants"] |= {v: VARIANTS[v] for v in args.variants}
    workers = max(1, args.workers // len(args.variants))
    summaries = {}
    for case in args.cases:
        with ThreadPoolExecutor(min(len(args.variants), args.workers)) as pool:
            runs = {variant: pool.submit(run_case, case, cases[case], VARIANTS[variant],
                                         workers) for variant in args.variants}
            summaries[case] = {variant: run.result() for variant, run in runs.items()}
        report(output, case, {v: figures(s) for v, s in summaries[case].items()})
    if {"busy", "busy_check"} <= summaries.keys():
        report(output, "busy_pooled", {
            v: figures(summaries["busy"][v] + summaries["busy_check"][v]) for v in args.variants})
    RESULTS.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(output, indent=1) + "\n")


if __name__ == "__main__":
    main()
