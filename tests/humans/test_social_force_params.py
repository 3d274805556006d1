"""The humans block's parameters: checked on construction, read from
``blocks.humans.params`` and used by the block the stack builds."""

import math
import pathlib

import pytest

from mrta_drake.errors import InputError
from mrta_drake.humans.social_force_params import SocialForceParams
from mrta_drake.scenario.loading import load_scenario
from mrta_drake.scenario.schema import RobotConfig
from mrta_drake.stack.blocks import BuildContext, resolve_block

ROOT = pathlib.Path(__file__).resolve().parents[2]


@pytest.mark.parametrize(("changes", "field", "message"), [
    ({"radius": 0.0}, "radius", "must be > 0, got 0.0"),
    ({"relaxation_time": float("nan")}, "relaxation_time", "must be > 0, got nan"),
    ({"wall_strength": -1.0}, "wall_strength", "must be >= 0, got -1.0"),
    ({"desired_speed": 2.0}, "desired_speed", "must be <= max_speed 1.5, got 2.0"),
    ({"robot_repulsion_gain": -1.0}, "robot_repulsion_gain", "must be >= 0, got -1.0"),
    ({"yield_time": float("inf")}, "yield_time", "must be >= 0, got inf"),
    ({"passing_gap": 0}, "passing_gap", "must be > 0, got 0"),
    ({"sidestep_ratio": "half"}, "sidestep_ratio", "must be >= 0, got 'half'"),
    ({"waiting_gap": 1.5}, "waiting_gap", "must be < yield_distance 1.5, got 1.5"),
    ({"negligible_force": -1e-9}, "negligible_force", "must be >= 0, got -1e-09"),
])
def test_bad_params_name_the_field_and_the_value(changes, field, message):
    with pytest.raises(InputError) as error:
        SocialForceParams(**changes)
    assert error.value.field == field
    assert str(error.value) == f"{field}: {message}"


def test_robot_repulsion_is_the_originals_x90_at_equal_centre_distance():
    # The original's potential: 90 V0 exp(-d / sigma) at centre distance d; this model's:
    # gain V0 exp(-(d - r_person - r_robot) / sigma).
    params = SocialForceParams()
    reach = params.radius + RobotConfig().radius
    assert params.robot_repulsion_gain == pytest.approx(
        90.0 * math.exp(-reach / params.repulsion_range), rel=0.01)


def test_a_scenario_sets_how_people_walk_in_the_humans_block():
    scenario = load_scenario(ROOT / "scenarios/hospital_6_robots.yaml", overrides={
        "blocks.humans.params": {"radius": 0.3, "max_speed": 1.2, "desired_speed": 0.8}})
    humans_type, params = resolve_block(scenario, "humans")
    assert params == SocialForceParams(radius=0.3, max_speed=1.2, desired_speed=0.8)
    humans = humans_type.make(BuildContext.for_scenario(scenario), params)
    assert set(humans.human_radii) == {0.3}
    walkers = [p for p in humans.people if p.name == "nurse_east_1"]
    assert [p.desired_speed for p in walkers] == [0.8]


def test_a_bad_param_in_a_scenario_is_one_line_naming_file_field_and_value():
    scenario = load_scenario(ROOT / "scenarios/hospital_6_robots.yaml",
                             overrides={"blocks.humans.params": {"waypoint_tolerance": -0.1}})
    with pytest.raises(InputError) as error:
        resolve_block(scenario, "humans")
    assert str(error.value).endswith("hospital_6_robots.yaml: blocks.humans.params."
                                     "waypoint_tolerance: must be > 0, got -0.1")
