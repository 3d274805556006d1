"""Profiles: ``profile: paper`` sets every switch of docs/fidelity.md, and only where the
scenario leaves it unset."""

import dataclasses
import pathlib
import re

import pytest

from mrta_drake.errors import InputError
from mrta_drake.scenario.loading import load_scenario
from mrta_drake.scenario.profiles import PAPER_SWITCHES
from mrta_drake.stack.blocks import resolve_block

ROOT = pathlib.Path(__file__).resolve().parents[2]
HOSPITAL = ROOT / "scenarios/hospital_6_robots.yaml"
# A switch cell of docs/fidelity.md's table: `dotted.field: value`.
SWITCH_CELL = re.compile(r"^`([a-z_.]+): ([^`]+)`$")


def _documented_switches() -> dict[str, str]:
    """Field -> paper value (as written) of every switch in docs/fidelity.md's table."""
    switches = {}
    for line in (ROOT / "docs/fidelity.md").read_text().splitlines():
        cells = [cell.strip() for cell in line.strip().strip("|").split("|")]
        if line.startswith("|") and len(cells) >= 2:
            match = SWITCH_CELL.match(cells[-1])
            if match:
                switches[match.group(1)] = match.group(2)
    return switches


def _value(scenario, field: str):
    """The typed value of dotted ``field`` of ``scenario``; a block's params are read from
    its checked parameters dataclass."""
    parts = field.split(".")
    if parts[0] == "blocks" and parts[2] == "params":
        node = resolve_block(scenario, parts[1])[1]
        parts = parts[3:]
    else:
        node = scenario
    for part in parts:
        assert dataclasses.is_dataclass(node), f"{field}: {part} is not a field"
        assert part in {f.name for f in dataclasses.fields(node)}, f"{field}: no {part}"
        node = getattr(node, part)
    return node


def test_every_documented_switch_exists_and_the_paper_profile_sets_it():
    documented = _documented_switches()
    assert set(documented) == {switch.field for switch in PAPER_SWITCHES}
    ours = load_scenario(HOSPITAL, check_world=False)
    paper = load_scenario(HOSPITAL, check_world=False, overrides={"profile": "paper"})
    for switch in PAPER_SWITCHES:
        assert _value(paper, switch.field) == switch.value, switch.field
        assert str(switch.value).lower() == documented[switch.field].lower(), switch.field
        assert _value(ours, switch.field) != switch.value, f"{switch.field} is no switch"


def test_a_field_the_scenario_sets_wins_over_the_profile():
    followers = "blocks.controller.params.coordination.followers"
    scenario = load_scenario(HOSPITAL, check_world=False,
                             overrides={"profile": "paper", followers: "in_the_way"})
    assert _value(scenario, followers) == "in_the_way"
    assert _value(scenario, "blocks.controller.params.coordination.leader_rule") == (
        "largest_priority")


def test_block_params_are_set_only_for_the_kind_they_belong_to():
    scenario = load_scenario(HOSPITAL, check_world=False, overrides={
        "profile": "paper", "blocks.controller.kind": "go_to_goal",
        "blocks.allocator.kind": "greedy"})
    assert scenario.blocks.controller.params == {}
    assert scenario.blocks.allocator.params == {}
    assert scenario.blocks.planner.params == {"cost_resting_robots": False}


def test_an_unknown_profile_is_one_line_naming_the_field():
    with pytest.raises(InputError, match=r"hospital_6_robots.yaml: profile: unknown profile "
                       r"'papers' \(one of mrta_drake, paper\)"):
        load_scenario(HOSPITAL, check_world=False, overrides={"profile": "papers"})
