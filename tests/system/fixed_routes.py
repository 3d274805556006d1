"""A test building's scenario with robots on fixed routes and no tasks, for end-to-end
runs of how robots share single-file corridors and spots."""

from pathlib import Path

import yaml

from mrta_drake import load_scenario
from mrta_drake.scenario.schema import Scenario
from mrta_drake.tools.building_import import ImportOptions, import_building


def fixed_routes(building: Path, out: Path, robots: list[dict]) -> tuple[Scenario, list[str]]:
    """``building`` imported into ``out``, its scenario with ``robots`` (entries of the
    ``robots`` section, each ``route`` given by location names) on fixed routes (the
    ``fixed`` allocator) and without tasks, loaded; and the location names by id."""
    import_building(str(building), str(out), ImportOptions(robots=2))
    raw = yaml.safe_load((out / "scenario.yaml").read_text())
    names = [loc["name"] for loc in
             yaml.safe_load((out / "navigation.yaml").read_text())["locations"]]
    raw["robots"] = [robot | {"route": [names.index(n) for n in robot["route"]]}
                     for robot in robots]
    raw.setdefault("blocks", {})["allocator"] = {"kind": "fixed"}
    raw.pop("tasks")
    path = out / "fixed_routes.yaml"
    path.write_text(yaml.safe_dump(raw))
    return load_scenario(path), names
