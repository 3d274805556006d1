"""The switches of the loop from execution back to allocation (docs/allocation.md, "Allocation
meets execution"), shared by every ``TaskAllocator`` block whatever allocator it runs."""

import dataclasses
import inspect
import math
from dataclasses import dataclass

import numpy as np

from mrta_drake.allocation.local_search import LocalSearchParams
from mrta_drake.allocation.travel_time_model import Estimator, TravelTimeModel
from mrta_drake.errors import require_non_negative


@dataclass(frozen=True)
class FeedbackParams:
    """How the allocator block learns from the run and re-plans.

    ``learn_travel_times``: plan with travel times learned from every completed leg
    (``allocation.travel_time_model``), summarised by ``travel_time_estimator`` (``mean``,
    ``recent``: weight ``recent_weight`` for each new sample, or ``quantile``: the
    ``quantile`` of the last ``quantile_window`` samples), a pair's own samples counting
    against the fleet-wide ratio as ``prior_samples`` samples, each leg rounded to whole
    seconds as ``travel_time_rounding`` says (``up`` or ``nearest``: unbiased; see
    ``TravelTimeModel``). ``planning_margin`` (s) is added to every leg planned (with or
    without learning): a robust plan promises only what it can keep with that margin.

    ``replan_on_delay``: between batches, allocate again when a robot's progress (with the
    travel times planned with) makes one of its planned drop-offs late or moves it by more
    than ``drift_margin`` (s) from its planned time, at most once every
    ``replan_interval`` (s). With ``retime_on_drift`` a drift that turns no drop-off planned
    on time late only re-times the plan (the same routes, the completion times predicted
    now) instead of allocating again, at any check (re-timing changes no route, so
    ``replan_interval`` does not limit it). With ``replan_only_if_fewer_late`` an allocation
    made on delay takes the allocator's routes only when they have fewer tasks late than the
    robots' current routes (re-timed); otherwise the robots keep their routes, so a re-plan
    moves no task between robots for nothing.

    ``earliest_drop_offs``: every allocation is improved by local search
    (``allocation.local_search``: the fewest late tasks, then the least tardiness, then the
    earliest drop-offs), so that a task planned on time has as much room for delays as the
    search finds, whatever the allocator's own objective. With ``write_off_lateness`` (s,
    None: never) that search writes off a task planned more than that late: it goes after
    the tasks that can still be on time instead of as early as it can (``Allocation.rank``);
    with ``safety_slack`` (s, 0: none) it ranks, after the fewest late tasks and the least
    tardiness, the least room short of that slack before the deadlines: among plans as late,
    the one giving the tightest promises more room.

    ``learn_travel_times``, ``replan_on_delay``, ``retime_on_drift``,
    ``replan_only_if_fewer_late`` and ``earliest_drop_offs`` are on by default, with a write-off
    after 5 s, legs rounded to the nearest second and a 10 s safety slack (measured better:
    docs/allocation.md);
    ``learn_travel_times``, ``replan_on_delay`` and ``earliest_drop_offs`` false, with no
    margin, is the open loop (``OPEN_LOOP``): plans made only when batches arrive or robots
    break down, from the scenario's matrix, as the allocator answers them.
    """

    learn_travel_times: bool = True
    replan_on_delay: bool = True
    travel_time_estimator: str = "mean"
    recent_weight: float = 0.3
    quantile: float = 0.8
    quantile_window: int = 20
    prior_samples: float = 2.0
    travel_time_rounding: str = "nearest"
    planning_margin: float = 0.0
    drift_margin: float = 1.0
    replan_interval: float = 10.0
    retime_on_drift: bool = True
    replan_only_if_fewer_late: bool = True
    earliest_drop_offs: bool = True
    write_off_lateness: float | None = 5.0
    safety_slack: float = 10.0

    def __post_init__(self):
        self.estimator()  # checks the estimator's fields
        self.travel_time_model(np.zeros((1, 1)))  # and the rounding
        require_non_negative(self, "prior_samples", "planning_margin", "drift_margin",
                             "replan_interval", "safety_slack")
        if self.write_off_lateness is not None:
            require_non_negative(self, "write_off_lateness")
        parent = getattr(super(), "__post_init__", None)
        if parent is not None:
            parent()

    def estimator(self) -> Estimator:
        return Estimator(self.travel_time_estimator, self.recent_weight, self.quantile,
                         self.quantile_window)

    def local_search(self) -> LocalSearchParams:
        """The local search of ``earliest_drop_offs``."""
        write_off = math.inf if self.write_off_lateness is None else self.write_off_lateness
        return LocalSearchParams(write_off=float(write_off), slack=float(self.safety_slack))

    def travel_time_model(self, prior) -> TravelTimeModel:
        """The model planning with the scenario's matrix ``prior`` (s)."""
        return TravelTimeModel(prior, self.estimator(), self.prior_samples,
                               self.planning_margin, self.travel_time_rounding)

    @classmethod
    def of(cls, params) -> "FeedbackParams":
        """The feedback fields of ``params`` (an instance of a ``with_feedback`` class)."""
        return cls(**{f.name: getattr(params, f.name) for f in dataclasses.fields(cls)})


OPEN_LOOP = FeedbackParams(learn_travel_times=False, replan_on_delay=False, planning_margin=0.0,
                           retime_on_drift=False, earliest_drop_offs=False)


def with_feedback(params_class: type) -> type:
    """``params_class`` (an allocator's frozen params dataclass) with the ``FeedbackParams``
    fields added, for an allocator block's ``blocks.allocator.params``."""
    combined = type(params_class.__name__, (FeedbackParams, params_class), {
        "__doc__": "\n\n".join(inspect.cleandoc(cls.__doc__ or "")
                                for cls in (params_class, FeedbackParams)),
        "__module__": params_class.__module__,
        "allocator_params": params_class,
    })
    return dataclass(frozen=True)(combined)


def allocator_params(params):
    """The allocator's own part of ``params`` (an instance of a ``with_feedback`` class)."""
    own = params.allocator_params
    return own(**{f.name: getattr(params, f.name) for f in dataclasses.fields(own)})
