"""CPU time along the two chains of a cold quickstart (``mrta-sim run
scenarios/hospital_6_robots.yaml --duration 60``, numba's cache in an empty folder): the CLI
process up to the moment it waits for the second compiling process (``kernel_cache.
Compilation``), the second process (from the CLI's CPU time when it was started), and the run
after the wait. The critical path, max(CLI before the wait, start + second process) + after
the wait, is about the wall time the command takes on a quiet host with 2 cores or more; on a
loaded one, wall time says little and this is what compares (docs/benchmarks.md, "The first
run").

    PYTHONPATH=<tree> python benchmarks/first_run_paths.py [--runs N]

prints one JSON line per run (CPU s). The tree measured is the ``mrta_drake`` on the path:
run it alternately with two trees to compare them.
"""

import argparse
import contextlib
import io
import json
import os
import pathlib
import resource
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]


def measure() -> dict:
    """One cold quickstart in this process (call it once per process: numba keeps what it
    compiled)."""
    start = time.process_time()
    with tempfile.TemporaryDirectory() as cache:
        os.environ["NUMBA_CACHE_DIR"] = cache
        from mrta_drake.stack import kernel_cache
        from mrta_drake.tools import cli

        marks = {}
        fork, finish = os.fork, kernel_cache.Compilation.finish

        def started():
            marks.setdefault("second_started", time.process_time() - start)
            return fork()

        def finished(self):
            kernel_cache.compile_kernels(self._here)
            marks["before_wait"] = time.process_time() - start
            if self._child is not None:
                os.waitpid(self._child, 0)
                self._child = None
            marks["after_wait"] = time.process_time()

        os.fork = started
        kernel_cache.Compilation.finish = finished
        try:
            with contextlib.redirect_stdout(io.StringIO()):
                code = cli.main(["run", str(ROOT / kernel_cache.QUICKSTART[0]),
                                 *kernel_cache.QUICKSTART[1:]])
        finally:
            os.fork, kernel_cache.Compilation.finish = fork, finish
    if code:
        raise SystemExit(f"quickstart failed ({code})")
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    second = children.ru_utime + children.ru_stime
    after = time.process_time() - marks["after_wait"]
    chains = (marks["before_wait"], marks.get("second_started", 0.0) + second)
    return {"cli_before_wait": round(chains[0], 2),
            "second_started": round(marks.get("second_started", 0.0), 2),
            "second": round(second, 2), "after_wait": round(after, 2),
            "critical_path": round(max(chains) + after, 2),
            "both_processes": round(time.process_time() - start + second, 2),
            "load_average": round(os.getloadavg()[0], 1)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=1, help="cold runs, each in a fresh "
                        "process (default 1)")
    parser.add_argument("--one", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one:
        print(json.dumps(measure()), flush=True)
        return
    for _ in range(args.runs):
        subprocess.run([sys.executable, __file__, "--one"], check=True)


if __name__ == "__main__":
    main()
