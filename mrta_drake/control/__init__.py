"""Control of dynamic unicycles: nominal path following (``nominal``), robot clusters and
their leaders (``clusters``), and second-order CBF safety filters solved as QPs (``cbf_qp``).
The controller blocks beside them (``ClusterCbfController``, ``GoToGoalController``) call it
every tick."""

from mrta_drake.control.cbf_qp import CbfParams, CbfQp, QpSolution, WallRays, safety_rows
from mrta_drake.control.clusters import (
    LEADER_RULES,
    LeaderRule,
    form_clusters,
    register_leader_rule,
)
from mrta_drake.control.nominal import NominalParams, nominal_control, slow_down

__all__ = [
    "LEADER_RULES",
    "CbfParams",
    "CbfQp",
    "LeaderRule",
    "NominalParams",
    "QpSolution",
    "WallRays",
    "form_clusters",
    "nominal_control",
    "register_leader_rule",
    "safety_rows",
    "slow_down",
]
