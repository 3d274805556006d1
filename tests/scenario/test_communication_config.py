"""The ``communication:`` section: defaults ideal, bad values one line naming the field."""

import pathlib

import pytest

from mrta_drake.errors import InputError
from mrta_drake.scenario.loading import load_scenario
from mrta_drake.scenario.schema import CommunicationConfig
from mrta_drake.scenario.validate import validate_scenario

SCENARIO = pathlib.Path(__file__).resolve().parents[2] / "scenarios/hospital_6_robots.yaml"


def test_the_default_network_is_ideal_and_any_delay_or_loss_is_not():
    assert CommunicationConfig().ideal
    assert not CommunicationConfig(latency=0.1).ideal
    assert not CommunicationConfig(jitter=0.1).ideal
    assert not CommunicationConfig(loss=0.1).ideal


@pytest.mark.parametrize(("field", "value", "message"), [
    ("latency", -0.1, "must be >= 0 s"), ("jitter", -1.0, "must be >= 0 s"),
    ("stale_after", -0.5, "must be >= 0 s"), ("loss", 1.0, "must be in [0, 1)"),
    ("loss", -0.2, "must be in [0, 1)")])
def test_a_bad_value_names_the_file_and_the_field(field, value, message):
    with pytest.raises(InputError) as error:
        load_scenario(SCENARIO, overrides={f"communication.{field}": value})
    assert str(error.value) == (f"{SCENARIO}: communication.{field}: {message}, "
                                f"got {value!r}")


def test_an_unknown_network_kind_is_refused_when_validated():
    with pytest.raises(InputError, match=r"communication.kind: unknown kind 'mesh'"):
        validate_scenario(SCENARIO, overrides={"communication.kind": "mesh"})
