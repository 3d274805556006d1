"""Measuring the allocator's travel times: one robot, driven by the scenario's own blocks,
between every ordered pair of locations.

The robot (the scenario's first, or the one named) drives, alone and headless, with the
scenario's waypoint generator, queues, planner, controller and robots block, and the
``fixed`` allocator giving it a route: an Eulerian circuit of the complete directed graph of
the L locations, so that one run drives every ordered pair ``(a, b)`` once as consecutive
stops, L(L-1) legs. It starts standing on the circuit's first location, heading as a robot
that has just driven in. Repeat ``r`` drives the circuit with location ids shifted by ``r``
(mod L): each leg comes after another leg and at another point of the run. People are left
out unless asked for (then they walk as in the scenario, with its seed); scheduled
disturbances always are.

A leg's time is measured as the allocator predicts it: it completes stop ``k`` at
``c_k = c_{k-1} + travel[a, b] + service_time`` (``allocation/problem.py``), so
``travel[a, b]`` = the time the waypoint generator reports completing the stop at ``b``
(its ``Visit``) minus the time it reported completing the stop at ``a``, minus the
service time: driving only, queueing and entering included. The matrix is the ``max`` or
``mean`` over repeats, rounded up to whole seconds, 0 on the diagonal. A leg not completed
within ``time_limit`` s is a failure: the run stops there and a new one goes on from the
leg's destination; failures are reported, never written as numbers.
"""

import dataclasses
import math
from dataclasses import dataclass

import networkx as nx
import numpy as np
from pydrake.systems.analysis import Simulator

from mrta_drake.errors import InputError
from mrta_drake.navigation.roadways import Roadways
from mrta_drake.scenario.schema import DisturbancesConfig, HumansConfig, Scenario
from mrta_drake.stack.blocks import BuildContext, replace_block

STATS = ("max", "mean")
_SLICE = 1.0  # s of simulation between looks at the robot's progress
_ROUNDING = 1e-6  # s; float noise in visit times must not add a second when rounding up


@dataclass(frozen=True)
class LegFailure:
    """The robot did not complete the leg ``origin`` -> ``destination`` (location ids)
    within ``time_limit`` s, in repeat ``repeat`` (from 0)."""

    repeat: int
    origin: int
    destination: int
    time_limit: float


@dataclass(frozen=True, eq=False)
class LegSamples:
    """Measured travel times: ``samples[r, a, b]`` (repeats, L, L) the driving time of leg
    ``a`` -> ``b`` in repeat ``r``, s (0 on the diagonal, NaN where the leg failed);
    ``failures`` those legs; ``robot`` the robot that drove."""

    samples: np.ndarray
    failures: tuple[LegFailure, ...]
    robot: str
    source: str = ""  # the scenario file

    def matrix(self, stat: str = "max") -> np.ndarray:
        """The (L, L) integer matrix (s): ``stat`` (``max`` or ``mean``) over repeats,
        rounded up; InputError listing the failed legs if any leg failed."""
        check_stat(stat)
        if self.failures:
            failed = ", ".join(f"{f.origin}->{f.destination} (repeat {f.repeat + 1})"
                               for f in self.failures)
            raise InputError(self.source, None,
                             f"{self.robot} did not complete {len(self.failures)} leg(s) "
                             f"within {self.failures[0].time_limit:g} s: {failed}")
        reduced = self.samples.max(axis=0) if stat == "max" else self.samples.mean(axis=0)
        return np.ceil(reduced - _ROUNDING).astype(int)

    def describe(self, stat: str = "max") -> str:
        """One line: how many legs and repeats, the range and median of the ``stat``
        matrix and the largest difference between repeats of one leg, s."""
        matrix = self.matrix(stat)
        off = ~np.eye(len(matrix), dtype=bool)
        spread = np.ptp(self.samples, axis=0)[off].max()
        return (f"{off.sum()} legs x {len(self.samples)} repeats ({stat}): "
                f"{matrix[off].min()}-{matrix[off].max()} s, median {np.median(matrix[off]):g} "
                f"s; largest difference between repeats of a leg {spread:.1f} s")


def eulerian_circuit(num_locations: int, shift: int = 0) -> list[int]:
    """A closed route through locations ``0..num_locations-1`` whose consecutive pairs are
    every ordered pair of distinct locations exactly once (num_locations (num_locations - 1)
    legs), starting and ending at ``shift``; ids shifted by ``shift`` (mod num_locations)."""
    graph = nx.complete_graph(num_locations, create_using=nx.DiGraph)
    route = [a for a, _ in nx.eulerian_circuit(graph, source=0)] + [0]
    return [(a + shift) % num_locations for a in route]


def collect_travel_times(scenario: Scenario, repeats: int = 1, stat: str = "max",
                         robot: str | None = None, humans: bool = False,
                         time_limit: float = 300.0, progress: bool = False) -> np.ndarray:
    """The (L, L) integer travel-time matrix (s) of ``scenario``, measured as described in
    the module docstring; InputError listing the failed legs if any leg failed."""
    check_stat(stat)
    return measure_legs(scenario, repeats, robot, humans, time_limit, progress).matrix(stat)


def measure_legs(scenario: Scenario, repeats: int = 1, robot: str | None = None,
                 humans: bool = False, time_limit: float = 300.0,
                 progress: bool = False) -> LegSamples:
    """Drive every leg ``repeats`` times (see the module docstring) and return the samples;
    ``progress`` shows a bar counting legs."""
    from tqdm import tqdm

    if repeats < 1:
        raise InputError(None, "repeats", f"must be >= 1, got {repeats}")
    if not time_limit > 0:
        raise InputError(None, "time_limit", f"must be > 0 s, got {time_limit}")
    names = [r.name for r in scenario.robots]
    if robot is not None and robot not in names:
        raise InputError(scenario.source, "robot",
                         f"unknown robot {robot!r} (robots: {', '.join(names)})")
    index = 0 if robot is None else names.index(robot)
    context = BuildContext.for_scenario(scenario)
    scenario, roadways = context.scenario, context.roadways
    ids = sorted(location.id for location in scenario.locations)
    count = len(ids)
    if count < 2 or ids != list(range(count)):
        raise InputError(scenario.source, "locations", "travel times need at least two "
                         f"locations with ids 0..L-1 (they index the matrix), got {ids}")
    samples = np.full((repeats, count, count), np.nan)
    for r in range(repeats):
        np.fill_diagonal(samples[r], 0.0)
    failures = []
    with tqdm(total=repeats * count * (count - 1), unit="leg", disable=not progress) as bar:
        for r in range(repeats):
            route = eulerian_circuit(count, r)
            while len(route) > 1:
                alone = _one_robot(scenario, index, route, roadways, humans)
                driven = 0
                for origin, destination, seconds in _drive(alone, route, time_limit):
                    driven += 1
                    bar.update(1)
                    if seconds is None:
                        failures.append(LegFailure(r, origin, destination, time_limit))
                    else:
                        samples[r, origin, destination] = seconds
                route = route[driven:]
    return LegSamples(samples, tuple(failures), names[index], scenario.source)


def check_stat(stat: str) -> None:
    """InputError unless ``stat`` is one of ``STATS``."""
    if stat not in STATS:
        raise InputError(None, "stat", f"must be one of {', '.join(STATS)}, got {stat!r}")


def _one_robot(scenario: Scenario, index: int, route: list[int], roadways: Roadways,
               humans: bool) -> Scenario:
    """``scenario`` with only robot ``index``, standing on ``route[0]``'s point heading as
    if it had just driven in (from the last entry point, or the head queue slot), given
    ``route`` by the ``fixed`` allocator; without people unless ``humans``, and without
    scheduled disturbances (travel times are the nominal ones; a breakdown or outage may
    also name a robot left out here)."""
    place = roadways.place(route[0])
    came_from = place.entry[-1] if len(place.entry) else place.queue[0]
    dx, dy = place.point - came_from
    heading = math.atan2(dy, dx)
    robot = dataclasses.replace(
        scenario.robots[index], start=[float(place.point[0]), float(place.point[1]), heading],
        start_location=route[0], route=list(route))
    alone = dataclasses.replace(scenario, robots=[robot],
                                humans=scenario.humans if humans else HumansConfig(),
                                disturbances=DisturbancesConfig())
    return replace_block(alone, "allocator", "fixed")


def _drive(scenario: Scenario, route: list[int], time_limit: float):
    """Simulate the one robot of ``scenario`` along its ``route``; yield
    ``(origin, destination, seconds)`` for each leg as it is completed (driving time, s),
    or with ``seconds`` None for a leg not completed within ``time_limit`` s, then stop."""
    from mrta_drake.stack.diagram import build_diagram

    stack = build_diagram(scenario)
    simulator = Simulator(stack.diagram)
    simulator.Initialize()
    progress = stack.waypoint_output(0, "progress")
    context = progress.get_system().GetMyContextFromRoot(simulator.get_context())
    service = scenario.tasks.service_time
    done, left_at = 0, 0.0  # visits seen; when the robot completed the last one, s
    try:
        while done < len(route):
            simulator.AdvanceTo(simulator.get_context().get_time() + _SLICE)
            for visit in progress.Eval(context).visits[done:]:
                if done > 0:
                    yield route[done - 1], route[done], visit.time - left_at - service
                done, left_at = done + 1, visit.time
            if done < len(route) and context.get_time() - left_at > time_limit + service:
                if done == 0:
                    raise InputError(scenario.source, "locations", f"a robot standing on "
                                     f"location {route[0]}'s point did not complete a stop "
                                     f"there within {time_limit:g} s")
                yield route[done - 1], route[done], None
                return
    finally:
        stack.recorder.close()
