"""Seeded random task streams: Poisson and fixed-time batches, weights, deadlines, the
scenario's ``tasks.generate`` block and the MRTA-Sim JSON writer."""

import dataclasses
import json
import math
import pathlib

import numpy as np
import pytest

from mrta_drake.errors import InputError
from mrta_drake.scenario.loading import load_scenario
from mrta_drake.scenario.schema import LocationConfig, TaskGenerationConfig
from mrta_drake.scenario.section_files import load_task_file
from mrta_drake.scenario.task_streams import generate_tasks, write_mrta_sim_json

ROOT = pathlib.Path(__file__).resolve().parents[2]
LOCATIONS = [LocationConfig(id=k, name=name) for k, name in
             enumerate(["lobby", "room_1", "room_2", "lab"])]


def travel(a: int, b: int) -> float:
    """A made-up travel-time estimate, s."""
    return 10.0 + 5.0 * abs(a - b)


def draw(config: TaskGenerationConfig, seed: int = 0, duration: float = 600.0):
    return generate_tasks(config, LOCATIONS, travel, seed, duration, "test.yaml")


def test_same_seed_same_stream_other_seed_other_stream():
    config = TaskGenerationConfig(rate=0.05, batch_size=[1, 3])
    assert draw(config, seed=4) == draw(config, seed=4)
    assert draw(config, seed=4) != draw(config, seed=5)


def test_poisson_arrivals_have_the_given_rate_within_start_and_end():
    config = TaskGenerationConfig(rate=0.1, start=100.0, end=20100.0, whole_seconds=False)
    arrivals = np.array([batch.arrival for batch in draw(config)])
    assert 100.0 <= arrivals.min() and arrivals.max() < 20100.0
    assert np.all(np.diff(arrivals) >= 0)
    # 2000 expected; the count of a Poisson process has standard deviation sqrt(2000) ~ 45.
    assert abs(len(arrivals) - 2000) < 4 * 45
    gaps = np.diff(arrivals)
    assert gaps.mean() == pytest.approx(10.0, rel=0.1)  # exponential with mean 1 / rate


def test_end_defaults_to_the_duration():
    arrivals = [b.arrival for b in draw(TaskGenerationConfig(rate=0.5), duration=50.0)]
    assert arrivals and max(arrivals) < 50.0


def test_fixed_times_and_batch_sizes():
    config = TaskGenerationConfig(times=[30.0, 0.0, 12.5], batch_size=[2, 4],
                                  whole_seconds=False)
    batches = draw(config)
    assert [b.arrival for b in batches] == [0.0, 12.5, 30.0]
    sizes = [len(b.tasks) for b in draw(dataclasses.replace(config, times=[1.0] * 200))]
    assert set(sizes) == {2, 3, 4}


def test_location_weights_and_distinct_pickup_and_dropoff():
    config = TaskGenerationConfig(times=[0.0] * 400, pickup_weights={"lobby": 3, "2": 1},
                                  dropoff_weights={"room_1": 1, "room_2": 1, "lobby": 1})
    tasks = [t for b in draw(config) for t in b.tasks]
    pickups = [t.pickup for t in tasks]
    assert set(pickups) == {0, 2}
    assert pickups.count(0) / len(pickups) == pytest.approx(0.75, abs=0.06)
    assert {t.dropoff for t in tasks} <= {0, 1, 2}
    assert all(t.pickup != t.dropoff for t in tasks)


def test_slack_deadlines_scale_the_travel_estimate_and_are_whole_seconds():
    config = TaskGenerationConfig(rate=0.05, slack=[1.5, 2.5], batch_size=[1, 3])
    batches = draw(config)
    for batch in batches:
        assert batch.arrival == int(batch.arrival)
        for task in batch.tasks:
            assert task.deadline == int(task.deadline)
            allowed = task.deadline - batch.arrival
            estimate = travel(task.pickup, task.dropoff)
            assert 1.5 * estimate <= allowed < 2.5 * estimate + 1.0


def test_deadline_range_ignores_travel():
    config = TaskGenerationConfig(times=[5.0] * 50, deadline_range=[60.0, 90.0],
                                  whole_seconds=False)
    batches = generate_tasks(config, LOCATIONS, None, 0, 600.0)
    allowed = [t.deadline - b.arrival for b in batches for t in b.tasks]
    assert min(allowed) >= 60.0 and max(allowed) <= 90.0


def test_changing_batch_sizes_keeps_the_arrivals():
    one = draw(TaskGenerationConfig(rate=0.05, batch_size=[1, 1]))
    three = draw(TaskGenerationConfig(rate=0.05, batch_size=[3, 3]))
    assert [b.arrival for b in one] == [b.arrival for b in three]


@pytest.mark.parametrize("changes, field, words", [
    ({"times": [1.0]}, "tasks.generate.rate", "either"),
    ({"rate": 0.0}, "tasks.generate.rate", "either"),
    ({"batch_size": [3, 1]}, "tasks.generate.batch_size", "[3, 1]"),
    ({"slack": [0.0, 2.0]}, "tasks.generate.slack", "min > 0"),
    ({"slack": [2.0, math.nan]}, "tasks.generate.slack", "finite [min, max]"),
    ({"slack": [2.0, math.inf]}, "tasks.generate.slack", "finite [min, max]"),
    ({"rate": math.inf}, "tasks.generate.rate", "must be a finite number > 0"),
    ({"rate": 0.0, "times": [1.0, math.nan]}, "tasks.generate.times[1]",
     "must be a finite number >= 0 s, got nan"),
    ({"pickup_weights": {"kitchen": 1.0}}, "tasks.generate.pickup_weights.kitchen",
     "unknown location 'kitchen'"),
    ({"pickup_weights": {"lab": 1.0}, "dropoff_weights": {"lab": 1.0}},
     "tasks.generate.dropoff_weights", "other than the pickup 3"),
])
def test_bad_configs_name_the_field(changes, field, words):
    config = dataclasses.replace(TaskGenerationConfig(rate=0.05), **changes)
    with pytest.raises(InputError) as error:
        draw(config)
    assert error.value.field == field and error.value.file == "test.yaml"
    assert words in str(error.value)


def _scenario_file(tmp_path, generate: str) -> pathlib.Path:
    models = ROOT / "models/hospital"
    path = tmp_path / "generated.yaml"
    path.write_text(f"""
world: {{floor_plan: {models / 'floor_plan.yaml'}}}
locations: {models / 'navigation.yaml'}
roadways: {models / 'navigation.yaml'}
robots: [{{name: robot1, start: [0.0, 2.2, -1.5708], start_location: 0}}]
tasks:
  stream: [{{arrival: 100, tasks: [{{pickup: 0, dropoff: 1, deadline: 400}}]}}]
  generate: {generate}
seed: 7
duration: 300
""")
    return path


def test_scenario_generate_block_uses_the_seed_and_roadway_travel_times(tmp_path):
    path = _scenario_file(tmp_path, "{rate: 0.03, batch_size: [1, 2], slack: [2, 3]}")
    scenario = load_scenario(path)
    stream = scenario.tasks.stream
    assert len(stream) > 3
    assert [b.arrival for b in stream] == sorted(b.arrival for b in stream)
    assert any(b.arrival == 100 and b.tasks[0].deadline == 400 for b in stream)  # inline kept
    assert load_scenario(path).tasks.stream == stream
    reseeded = load_scenario(path, overrides={"seed": 8}).tasks.stream
    assert reseeded != stream and len(reseeded) > 1
    # Deadlines leave 2 to 3 times the allocator's roadway estimate.
    from mrta_drake.navigation.roadways import Roadways

    estimate = Roadways(scenario.roadways, scenario.locations).travel_time_estimate(
        scenario.tasks.estimate_speed)
    for batch in stream:
        for task in batch.tasks:
            if batch.arrival != 100:
                allowed = task.deadline - batch.arrival
                assert 2 * estimate[task.pickup, task.dropoff] <= allowed
                assert allowed <= 3 * estimate[task.pickup, task.dropoff] + 1


def test_the_loader_and_the_allocator_share_one_estimate(tmp_path, monkeypatch):
    from mrta_drake.navigation.roadways import Roadways
    from mrta_drake.stack.blocks import BuildContext

    made = []
    estimate = Roadways.travel_time_estimate
    monkeypatch.setattr(Roadways, "travel_time_estimate",
                        lambda self, speed: made.append(speed) or estimate(self, speed))
    path = _scenario_file(tmp_path, "{rate: 0.03, batch_size: [1, 2], slack: [2, 3]}")
    speed = {"tasks.estimate_speed": 0.4321}  # not estimated by an earlier test
    scenario = load_scenario(path, overrides=speed)
    for seed in (7, 8):  # the same roadways, locations and speed: estimated once
        times = BuildContext.for_scenario(load_scenario(path, overrides=speed | {
            "seed": seed})).travel_times
    assert made == [0.4321]
    np.testing.assert_array_equal(times, Roadways(
        scenario.roadways, scenario.locations).travel_time_estimate(0.4321))
    load_scenario(path, overrides={"tasks.estimate_speed": 0.4322})
    assert made[-2:] == [0.4321, 0.4322]  # another speed: estimated anew


def test_scenario_generate_block_uses_the_travel_time_file(tmp_path):
    matrix = tmp_path / "travel.csv"
    matrix.write_text("\n".join(",".join("0" if i == j else str(10 * (i + j)) for j in range(6))
                                for i in range(6)))
    path = _scenario_file(tmp_path, "{times: [5, 9], batch_size: [3, 3], slack: [1.5, 1.5]}")
    path.write_text(path.read_text().replace("  stream:", f"  travel_times: {matrix}\n  stream:"))
    for batch in load_scenario(path).tasks.stream:
        for task in batch.tasks:
            if batch.arrival != 100:
                assert task.deadline - batch.arrival == 15 * (task.pickup + task.dropoff)


def test_scenario_generate_errors_name_the_scenario_file(tmp_path):
    path = _scenario_file(tmp_path, "{rate: 0.03, pickup_weights: {nowhere: 1}}")
    with pytest.raises(InputError) as error:
        load_scenario(path)
    assert error.value.file == str(path)
    assert error.value.field == "tasks.generate.pickup_weights.nowhere"


def test_mrta_sim_json_round_trips(tmp_path):
    batches = draw(TaskGenerationConfig(rate=0.05, batch_size=[1, 3]))
    path = tmp_path / "out" / "stream.json"
    write_mrta_sim_json(str(path), batches, agents=range(3))
    content = json.loads(path.read_text())
    assert content["agents"] == [0, 1, 2]
    first = content["tasks_stream"][0]
    assert isinstance(first["arrival"], int)
    assert set(first["tasks"][0]) == {"start", "end", "deadline"}
    assert load_task_file(str(path)).batches == batches
    assert load_task_file(str(path)).agents == [0, 1, 2]
