"""End to end: a building imported by ``mrta-sim import`` runs and robots complete tasks."""

from pathlib import Path

from mrta_drake import load_scenario, simulate
from mrta_drake.tools.building_import import ImportOptions, import_building

BUILDING = Path(__file__).parents[1] / "data" / "buildings" / "one_level.building.yaml"


def test_imported_building_runs_and_completes_tasks(tmp_path):
    import_building(str(BUILDING), str(tmp_path), ImportOptions(robots=3, seed=2))
    scenario = load_scenario(tmp_path / "scenario.yaml")
    result = simulate(scenario, duration=120.0, plots=False)
    summary = result.summary
    assert summary["tasks"]["released"] >= 3
    assert summary["tasks"]["completed"] >= 3
    assert summary["deadlocks"]["count"] == 0
    safety = summary["safety"]
    assert safety["robot_wall_contacts"] == 0 and safety["robot_robot_contacts"] == 0
