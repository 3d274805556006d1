"""The controllers' parameter groups in a scenario: the nested layout loads, bad values and the
old flat layout are refused with one line naming the file, the field and where it went."""

import dataclasses
import pathlib

import pytest

from mrta_drake.control.cbf_params import CbfParams, CoordinationParams
from mrta_drake.control.go_to_goal_controller import GoToGoalParams
from mrta_drake.control.nominal import NominalParams
from mrta_drake.errors import InputError
from mrta_drake.scenario.loading import load_scenario
from mrta_drake.stack.blocks import resolve_block

ROOT = pathlib.Path(__file__).resolve().parents[2]
SCENARIO = ROOT / "scenarios/hospital_6_robots.yaml"
PARAMS = "blocks.controller.params"

# Every field of the flat CbfParams that scenarios used before the groups.
FLAT_LAYOUT = (
    "k_x", "k_v", "k_theta", "lookahead", "heading_gate", "heading_gate_cluster", "max_speed",
    "min_speed", "max_accel", "max_yaw_rate", "k_slow", "slow_accel", "goal_tolerance",
    "brake_accel", "pass_offset", "pass_clearance", "pass_range", "safety_distance_human",
    "safety_distance_wall", "safety_distance_robot", "alpha1_human", "alpha2_human",
    "alpha1_wall", "alpha2_wall", "alpha1_robot", "alpha2_robot", "slack_weight", "ray_count",
    "ray_spacing", "ray_start", "rays_in_body_frame", "ray_range", "coordination",
    "cluster_radius", "solver", "leader_rule", "followers", "yield_clearance", "yield_horizon",
    "arrival_radius", "stall_time", "stall_speed")


def _controller_params(kind: str, **overrides):
    scenario = load_scenario(SCENARIO, check_world=False, overrides={
        "blocks.controller.kind": kind, **{f"{PARAMS}.{k}": v for k, v in overrides.items()}})
    return resolve_block(scenario, "controller")[1]


def _field(params, dotted: str):
    for name in dotted.split("."):
        params = getattr(params, name)
    return params


def test_the_nested_layout_loads_into_the_groups():
    params = _controller_params("cluster_cbf", **{
        "coordination": {"mode": "decentralized", "cluster_radius": 3.0},
        "nominal.max_speed": 1.2, "safety_distances.human": 0.8, "qp.solver": "osqp",
        "predict_latency": False})
    assert params == CbfParams(
        nominal=NominalParams(max_speed=1.2),
        safety_distances=dataclasses.replace(CbfParams().safety_distances, human=0.8),
        qp=dataclasses.replace(CbfParams().qp, solver="osqp"),
        coordination=CoordinationParams(mode="decentralized", cluster_radius=3.0),
        predict_latency=False)
    assert params.row_params[[0, 3, 9, 10, 11]].tolist() == [0.6, 0.8, 3.0, 0.3, 12]
    # The closest point's contact guard is used as at most the rays' wall distance.
    small = _controller_params("cluster_cbf", **{"safety_distances.wall": 0.25})
    assert small.row_params[[0, 10]].tolist() == [0.25, 0.25]
    plain = _controller_params("go_to_goal", **{"nominal.k_x": 2.0})
    assert plain == GoToGoalParams(nominal=NominalParams(k_x=2.0))


def test_every_field_of_the_flat_layout_names_its_new_place():
    moved = CbfParams.moved_fields
    assert set(FLAT_LAYOUT) <= set(moved)
    for old in FLAT_LAYOUT:
        _field(CbfParams(), moved[old])  # the new place exists
    assert moved["coordination"] == "coordination.mode"
    assert moved["safety_distance_wall"] == "safety_distances.wall"
    for old, new in GoToGoalParams.moved_fields.items():
        assert _field(GoToGoalParams(), new) == _field(CbfParams(), CbfParams.moved_fields[old])


@pytest.mark.parametrize("kind,old,value,new", [
    ("cluster_cbf", "cluster_radius", 3.0, "coordination.cluster_radius"),
    ("cluster_cbf", "coordination", "decentralized", "coordination.mode"),
    ("cluster_cbf", "safety_distance_human", 0.8, "safety_distances.human"),
    ("cluster_cbf", "solver", "osqp", "qp.solver"),
    ("go_to_goal", "max_speed", 1.0, "nominal.max_speed"),
    ("go_to_goal", "ray_count", 8, "sensing.ray_count"),
])
def test_an_old_flat_field_gives_one_line_with_its_new_place(kind, old, value, new):
    with pytest.raises(InputError) as error:
        _controller_params(kind, **{old: value})
    assert str(error.value) == f"{SCENARIO}: {PARAMS}.{old}: moved to {PARAMS}.{new}"
    assert error.value.file == str(SCENARIO) and error.value.field == f"{PARAMS}.{old}"


def test_a_field_go_to_goal_never_used_is_unknown():
    with pytest.raises(InputError, match=f"{PARAMS}.cluster_radius: unknown field"):
        _controller_params("go_to_goal", cluster_radius=3.0)


@pytest.mark.parametrize("group,value,message", [
    ("coordination.mode", "magic", "must be one of clusters, decentralized, centralized"),
    ("coordination.followers", "none", "must be one of all, in_the_way"),
    ("coordination.stall_time", 0.0, "must be > 0, got 0.0"),
    ("qp.solver", "gurobi", "must be one of clarabel, osqp, active_set, got 'gurobi'"),
    ("nominal.max_accel", -1.0, "must be > 0, got -1.0"),
    ("nominal.min_speed", 0.2, "must be <= 0, got 0.2"),
    ("barrier_rates.alpha1_wall", 0.0, "must be > 0, got 0.0"),
    ("safety_distances.robot", -0.1, "must be >= 0, got -0.1"),
    ("sensing.ray_range", 0.0, "must be > 0, got 0.0"),
])
def test_a_bad_value_in_a_group_gives_one_line(group, value, message):
    with pytest.raises(InputError) as error:
        _controller_params("cluster_cbf", **{group: value})
    assert str(error.value).startswith(f"{SCENARIO}: {PARAMS}.{group}: {message}")
    assert "\n" not in str(error.value)


def test_robots_cruise_at_k_x_times_lookahead_within_max_speed():
    assert NominalParams().cruise_speed == pytest.approx(0.75)
    assert NominalParams(max_speed=0.5).cruise_speed == 0.5
