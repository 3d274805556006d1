"""The committed scenario field reference is what the schema generates."""

import pathlib

from mrta_drake.schema_docs import reference

ROOT = pathlib.Path(__file__).resolve().parent.parent


def test_scenario_reference_is_current():
    committed = (ROOT / "docs/scenario_reference.md").read_text()
    assert committed == reference(), (
        "docs/scenario_reference.md is stale: run "
        "`python -m mrta_drake.schema_docs > docs/scenario_reference.md`")
