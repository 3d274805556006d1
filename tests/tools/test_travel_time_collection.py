"""Travel-time collection: one robot drives every ordered pair of locations of a small open
room with a lane loop; the matrix, repeats and stats, failed legs, files and the CLI."""

import dataclasses
import math
import pathlib

import numpy as np
import pytest
import yaml

from mrta_drake import load_scenario, simulate
from mrta_drake.errors import InputError
from mrta_drake.navigation.roadways import Roadways
from mrta_drake.results.timing import leg_rows
from mrta_drake.scenario.schema import DisturbancesConfig
from mrta_drake.scenario.travel_times import load_travel_times, write_travel_times
from mrta_drake.stack.blocks import BuildContext, replace_block, resolve_block
from mrta_drake.tools.cli import main
from mrta_drake.tools.travel_time_collection import (
    _drive,
    _one_robot,
    collect_travel_times,
    eulerian_circuit,
    measure_legs,
)

ROOT = pathlib.Path(__file__).resolve().parents[2]

# A 9 m x 6 m room; a counterclockwise one-way loop (eastbound at y = 2.2, westbound at
# y = 3.8); three locations: west and east below the loop, north above it.
FLOOR_PLAN = """
name: tiny
bounds: [0.0, 9.0, 0.0, 6.0]
walls:
  - {from: [0.0, 0.0], to: [9.0, 0.0]}
  - {from: [9.0, 0.0], to: [9.0, 6.0]}
  - {from: [9.0, 6.0], to: [0.0, 6.0]}
  - {from: [0.0, 6.0], to: [0.0, 0.0]}
"""
# Three walls closing the north location in (its queue slot stays outside).
ENCLOSURE = """
  - {from: [3.7, 6.0], to: [3.7, 4.5]}
  - {from: [3.7, 4.5], to: [5.3, 4.5]}
  - {from: [5.3, 4.5], to: [5.3, 6.0]}
"""
SCENARIO = """
world: {floor_plan: floor_plan.yaml}
locations:
  - {id: 0, name: west, point: [1.0, 0.9], queue: [[2.2, 1.2]], exit_node: S1,
     approach_node: S1}
  - {id: 1, name: east, point: [8.0, 0.9], queue: [[6.8, 1.2]], exit_node: S7,
     approach_node: S4}
  - {id: 2, name: north, point: [4.5, 5.2], queue: [[5.6, 4.8]], exit_node: N4,
     approach_node: N7}
roadways:
  nodes: {S1: [1.5, 2.2], S4: [4.5, 2.2], S7: [7.5, 2.2], N7: [7.5, 3.8], N4: [4.5, 3.8],
          N1: [1.5, 3.8]}
  edges: [[S1, S4], [S4, S7], [S7, N7], [N7, N4], [N4, N1], [N1, S1]]
robots:
  - {name: r1, start: [1.0, 0.9], start_location: 0}
  - {name: r2, start: [8.0, 0.9], start_location: 1}
seed: 0
duration: 60.0
"""


def _write_world(folder, floor_plan: str = FLOOR_PLAN) -> str:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "floor_plan.yaml").write_text(floor_plan)
    (folder / "scenario.yaml").write_text(SCENARIO)
    return str(folder / "scenario.yaml")


@pytest.fixture(scope="module")
def tiny(tmp_path_factory) -> str:
    return _write_world(tmp_path_factory.mktemp("tiny"))


@pytest.fixture(scope="module")
def legs(tiny):
    return measure_legs(load_scenario(tiny), repeats=2)


@pytest.mark.parametrize("count", [2, 3, 6])
def test_eulerian_circuit_drives_every_ordered_pair_once(count):
    pairs = {(a, b) for a in range(count) for b in range(count) if a != b}
    for shift in range(count):
        route = eulerian_circuit(count, shift)
        assert route[0] == route[-1] == shift
        driven = list(zip(route, route[1:], strict=False))
        assert len(driven) == len(pairs) and set(driven) == pairs


def test_matrix_is_square_positive_and_physically_plausible(tiny, legs):
    scenario = load_scenario(tiny)
    matrix = legs.matrix("max")
    assert legs.failures == () and legs.robot == "r1"
    assert legs.samples.shape == (2, 3, 3) and np.isfinite(legs.samples).all()
    assert matrix.shape == (3, 3) and matrix.dtype.kind == "i"
    assert (np.diag(matrix) == 0).all()
    off = ~np.eye(3, dtype=bool)
    assert (matrix[off] > 0).all()
    # No faster than a straight line at the robots' top speed...
    max_speed = resolve_block(scenario, "robots")[1].max_speed
    points = np.array([location.point for location in scenario.locations])
    straight = np.linalg.norm(points[:, None] - points[None], axis=2)
    assert (legs.samples[:, off] >= straight[off] / max_speed).all()
    # ...and close to the roadway estimate at the nominal speed.
    estimate = Roadways(scenario.roadways, scenario.locations).travel_time_estimate(
        scenario.tasks.estimate_speed)
    ratio = matrix[off] / estimate[off]
    assert (ratio > 0.4).all() and (ratio < 2.5).all(), ratio


def test_a_leg_is_what_the_results_measure_minus_the_service_time(tiny, legs):
    """Repeat 0 starts with the leg west -> north, the robot standing on west's point as if
    it had just driven in from the queue slot; a plain run of that route, timed by the
    results' ``leg_rows``, gives the same leg."""
    scenario = load_scenario(tiny)
    heading = math.atan2(0.9 - 1.2, 1.0 - 2.2)
    robot = dataclasses.replace(scenario.robots[0], start=[1.0, 0.9, heading], route=[0, 2])
    scenario = replace_block(dataclasses.replace(scenario, robots=[robot]), "allocator", "fixed")
    rows = leg_rows(simulate(scenario, duration=25.0, plots=False).events)
    assert [row["location"] for row in rows] == [0, 2]
    measured = rows[1]["actual"] - scenario.tasks.service_time
    assert legs.samples[0, 0, 2] == pytest.approx(measured, abs=1e-9)


def test_repeats_drive_other_circuits_and_mean_is_at_most_max(legs):
    maximum, mean = legs.matrix("max"), legs.matrix("mean")
    assert (mean <= maximum).all()
    assert (maximum >= legs.samples.max(axis=0)).all()
    assert (maximum < legs.samples.max(axis=0) + 1).all()
    # Each leg follows another leg in the other repeat, so some legs take other times.
    assert not np.array_equal(legs.samples[0], legs.samples[1])
    with pytest.raises(InputError, match="stat.*median"):
        legs.matrix("median")


def test_failed_legs_are_reported_and_never_written(tmp_path):
    walled_in = FLOOR_PLAN + ENCLOSURE
    scenario = load_scenario(_write_world(tmp_path, walled_in))
    failed = measure_legs(scenario, time_limit=20.0)
    assert {(f.origin, f.destination) for f in failed.failures} == {
        (0, 2), (2, 0), (1, 2), (2, 1)}
    assert np.isnan(failed.samples[0, [0, 1, 2, 2], [2, 2, 0, 1]]).all()
    assert np.isfinite(failed.samples[0, [0, 1], [1, 0]]).all()
    with pytest.raises(InputError) as error:
        failed.matrix()
    message = str(error.value)
    assert "\n" not in message and "r1 did not complete 4 leg(s) within 20 s" in message
    assert "0->2 (repeat 1)" in message and "2->1 (repeat 1)" in message


def test_matrix_files_round_trip_as_yaml_and_csv(tmp_path, legs):
    matrix = legs.matrix("max")
    for name in ("times.yaml", "times.csv"):
        path = str(tmp_path / name)
        write_travel_times(path, matrix, stat="max", repeats=2)
        assert np.array_equal(load_travel_times(path, 3), matrix)
    content = yaml.safe_load((tmp_path / "times.yaml").read_text())
    assert content["stat"] == "max" and content["repeats"] == 2


def test_cli_writes_the_matrix_and_refuses_bad_flags(tmp_path, tiny, legs, capsys):
    out = tmp_path / "matrix.yaml"
    assert main(["travel-times", tiny, "--out", str(out), "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert f"written to {out}" in printed and "6 legs x 1 repeats (max)" in printed
    content = yaml.safe_load(out.read_text())
    assert content["stat"] == "max" and content["repeats"] == 1 and content["robot"] == "r1"
    # One repeat drives repeat 0's circuit: the same legs as the library's first repeat.
    assert np.array_equal(load_travel_times(str(out), 3),
                          np.ceil(legs.samples[0] - 1e-6).astype(int))
    for flags, field in ((["--repeats", "0"], "repeats"), (["--stat", "median"], "stat"),
                         (["--robot", "r9"], "robot"), (["--out", "m.txt"], "--out")):
        assert main(["travel-times", tiny, *flags, "--quiet"]) == 2
        error = capsys.readouterr().err
        assert error.count("\n") == 1 and field in error, error


def test_collect_checks_the_stat_before_driving(tiny):
    with pytest.raises(InputError, match="stat"):
        collect_travel_times(load_scenario(tiny), stat="median")


def test_scheduled_disturbances_are_left_out_of_the_measuring_run():
    # Its breakdown and outage name robots the one-robot run does not have; its blockage
    # would make the times not the nominal ones.
    scenario = load_scenario(ROOT / "scenarios/hospital_disturbances.yaml")
    context = BuildContext.for_scenario(scenario)
    alone = _one_robot(context.scenario, 0, [0, 1], context.roadways, humans=False)
    assert alone.disturbances == DisturbancesConfig()
    ((origin, destination, seconds),) = _drive(alone, [0, 1], time_limit=120.0)
    assert (origin, destination) == (0, 1) and 0.0 < seconds < 120.0
