"""Time per CBF control call: a lone robot and 2-, 3-, 5- and 10-robot clusters.

Robots stand in the hospital's east corridor (the project's floor plan, or a plain corridor if
it is missing) in states where the safety rows are active, so that every call solves a QP.
Measured in one run:

- ``tick``: ``ClusterCbfController.control`` for the whole cluster: nominal control, cluster
  and leader, 12 wall rays per robot, rows, QP (Clarabel, and OSQP);
- ``qp``: ``CbfQp.solve`` alone on the same rows (reused MathematicalProgram);
- ``cvxpy``: the same QP written in cvxpy with parameters (compiled once; Clarabel and OSQP
  with the same tolerances), as a user would otherwise write it.

"first" is the first call of a fresh object (program building, cvxpy's compilation; solver
libraries are loaded before timing); "steady" the mean over the following calls. The table
shows CPU time (``time.process_time``; the machine is shared), the JSON wall-clock time too.
Paper (Table II, i9-9900X, wall clock, CBF-QP per call): 1 robot 8.54 ms, 2-robot cluster
14.3 ms, 3-robot cluster 12.3 ms; first call 12.6 ms, 1.50 s, 1.54 s.

Run from the repository root with the package importable (``pip install -e .``):
``python benchmarks/cbf_qp.py [--calls N]``; prints a table and writes
``benchmarks/results/cbf_qp.json``.
"""

import argparse
import json
import math
import os
import pathlib
import platform
import time

import cvxpy as cp
import numpy as np
from pydrake.solvers import ClarabelSolver, MathematicalProgram, OsqpSolver

from mrta_drake.control.cbf_params import CbfParams
from mrta_drake.control.cluster_cbf_controller import ClusterCbfController
from mrta_drake.control.qp_solver import CbfQp, QpParams
from mrta_drake.payloads import PATH_OK, FleetPaths, RobotPath, frozen_array
from mrta_drake.world.obstacles import Box, Obstacles

ROOT = pathlib.Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks/results/cbf_qp.json"
SIZES = (1, 2, 3, 5, 10)
PAPER_MS = {1: (8.54, 12.6), 2: (14.3, 1500.0), 3: (12.3, 1540.0)}  # steady, first
CORRIDOR_X = 5.0  # m, centre line of the hospital's east corridor


def _obstacles() -> tuple[Obstacles, str]:
    path = ROOT / "models/hospital/floor_plan.yaml"
    if path.is_file():
        from mrta_drake.world.floor_plan import load_floor_plan

        return load_floor_plan(path).obstacles, "hospital floor plan"
    walls = (Box("west", (3.5, -10.0), (0.2, 30.0)), Box("east", (6.5, -10.0), (0.2, 30.0)))
    return Obstacles(walls), "plain 2.8 m corridor"


def _scene(k: int, variants: int, rng) -> tuple[list[np.ndarray], FleetPaths]:
    """``variants`` jittered states (k, 4) of k robots in one cluster, and their paths. A lone
    robot drives at the corridor wall; in a cluster the robots stand 1.1 m apart along the
    corridor, alternately facing each other, the leader driving at its neighbour."""
    if k == 1:
        base = np.array([[CORRIDOR_X + 0.4, -10.0, 0.3, 1.2]])
        goals = [[9.0, -9.0]]
    else:
        y = -3.0 - 1.1 * np.arange(k)
        theta = np.where(np.arange(k) % 2 == 0, -math.pi / 2, math.pi / 2)
        base = np.column_stack([np.full(k, CORRIDOR_X), y, theta, np.full(k, 0.8)])
        goals = [[CORRIDOR_X, yi + 8.0 * math.sin(t)] for yi, t in zip(y, theta, strict=True)]
    paths = FleetPaths(tuple(RobotPath(f"robot{i + 1}", PATH_OK, frozen_array([s[:2], g]))
                             for i, (s, g) in enumerate(zip(base, goals, strict=True))))
    jitter = [0.05, 0.05, 0.05, 0.1]
    states = [base + rng.uniform(-1, 1, base.shape) * jitter for _ in range(variants)]
    return states, paths


class _CvxpyQp:
    """The same QP in cvxpy, with parameters so that it is compiled once."""

    def __init__(self, k: int, m: int, solver: str, slack_weight: float):
        self.solver, self.m = solver, m
        self.u_nom = cp.Parameter(2 * k)
        self.G = cp.Parameter((m, 2 * k))
        self.b = cp.Parameter(m)
        self.lo, self.hi = cp.Parameter(2 * k), cp.Parameter(2 * k)
        self.u, s = cp.Variable(2 * k), cp.Variable(m, nonneg=True)
        self.problem = cp.Problem(
            cp.Minimize(cp.sum_squares(self.u - self.u_nom) + slack_weight * cp.sum(s)),
            [self.G @ self.u + s >= self.b, self.u >= self.lo, self.u <= self.hi])

    def solve(self, u_nom, G, b, lower, upper) -> np.ndarray:
        pad = self.m - len(b)  # trivial rows 0 >= -1 keep the compiled size
        self.G.value = np.vstack([G, np.zeros((pad, G.shape[1]))])
        self.b.value = np.concatenate([b, -np.ones(pad)])
        self.u_nom.value = np.ravel(u_nom)
        self.lo.value, self.hi.value = np.ravel(lower), np.ravel(upper)
        if self.solver == "clarabel":
            self.problem.solve(solver=cp.CLARABEL)
        else:  # the tolerances CbfQp gives OSQP
            self.problem.solve(solver=cp.OSQP, eps_abs=1e-7, eps_rel=1e-7, polishing=True,
                               max_iter=20000)
        return self.u.value


def _time(fn, items) -> tuple[dict, list]:
    """CPU and wall-clock ms of the first call and mean ms of the rest, and all results."""
    out = []
    cpu, wall = time.process_time(), time.perf_counter()
    out.append(fn(items[0]))
    first_cpu, first_wall = time.process_time() - cpu, time.perf_counter() - wall
    cpu, wall = time.process_time(), time.perf_counter()
    for item in items[1:]:
        out.append(fn(item))
    rest = len(items) - 1
    return {"first_ms": 1e3 * first_cpu, "steady_ms": 1e3 * (time.process_time() - cpu) / rest,
            "first_wall_ms": 1e3 * first_wall,
            "steady_wall_ms": 1e3 * (time.perf_counter() - wall) / rest}, out


def _load_solvers() -> None:
    """Pay the one-time loading of the solver libraries before timing anything."""
    prog = MathematicalProgram()
    x = prog.NewContinuousVariables(1)
    prog.AddQuadraticCost([[2.0]], [0.0], x)
    for solver in (ClarabelSolver(), OsqpSolver()):
        solver.Solve(prog, None, None)
    z = cp.Variable()
    for name in (cp.CLARABEL, cp.OSQP):
        cp.Problem(cp.Minimize(cp.square(z - 1))).solve(solver=name)


def run(calls: int) -> dict:
    _load_solvers()
    obstacles, world = _obstacles()
    rng = np.random.default_rng(0)
    rows_out = []
    for k in SIZES:
        states, paths = _scene(k, calls, rng)
        names = [p.robot for p in paths.paths]
        row = {"robots": k}
        for solver in ("clarabel", "osqp"):
            controller = ClusterCbfController(names, obstacles,
                                              CbfParams(qp=QpParams(solver=solver)), rate_hz=20.0)
            row[f"tick_{solver}"], ticks = _time(
                lambda s, c=controller, p=paths: c.control(0.0, s, p), states)
            clusters = {t[1].clusters for t in ticks}
            assert clusters == {(tuple(range(k)),)}, clusters
            problems = []
            for s in states:
                (problem,) = controller.plan(s, paths).problems
                problems.append((problem.u_nominal, problem.rows.G, problem.rows.b,
                                 problem.lower, problem.upper))
            qp = CbfQp(solver, controller.params.qp.slack_weight)
            row[f"qp_{solver}"], solutions = _time(lambda p, q=qp: q.solve(*p), problems)
            assert all(s.success and s.solved for s in solutions), "a call skipped the solver"
            row["rows"] = m = max(len(p[2]) for p in problems)
            cpu, wall = time.process_time(), time.perf_counter()
            cvx = _CvxpyQp(k, m, solver, controller.params.qp.slack_weight)
            build_cpu, build_wall = time.process_time() - cpu, time.perf_counter() - wall
            timing, u = _time(lambda p, c=cvx: c.solve(*p), problems)
            timing["first_ms"] += 1e3 * build_cpu
            timing["first_wall_ms"] += 1e3 * build_wall
            row[f"cvxpy_{solver}"] = timing
            gap = max(np.abs(np.ravel(a.u) - b).max() for a, b in zip(solutions, u, strict=True))
            row[f"cvxpy_{solver}_max_input_difference"] = float(gap)
        rows_out.append(row)
    return {"world": world, "calls_per_case": calls, "python": platform.python_version(),
            "machine": platform.processor() or platform.machine(), "cpus": os.cpu_count(),
            "paper_ms": {str(k): {"steady": v[0], "first": v[1]} for k, v in PAPER_MS.items()},
            "results": rows_out}


def table(report: dict) -> str:
    head = (f"{'robots':>6} {'rows':>4} | {'tick clarabel':>15} {'tick osqp':>15} | "
            f"{'qp clarabel':>15} {'qp osqp':>15} | {'cvxpy clarabel':>16} "
            f"{'cvxpy osqp':>16} | {'paper':>16}")
    lines = [f"CBF control call, CPU ms: steady-state mean (first call); {report['world']}, "
             f"{report['calls_per_case']} calls per case; paper: wall clock", head,
             "-" * len(head)]
    def cell(r, key, width=15):
        return f"{r[key]['steady_ms']:7.3f} ({r[key]['first_ms']:5.1f})".rjust(width)

    for r in report["results"]:
        paper = PAPER_MS.get(r["robots"])
        paper_text = f"{paper[0]:6.2f} ({paper[1]:6.1f})" if paper else ""
        lines.append(f"{r['robots']:>6} {r['rows']:>4} | {cell(r, 'tick_clarabel')} "
                     f"{cell(r, 'tick_osqp')} | {cell(r, 'qp_clarabel')} {cell(r, 'qp_osqp')} | "
                     f"{cell(r, 'cvxpy_clarabel', 16)} {cell(r, 'cvxpy_osqp', 16)} | "
                     f"{paper_text:>16}")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calls", type=int, default=300, help="calls per case")
    args = parser.parse_args()
    report = run(args.calls)
    print(table(report))
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    tmp = RESULTS.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(report, indent=2) + "\n")
    tmp.replace(RESULTS)
    print(f"wrote {RESULTS.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
