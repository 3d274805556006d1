"""Tutorial 6: the allocator's travel times, a sweep over them, and a plot of the results.

The allocator plans with a matrix of travel times between locations, in whole seconds
(docs/allocation.md): a robot doing stops ``a_1 .. a_n`` completes stop k at
``max(c_{k-1}, release) + travel[loc_{k-1}, loc_k] + service_time``. Those predictions decide
which robot gets which task and whether a deadline can be met, so it matters how good they
are. The matrix is the scenario's ``tasks.travel_times`` file, or else an estimate: the
length of each leg along the one-way roadway lanes divided by ``tasks.estimate_speed``
(m/s, default 0.6), rounded up (``BuildContext.travel_times``,
``Roadways.travel_time_estimate``). The estimate ignores turning, queueing at rooms, people
and other robots. The six-robot hospital scenario ships a measured matrix
(``scenarios/travel_times/hospital.yaml``, written by ``mrta-sim travel-times``: one robot
drove every leg with the scenario's own blocks).

1. Print the measured matrix next to the estimate, and the average speed the measured
   matrix amounts to (total leg length / total measured time). With ``--collect`` the matrix
   is measured afresh first, as ``mrta-sim travel-times`` does it
   (``collect_travel_times``: one robot, alone, with the scenario's own planner, controller
   and queues, drives every ordered pair of locations in one circuit; about a minute), and
   written to ``DIR/travel_times.yaml`` with ``write_travel_times``; a scenario uses such a
   file through ``tasks.travel_times``.
2. Sweep the speed the estimate assumes, with the measured file switched off
   (``tasks.travel_times: ""``). A sweep spec (``mrta_drake/tools/sweep.py``, written to
   ``DIR/sweep.yaml``) names a base scenario and a ``grid`` of dotted scenario fields, one
   run per combination, each in its own process (``--workers``), resumable: a run whose
   ``summary.json`` exists is not run again. The run's duration is a one-value grid entry so
   that it is part of each run's name; change ``--duration`` and the runs are new. People
   are left out (``humans: false``, a sweep-only key) to keep the runs short.
3. Read the results: ``results.csv`` (one row per run: tasks, clearances, deadlocks, ...)
   and each run's ``runs/<run>/summary.json``, whose ``legs`` pair the predicted duration of
   every completed stop with the actual one. The table gives, per assumed speed, how many
   tasks were on time and the mean of actual minus predicted stop duration: negative, the
   allocator was pessimistic; positive, optimistic.
4. Plot (``DIR/sweep.png``): predicted against actual stop durations, and the mean error
   against the assumed speed, with the measured matrix's average speed marked. The error
   crosses zero near the speed the robots really make on average, turning, queueing and
   giving way included.

Without ``--out`` the sweep goes to a new temporary folder. ``--meshcat`` afterwards shows
the run whose predictions were best, live.

Run::

    python tutorials/06_travel_times_and_sweeps.py [--duration 60] [--speeds 0.4 0.6 0.8]
        [--workers 2] [--collect] [--meshcat] [--out DIR]
"""

import json
import os
import pathlib
import tempfile

import numpy as np
import yaml
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from tutorial_common import open_meshcat, options

from mrta_drake import load_scenario, simulate
from mrta_drake.results.report import text_table
from mrta_drake.scenario.travel_times import write_travel_times
from mrta_drake.stack.blocks import BuildContext
from mrta_drake.tools.sweep import format_table, load_sweep, run_sweep, sweep_scenario
from mrta_drake.tools.travel_time_collection import collect_travel_times

SCENARIO = pathlib.Path(__file__).resolve().parent.parent / "scenarios/hospital_6_robots.yaml"
SPEED = "tasks.estimate_speed"


def leg_errors(summary: dict) -> np.ndarray:
    """(k, 2) predicted and actual durations (s) of the run's completed stops that have a
    prediction."""
    return np.array([(leg["predicted"], leg["actual"]) for leg in summary["legs"]
                     if leg["predicted"] is not None]).reshape(-1, 2)


def plot_sweep(path: str, speeds: list[float], legs: list[np.ndarray],
               measured_speed: float) -> None:
    """Left: predicted against actual stop durations, one colour per assumed speed, with
    y = x. Right: mean actual - predicted (s) against the assumed speed (m/s), with the
    measured matrix's average speed marked."""
    figure = Figure(figsize=(10.0, 4.5))
    left, right = figure.subplots(1, 2)
    for speed, pairs in zip(speeds, legs, strict=True):
        left.plot(pairs[:, 0], pairs[:, 1], "o", ms=4, label=f"{speed:g} m/s")
    top = max((pairs.max() for pairs in legs if pairs.size), default=1.0) * 1.05
    left.plot([0, top], [0, top], "k--", lw=0.8)
    left.set(xlabel="predicted (s)", ylabel="actual (s)", title="Stop durations")
    left.legend(title="assumed speed", fontsize=8)
    means = [(pairs[:, 1] - pairs[:, 0]).mean() if pairs.size else np.nan for pairs in legs]
    right.plot(speeds, means, "o-")
    right.axhline(0.0, color="black", lw=0.8)
    right.axvline(measured_speed, color="red", ls="--", lw=0.8,
                  label="average speed of the measured matrix")
    right.legend(fontsize=8)
    right.set(xlabel="assumed speed (m/s)", ylabel="mean actual - predicted (s)",
              title="Prediction error")
    FigureCanvasAgg(figure).print_png(path)


def main(argv=None) -> dict:
    parser = options(__doc__, duration=60.0)
    parser.add_argument("--speeds", type=float, nargs="+", default=[0.4, 0.6, 0.8],
                        help="assumed speeds to sweep, m/s")
    parser.add_argument("--workers", type=int, default=2, help="runs in parallel")
    parser.add_argument("--collect", action="store_true",
                        help="measure the travel times afresh instead of reading the shipped "
                        "file (about a minute)")
    args = parser.parse_args(argv)
    out = args.out or tempfile.mkdtemp(prefix="mrta_tutorial_06_")
    os.makedirs(out, exist_ok=True)

    scenario = load_scenario(SCENARIO)
    context = BuildContext.for_scenario(scenario)
    roadways, source = context.roadways, context.scenario.tasks.travel_times
    if args.collect:
        print("Measuring the travel times: one robot drives every leg...", flush=True)
        measured = collect_travel_times(scenario, progress=True)
        source = os.path.join(out, "travel_times.yaml")
        write_travel_times(source, measured, stat="max", repeats=1)
    else:
        measured = context.travel_times
    estimate = roadways.travel_time_estimate(context.scenario.tasks.estimate_speed)
    names = [location.name for location in context.scenario.locations]
    print(f"Travel times (s) from row to column: measured "
          f"({os.path.basename(source)}), and in brackets "
          f"estimated at {context.scenario.tasks.estimate_speed:g} m/s:")
    print(text_table(["from \\ to", *names], [
        [name, *(f"{m} ({e})" for m, e in zip(measured_row, estimate_row, strict=True))]
        for name, measured_row, estimate_row in zip(names, measured, estimate, strict=True)]))
    ids = roadways.location_ids
    length = sum(roadways.leg_length(a, b) for a in ids for b in ids if a != b)
    measured_speed = length / measured.sum()
    print(f"The measured matrix amounts to {measured_speed:.2f} m/s on average "
          f"({length:.0f} m of legs in {measured.sum()} s).")

    spec_file = os.path.join(out, "sweep.yaml")
    with open(spec_file, "w") as f:
        yaml.safe_dump({"scenario": str(SCENARIO),
                        "grid": {SPEED: args.speeds, "duration": [args.duration]},
                        "fixed": {"tasks.travel_times": "", "humans": False}}, f,
                       sort_keys=False)
    spec = load_sweep(spec_file)
    print(f"\nSweep {spec_file}: {len(spec.runs())} runs of {args.duration:g} s, "
          f"{args.workers} at a time...", flush=True)
    result = run_sweep(spec, out, workers=args.workers)
    print(format_table(result.rows))

    summaries, legs = [], []
    for run in spec.runs():
        with open(os.path.join(out, "runs", run.run_id, "summary.json")) as f:
            summaries.append(json.load(f))
        legs.append(leg_errors(summaries[-1]))
    errors = [pairs[:, 1] - pairs[:, 0] for pairs in legs]
    print(text_table(["assumed speed m/s", "tasks on time", "stops with prediction",
                      "mean actual - predicted s", "mean |error| s"], [
        [f"{speed:g}", f"{s['tasks']['on_time']} of {s['tasks']['released']}", len(e),
         f"{e.mean():+.1f}" if e.size else "-", f"{np.abs(e).mean():.1f}" if e.size else "-"]
        for speed, s, e in zip(args.speeds, summaries, errors, strict=True)]))
    plot = os.path.join(out, "sweep.png")
    plot_sweep(plot, args.speeds, legs, measured_speed)
    print(f"Results in {out}: results.csv, runs/, sweep.png")

    if args.meshcat:
        best = min(range(len(errors)), key=lambda k: np.abs(errors[k]).mean()
                   if errors[k].size else np.inf)
        print(f"The best-predicted run, assumed speed {args.speeds[best]:g} m/s, live:")
        simulate(sweep_scenario(spec.scenario, spec.runs()[best].settings),
                 meshcat=open_meshcat(True), realtime_rate=1.0)
    return {"out": out, "measured": measured, "measured_file": source, "estimate": estimate,
            "measured_speed": measured_speed, "rows": result.rows,
            "summaries": summaries, "legs": legs, "plot": plot}


if __name__ == "__main__":
    main()
