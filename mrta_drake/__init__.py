"""mrta-drake: test multi-robot task allocation with planning and control in a Drake hospital.

The public API: ``load_scenario`` reads a scenario file, ``build_diagram`` wires its blocks
into a Drake diagram (``add_stack`` onto your own builder), ``simulate`` runs it; the block
classes are the default implementations of each slot, to use, subclass or replace.
"""

from mrta_drake.allocation import GreedyAllocator, SmtAllocator
from mrta_drake.blocks import register_block
from mrta_drake.diagram import add_stack, build_diagram
from mrta_drake.scenario import load_scenario
from mrta_drake.simulate import SimulationResult, simulate
from mrta_drake.systems.cluster_cbf_controller import ClusterCbfController
from mrta_drake.systems.fixed_sequence_allocator import FixedSequenceAllocator
from mrta_drake.systems.go_to_goal_controller import GoToGoalController
from mrta_drake.systems.planner_service import PlannerService
from mrta_drake.systems.room_queues import RoomQueues
from mrta_drake.systems.social_force_humans import SocialForceHumans
from mrta_drake.systems.task_allocator import TaskAllocator
from mrta_drake.systems.unicycle_robots import UnicycleRobots
from mrta_drake.systems.waypoint_generator import WaypointGenerator

__all__ = [
    "ClusterCbfController",
    "FixedSequenceAllocator",
    "GoToGoalController",
    "GreedyAllocator",
    "PlannerService",
    "RoomQueues",
    "SimulationResult",
    "SmtAllocator",
    "SocialForceHumans",
    "TaskAllocator",
    "UnicycleRobots",
    "WaypointGenerator",
    "add_stack",
    "build_diagram",
    "load_scenario",
    "register_block",
    "simulate",
]
