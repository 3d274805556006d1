"""Printing results: one run's ``summary.json`` as tables, or two runs side by side."""

import json
import math
import os

from mrta_drake.errors import InputError

SUMMARY_FILE = "summary.json"


def load_summary(folder: str) -> dict:
    """The summary of the run whose results ``mrta-sim run --out`` wrote to ``folder``,
    checked printable (``format_summary``): one edited by hand, or written by another
    version, that is not raises ``InputError``."""
    path, summary = _read_summary(folder)
    printed(path, format_summary, summary)
    return summary


def summary_report(folder: str) -> str:
    """The tables ``mrta-sim report`` prints for the run in ``folder`` (``format_summary``;
    ``InputError`` as for ``load_summary``)."""
    path, summary = _read_summary(folder)
    return printed(path, format_summary, summary)


def _read_summary(folder: str) -> tuple[str, dict]:
    """The path of ``folder``'s summary and the summary read from it, a mapping with the
    tasks, robots and safety sections; else ``InputError``."""
    path = os.path.join(folder, SUMMARY_FILE)
    if not os.path.isdir(folder):
        raise InputError(folder, None, "no such folder")
    if not os.path.isfile(path):
        raise InputError(folder, None, f"no {SUMMARY_FILE} here (write one with "
                         "`mrta-sim run SCENARIO --out DIR`)")
    try:
        with open(path) as f:
            summary = json.load(f)
    except (OSError, ValueError) as error:
        raise InputError(path, None, f"unreadable: {error}") from None
    if not isinstance(summary, dict) or not {"tasks", "robots", "safety"} <= summary.keys():
        raise InputError(path, None, "not a run summary (tasks, robots, safety missing)")
    return path, summary


def printed(where: str, format_results, *summaries) -> str:
    """``format_results(*summaries)``; a field missing or of another type than this
    version writes raises ``InputError`` naming ``where`` (the file or files)."""
    try:
        return format_results(*summaries)
    except KeyError as error:
        raise InputError(where, None, f"not a summary this version can print: field "
                         f"{error.args[0]!r} missing (written by another version, or "
                         "edited?)") from None
    except (TypeError, ValueError, IndexError, AttributeError) as error:
        raise InputError(where, None, f"not a summary this version can print: a field "
                         f"has another type ({error})") from None


def format_summary(summary: dict) -> str:
    """The summary as plain-text tables: run, tasks, robots, safety, humans, deadlocks,
    disturbances."""
    tasks = summary["tasks"]
    lines = [
        f"scenario   {summary['scenario']}",
        f"           hash {summary['scenario_hash']}, seed {summary['seed']}, "
        f"drake {summary['versions'].get('drake')}",
        f"simulated  {summary['duration']:.1f} s"
        + (" (interrupted)" if summary.get("interrupted") else "")
        + f" in {summary['wall_time']:.2f} s wall "
        f"(real-time factor {_number(summary['real_time_factor'], '.1f')})",
        f"tasks      {tasks['total']} total, {tasks['released']} released, "
        f"{tasks['completed']} completed: {tasks['on_time']} on time, {tasks['late']} late; "
        f"{tasks['missed']} missed deadline"
        + (f"; {tasks['failed']} failed (items lost)" if tasks.get("failed") else ""),
    ]
    if tasks["completed"]:
        lines.append(f"lateness   mean {_number(tasks['mean_lateness'], '.1f', True)} s, "
                     f"max {_number(tasks['max_lateness'], '.1f', True)} s, tardiness "
                     f"{_number(tasks['total_tardiness'], '.1f')} s")
    lines += _format_predictions(summary.get("predictions"), len(summary["legs"]))
    if tasks["per_task"]:
        lines += ["", text_table(
            ["task", "arrival", "robot", "pickup pred", "actual", "drop-off pred", "actual",
             "deadline", "lateness", "status"],
            [[t["id"], _number(t["arrival"], ".1f"), t["robot"] or "-",
              _number(t["predicted_pickup"], ".1f"), _number(t["actual_pickup"], ".1f"),
              _number(t["predicted_dropoff"], ".1f"), _number(t["actual_dropoff"], ".1f"),
              _number(t["deadline"], ".1f"), _number(t["lateness"], ".1f", sign=True), t["status"]]
             for t in tasks["per_task"]])]
    lines += ["", text_table(
        ["robot", "distance m", "busy s", "queue s", "idle s", "stops", "planner failures"],
        [[name, _number(r["distance"], ".1f"), _number(r["busy_time"], ".1f"),
          _number(r["queue_time"], ".1f"), _number(r["idle_time"], ".1f"),
          r["stops_completed"], r["planner_failures"]]
         for name, r in summary["robots"].items()])]
    safety = summary["safety"]
    lines += ["", "safety"]
    for kind, label in (("robot_robot", "robot-robot"), ("robot_wall", "robot-wall"),
                        ("robot_human", "robot-human")):
        value = safety[f"min_{kind}"]
        lines.append(f"  min {label:<14}" + ("n/a" if value is None else
                     f"{value:6.3f} m at {safety[f'min_{kind}_time']:.1f} s "
                     f"({', '.join(safety[f'min_{kind}_between'])})"))
    lines += [
        f"  {'contacts':<18}{safety['robot_robot_contacts']} robot-robot, "
        f"{safety['robot_wall_contacts']} robot-wall, {safety['robot_human_contacts']} "
        "robot-human",
    ]
    if "robot_wall_close_time" in safety:  # summaries written before it have none
        lines.append(f"  {'near walls':<18}{safety['robot_wall_close_time']:.1f} robot-s "
                     f"within {safety['robot_wall_close_distance']:g} m of a wall")
    lines += [
        f"  {'CBF slack':<18}max {safety['max_cbf_slack']:.3g} m/s^2, "
        f"{safety['cbf_slack_time']:.1f} s relaxed",
        f"  {'failures':<18}{summary['planner_failures']} planner, "
        f"{summary['controller_failures']} controller",
    ]
    humans = summary.get("humans")
    if humans:
        lines.append(f"humans     {humans['personal_space_time']:.1f} robot-s in personal "
                     f"space, {humans['contacts']} contacts, {humans['encounters']} "
                     f"encounters, {humans['detour_length']:.1f} m detours")
    lines.append(_format_deadlocks(summary["deadlocks"]))
    if summary.get("back_offs", {}).get("count"):
        per_robot = ", ".join(f"{robot} {n}" for robot, n in summary["back_offs"]["robots"].items())
        releases = summary["back_offs"].get("releases")
        lines.append(f"back-offs  {summary['back_offs']['count']} ordered by the deadlock "
                     f"watchdog ({per_robot})"
                     + (f", {releases} to break gridlocks of waits" if releases else ""))
    lines += _format_disturbances(summary.get("disturbances") or [], summary["duration"])
    return "\n".join(lines)


def _format_predictions(predictions: dict | None, stops: int) -> list[str]:
    """Lines on the allocator's predictions (``summary["predictions"]``)."""
    if not predictions:
        return []
    lines = []
    for key, label in (("dropoff_error", "drop-offs"), ("leg_error", "legs")):
        error = predictions[key]
        if error["count"]:
            what = f"{stops} stops done; " if key == "leg_error" else ""
            lines.append(f"{label:<11}{what}actual - predicted: |median| "
                         f"{error['median_abs']:.1f} s, |p90| {error['p90_abs']:.1f} s, bias "
                         f"{error['bias']:+.1f} s, max {error['max']:+.1f} s")
    broken, replans = predictions["broken_promises"], predictions["replans"]
    reasons = ", ".join(f"{n} {kind}" for kind, n in sorted(replans["reasons"].items()))
    lines.append(f"promises   {predictions['promised']} planned on time, {len(broken)} broken"
                 + (f" ({', '.join(map(str, broken))})" if broken else "")
                 + f"; {len(predictions['unpromised'])} not promised; {replans['count']} "
                 f"re-plans on drift" + (f" ({reasons})" if reasons else ""))
    return lines


def _format_disturbances(disturbances: list[dict], duration: float) -> list[str]:
    lines = ["disturbances"] if disturbances else []
    for d in disturbances:
        window = (f"from {d['start']:g} s" if d["end"] is None
                  else f"{d['start']:g}-{d['end']:g} s")
        if d["start"] >= duration:
            what = "after the end of the run"
        elif d["kind"] == "blockage":
            what = (f"re-routed {', '.join(d['robots_rerouted']) or 'nobody'} "
                    f"({d['detours']} detours)" + (
                        f"; no lane left for {', '.join(d['robots_waited'])}"
                        if d["robots_waited"] else ""))
        elif d["kind"] == "breakdown":
            what = ("never out of the fleet" if d["removed_at"] is None else
                    f"out of the fleet at {d['removed_at']:g} s, tasks reassigned "
                    f"{d['tasks_reassigned']}, failed {d['tasks_failed']}")
        else:
            what = f"closest robot {_number(d['min_robot_clearance'], '.3f')} m"
        lines.append(f"  {d['kind']} {d.get('name') or d.get('robot')} {window}: {what}")
    return lines


def _format_deadlocks(deadlocks: dict) -> str:
    if not deadlocks["count"]:
        return (f"deadlocks  none (no robot with a target stuck for "
                f"{deadlocks['stuck_time']:g} s)")
    lines = [f"deadlocks  {deadlocks['count']}"]
    for d in deadlocks["episodes"]:
        until = "the end" if d["end"] is None else f"{d['end']:.1f} s"
        near = ", ".join(d["robots_near"] + d["humans_near"]) or "nobody"
        lines.append(f"  {d['robot']} stuck from {d['start']:.1f} s to {until} "
                     f"({d['duration']:.1f} s) at ({d['position'][0]:.2f}, "
                     f"{d['position'][1]:.2f}); near: {near}")
    return "\n".join(lines)


# --- Two runs side by side ---------------------------------------------------------------------


def _total(key):
    return lambda s: sum(r[key] for r in s["robots"].values())


# (label, how to read it from a summary) for ``format_comparison``.
_COMPARED = [
    ("tasks completed", lambda s: s["tasks"]["completed"]),
    ("tasks on time", lambda s: s["tasks"]["on_time"]),
    ("tasks late", lambda s: s["tasks"]["late"]),
    ("deadlines missed", lambda s: s["tasks"]["missed"]),
    ("mean lateness s", lambda s: s["tasks"]["mean_lateness"]),
    ("max lateness s", lambda s: s["tasks"]["max_lateness"]),
    ("total tardiness s", lambda s: s["tasks"]["total_tardiness"]),
    ("distance m (all robots)", _total("distance")),
    ("busy time s (all robots)", _total("busy_time")),
    ("queue time s (all robots)", _total("queue_time")),
    ("min robot-robot m", lambda s: s["safety"]["min_robot_robot"]),
    ("min robot-wall m", lambda s: s["safety"]["min_robot_wall"]),
    ("min robot-human m", lambda s: s["safety"]["min_robot_human"]),
    ("robot-robot contacts", lambda s: s["safety"]["robot_robot_contacts"]),
    ("robot-wall contacts", lambda s: s["safety"]["robot_wall_contacts"]),
    ("robot-human contacts", lambda s: s["safety"]["robot_human_contacts"]),
    ("robot-s near walls", lambda s: s["safety"].get("robot_wall_close_time")),
    ("max CBF slack m/s^2", lambda s: s["safety"]["max_cbf_slack"]),
    ("planner failures", lambda s: s["planner_failures"]),
    ("controller failures", lambda s: s["controller_failures"]),
    ("deadlocks", lambda s: s["deadlocks"]["count"]),
    ("watchdog back-offs", lambda s: s.get("back_offs", {}).get("count")),
    ("simulated s", lambda s: s["duration"]),
    ("real-time factor", lambda s: s["real_time_factor"]),
]


def format_comparison(a: dict, b: dict, names: tuple[str, str] = ("A", "B")) -> str:
    """Two summaries side by side, with the difference (second minus first) per figure,
    and per-robot distances for the robots both runs have."""
    rows = [["scenario hash", a["scenario_hash"], b["scenario_hash"],
             "same" if a["scenario_hash"] == b["scenario_hash"] else "differ"],
            ["seed", a["seed"], b["seed"], "same" if a["seed"] == b["seed"] else "differ"]]
    for label, read in _COMPARED:
        rows.append(_compared(label, read(a), read(b)))
    for name in a["robots"]:
        if name in b["robots"]:
            rows.append(_compared(f"distance m {name}", a["robots"][name]["distance"],
                                  b["robots"][name]["distance"]))
    return text_table(["", *names, f"{names[1]} - {names[0]}"], rows)


def format_runs(summaries: dict[str, dict]) -> str:
    """Any number of summaries (run name -> summary) side by side: the figures of
    ``format_comparison``, one column per run."""
    return text_table(["", *summaries], [[label, *(_number(read(s)) for s in summaries.values())]
                                         for label, read in _COMPARED])


def _compared(label: str, x, y) -> list:
    difference = "n/a" if x is None or y is None else _number(y - x, sign=True)
    return [label, _number(x), _number(y), difference]


# --- Formatting --------------------------------------------------------------------------------


def _number(value, spec: str | None = None, sign: bool = False) -> str:
    """``value`` formatted with ``spec`` (default: 2 decimals, 3 significant digits below
    0.1); "-" for None and NaN; ints as ints. ``sign`` shows a plus sign."""
    plus = "+" if sign else ""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"
    if isinstance(value, int):
        return f"{value:{plus}d}"
    if spec is None:
        spec = ".2f" if value == 0 or abs(value) >= 0.1 else ".3g"
    return format(value, plus + spec)


def text_table(header: list[str], rows: list[list]) -> str:
    """``rows`` under ``header`` as plain text: the first column left-aligned, the others
    right-aligned, two spaces apart."""
    cells = [[str(c) for c in header]] + [[str(c) for c in row] for row in rows]
    widths = [max(len(row[k]) for row in cells) for k in range(len(header))]
    return "\n".join(
        "  ".join(cell.ljust(w) if k == 0 else cell.rjust(w)
                  for k, (cell, w) in enumerate(zip(row, widths, strict=True))).rstrip()
        for row in cells)
