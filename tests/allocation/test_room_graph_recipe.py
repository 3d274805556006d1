"""The tight regime's instances (benchmarks/room_graph.py): travel times with the facts of
SMrTa's recipe, the same for the same seed."""

import pathlib
import sys

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "benchmarks"))

from room_graph import DOORS, LONGEST, NUM_ROOMS, room_graph_travel  # noqa: E402


def test_travel_times_are_a_metric_with_the_recipes_longest_trip():
    travel = room_graph_travel(np.random.default_rng(3))
    assert travel.shape == (NUM_ROOMS, NUM_ROOMS)
    assert np.issubdtype(travel.dtype, np.integer)
    assert (np.diag(travel) == 0).all() and (travel == travel.T).all()
    off_diagonal = travel[~np.eye(NUM_ROOMS, dtype=bool)]
    assert off_diagonal.min() > DOORS and off_diagonal.max() == LONGEST
    via = travel[:, :, None] + travel[None, :, :]  # i -> k -> j
    assert (travel <= via.min(axis=1)).all()


def test_nearest_rooms_and_mean_trip_are_near_the_recipes():
    nearest, means = [], []
    for seed in range(4):
        travel = room_graph_travel(np.random.default_rng(seed))
        off = travel + np.eye(NUM_ROOMS, dtype=int) * 10**6
        nearest.append(np.sort(off, axis=1)[:, 0].mean())
        means.append(travel.sum() / (NUM_ROOMS * (NUM_ROOMS - 1)))
    assert 8.0 <= np.mean(nearest) <= 13.0  # s; the recipe's: about 10
    assert 42.0 <= np.mean(means) <= 54.0  # s; the recipe's: about 48


def test_the_same_seed_draws_the_same_rooms():
    first = room_graph_travel(np.random.default_rng(11))
    assert (first == room_graph_travel(np.random.default_rng(11))).all()
    assert (first != room_graph_travel(np.random.default_rng(12))).any()
