"""Task allocation: the SMrTa problem, the SMT and greedy allocators, a checker, and the allocator
blocks (``TaskAllocator``, ``FixedSequenceAllocator``)."""

from mrta_drake.allocation.greedy_allocator import GreedyAllocator, GreedyAllocatorParams
from mrta_drake.allocation.problem import (
    FEASIBLE,
    INFEASIBLE,
    UNKNOWN,
    Action,
    Allocation,
    AllocationProblem,
    RobotStart,
    RobotStatus,
    Task,
    committed_start,
)
from mrta_drake.allocation.smt_allocator import SmtAllocator, SmtAllocatorParams
from mrta_drake.allocation.verify import verify_allocation

__all__ = [
    "FEASIBLE",
    "INFEASIBLE",
    "UNKNOWN",
    "Action",
    "Allocation",
    "AllocationProblem",
    "GreedyAllocator",
    "GreedyAllocatorParams",
    "RobotStart",
    "RobotStatus",
    "SmtAllocator",
    "SmtAllocatorParams",
    "Task",
    "committed_start",
    "verify_allocation",
]
