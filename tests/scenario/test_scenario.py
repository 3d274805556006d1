"""Scenario loading: valid files load into frozen dataclasses; every broken file in
tests/data/broken_scenarios gives one clear line naming file, field and value, exit 2."""

import dataclasses
import pathlib
import subprocess
import sys

import pytest

from mrta_drake.errors import InputError
from mrta_drake.scenario.loading import load_scenario
from mrta_drake.scenario.section_files import load_task_file
from mrta_drake.tools.cli import main

ROOT = pathlib.Path(__file__).resolve().parents[2]
BROKEN_DIR = ROOT / "tests/data/broken_scenarios"
BROKEN = sorted(p for p in BROKEN_DIR.glob("*.yaml") if p.read_text().startswith("# expect:"))
# The files the broken scenarios name (robot setups, task files, maps), and the paper's tasks.
NAMED = {p.name for p in BROKEN_DIR.iterdir() if p not in BROKEN} | {"hospital_paper_stream.json"}


def _expectation(path: pathlib.Path) -> str:
    return path.read_text().splitlines()[0].removeprefix("# expect:").strip()


@pytest.mark.parametrize("path", BROKEN, ids=lambda p: p.stem)
def test_broken_scenario_gives_one_clear_line(path, capsys):
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("error: ")
    assert _expectation(path) in lines[0]
    assert any(name in lines[0] for name in NAMED | {path.name})


@pytest.mark.parametrize("name", ["robot_in_wall", "duplicate_key", "task_file_agents_differ"])
def test_broken_files_fail_through_the_console_script_without_traceback(name):
    path = BROKEN_DIR / f"{name}.yaml"
    done = subprocess.run([sys.executable, "-m", "mrta_drake.tools.cli", "validate", str(path)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2
    assert "Traceback" not in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1


def test_hospital_scenario_loads_frozen_with_legacy_task_stream():
    scenario = load_scenario(ROOT / "scenarios/hospital_6_robots.yaml")
    assert [r.name for r in scenario.robots] == [f"robot{k}" for k in range(1, 7)]
    assert [b.arrival for b in scenario.tasks.stream] == [0.0, 40.0]
    second = scenario.tasks.stream[1].tasks[0]
    assert (second.pickup, second.dropoff, second.deadline) == (3, 0, 150.0)
    assert {loc.id for loc in scenario.locations} == set(range(6))
    assert scenario.roadways.edges
    with pytest.raises(dataclasses.FrozenInstanceError):
        scenario.seed = 3
    assert pathlib.Path(scenario.world.floor_plan).is_absolute()


def test_original_robot_setup_is_read_unchanged(tmp_path):
    scenario_file = tmp_path / "s.yaml"
    scenario_file.write_text(
        f"world: {{floor_plan: {ROOT / 'models/hospital/floor_plan.yaml'}}}\n"
        f"robots: {ROOT / 'scenarios/robots/hospital_2_robots_mrta_sim.yaml'}\n")
    scenario = load_scenario(scenario_file)
    assert [(r.name, r.start) for r in scenario.robots] == [
        ("robot1", [0.0, 2.2]), ("robot2", [4.25, -27.2])]


def test_task_file_agents_are_the_start_locations_of_robots_placed_by_their_start(tmp_path):
    """MRTA-Sim robots have no start_location: each starts at the location within 1 m."""
    navigation = ROOT / "models/hospital/navigation.yaml"
    scenario_file = tmp_path / "s.yaml"
    scenario_file.write_text(
        f"world: {{floor_plan: {ROOT / 'models/hospital/floor_plan.yaml'}}}\n"
        f"locations: {navigation}\nroadways: {navigation}\n"
        f"robots: {ROOT / 'scenarios/robots/hospital_2_robots_mrta_sim.yaml'}\n"
        "tasks: {file: tasks.json}\n")
    tasks = tmp_path / "tasks.json"
    stream = '"tasks_stream": [{"arrival": 0, "tasks": [{"start": 0, "end": 3, "deadline": 99}]}]'
    tasks.write_text(f'{{{stream}, "agents": [0, 3]}}')
    assert load_scenario(scenario_file, check_world=False).tasks.stream[0].tasks[0].dropoff == 3
    tasks.write_text(f'{{{stream}, "agents": [0, 1]}}')
    with pytest.raises(InputError) as error:
        load_scenario(scenario_file, check_world=False)
    assert str(error.value) == f"{tasks}: agents[1]: 1, but robot2 (robots[1]) starts at location 3"


def test_robot_setup_in_our_format_names_its_own_file(tmp_path):
    robots = tmp_path / "robots.yaml"
    robots.write_text("robots:\n  - {name: robot1, start: [0.0, 2.2], radius: big}\n")
    scenario_file = tmp_path / "s.yaml"
    scenario_file.write_text(f"world: {{floor_plan: {ROOT / 'models/hospital/floor_plan.yaml'}}}\n"
                             "robots: robots.yaml\n")
    with pytest.raises(InputError) as error:
        load_scenario(scenario_file)
    assert str(error.value) == f"{robots}: robots[0].radius: expected a number, got 'big'"


@pytest.mark.parametrize("navigation, field, words", [
    ("locations:\n  - {id: 0, point: [.nan, 1.0]}\n", "locations[0].point",
     "expected [x, y] in metres, got [nan, 1.0]"),
    ("locations:\n  - {id: 0, point: here}\n", "locations[0].point", "expected a list"),
    ("roadways:\n  nodes: {a: [0.0, 1.0]}\n  edges: [[a, b]]\n", "roadways.edges[0]",
     "unknown node 'b'"),
])
def test_a_section_in_its_own_file_names_that_file(tmp_path, navigation, field, words):
    # `locations: navigation.yaml` (as `mrta-sim import` writes): a bad value in that file
    # names that file, not the scenario that reads it.
    section = "locations" if navigation.startswith("locations") else "roadways"
    (tmp_path / "navigation.yaml").write_text(navigation)
    scenario_file = tmp_path / "s.yaml"
    scenario_file.write_text(f"world: {{floor_plan: {ROOT / 'models/hospital/floor_plan.yaml'}}}\n"
                             "robots:\n  - {name: robot1, start: [0.0, 2.2]}\n"
                             f"{section}: navigation.yaml\n")
    with pytest.raises(InputError) as error:
        load_scenario(scenario_file, check_world=False)
    assert str(error.value).startswith(f"{tmp_path / 'navigation.yaml'}: {field}: {words}")


def test_original_task_stream_json_and_our_stream_agree(tmp_path):
    legacy = tmp_path / "legacy.json"
    legacy.write_text('{"tasks_stream": [{"arrival": 40, "tasks": [{"start": 3, "end": 0, '
                      '"deadline": 150}]}], "agents": [0, 1]}')
    ours = tmp_path / "ours.yaml"
    ours.write_text("stream:\n  - {arrival: 40, tasks: [{pickup: 3, dropoff: 0, "
                    "deadline: 150}]}\n")
    assert load_task_file(legacy).batches == load_task_file(ours).batches


def test_unknown_task_stream_format_is_named(tmp_path):
    path = tmp_path / "tasks.yaml"
    path.write_text("batches: []\n")
    with pytest.raises(InputError, match="tasks.yaml: expected `tasks_stream:`"):
        load_task_file(path)
