"""The servable task stream of an imported building: where, when and how many."""

import numpy as np
import pytest

from mrta_drake.errors import InputError
from mrta_drake.scenario.stream_sizing import BATCH_SIZE, UTILISATION, size_stream


def uniform(n: int, leg: float) -> np.ndarray:
    return np.full((n, n), leg) - leg * np.eye(n)


def test_stream_fits_the_fleet_and_ends_in_time():
    times = uniform(5, 20.0)
    stream = size_stream(times, robots=6, duration=600.0, service_time=1.0)
    assert stream.locations == (0, 1, 2, 3, 4)
    task = 2 * 20.0 + 2 * 1.0  # every leg here is 20 s: longest = mean task
    assert stream.end == 600.0 - 2 * task
    assert stream.times[0] == 0.0 and max(stream.times) <= stream.end
    assert list(stream.times) == sorted(stream.times)
    work = len(stream.times) * np.mean(BATCH_SIZE) * task
    assert work <= UTILISATION * 6 * (600.0 - task) < work + np.mean(BATCH_SIZE) * task
    # Half the robots: about half the batches.
    fewer = size_stream(times, robots=3, duration=600.0, service_time=1.0)
    assert len(fewer.times) == len(stream.times) // 2


def test_far_apart_locations_use_the_largest_neighbourhood():
    points = np.array([[0, 0], [1000, 0], [1010, 0], [1000, 20], [2000, 500]], dtype=float)
    times = np.linalg.norm(points[:, None] - points[None], axis=-1) / 0.6
    stream = size_stream(times, robots=6, duration=600.0, service_time=1.0)
    assert stream.locations == (1, 2, 3)
    assert len(stream.times) >= 1


def test_too_short_a_run_is_one_line():
    with pytest.raises(InputError, match="--duration") as error:
        size_stream(uniform(3, 400.0), robots=2, duration=600.0, service_time=1.0,
                    source="far.building.yaml")
    assert str(error.value).startswith("far.building.yaml: --duration: ")
    with pytest.raises(InputError, match="and a mean task"):  # long services
        size_stream(uniform(3, 12.0), robots=2, duration=60.0, service_time=10.0)


def test_several_levels_span_the_most_levels_alike():
    # Four locations near each other on L1, one on L2 that only two of them reach in time
    # (through a lift): the stream spans both levels, each level alike.
    points = np.array([[0, 0], [10, 0], [0, 10], [10, 10], [80, 0]], dtype=float)
    times = np.linalg.norm(points[:, None] - points[None], axis=-1) / 0.6
    levels = ["L1", "L1", "L1", "L1", "L2"]
    one_level = size_stream(times, robots=6, duration=600.0, service_time=1.0)
    assert one_level.locations == (0, 1, 2, 3)
    assert one_level.weights == (0.25,) * 4
    stream = size_stream(times, robots=6, duration=600.0, service_time=1.0, levels=levels)
    assert stream.locations == (1, 3, 4)
    assert stream.weights == (0.5, 0.5, 1.0)


SPAN = 600.0 - (2 * 20.0 + 2 * 1.0)  # the run but its longest task, uniform(n, 20.0)


def wait(load: float, batches: int) -> float:
    """The s a task waits for one resource held ``load`` s per task in holds of one
    length (Pollaczek-Khinchine: ``rate x load^2 / (2 (1 - rate x load))``), ``batches``
    batches over ``SPAN``."""
    rate = batches * 1.5 / SPAN
    return rate * load ** 2 / (2 * (1 - rate * load)) if rate * load < 1 else np.inf


def served(load: float, task: float, robots: int = 6) -> int:
    """The most batches whose tasks, each ``task`` s and ``wait``, fit the fleet's
    ``robots x SPAN`` s."""
    batches = 0
    while (batches + 1) * 1.5 * (task + wait(load, batches + 1)) <= robots * SPAN:
        batches += 1
    return batches


def test_a_single_file_bottleneck_bounds_the_batches():
    # Every trip between two locations drives one corridor for 15 s (a robot already at
    # its pickup drives none): a task's loaded trip, and its empty trip to the pickup
    # unless one of the 3 free robots (half of 6) stands there, (4/5)^3; a batch of two
    # (2/3 of the tasks) shares its pickup and drop-off 1 time in 20: one trip for both.
    times = uniform(5, 20.0)
    fleet = size_stream(times, robots=6, duration=600.0, service_time=1.0)
    corridor = size_stream(times, robots=6, duration=600.0, service_time=1.0,
                           holds=lambda i, j: {("corridor",): 15.0} if i != j else {})
    load = (15.0 + 15.0 * (4 / 5) ** 3) * (1 - 0.5 * (2 / 3) / 20)
    assert len(corridor.times) == served(load, 2 * 20.0 + 2 * 1.0) == 15
    assert len(corridor.times) < len(fleet.times)
    # The last batch arrives two tasks' waits earlier: time for them before the end.
    assert corridor.end == pytest.approx(fleet.end - 2 * wait(load, 15))
    assert corridor.locations == fleet.locations


def test_two_locations_share_trips_and_find_a_robot_at_the_pickup():
    # Only the trip from location 1 to 0 drives the corridor (60 s): the loaded trips of
    # half the tasks, the empty ones of the other half where none of the 3 free robots
    # stands at location 1 ((1/2)^3), and a batch of two (2/3 of the tasks) shares its
    # way (chance 1/2) and then one trip serves both.
    times = uniform(2, 20.0)
    stream = size_stream(times, robots=6, duration=600.0, service_time=1.0,
                         holds=lambda i, j: {("corridor",): 60.0} if (i, j) == (1, 0) else {})
    load = 60.0 * (0.5 + 0.5 * 0.5 ** 3) * (1 - 0.5 * (2 / 3) * 0.5)
    assert len(stream.times) == served(load, 2 * 20.0 + 2 * 1.0)


def test_a_trip_waits_at_each_resource_it_holds_in_turn():
    # Two corridors of 10 s each on every trip: held one after the other, a trip waits
    # for each; held together (one run), for the longer wait only.
    times = uniform(5, 20.0)
    in_turn = size_stream(times, robots=6, duration=600.0, service_time=1.0,
                          holds=lambda i, j: {("a",): 10.0, ("b",): 10.0} if i != j else {})
    together = size_stream(times, robots=6, duration=600.0, service_time=1.0,
                           holds=lambda i, j: {("a", "b"): 10.0} if i != j else {})
    load = (10.0 + 10.0 * (4 / 5) ** 3) * (1 - 0.5 * (2 / 3) / 20)
    assert len(together.times) == served(load, 2 * 20.0 + 2 * 1.0)
    assert len(in_turn.times) < len(together.times)


def test_resources_less_busy_than_the_fleet_keep_the_fleet_bound():
    times = uniform(5, 20.0)
    fleet = size_stream(times, robots=6, duration=600.0, service_time=1.0)
    rooms = size_stream(times, robots=6, duration=600.0, service_time=1.0,
                        holds=lambda i, j: {(("room", j),): 3.0, ("corridor",): 2.0 * (i != j)})
    assert (len(rooms.times), rooms.locations) == (len(fleet.times), fleet.locations)
    assert fleet.end - 10.0 < rooms.end < fleet.end  # their short waits
