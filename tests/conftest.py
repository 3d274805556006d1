"""Shared test setup."""

import pytest

from mrta_drake.stack import blocks


@pytest.fixture(autouse=True)
def project_block_kinds(monkeypatch):
    """Each test registers block kinds (a tutorial's allocator, a sweep's plugin) on copies
    of the registry's slots, so later tests (the scenario reference) see the project's
    kinds only."""
    for slot, kinds in blocks._REGISTRY.items():
        monkeypatch.setitem(blocks._REGISTRY, slot, dict(kinds))
