"""The ``mrta-sim`` command line."""

import argparse
import gc
import math
import signal
import sys

from mrta_drake.errors import InputError


def _positive(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not 0 < value < math.inf:
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {text}")
    return value


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="mrta-sim",
        description="Multi-robot task allocation with planning and control in Drake.")
    commands = parser.add_subparsers(dest="command", required=True)

    run = commands.add_parser("run", help="run a scenario (headless unless --meshcat)")
    run.add_argument("scenario", help="scenario YAML file")
    run.add_argument("--duration", type=_positive, help="simulated seconds, the scenario's "
                     "duration (a generated task stream runs to it; default: the scenario's)")
    run.add_argument("--meshcat", action="store_true", help="serve the live 3D view")
    run.add_argument("--realtime", type=_positive, default=None,
                     help="pace the run at this multiple of real time (default with "
                     "--meshcat: 1)")
    run.add_argument("--record", metavar="HTML", help="write a self-contained replay page")
    run.add_argument("--out", metavar="DIR", help="write timeline.csv, events.jsonl, "
                     "summary.json and plots here")
    run.add_argument("--no-plots", dest="plots", action="store_false",
                     help="with --out, skip the PNG plots")
    run.add_argument("--seed", type=int, help="override the scenario's seed")
    run.add_argument("--quiet", action="store_true", help="no progress bar")

    validate = commands.add_parser("validate", help="check a scenario file and exit")
    validate.add_argument("scenario", help="scenario YAML file")

    diagram = commands.add_parser("diagram", help="write the scenario's block diagram")
    diagram.add_argument("scenario", help="scenario YAML file")
    diagram.add_argument("output", help="output file: .dot, or .png/.svg (needs graphviz)")
    diagram.add_argument("--depth", type=int, default=1, help="diagram nesting depth")

    sweep = commands.add_parser("sweep", help="run a scenario over a grid of variations "
                                "(resumable; see mrta_drake/tools/sweep.py)")
    sweep.add_argument("spec", help="sweep spec YAML file")
    sweep.add_argument("--out", metavar="DIR", help="results folder (default: "
                       "sweeps/<spec name>); runs already in it are not redone")
    sweep.add_argument("--workers", type=int, help="parallel local processes (default: one "
                       "per CPU)")
    sweep.add_argument("--ray", metavar="ADDRESS", help="run on this Ray cluster instead "
                       "(e.g. auto, ray://host:10001, local)")
    sweep.add_argument("--plots", action="store_true", help="write each run's PNG plots")
    sweep.add_argument("--quiet", action="store_true", help="no progress bar")

    report = commands.add_parser("report", help="print the results of a run (its --out DIR)")
    report.add_argument("folder", help="results folder written by `run --out`")

    compare = commands.add_parser("compare", help="print two runs' results side by side")
    compare.add_argument("first", help="results folder written by `run --out`")
    compare.add_argument("second", help="another results folder")

    travel = commands.add_parser("travel-times", help="measure the allocator's travel-time "
                                 "matrix: one robot drives every ordered pair of locations")
    travel.add_argument("scenario", help="scenario YAML file")
    travel.add_argument("--repeats", type=int, default=1, help="runs over every leg "
                        "(default 1)")
    travel.add_argument("--stat", default="max", help="max or mean over repeats (default max)")
    travel.add_argument("--robot", help="the robot that drives (default: the first)")
    travel.add_argument("--humans", action="store_true", help="keep the scenario's people")
    travel.add_argument("--time-limit", type=_positive, default=300.0, help="s a leg may "
                        "take before it counts as failed (default 300)")
    travel.add_argument("--out", metavar="FILE", help="matrix file, .yaml or .csv (default: "
                        "travel_times/<scenario name>.yaml)")
    travel.add_argument("--quiet", action="store_true", help="no progress bar")

    building = commands.add_parser("import", help="make a runnable scenario folder from an "
                                   "Open-RMF .building.yaml, or a ROS map with --locations")
    building.add_argument("building", help="Open-RMF .building.yaml file, or a ROS map_server "
                          ".yaml file")
    building.add_argument("--locations", metavar="POINTS.yaml", default="", help="with a ROS "
                          "map: the named points robots serve (docs/worlds.md)")
    building.add_argument("--out", metavar="DIR", required=True, help="folder to write "
                          "scenario.yaml and navigation.yaml to")
    building.add_argument("--robots", type=int, default=3, help="robots (default 3)")
    building.add_argument("--people", type=int, default=0, help="people (default 0)")
    building.add_argument("--seed", type=int, default=0, help="seed of people and tasks "
                          "(default 0)")
    building.add_argument("--level", default="", help="the level to import (default: every "
                          "level, joined by the lifts)")
    building.add_argument("--graph", type=int, default=0, help="navigation graph "
                          "(graph_idx) robots drive on (default 0)")
    return parser


def main(argv=None) -> int:
    """Runs the command ``argv`` (default: this process's command line, ``sys.argv[1:]``,
    after which the process exits) and returns its exit code."""
    args = _parser().parse_args(argv)
    try:
        return _COMMANDS[args.command](args)
    except InputError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    except OSError as error:  # the disk or the file system refused: no traceback for that
        where = f"{error.filename}: " if error.filename else ""
        print(f"error: {where}{error.strerror or error}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    finally:
        if argv is None:  # the process exits next: its teardown need not walk the heap
            gc.freeze()


class _StopRequests:
    """SIGINT (Ctrl-C) and SIGTERM (a batch system's or ``timeout``'s stop) once a run
    goes (``listen``): the first asks it to stop after its current slice, writing its results
    so far (``simulate``'s ``stop_requested``); a second one interrupts it at once."""

    def __init__(self):
        self.requested = False
        self._previous = {}

    def listen(self) -> None:
        for number in (signal.SIGINT, signal.SIGTERM):
            try:
                self._previous[number] = signal.signal(number, self._handle)
            except ValueError:  # off the main thread, where no handler can be set
                return

    def restore(self) -> None:
        for number, handler in self._previous.items():
            signal.signal(number, handler)
        self._previous.clear()

    def _handle(self, number, frame) -> None:
        if self.requested:
            raise KeyboardInterrupt
        self.requested = True


def _run(args) -> int:
    # Start-up (imports, loading, building) makes little cyclic garbage, and what it builds
    # lives as long as the run: collecting meanwhile only walks the growing heap again and
    # again (``_before_run`` turns collecting back on).
    gc.disable()
    compiling = _start_compiling()  # first: a second process may start compiling at once
    stops = _StopRequests()
    try:
        return _run_scenario(args, compiling, stops)
    finally:
        stops.restore()
        compiling.cancel()  # when the run failed before it was done
        gc.unfreeze()  # collectable again by a caller that goes on (tests, a benchmark)
        gc.enable()


def _before_run(compiling) -> None:
    """Finishes compiling the kernels, then moves every object start-up made to the
    collector's permanent generation (``gc.freeze``: not walked by the collections during
    the run) and turns collecting back on for what the run makes."""
    compiling.finish()
    gc.freeze()
    gc.enable()


def _run_scenario(args, compiling, stops: _StopRequests) -> int:
    from mrta_drake.results.report import format_summary
    from mrta_drake.scenario.loading import load_scenario
    from mrta_drake.stack.simulate import simulate

    overrides = {name: value for name, value in (("seed", args.seed),
                                                   ("duration", args.duration))
                 if value is not None}
    scenario = load_scenario(args.scenario, overrides=overrides or None)
    _check_writable("--out", args.out, folder=True)
    _check_writable("--record", args.record)
    _announce(compiling)
    meshcat = None
    realtime = args.realtime or 0.0
    if args.meshcat:
        from pydrake.geometry import Meshcat

        meshcat = Meshcat()
        print(f"Meshcat: {meshcat.web_url()}", flush=True)
        realtime = args.realtime or 1.0
    result = simulate(scenario, duration=args.duration, meshcat=meshcat,
                      record_html=args.record, out_dir=args.out,
                      progress=not args.quiet and sys.stderr.isatty(), realtime_rate=realtime,
                      plots=args.plots,
                      before_run=lambda: (_before_run(compiling), stops.listen()),
                      stop_requested=lambda: stops.requested)
    print(format_summary(result.summary))
    if args.record:
        print(f"replay written to {args.record}")
    if args.out:
        print(f"results written to {args.out}")
    return 130 if result.summary["interrupted"] else 0


def _start_compiling():
    """When numba's cache lacks the stack's entry kernels (the first run after installing),
    starts compiling them (``kernel_cache.Compilation``); warm, nothing is started."""
    from mrta_drake.stack import kernel_cache

    return kernel_cache.Compilation(kernel_cache.missing_kernels())


def _announce(compilation) -> None:
    """Says once on stderr that kernels are compiling, with the estimated time; only once
    the scenario and the outputs are found good, so that bad input stays a one-line error."""
    if compilation.seconds > 0:
        print(f"compiling kernels, once, ~{compilation.seconds:.0f} s", file=sys.stderr,
              flush=True)


def _validate(args) -> int:
    from mrta_drake.scenario.validate import validate_scenario

    scenario = validate_scenario(args.scenario)
    print(f"{args.scenario}: ok ({len(scenario.robots)} robots, {len(scenario.locations)} "
          f"locations, {sum(len(b.tasks) for b in scenario.tasks.stream)} tasks)")
    return 0


def _diagram(args) -> int:
    import os
    import subprocess

    from mrta_drake.scenario.loading import load_scenario
    from mrta_drake.stack.diagram import build_diagram

    _check_writable("output", args.output)
    stack = build_diagram(load_scenario(args.scenario))
    dot = stack.diagram.GetGraphvizString(max_depth=args.depth)
    extension = os.path.splitext(args.output)[1].lstrip(".").lower()
    if extension in ("", "dot", "gv"):
        with open(args.output, "w") as f:
            f.write(dot)
    else:
        try:
            subprocess.run(["dot", f"-T{extension}", "-o", args.output], input=dot.encode(),
                           check=True, capture_output=True)
        except FileNotFoundError:
            raise InputError(None, "output", "rendering needs graphviz's `dot`; "
                             "write a .dot file instead") from None
        except subprocess.CalledProcessError as error:
            said = error.stderr.decode(errors="replace").strip().splitlines()
            raise InputError(None, "output", f"graphviz cannot write {args.output!r}: "
                             f"{said[0] if said else 'failed'}") from None
    print(f"diagram written to {args.output}")
    return 0


def _report(args) -> int:
    from mrta_drake.results.report import summary_report

    print(summary_report(args.folder))
    return 0


def _compare(args) -> int:
    import os

    from mrta_drake.results.report import format_comparison, load_summary, printed

    names = tuple(os.path.basename(os.path.normpath(f)) for f in (args.first, args.second))
    if names[0] == names[1]:
        names = (args.first, args.second)
    print(printed(f"{args.first} and {args.second}", format_comparison,
                  load_summary(args.first), load_summary(args.second), names))
    return 0


def _sweep(args) -> int:
    import os

    from mrta_drake.tools.sweep import format_table, load_sweep, run_sweep

    if args.workers is not None and args.workers < 1:
        raise InputError(None, "--workers", f"must be >= 1, got {args.workers}")
    spec = load_sweep(args.spec)
    out = args.out or os.path.join("sweeps", os.path.splitext(os.path.basename(args.spec))[0])
    _check_writable("--out", out, folder=True)
    result = run_sweep(spec, out, workers=args.workers, ray_address=args.ray,
                       plots=args.plots, progress=not args.quiet and sys.stderr.isatty())
    print(format_table(result.rows))
    failed = sum(row["status"] != "ok" for row in result.rows)
    print(f"{len(result.rows)} runs ({result.ran} run now, {result.reused} reused, {failed} "
          f"failed); table: {', '.join(result.table)}")
    return 0


def _travel_times(args) -> int:
    import os

    from mrta_drake.scenario.loading import load_scenario
    from mrta_drake.scenario.travel_times import write_travel_times
    from mrta_drake.tools.travel_time_collection import check_stat, measure_legs

    stem = os.path.splitext(os.path.basename(args.scenario))[0]
    out = args.out or os.path.join("travel_times", f"{stem}.yaml")
    if os.path.splitext(out)[1].lower() not in (".yaml", ".yml", ".csv"):
        raise InputError(None, "--out", f"must end in .yaml, .yml or .csv, got {out!r}")
    check_stat(args.stat)
    _check_writable("--out", out)
    legs = measure_legs(load_scenario(args.scenario), args.repeats, args.robot, args.humans,
                        args.time_limit, progress=not args.quiet and sys.stderr.isatty())
    matrix = legs.matrix(args.stat)
    write_travel_times(out, matrix, stat=args.stat, repeats=args.repeats, robot=legs.robot,
                       humans=args.humans)
    print("travel times (s), row = from, column = to:")
    for row in matrix:
        print(" ".join(f"{value:4d}" for value in row))
    print(legs.describe(args.stat))
    print(f"written to {out}")
    return 0


def _import(args) -> int:
    from mrta_drake.tools.building_import import ImportOptions, import_building
    from mrta_drake.tools.map_import import import_ros_map
    from mrta_drake.world.rmf_scenario import building_at

    options = ImportOptions(robots=args.robots, people=args.people, seed=args.seed,
                            level=args.level, graph=args.graph)
    if not args.building.endswith(".building.yaml"):
        if not args.locations:
            raise InputError(args.building, None, "a ROS map needs --locations POINTS.yaml "
                             "(an Open-RMF building file ends in .building.yaml)")
        _check_writable("--out", args.out, folder=True)
        report = import_ros_map(args.building, args.locations, args.out, options)
        print("\n".join(report.lines))
        return 0
    if args.locations:
        raise InputError(None, "--locations", "is for ROS maps; a building names its places")
    building_at(args.building)  # a broken building is refused before anything is written
    _check_writable("--out", args.out, folder=True)
    report = import_building(args.building, args.out, options)
    print("\n".join(report.lines))
    return 0


def _check_writable(flag: str, path: str | None, folder: bool = False) -> None:
    """Make the folder ``path`` (``folder``) or the one ``path`` goes in, before a long run
    rather than after it; InputError naming ``flag`` when that is not possible."""
    import os

    if not path:
        return
    target = path if folder else os.path.dirname(os.path.abspath(path))
    try:
        os.makedirs(target, exist_ok=True)
    except OSError as error:
        raise InputError(None, flag, f"cannot write to {path!r}: {error.strerror}") from None
    if not os.access(target, os.W_OK):
        raise InputError(None, flag, f"cannot write to {path!r}: the folder is read-only")


_COMMANDS = {"run": _run, "validate": _validate, "diagram": _diagram, "report": _report,
             "compare": _compare, "sweep": _sweep, "travel-times": _travel_times,
             "import": _import}


if __name__ == "__main__":
    sys.exit(main())
