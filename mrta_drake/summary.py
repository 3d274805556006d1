"""The figures of one run: what the CLI prints and ``summary.json`` holds."""

import hashlib
import platform
from importlib import metadata

import numpy as np

from mrta_drake.payloads import DROPOFF


def scenario_hash(scenario) -> str:
    """A short stable hash of the loaded scenario (its dataclass repr)."""
    return hashlib.sha256(repr(scenario).encode()).hexdigest()[:16]


def _versions() -> dict:
    versions = {"python": platform.python_version()}
    for package in ("mrta-drake", "drake", "numpy", "z3-solver"):
        try:
            versions[package] = metadata.version(package)
        except metadata.PackageNotFoundError:
            versions[package] = None
    return versions


def summarize(stack, times, states, humans, duration: float, wall_time: float,
              cpu_time: float) -> dict:
    """Summary of a run from the recorder's arrays: ``times`` (T,), robot ``states``
    (T, N, 4), ``humans`` positions (T, M, 2). Distances in m, times in s."""
    scenario = stack.scenario
    radii = np.array([r.radius for r in scenario.robots])
    names = [r.name for r in scenario.robots]
    xy = states[..., :2]
    steps = np.linalg.norm(np.diff(xy, axis=0), axis=-1) if len(xy) > 1 else np.zeros((0, 1))
    robots = {}
    visits = {name: 0 for name in names}
    for event in stack.recorder.events:
        if event["type"] == "arrival":
            visits[event["robot"]] += 1
    for k, name in enumerate(names):
        robots[name] = {
            "distance": float(steps[:, k].sum()) if len(steps) else 0.0,
            "final_pose": [float(v) for v in states[-1, k, :3]] if len(states) else None,
            "stops_completed": visits[name],
        }
    telemetry = stack.recorder.telemetry
    summary = {
        "scenario": scenario.source,
        "scenario_hash": scenario_hash(scenario),
        "seed": scenario.seed,
        "versions": _versions(),
        "duration": duration,
        "wall_time": wall_time,
        "cpu_time": cpu_time,
        "real_time_factor": duration / wall_time if wall_time > 0 else None,
        "robots": robots,
        "safety": _safety(stack, xy, radii, humans),
        "tasks": _tasks(stack.recorder.events),
        "planner_failures": int(max((e["total"] for e in stack.recorder.events
                                     if e["type"] == "planner_failure"), default=0)),
        "controller_failures": int(sum(t.failures for t in telemetry)),
    }
    return summary


def _safety(stack, xy: np.ndarray, radii: np.ndarray, humans: np.ndarray) -> dict:
    """Smallest surface-to-surface clearances over the run (negative = overlap)."""
    T, N = xy.shape[:2]
    result = {"min_robot_robot": None, "min_robot_wall": None, "min_robot_human": None,
              "robot_robot_contacts": 0, "robot_wall_contacts": 0}
    if T == 0:
        return result
    obstacles = stack.world.obstacles
    wall = obstacles.signed_distance(xy.reshape(-1, 2)).reshape(T, N) - radii
    result["min_robot_wall"] = float(wall.min())
    result["robot_wall_contacts"] = int(_onsets(wall < 0).sum())
    if N > 1:
        i, j = np.triu_indices(N, 1)
        gap = np.linalg.norm(xy[:, i] - xy[:, j], axis=-1) - radii[i] - radii[j]
        result["min_robot_robot"] = float(gap.min())
        result["robot_robot_contacts"] = int(_onsets(gap < 0).sum())
    if humans.size and stack.humans is not None:
        human_radii = np.asarray(stack.humans.human_radii)
        gap = (np.linalg.norm(xy[:, :, None] - humans[:, None, :], axis=-1)
               - radii[None, :, None] - human_radii[None, None, :])
        result["min_robot_human"] = float(gap.min())
    return result


def _onsets(flags: np.ndarray) -> np.ndarray:
    """Per column, how many times ``flags`` (T, K) turns true."""
    before = np.vstack([np.zeros((1,) + flags.shape[1:], bool), flags[:-1]])
    return (flags & ~before).sum(axis=0)


def _tasks(events: list) -> dict:
    """Task completions seen in the recorder's arrival events."""
    done = sorted({e["task"] for e in events
                   if e["type"] == "arrival" and e.get("action") == DROPOFF
                   and e.get("task") is not None})
    return {"completed": len(done), "completed_ids": done}


def format_summary(summary: dict) -> str:
    """The summary as a short plain-text table."""
    lines = [
        f"scenario   {summary['scenario']}",
        f"simulated  {summary['duration']:.1f} s in {summary['wall_time']:.2f} s wall "
        f"(real-time factor {summary['real_time_factor']:.1f})",
        f"tasks      {summary['tasks']['completed']} completed",
        "",
        f"{'robot':<12}{'distance m':>12}{'stops':>8}   final pose (x, y, theta)",
    ]
    for name, robot in summary["robots"].items():
        pose = robot["final_pose"] or [float("nan")] * 3
        lines.append(f"{name:<12}{robot['distance']:>12.1f}{robot['stops_completed']:>8}   "
                     f"({pose[0]:.2f}, {pose[1]:.2f}, {pose[2]:.2f})")
    safety = summary["safety"]
    lines.append("")
    for key in ("min_robot_robot", "min_robot_wall", "min_robot_human"):
        value = safety[key]
        lines.append(f"{key.replace('_', ' '):<18}"
                     + ("   n/a" if value is None else f"{value:8.3f} m"))
    lines.append(f"{'contacts':<18}{safety['robot_robot_contacts']:>6} robot-robot, "
                 f"{safety['robot_wall_contacts']} robot-wall")
    lines.append(f"{'failures':<18}{summary['planner_failures']:>6} planner, "
                 f"{summary['controller_failures']} controller")
    return "\n".join(lines)
