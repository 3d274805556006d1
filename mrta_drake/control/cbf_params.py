"""The parameters of ``ClusterCbfController``, in groups: nominal control, safety distances,
barrier rates, the QP, the wall rays, the coordination of robots near each other, and whether
to plan from the state predicted for when the commands act.

In a scenario (``blocks.controller.params``)::

    controller:
      kind: cluster_cbf
      params:
        nominal: {max_speed: 1.2}
        safety_distances: {human: 0.8}
        coordination: {mode: decentralized}
"""

from dataclasses import dataclass, field
from functools import cached_property
from typing import ClassVar

import numpy as np

from mrta_drake.control.barriers import BarrierRates, SafetyDistances
from mrta_drake.control.followers import FOLLOWER_RULES
from mrta_drake.control.nominal import NominalParams
from mrta_drake.control.param_groups import moved_from_flat
from mrta_drake.control.qp_solver import QpParams
from mrta_drake.control.wall_rays import SensingParams
from mrta_drake.errors import InputError, require_choice, require_non_negative, require_positive

COORDINATION_MODES = ("clusters", "decentralized", "centralized")


@dataclass(frozen=True)
class CoordinationParams:
    """How robots near each other are controlled together.

    ``mode``: ``clusters`` (robots within ``cluster_radius`` m of each other, transitively,
    solve one joint QP; its leader keeps its nominal), ``decentralized`` (each robot its own
    QP, the others within ``cluster_radius`` as moving obstacles) or ``centralized`` (one QP
    for all). ``cluster_radius`` is also the range of robot-pair rows.

    ``leader_rule``: who leads a cluster, a key of ``clusters.LEADER_RULES`` (``priority``: the
    smallest leads; ``largest_priority``; ``distance_to_goal``; or one registered with
    ``register_leader_rule``). ``followers``:
    which other members get the slow-down nominal (``followers.FOLLOWER_RULES``: ``all`` or
    ``in_the_way``, within ``yield_clearance`` m of a path's next ``yield_horizon`` m; where
    the two drive head on, not when at least ``head_on_clearance`` m (at most
    ``yield_clearance``; None: ``yield_clearance``, no exception) beside the other's path;
    see ``mrta_drake.control.followers``).

    ``arrival_radius`` (m): a robot this near the end of its stop-at-end path is done and
    leads no cluster (a queue slot or room point too near a wall can be unreachable by a few
    centimetres). A robot stands when its |v| < ``stall_speed`` (m/s): a cluster leader
    standing ``stall_time`` s while active passes the lead on (``clusters.stall_times_of``;
    not with ``stalled_leader_hands_on`` off, as in the paper),
    and a standing robot blocked by a barrier turns along it (``steering``).
    """

    mode: str = "clusters"
    cluster_radius: float = 4.0
    leader_rule: str = "priority"
    followers: str = "in_the_way"
    yield_clearance: float = 1.0
    head_on_clearance: float | None = None
    yield_horizon: float = 3.0
    arrival_radius: float = 0.5
    stall_time: float = 3.0
    stall_speed: float = 0.05
    stalled_leader_hands_on: bool = True

    def __post_init__(self):
        require_choice(self, "mode", COORDINATION_MODES)
        require_choice(self, "followers", FOLLOWER_RULES)
        require_non_negative(self, "cluster_radius", "yield_clearance", "yield_horizon",
                             "arrival_radius", "stall_speed")
        require_positive(self, "stall_time")
        if self.head_on_clearance is not None:
            require_non_negative(self, "head_on_clearance")
            if self.head_on_clearance > self.yield_clearance:
                raise InputError(None, "head_on_clearance", f"must be at most yield_clearance "
                                 f"({self.yield_clearance!r}), got {self.head_on_clearance!r}")

    @property
    def head_on(self) -> float:
        """The clearance (m) beside a path at which a robot driving head on is out of the
        way: ``head_on_clearance``, or ``yield_clearance`` when that is None."""
        return self.yield_clearance if self.head_on_clearance is None else self.head_on_clearance


@dataclass(frozen=True)
class CbfParams:
    """All parameters of ``ClusterCbfController``, one group per job (see each group's
    class). ``predict_latency``: plan from each robot's state predicted for the tick at which
    the new commands act (see ``ClusterCbfController``)."""

    nominal: NominalParams = field(default_factory=NominalParams)
    safety_distances: SafetyDistances = field(default_factory=SafetyDistances)
    barrier_rates: BarrierRates = field(default_factory=BarrierRates)
    qp: QpParams = field(default_factory=QpParams)
    sensing: SensingParams = field(default_factory=SensingParams)
    coordination: CoordinationParams = field(default_factory=CoordinationParams)
    predict_latency: bool = True

    moved_fields: ClassVar[dict[str, str]] = moved_from_flat(
        {"nominal": NominalParams, "barrier_rates": BarrierRates, "qp": QpParams,
         "sensing": SensingParams, "coordination": CoordinationParams},
        {"safety_distance_wall": "safety_distances.wall",
         "safety_distance_human": "safety_distances.human",
         "safety_distance_robot": "safety_distances.robot", "coordination": "coordination.mode"})

    @cached_property
    def row_params(self) -> np.ndarray:
        """Safety distance (m), alpha1, alpha2 (1/s) of walls, humans, robots, then the cluster
        radius (m), the closest wall point's distance (m; ``SafetyDistances.wall_contact``,
        at most ``wall``) and its column in the wall points (``SensingParams.ray_count``:
        after the rays), for the compiled row kernel (``safety_rows.fill_rows``)."""
        d, rates = self.safety_distances, self.barrier_rates
        return np.array([d.wall, rates.alpha1_wall, rates.alpha2_wall,
                         d.human, rates.alpha1_human, rates.alpha2_human,
                         d.robot, rates.alpha1_robot, rates.alpha2_robot,
                         self.coordination.cluster_radius, min(d.wall_contact, d.wall),
                         self.sensing.ray_count])
