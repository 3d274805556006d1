"""mrta-drake: test multi-robot task allocation with planning and control in a Drake hospital.

The public API: ``load_scenario`` reads a scenario file, ``build_diagram`` wires its blocks
into a Drake diagram (``add_stack`` onto your own builder), ``simulate`` runs it; the block
classes are the default implementations of each slot, to use, subclass or replace.
Names are imported on first use, so ``import mrta_drake.errors`` stays light.
"""

import importlib
import os

# numba formats an error message for every overload it tries and rejects while typing a
# kernel (thousands per kernel), and with highlighting on each one re-initialises colorama
# around stdout and stderr: ~9 % of compiling the controller's kernels (docs/benchmarks.md,
# "The first run", ninth round). numba's documented switch turns highlighting off (its
# messages lose their bold, nothing else) when numba is imported after this package.
os.environ.setdefault("NUMBA_DISABLE_ERROR_MESSAGE_HIGHLIGHTING", "1")

_PUBLIC = {
    "load_scenario": "mrta_drake.scenario.loading",
    "build_diagram": "mrta_drake.stack.diagram",
    "add_stack": "mrta_drake.stack.diagram",
    "simulate": "mrta_drake.stack.simulate",
    "SimulationResult": "mrta_drake.stack.simulate",
    "register_block": "mrta_drake.stack.blocks",
    "SmtAllocator": "mrta_drake.allocation",
    "GreedyAllocator": "mrta_drake.allocation",
    "TaskAllocator": "mrta_drake.allocation.task_allocator",
    "FixedSequenceAllocator": "mrta_drake.allocation.fixed_sequence_allocator",
    "FleetWaypoints": "mrta_drake.navigation.waypoint_generator",
    "WaypointPolicy": "mrta_drake.navigation.waypoint_generator",
    "WaypointGenerator": "mrta_drake.navigation.waypoint_generator",
    "RoomQueues": "mrta_drake.navigation.room_queues",
    "PlannerService": "mrta_drake.navigation.planner_service",
    "ClusterCbfController": "mrta_drake.control.cluster_cbf_controller",
    "GoToGoalController": "mrta_drake.control.go_to_goal_controller",
    "UnicycleRobots": "mrta_drake.robots.unicycle_robots",
    "SocialForceHumans": "mrta_drake.humans.social_force_humans",
}

__all__ = sorted(_PUBLIC)


def __getattr__(name: str):
    if name not in _PUBLIC:
        raise AttributeError(f"module 'mrta_drake' has no attribute {name!r}")
    value = getattr(importlib.import_module(_PUBLIC[name]), name)
    globals()[name] = value
    return value


def __dir__():
    return __all__
