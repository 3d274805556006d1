"""Travel-time matrices between locations, for the allocator: read, write, estimate.

A matrix ``T`` (L, L) of integer seconds: ``T[i, j]`` is the time to drive from location ``i``
to location ``j`` (row and column = location id; ids are 0..L-1). Files are YAML
(``travel_times: [[...], ...]``, optionally ``stat`` and ``repeats`` describing how they were
measured) or CSV (one row per line, no header).

``allocator_travel_times`` is the one owner of a scenario's matrix: the loader's slack
deadlines of a generated stream and the diagram's allocator both take it from there.
"""

import csv
import hashlib
import math
import os

import numpy as np
import yaml

from mrta_drake.errors import InputError
from mrta_drake.scenario.schema import Scenario
from mrta_drake.scenario.typed_yaml import read_yaml


def allocator_travel_times(scenario: Scenario, roadways=None) -> np.ndarray:
    """The allocator's (L, L) integer travel times (s) between ``scenario``'s locations
    (rows and columns in ascending id order): its ``tasks.travel_times`` file, else the
    estimate from the roadway legs at ``tasks.estimate_speed``
    (``Roadways.travel_time_estimate``; location points the scenario leaves out are taken
    from its floor plan). ``roadways``: the scenario's ``Roadways`` when the caller has
    them (built here otherwise).

    The estimate is made once per roadways, locations and speed and kept for the last few
    (read-only): it depends on nothing else, so the same scenario gives the same matrix
    however often it is asked for in one process."""
    tasks = scenario.tasks
    if tasks.travel_times:
        return load_travel_times(tasks.travel_times, len(scenario.locations))
    if not all(location.point for location in scenario.locations):
        from mrta_drake.world.plant import load_floor_plan_of, resolve_locations

        scenario = resolve_locations(scenario, load_floor_plan_of(scenario, objects=False))
    content = repr((scenario.roadways, scenario.locations, tasks.estimate_speed)).encode()
    key = hashlib.sha256(content).digest()
    if key not in _ESTIMATES:
        if roadways is None:
            from mrta_drake.navigation.roadways import Roadways

            roadways = Roadways(scenario.roadways, scenario.locations, scenario.source)
        estimate = roadways.travel_time_estimate(tasks.estimate_speed)
        estimate.setflags(write=False)
        _ESTIMATES[key] = estimate
        while len(_ESTIMATES) > _KEPT:
            _ESTIMATES.pop(next(iter(_ESTIMATES)))
    return _ESTIMATES[key]


_KEPT = 4  # estimates kept, the oldest dropped first
_ESTIMATES: dict[bytes, np.ndarray] = {}  # by a digest of the roadways, locations and speed


def load_travel_times(path: str, num_locations: int) -> np.ndarray:
    """The (L, L) integer matrix in ``path``; InputError naming the file, the entry and the
    value when it is not a square matrix of non-negative numbers of the right size."""
    if path.lower().endswith(".csv"):
        try:
            with open(path, newline="") as f:
                rows = [row for row in csv.reader(f) if row]
        except FileNotFoundError:
            raise InputError(path, None, "travel-time file not found") from None
        field = "row"
    else:
        content = read_yaml(path, "travel-time file")
        if not isinstance(content, dict) or "travel_times" not in content:
            raise InputError(path, "travel_times", "is required (a list of rows, s)")
        rows = content["travel_times"]
        field = "travel_times"
    if not isinstance(rows, list) or len(rows) != num_locations:
        raise InputError(path, field, f"expected {num_locations} rows (one per location), got "
                         f"{len(rows) if isinstance(rows, list) else rows!r}")
    matrix = np.zeros((num_locations, num_locations))
    for i, row in enumerate(rows):
        if not isinstance(row, list) or len(row) != num_locations:
            raise InputError(path, f"{field}[{i}]", f"expected {num_locations} entries")
        for j, value in enumerate(row):
            try:
                number = float(value)
            except (TypeError, ValueError):
                number = math.nan
            if not (number >= 0 and math.isfinite(number)):
                raise InputError(path, f"{field}[{i}][{j}]",
                                 f"expected a number of seconds >= 0, got {value!r}")
            matrix[i, j] = number
    return np.ceil(matrix).astype(int)


def write_travel_times(path: str, matrix: np.ndarray, **notes) -> None:
    """Write ``matrix`` (integer s) as YAML, or CSV when ``path`` ends in .csv; ``notes``
    (e.g. stat, repeats) go into the YAML beside the matrix."""
    matrix = np.asarray(matrix, dtype=int)
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    if path.lower().endswith(".csv"):
        with open(path, "w", newline="") as f:
            csv.writer(f).writerows(matrix.tolist())
        return
    with open(path, "w") as f:
        yaml.safe_dump({**notes, "travel_times": matrix.tolist()}, f,
                       default_flow_style=None, sort_keys=False)
