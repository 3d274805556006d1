"""The ``mrta-sim`` command line."""

import argparse
import sys

from mrta_drake.errors import InputError


def _positive(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {text}")
    return value


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="mrta-sim",
        description="Multi-robot task allocation with planning and control in Drake.")
    commands = parser.add_subparsers(dest="command", required=True)

    run = commands.add_parser("run", help="run a scenario (headless unless --meshcat)")
    run.add_argument("scenario", help="scenario YAML file")
    run.add_argument("--duration", type=_positive, help="simulated seconds (default: the "
                     "scenario's)")
    run.add_argument("--meshcat", action="store_true", help="serve the live 3D view")
    run.add_argument("--realtime", type=_positive, default=None,
                     help="pace the run at this multiple of real time (default with "
                     "--meshcat: 1)")
    run.add_argument("--record", metavar="HTML", help="write a self-contained replay page")
    run.add_argument("--out", metavar="DIR", help="write timeline.csv, events.jsonl and "
                     "summary.json here")
    run.add_argument("--seed", type=int, help="override the scenario's seed")
    run.add_argument("--quiet", action="store_true", help="no progress bar")

    validate = commands.add_parser("validate", help="check a scenario file and exit")
    validate.add_argument("scenario", help="scenario YAML file")

    diagram = commands.add_parser("diagram", help="write the scenario's block diagram")
    diagram.add_argument("scenario", help="scenario YAML file")
    diagram.add_argument("output", help="output file: .dot, or .png/.svg (needs graphviz)")
    diagram.add_argument("--depth", type=int, default=1, help="diagram nesting depth")
    return parser


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    try:
        return _COMMANDS[args.command](args)
    except InputError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


def _run(args) -> int:
    import dataclasses

    from mrta_drake.scenario import load_scenario
    from mrta_drake.simulate import simulate
    from mrta_drake.summary import format_summary

    scenario = load_scenario(args.scenario)
    if args.seed is not None:
        scenario = dataclasses.replace(scenario, seed=args.seed)
    meshcat = None
    realtime = args.realtime or 0.0
    if args.meshcat:
        from pydrake.geometry import Meshcat

        meshcat = Meshcat()
        print(f"Meshcat: {meshcat.web_url()}", flush=True)
        realtime = args.realtime or 1.0
    result = simulate(scenario, duration=args.duration, meshcat=meshcat,
                      record_html=args.record, out_dir=args.out,
                      progress=not args.quiet and sys.stderr.isatty(), realtime_rate=realtime)
    print(format_summary(result.summary))
    if args.record:
        print(f"replay written to {args.record}")
    if args.out:
        print(f"results written to {args.out}")
    return 0


def _validate(args) -> int:
    from mrta_drake.validate import validate_scenario

    scenario = validate_scenario(args.scenario)
    print(f"{args.scenario}: ok ({len(scenario.robots)} robots, {len(scenario.locations)} "
          f"locations, {sum(len(b.tasks) for b in scenario.tasks.stream)} tasks)")
    return 0


def _diagram(args) -> int:
    import os
    import subprocess

    from mrta_drake.diagram import build_diagram
    from mrta_drake.scenario import load_scenario

    stack = build_diagram(load_scenario(args.scenario))
    dot = stack.diagram.GetGraphvizString(max_depth=args.depth)
    extension = os.path.splitext(args.output)[1].lstrip(".").lower()
    if extension in ("", "dot", "gv"):
        with open(args.output, "w") as f:
            f.write(dot)
    else:
        try:
            subprocess.run(["dot", f"-T{extension}", "-o", args.output], input=dot.encode(),
                           check=True)
        except FileNotFoundError:
            raise InputError(None, "output", "rendering needs graphviz's `dot`; "
                             "write a .dot file instead") from None
    print(f"diagram written to {args.output}")
    return 0


_COMMANDS = {"run": _run, "validate": _validate, "diagram": _diagram}


if __name__ == "__main__":
    sys.exit(main())
