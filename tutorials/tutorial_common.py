"""What the tutorials share: their command-line options, and running a few variants of a
scenario one after the other, headless or live in one Meshcat."""

import argparse
import os

from pydrake.geometry import Meshcat

from mrta_drake import simulate


def options(doc: str, duration: float) -> argparse.ArgumentParser:
    """A parser with the options every tutorial takes (``--duration``, default ``duration``
    s; ``--meshcat``; ``--out DIR``), described by the first line of the tutorial's ``doc``."""
    parser = argparse.ArgumentParser(description=doc.splitlines()[0])
    parser.add_argument("--duration", type=float, default=duration, help="simulated s per run")
    parser.add_argument("--meshcat", action="store_true", help="watch live in Meshcat")
    parser.add_argument("--out", metavar="DIR", help="write the runs' files here")
    return parser


def open_meshcat(wanted: bool) -> Meshcat | None:
    """A Meshcat server whose address is printed, when ``wanted``."""
    if not wanted:
        return None
    meshcat = Meshcat()
    print(f"Meshcat: {meshcat.web_url()}", flush=True)
    return meshcat


def run_each(scenarios: dict, args: argparse.Namespace) -> dict:
    """Simulate each scenario (name -> ``Scenario``) for ``args.duration`` s, in order: with
    ``args.meshcat`` live at real time, with ``args.out`` writing each run's files to
    ``args.out/<name>``. Returns name -> ``SimulationResult``."""
    meshcat = open_meshcat(args.meshcat)
    results = {}
    for name, scenario in scenarios.items():
        print(f"Simulating {args.duration:g} s: {name}...", flush=True)
        results[name] = simulate(scenario, duration=args.duration, meshcat=meshcat,
                                 realtime_rate=1.0 if meshcat else 0.0,
                                 out_dir=os.path.join(args.out, name) if args.out else None)
    return results
