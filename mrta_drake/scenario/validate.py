"""Validating a scenario completely, without running it (``mrta-sim validate``)."""

from mrta_drake.navigation.roadways import Roadways
from mrta_drake.scenario.loading import load_scenario
from mrta_drake.scenario.schema import Scenario
from mrta_drake.stack.blocks import check_blocks
from mrta_drake.world.plant import load_floor_plan_of, resolve_locations


def validate_scenario(path: str, overrides=None) -> Scenario:
    """Load ``path`` (with ``load_scenario``'s ``overrides``) and check everything a run
    would need: fields, references, the floor plan, robot starts, block kinds and
    parameters, the roadway graph's connectivity.
    Raises ``InputError`` on the first problem; returns the scenario with locations
    resolved."""
    scenario = load_scenario(path, overrides=overrides)
    check_blocks(scenario)
    scenario = resolve_locations(scenario, load_floor_plan_of(scenario))
    if scenario.locations:
        Roadways(scenario.roadways, scenario.locations, scenario.source)
    return scenario
