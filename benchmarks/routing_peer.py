"""OR-Tools routing as a peer of the allocators: pickup and delivery with capacity and soft
deadlines, solved by guided local search within a wall-clock limit.

Each task is a pickup node and a delivery node on one vehicle, pickup first; a node's time
is its completion time (travel plus the service time, as in ``AllocationProblem``); every
second a drop-off is late costs ``LATE_PENALTY`` and every second driven costs 1, so the
search trades lateness for travel. Routes are open: they end at a dummy node reached at no
cost. The answer is read back as an ``Allocation`` (times and late tasks recomputed by our
model). Optional: ``pip install 'mrta-drake[benchmarks]'``; without OR-Tools
``available()`` is False. Answers depend on the host's speed (a wall-clock limit).
"""

from mrta_drake.allocation import Action, Allocation, AllocationProblem
from mrta_drake.payloads import DROPOFF, PICKUP

LATE_PENALTY = 1000  # objective units per second of lateness (1 per second driven)
HORIZON = 10**6  # s, the latest completion time the model allows

try:
    from ortools.constraint_solver import pywrapcp, routing_enums_pb2
except ImportError:  # the optional benchmarks extra is not installed
    pywrapcp = None


def available() -> bool:
    return pywrapcp is not None


def routing_allocation(problem: AllocationProblem, seconds: float) -> Allocation:
    """The best allocation OR-Tools finds for ``problem`` (no robot may carry items yet, no
    releases after 0) in ``seconds`` of guided local search."""
    robots = problem.robots
    num_robots = len(robots)
    end = num_robots
    actions = [Action(task.id, kind) for task in problem.tasks for kind in (PICKUP, DROPOFF)]
    places = [robot.location for robot in robots] + [None] + [
        problem.location(action) for action in actions]
    service = int(problem.service_time)
    manager = pywrapcp.RoutingIndexManager(len(places), num_robots, list(range(num_robots)),
                                           [end] * num_robots)
    routing = pywrapcp.RoutingModel(manager)
    travel = problem.travel

    def leg(from_index, to_index):
        a, b = manager.IndexToNode(from_index), manager.IndexToNode(to_index)
        if b == end or a == end:
            return 0
        return int(travel[places[a], places[b]])

    def timed_leg(from_index, to_index):
        if manager.IndexToNode(to_index) == end:
            return 0
        return leg(from_index, to_index) + service

    routing.SetArcCostEvaluatorOfAllVehicles(routing.RegisterTransitCallback(leg))
    routing.AddDimension(routing.RegisterTransitCallback(timed_leg), 0, HORIZON, False, "time")
    time = routing.GetDimensionOrDie("time")

    def load(index):
        node = manager.IndexToNode(index)
        if node <= end:
            return 0
        return 1 if actions[node - end - 1].kind == PICKUP else -1

    routing.AddDimensionWithVehicleCapacity(
        routing.RegisterUnaryTransitCallback(load), 0, [robot.capacity for robot in robots],
        True, "load")
    for r, robot in enumerate(robots):
        time.CumulVar(routing.Start(r)).SetValue(int(robot.ready_time))
    solver = routing.solver()
    for k in range(0, len(actions), 2):
        pickup = manager.NodeToIndex(end + 1 + k)
        drop = manager.NodeToIndex(end + 2 + k)
        routing.AddPickupAndDelivery(pickup, drop)
        solver.Add(routing.VehicleVar(pickup) == routing.VehicleVar(drop))
        solver.Add(time.CumulVar(pickup) <= time.CumulVar(drop))
        deadline = int(problem.task(actions[k].task).deadline)
        time.SetCumulVarSoftUpperBound(drop, deadline, LATE_PENALTY)
    search = pywrapcp.DefaultRoutingSearchParameters()
    search.first_solution_strategy = (
        routing_enums_pb2.FirstSolutionStrategy.PARALLEL_CHEAPEST_INSERTION)
    search.local_search_metaheuristic = (
        routing_enums_pb2.LocalSearchMetaheuristic.GUIDED_LOCAL_SEARCH)
    search.time_limit.FromMilliseconds(int(seconds * 1000))
    solution = routing.SolveWithParameters(search)
    if solution is None:
        raise RuntimeError("OR-Tools found no allocation")
    routes = []
    for r in range(num_robots):
        route, index = [], solution.Value(routing.NextVar(routing.Start(r)))
        while not routing.IsEnd(index):
            route.append(actions[manager.IndexToNode(index) - end - 1])
            index = solution.Value(routing.NextVar(index))
        routes.append(route)
    return Allocation.of(problem, routes)
