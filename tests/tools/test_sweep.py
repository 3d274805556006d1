"""Sweeps: a tiny grid runs in parallel processes, writes the table, resumes without redoing
runs and records a failing run as an error row; bad specs name the spec file and field."""

import csv
import json
import pathlib
import sys

import pytest

from mrta_drake.errors import InputError
from mrta_drake.tools.cli import main
from mrta_drake.tools.sweep import load_sweep, sweep_scenario

ROOT = pathlib.Path(__file__).resolve().parents[2]
ROUTES = ROOT / "scenarios/hospital_routes_6_robots.yaml"
HOSPITAL = ROOT / "scenarios/hospital_6_robots.yaml"
BROKEN = sorted((ROOT / "tests/data/broken_sweeps").glob("*.yaml"))


def write_spec(path: pathlib.Path, kinds: str, scenario=ROUTES, extra: str = "") -> str:
    path.write_text(f"""
scenario: {scenario}
grid:
  seed: [0, 1]
  blocks.controller.kind: {kinds}
{extra}fixed:
  duration: 5.0
""")
    return str(path)


def read_table(out: pathlib.Path) -> list[dict]:
    with open(out / "results.csv", newline="") as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def first_sweep(tmp_path_factory):
    """2 seeds x 2 controllers, 5 s each, on 2 worker processes."""
    folder = tmp_path_factory.mktemp("sweep")
    spec = write_spec(folder / "spec.yaml", "[cluster_cbf, go_to_goal]")
    out = folder / "out"
    code = main(["sweep", spec, "--out", str(out), "--workers", "2", "--quiet"])
    return folder, out, code


def test_tiny_sweep_runs_every_combination_and_writes_the_table(first_sweep, capsys):
    _, out, code = first_sweep
    assert code == 0
    rows = read_table(out)
    assert [r["run_id"] for r in rows] == [
        "seed=0__blocks.controller.kind=cluster_cbf", "seed=0__blocks.controller.kind=go_to_goal",
        "seed=1__blocks.controller.kind=cluster_cbf", "seed=1__blocks.controller.kind=go_to_goal"]
    assert {r["status"] for r in rows} == {"ok"}
    for row in rows:
        assert (out / "runs" / row["run_id"] / "summary.json").is_file()
        assert float(row["real_time_factor"]) > 0 and float(row["wall_time"]) > 0
        assert float(row["min_robot_robot"]) > 0
        assert row["tasks_completed"] == "0" and row["error"] == ""
    assert rows[0]["seed"] == "0" and rows[1]["blocks.controller.kind"] == "go_to_goal"


def test_sweep_resumes_and_records_a_failing_run_as_an_error_row(first_sweep, capsys):
    folder, out, _ = first_sweep
    summaries = sorted((out / "runs").glob("*/summary.json"))
    # A run stopped part way (Ctrl-C) wrote a summary saying so: it is run again.
    stopped, *summaries = summaries
    summary = json.loads(stopped.read_text())
    stopped.write_text(json.dumps(summary | {"interrupted": True, "duration": 2.0}))
    stamps = [p.stat().st_mtime_ns for p in summaries]
    spec = write_spec(folder / "more.yaml", "[cluster_cbf, go_to_goal, no_such_controller]")
    capsys.readouterr()
    assert main(["sweep", spec, "--out", str(out), "--workers", "2", "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert "6 runs (3 run now, 3 reused, 2 failed)" in printed
    assert [p.stat().st_mtime_ns for p in summaries] == stamps  # not redone
    redone = json.loads(stopped.read_text())
    assert not redone["interrupted"] and redone["duration"] == 5.0
    rows = read_table(out)
    assert len(rows) == 6
    failed = [r for r in rows if r["status"] == "error"]
    assert [r["run_id"] for r in failed] == [
        "seed=0__blocks.controller.kind=no_such_controller",
        "seed=1__blocks.controller.kind=no_such_controller"]
    assert all("unknown kind 'no_such_controller'" in r["error"] for r in failed)
    assert all(r["tasks_completed"] == "" for r in failed)
    assert (out / "runs" / failed[0]["run_id"] / "error.txt").is_file()
    assert "no_such_controller" in printed


def test_sweep_scenario_takes_the_first_robots_and_drops_people():
    settings = {"seed": 3, "robots": 2, "humans": False, "duration": 7.0}
    scenario = sweep_scenario(str(HOSPITAL), settings)
    assert [r.name for r in scenario.robots] == ["robot1", "robot2"]
    assert not scenario.humans.walkers and not scenario.humans.groups
    assert (scenario.seed, scenario.duration) == (3, 7.0)
    kept = sweep_scenario(str(HOSPITAL), {"humans": True})
    assert kept.humans.walkers and len(kept.robots) == 6


@pytest.mark.parametrize("extra, field, words", [
    ("  blocks.controler.kind: [a]\n", "grid.blocks.controler.kind", "unknown field 'controler'"),
    ("  robots: [2, 9]\n", "grid.robots[1]", "from 1 to the scenario's 6"),
    ("  humans: [yes please]\n", "grid.humans[0]", "true or false"),
    ("  duration: 5\n", "grid.duration", "non-empty list"),
    ("  locations.point: [1]\n", "grid.locations.point", "not a mapping"),
    ("  rates.controller: [20, fast]\n", "grid.rates.controller[1]", "expected a number"),
])
def test_bad_specs_name_the_spec_file_and_field(tmp_path, extra, field, words):
    spec = write_spec(tmp_path / "bad.yaml", "[go_to_goal]", extra=extra)
    with pytest.raises(InputError) as error:
        load_sweep(spec)
    assert (error.value.file, error.value.field) == (spec, field)
    assert words in str(error.value)


def test_spec_without_scenario_or_grid(tmp_path, capsys):
    spec = tmp_path / "bad.yaml"
    spec.write_text("scenario: nowhere.yaml\ngrid: {seed: [0]}\n")
    assert main(["sweep", str(spec)]) == 2
    assert "bad.yaml: scenario: file not found: 'nowhere.yaml'" in capsys.readouterr().err
    spec.write_text(f"scenario: {ROUTES}\ngrids: {{}}\n")
    with pytest.raises(InputError, match="unknown field"):
        load_sweep(str(spec))


@pytest.mark.parametrize("path", BROKEN, ids=lambda p: p.stem)
def test_broken_spec_gives_one_clear_line(path, tmp_path, capsys):
    """Each broken spec states the line it must produce in its first line: ``# expect: ...``."""
    assert main(["sweep", str(path), "--out", str(tmp_path / "out")]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    expected = path.read_text().splitlines()[0].removeprefix("# expect:").strip()
    assert len(lines) == 1 and lines[0].startswith("error: ")
    assert expected in lines[0]


def test_ray_without_ray_is_one_line(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray now fails
    spec = write_spec(tmp_path / "spec.yaml", "[go_to_goal]")
    assert main(["sweep", spec, "--out", str(tmp_path / "out"), "--ray", "auto"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["error: --ray: needs Ray: pip install 'mrta-drake[distributed]'"]


def test_example_spec_loads():
    spec = load_sweep(str(ROOT / "scenarios/sweeps/hospital_20_seeds.yaml"))
    runs = spec.runs()
    assert len(runs) == 40
    assert runs[-1].settings["seed"] == 19 and runs[-1].settings["duration"] == 300.0


PLUGIN = """
from mrta_drake.stack.blocks import block_type, register_block

register_block("controller", "plugin_go_to_goal", block_type("controller", "go_to_goal"))
"""


def test_plugins_register_kinds_for_the_spec_and_for_every_worker(tmp_path):
    # The plugin registers its kind in this process too (on a copy of the registry:
    # tests/conftest.py).
    (tmp_path / "my_blocks.py").write_text(PLUGIN)
    spec = tmp_path / "spec.yaml"
    spec.write_text(f"""
scenario: {ROUTES}
grid:
  blocks.controller.kind: [plugin_go_to_goal]
fixed:
  duration: 2.0
plugins: [my_blocks.py]
""")
    out = tmp_path / "out"
    assert main(["sweep", str(spec), "--out", str(out), "--workers", "1", "--quiet"]) == 0
    (row,) = read_table(out)
    # The worker is a fresh process: the run only works if it imported the plugin too.
    assert row["status"] == "ok", row["error"]
    assert float(row["min_robot_robot"]) > 0


@pytest.mark.parametrize("plugins, field, message", [
    ("[missing.py]", "plugins[0]", "file not found: 'missing.py'"),
    ("[broken.py]", "plugins[0]", "'broken.py' failed to import: ZeroDivisionError"),
    ("[no_such_module_here]", "plugins[0]", "failed to import: ModuleNotFoundError"),
])
def test_bad_plugins_name_the_spec_file_and_entry(tmp_path, plugins, field, message):
    (tmp_path / "broken.py").write_text("1 / 0\n")
    spec = tmp_path / "spec.yaml"
    spec.write_text(f"scenario: {ROUTES}\ngrid:\n  seed: [0]\nplugins: {plugins}\n")
    with pytest.raises(InputError) as caught:
        load_sweep(str(spec))
    assert caught.value.file == str(spec) and caught.value.field == field
    assert message in str(caught.value)

