"""Seeded random task streams: batches of pickup/drop-off tasks with deadlines.

``generate_tasks`` draws ``TaskBatch`` lists from a ``TaskGenerationConfig`` (its fields are
described in ``scenario_schema.py``); ``add_generated_tasks`` does it for a scenario's
``tasks.generate:`` block with the scenario's seed (``load_scenario`` calls it), and
``write_mrta_sim_json`` writes a stream as an original MRTA-Sim ``tasks_stream`` file.

The same config, locations, travel times and seed always give the same stream. Arrival times
and task contents come from separate random streams, so changing the arrival process keeps
the tasks of the batches that still arrive, and changing the tasks keeps the arrivals.

Times in s.
"""

import dataclasses
import json
import math
import os
from collections.abc import Callable, Sequence

import numpy as np

from mrta_drake.errors import InputError
from mrta_drake.scenario.schema import (
    LocationConfig,
    Scenario,
    TaskBatch,
    TaskConfig,
    TaskGenerationConfig,
)

FIELD = "tasks.generate"
_STREAM_KEY = 0x7A5C  # keeps this generator's draws apart from other users of the seed


def generate_tasks(config: TaskGenerationConfig, locations: Sequence[LocationConfig],
                   travel_time: Callable[[int, int], float] | None, seed: int,
                   duration: float, file: str | None = None) -> list[TaskBatch]:
    """The batches of ``config`` over ``locations``, drawn with ``seed``.

    ``travel_time(pickup, dropoff)`` estimates the drive between two location ids (s); it
    is needed only for slack deadlines (``deadline_range`` empty). ``duration`` (s) is the
    end of Poisson arrivals when ``config.end`` is 0. Raises ``InputError`` naming ``file``
    and the ``tasks.generate`` field for an invalid config.
    """
    end = config.end or duration
    _check(config, end, file)
    ids = [location.id for location in locations]
    pickup_p = _probabilities(config.pickup_weights, locations, file, "pickup_weights")
    dropoff_p = _probabilities(config.dropoff_weights, locations, file, "dropoff_weights")
    for k in np.flatnonzero(pickup_p):
        if not np.delete(dropoff_p, k).any():
            raise InputError(file, f"{FIELD}.dropoff_weights", f"no drop-off other than the "
                             f"pickup {ids[k]} has a positive weight")
    arrival_seed, task_seed = np.random.SeedSequence([seed, _STREAM_KEY]).spawn(2)
    arrivals = _arrivals(config, end, np.random.default_rng(arrival_seed))
    rng = np.random.default_rng(task_seed)
    batches = []
    for arrival in arrivals:
        if config.whole_seconds:
            arrival = float(math.floor(arrival))
        tasks = []
        for _ in range(int(rng.integers(config.batch_size[0], config.batch_size[1] + 1))):
            pickup = int(rng.choice(len(ids), p=pickup_p))
            weights = dropoff_p.copy()
            weights[pickup] = 0.0
            dropoff = int(rng.choice(len(ids), p=weights / weights.sum()))
            if config.deadline_range:
                allowed = rng.uniform(*config.deadline_range)
            else:
                allowed = rng.uniform(*config.slack) * travel_time(ids[pickup], ids[dropoff])
            deadline = arrival + allowed
            if config.whole_seconds:
                deadline = float(math.ceil(deadline))
            tasks.append(TaskConfig(ids[pickup], ids[dropoff], deadline))
        batches.append(TaskBatch(arrival, tasks))
    return batches


def add_generated_tasks(scenario: Scenario) -> Scenario:
    """``scenario`` with the batches of its ``tasks.generate`` block (drawn with its seed)
    merged into ``tasks.stream`` in arrival order; unchanged without the block. Slack
    deadlines use the allocator's travel times: the ``tasks.travel_times`` file, else the
    roadway estimate at ``tasks.estimate_speed``."""
    config = scenario.tasks.generate
    if config is None:
        return scenario
    travel_time = None if config.deadline_range else _allocator_travel_time(scenario)
    batches = generate_tasks(config, scenario.locations, travel_time, scenario.seed,
                             scenario.duration, scenario.source)
    stream = sorted(list(scenario.tasks.stream) + batches, key=lambda batch: batch.arrival)
    return dataclasses.replace(scenario,
                               tasks=dataclasses.replace(scenario.tasks, stream=stream))


def write_mrta_sim_json(path: str, batches: Sequence[TaskBatch],
                        agents: Sequence[int] = ()) -> None:
    """Write ``batches`` as an original MRTA-Sim task stream (``{"tasks_stream": [{"arrival",
    "tasks": [{"start", "end", "deadline"}]}], "agents": [...]}``); whole-second times are
    written as integers; ``agents`` (each robot's start location id, robot order) is left
    out when empty."""
    content = {"tasks_stream": [
        {"arrival": _number(batch.arrival),
         "tasks": [{"start": task.pickup, "end": task.dropoff,
                    "deadline": _number(task.deadline)} for task in batch.tasks]}
        for batch in batches]}
    if agents:
        content["agents"] = [int(agent) for agent in agents]
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    with open(path, "w", encoding="utf-8") as f:
        json.dump(content, f, indent=1)
        f.write("\n")


def _number(value: float) -> int | float:
    return int(value) if float(value).is_integer() else float(value)


def _arrivals(config: TaskGenerationConfig, end: float, rng: np.random.Generator) -> list:
    if config.times:
        return sorted(float(t) for t in config.times)
    arrivals = []
    t = config.start + rng.exponential(1.0 / config.rate)
    while t < end:
        arrivals.append(t)
        t += rng.exponential(1.0 / config.rate)
    return arrivals


def _allocator_travel_time(scenario: Scenario) -> Callable[[int, int], float]:
    """Travel time (s) between two location ids as the allocator sees it."""
    from mrta_drake.scenario.travel_times import allocator_travel_times

    times = allocator_travel_times(scenario)
    index = {location: k for k, location in enumerate(sorted(
        location.id for location in scenario.locations))}
    return lambda a, b: float(times[index[a], index[b]])


def _probabilities(weights: dict, locations: Sequence[LocationConfig], file,
                   name: str) -> np.ndarray:
    """Per location (in ``locations`` order), the probability of being drawn."""
    if not weights:
        return np.full(len(locations), 1.0 / len(locations))
    by_key = {str(location.id): k for k, location in enumerate(locations)}
    by_key |= {location.name: k for k, location in enumerate(locations) if location.name}
    p = np.zeros(len(locations))
    for key, weight in weights.items():
        where = f"{FIELD}.{name}.{key}"
        if str(key) not in by_key:
            raise InputError(file, where, f"unknown location {key!r} (a location name or id)")
        if not weight >= 0:
            raise InputError(file, where, f"must be >= 0, got {weight}")
        p[by_key[str(key)]] = weight
    if not p.sum() > 0:
        raise InputError(file, f"{FIELD}.{name}", "at least one weight must be > 0")
    return p / p.sum()


def _check(config: TaskGenerationConfig, end: float, file) -> None:
    if (config.rate > 0) == bool(config.times):
        raise InputError(file, f"{FIELD}.rate", "give either `rate` (batches per s) or "
                         f"`times` (s), got rate {config.rate} and times {config.times}")
    if not 0 <= config.rate < math.inf:
        raise InputError(file, f"{FIELD}.rate", f"must be a finite number > 0 batches per s, "
                         f"got {config.rate}")
    for k, t in enumerate(config.times):
        if not 0 <= t < math.inf:
            raise InputError(file, f"{FIELD}.times[{k}]", f"must be a finite number >= 0 s, "
                             f"got {t}")
    if not 0 <= config.start < math.inf or (config.rate > 0 and not end > config.start):
        raise InputError(file, f"{FIELD}.start", f"need 0 <= start < end, got start "
                         f"{config.start} and end {end}")
    _check_range(config.batch_size, file, "batch_size", minimum=1)
    _check_range(config.slack, file, "slack", minimum=0.0, open_below=True)
    if config.deadline_range:
        _check_range(config.deadline_range, file, "deadline_range", minimum=0.0,
                     open_below=True)


def _check_range(values, file, name: str, minimum: float, open_below: bool = False) -> None:
    low_ok = len(values) == 2 and (values[0] > minimum if open_below else values[0] >= minimum)
    if not low_ok or not values[0] <= values[1] < math.inf:
        bound = ">" if open_below else ">="
        raise InputError(file, f"{FIELD}.{name}",
                         f"expected finite [min, max] with min {bound} {minimum} and min <= "
                         f"max, got {values}")
