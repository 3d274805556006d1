"""`mrta-sim report` and `mrta-sim compare` print a run's results, or two side by side."""

import json
import pathlib
import re

import pytest

from mrta_drake.results.report import format_comparison, format_runs, format_summary
from mrta_drake.results.timing import task_rows, task_totals
from mrta_drake.scenario.schema import TaskBatch, TaskConfig
from mrta_drake.tools.cli import main

ROOT = pathlib.Path(__file__).resolve().parents[2]
ROUTES = ROOT / "scenarios/hospital_routes_6_robots.yaml"


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    """A 5 s run written by the CLI, and a copy of its summary with tasks and a deadlock."""
    first = tmp_path_factory.mktemp("first")
    assert main(["run", str(ROUTES), "--duration", "5", "--out", str(first), "--quiet",
                 "--no-plots"]) == 0
    summary = json.loads((first / "summary.json").read_text())
    stream = [TaskBatch(0.0, [TaskConfig(1, 2, 100.0), TaskConfig(3, 4, 50.0)])]
    events = [
        {"time": 0.0, "type": "plan", "revision": 1, "plans": {"robot2": [
            {"key": "t0/dropoff", "task": 0, "action": "dropoff", "location": 2,
             "planned": 80.0}]}},
        {"time": 90.1, "type": "arrival", "robot": "robot2", "key": "t0/dropoff",
         "location": 2, "at": 90.0, "task": 0, "action": "dropoff"},
    ]
    rows = task_rows(stream, events, 120.0)
    summary["tasks"] = task_totals(rows) | {"per_task": rows}
    summary["deadlocks"]["count"] = 1
    summary["deadlocks"]["episodes"] = [{
        "robot": "robot3", "start": 40.0, "detected": 70.0, "end": None,
        "position": [4.5, -12.0], "robots_near": ["robot4"], "humans_near": ["nurse"],
        "duration": 80.0}]
    summary["real_time_factor"] *= 2
    second = tmp_path_factory.mktemp("second")
    (second / "summary.json").write_text(json.dumps(summary))
    return first, second


def test_report_prints_run_robot_and_safety_rows(folders, capsys):
    first, _ = folders
    assert main(["report", str(first)]) == 0
    printed = capsys.readouterr().out
    for expected in ("real-time factor", "tasks      0 total", "min robot-robot",
                     "min robot-wall", "contacts", "near walls", "CBF slack",
                     "deadlocks  none"):
        assert expected in printed
    robot_rows = [line for line in printed.splitlines() if line.startswith("robot")]
    assert [row.split()[0] for row in robot_rows[1:]] == [f"robot{k}" for k in range(1, 7)]


def test_report_prints_tasks_against_deadlines_and_deadlocks(folders):
    _, second = folders
    printed = format_summary(json.loads((second / "summary.json").read_text()))
    assert "2 completed" not in printed and "1 completed: 1 on time, 0 late" in printed
    task_lines = [line.split() for line in printed.splitlines() if line[:1].isdigit()]
    # task, arrival, robot, pickup pred, actual, drop-off pred, actual, deadline, lateness
    assert task_lines[0] == ["0", "0.0", "robot2", "-", "-", "80.0", "90.0", "100.0", "-10.0",
                             "on_time"]
    assert task_lines[1][2] == "-" and task_lines[1][-1] == "unassigned"
    assert "robot3 stuck from 40.0 s to the end (80.0 s) at (4.50, -12.00); near: robot4, " \
           "nurse" in printed


def test_compare_prints_both_runs_and_the_differences(folders, capsys):
    first, second = folders
    assert main(["compare", str(first), str(second)]) == 0
    printed = capsys.readouterr().out
    header, *rows = printed.splitlines()
    assert header.split() == [first.name, second.name, f"{second.name}", "-", first.name]
    table = {cells[0]: cells[1:] for cells in (re.split(r"\s{2,}", row) for row in rows)}
    assert table["tasks completed"] == ["0", "1", "+1"]
    assert table["tasks on time"] == ["0", "1", "+1"]
    assert table["deadlocks"] == ["0", "1", "+1"]
    assert table["seed"] == ["0", "0", "same"]
    assert table["mean lateness s"] == ["-", "-10.00", "n/a"]
    assert table["min robot-robot m"][2] == "+0.00"
    assert "distance m robot6" in table and "real-time factor" in table


def test_runs_side_by_side_show_each_run_in_its_column(folders):
    first, second = (json.loads((f / "summary.json").read_text()) for f in folders)
    header, *rows = format_runs({"a": first, "b": second, "c": first}).splitlines()
    assert header.split() == ["a", "b", "c"]
    table = {cells[0]: cells[1:] for cells in (re.split(r"\s{2,}", row.strip())
                                               for row in rows)}
    assert table["tasks completed"] == ["0", "1", "0"]
    assert table["deadlocks"] == ["0", "1", "0"]
    assert table["min robot-robot m"][0] == table["min robot-robot m"][2]


def test_comparison_of_a_run_with_itself_shows_no_differences(folders):
    first, _ = folders
    summary = json.loads((first / "summary.json").read_text())
    printed = format_comparison(summary, summary)
    for line in printed.splitlines()[1:]:
        last = line.split()[-1]
        assert last in ("same", "n/a") or float(last) == 0.0, line


@pytest.mark.parametrize("command", [["report", "{empty}"], ["compare", "{run}", "{empty}"],
                                     ["report", "{broken}"], ["report", "{missing}"]])
def test_report_on_a_folder_without_a_summary_is_a_one_line_error(folders, tmp_path, capsys,
                                                                  command):
    (tmp_path / "empty").mkdir()
    (tmp_path / "broken").mkdir()
    (tmp_path / "broken" / "summary.json").write_text("{not json")
    paths = {"empty": tmp_path / "empty", "run": folders[0], "broken": tmp_path / "broken",
             "missing": tmp_path / "missing"}
    assert main([part.format(**paths) for part in command]) == 2
    error = capsys.readouterr().err
    assert error.startswith("error: ") and error.count("\n") == 1


@pytest.mark.parametrize("change, words", [
    (lambda s: s["robots"]["robot2"].pop("idle_time"), "field 'idle_time' missing"),
    (lambda s: s["safety"].update(max_cbf_slack=None), "a field has another type"),
    (lambda s: s["tasks"].update(per_task=[True]), "a field has another type"),
])
@pytest.mark.parametrize("command", [["report", "{edited}"], ["compare", "{run}", "{edited}"]])
def test_a_summary_this_version_cannot_print_is_a_one_line_error(folders, tmp_path, capsys,
                                                                  change, words, command):
    # summary.json edited by hand, or written by another version: no traceback.
    summary = json.loads((folders[0] / "summary.json").read_text())
    change(summary)
    edited = tmp_path / "edited"
    edited.mkdir()
    (edited / "summary.json").write_text(json.dumps(summary))
    assert main([part.format(run=folders[0], edited=edited) for part in command]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and error.startswith(f"error: {edited / 'summary.json'}: ")
    assert "not a summary this version can print" in error and words in error


def test_a_comparison_that_cannot_be_made_names_both_runs(folders, tmp_path, capsys):
    summary = json.loads((folders[0] / "summary.json").read_text())
    summary["safety"]["robot_wall_contacts"] = {"walls": 1}  # printable, not comparable
    edited = tmp_path / "edited"
    edited.mkdir()
    (edited / "summary.json").write_text(json.dumps(summary))
    assert main(["report", str(edited)]) == 0
    capsys.readouterr()
    assert main(["compare", str(folders[0]), str(edited)]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and error.startswith(f"error: {folders[0]} and {edited}: ")
