"""Control of dynamic unicycles: nominal path following (``nominal``, along ``paths``), robot
clusters and their leaders (``clusters``, ``followers``), second-order control barrier functions
(``barriers``) made into the safety rows of QPs (``wall_rays``, ``safety_rows``, ``steering``,
``tick_qps``) and solved (``qp_solver``). The controller blocks beside them
(``ClusterCbfController``, ``GoToGoalController``, sharing ``controller_common``) call them every
tick; ``tick_kernel`` is the cluster controller's compiled part before its QPs."""

from mrta_drake.control.barriers import BarrierRates, SafetyDistances
from mrta_drake.control.cbf_params import CbfParams, CoordinationParams
from mrta_drake.control.clusters import (
    LEADER_RULES,
    LeaderRule,
    form_clusters,
    register_leader_rule,
)
from mrta_drake.control.go_to_goal_controller import GoToGoalParams
from mrta_drake.control.nominal import NominalParams, nominal_control, slow_down
from mrta_drake.control.qp_solver import CbfQp, QpParams, QpSolution
from mrta_drake.control.safety_rows import safety_rows
from mrta_drake.control.wall_rays import SensingParams, WallRays

__all__ = [
    "LEADER_RULES",
    "BarrierRates",
    "CbfParams",
    "CbfQp",
    "CoordinationParams",
    "GoToGoalParams",
    "LeaderRule",
    "NominalParams",
    "QpParams",
    "QpSolution",
    "SafetyDistances",
    "SensingParams",
    "WallRays",
    "form_clusters",
    "nominal_control",
    "register_leader_rule",
    "safety_rows",
    "slow_down",
]
