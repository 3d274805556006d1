"""The committed scenario field reference is what the schema generates."""

import pathlib

from mrta_drake.scenario.field_reference import reference

ROOT = pathlib.Path(__file__).resolve().parents[2]


def test_scenario_reference_is_current():
    committed = (ROOT / "docs/scenario_reference.md").read_text()
    assert committed == reference(), (
        "docs/scenario_reference.md is stale: run "
        "`python -m mrta_drake.scenario.field_reference > docs/scenario_reference.md`")
