"""``mrta-sim import MAP.yaml --locations POINTS.yaml --out DIR``: a runnable scenario folder
from a ROS ``map_server`` map, which gives walls only, and a few named points.

The navigation (one-way lanes on the free space's skeleton, queue slots and parking at each
point: docs/worlds.md, "Navigation from a ROS map") is derived and written to
``DIR/navigation.yaml``, editable by hand; ``DIR/scenario.yaml`` names the map where it is
(a path relative to ``DIR``), puts robot k on location k's point (then on the locations'
parking spots), people walking between seeded random free points, and a seeded generated
task stream between the locations. World frame: the map's, x east, y north, metres.
"""

import os

import numpy as np

from mrta_drake.errors import InputError
from mrta_drake.navigation.location_derivation import load_points
from mrta_drake.navigation.navigation_derivation import derive_navigation, write_navigation
from mrta_drake.tools.building_import import (
    ImportOptions,
    ImportReport,
    check_people_fit,
    write_yaml,
)
from mrta_drake.world.floor_plan import FloorPlan
from mrta_drake.world.ros_map import load_ros_map

PERSON_CLEARANCE = 1.0  # m from walls of the points people walk between
PERSON_POINTS = 6  # random free points each imported scenario's people walk between
WALK_CLEARANCE = 0.5  # m from walls people need to pass (a 0.25 m body and its margin)


def import_ros_map(map_path: str, points_path: str, out_dir: str,
                   options: ImportOptions) -> ImportReport:
    """Writes ``out_dir/navigation.yaml`` and ``out_dir/scenario.yaml`` (see the module
    docstring); bad input raises ``InputError`` before anything is written, or, where the
    people do not fit, once the scenario is written and removed (``check_people_fit``)."""
    plan = load_ros_map(map_path)
    navigation = derive_navigation(plan, load_points(points_path), points_file=points_path)
    starts = _robot_starts(navigation["locations"], options.robots, points_path)
    rng = np.random.default_rng(options.seed)
    os.makedirs(out_dir, exist_ok=True)
    write_navigation(os.path.join(out_dir, "navigation.yaml"), navigation,
                     f"Navigation of {os.path.basename(map_path)} and "
                     f"{os.path.basename(points_path)}, derived by `mrta-sim import`\n"
                     "(docs/worlds.md). Fields follow LocationConfig and RoadwaysConfig; "
                     "world frame x east,\ny north, metres. Edit freely.")
    scenario = os.path.join(out_dir, "scenario.yaml")
    content = {
        "world": {"kind": "ros_map",
                  "floor_plan": os.path.relpath(os.path.abspath(map_path), out_dir)},
        "locations": "navigation.yaml",
        "roadways": "navigation.yaml",
        "robots": [{"name": f"robot{k + 1}", **start} for k, start in enumerate(starts)],
        "tasks": {"generate": {"rate": round(options.tasks_per_robot * len(starts), 6),
                               "batch_size": [1, 2], "slack": [2.0, 4.0]}},
        "seed": options.seed,
        "duration": float(options.duration),
    }
    if options.people:
        walk_points = _free_points(plan, navigation["locations"], rng)
        content["humans"] = {"groups": [{"kind": "visitors", "count": options.people,
                                         "points": walk_points}]}
    write_yaml(scenario, f"# {os.path.basename(map_path)}: imported by `mrta-sim import` "
               f"(seed {options.seed}).\n# Run: mrta-sim run scenario.yaml\n", content)
    check_people_fit([scenario], options.people)
    locations, lanes = navigation["locations"], navigation["roadways"]["edges"]
    return ImportReport([scenario], [
        f"{len(locations)} locations, {len(navigation['roadways']['nodes'])} roadway nodes, "
        f"{len(lanes)} one-way lanes, "
        f"{len(navigation['roadways']['single_file'])} single-file segments; "
        f"wrote {scenario}"])


def _robot_starts(locations: list[dict], count: int, points_path: str) -> list[dict]:
    """Robot k on location k's point (its start location), then on parking spots."""
    spots = [{"start": [*loc["point"], 0.0], "start_location": loc["id"]} for loc in locations]
    spots += [{"start": [*spot, 0.0]} for loc in locations for spot in loc["parking"]]
    if count > len(spots):
        raise InputError(points_path, "points", f"room for {len(spots)} robots (points and "
                         f"their parking spots), asked for {count}")
    return spots[:count]


def _free_points(plan: FloorPlan, locations: list[dict],
                 rng: np.random.Generator) -> list[list[float]]:
    """Seeded random points at least ``PERSON_CLEARANCE`` from every obstacle, all in the
    one region people can walk through (``WALK_CLEARANCE`` from walls) that holds the most
    locations, so a walk between any two of them exists."""
    from scipy import ndimage

    grid = plan.occupancy()
    distance = ndimage.distance_transform_edt(~grid.occupied) * grid.resolution
    labels, _ = ndimage.label(distance >= WALK_CLEARANCE)
    i, j = grid.world_to_cell(np.array([loc["point"] for loc in locations]))
    held = labels[i, j][labels[i, j] > 0]
    if len(held) == 0:
        raise InputError(plan.source, "map", "no location is in a region people can walk")
    region = labels == np.bincount(held).argmax()
    rows, cols = np.nonzero(region & (distance >= PERSON_CLEARANCE))
    if len(rows) == 0:
        raise InputError(plan.source, "map", f"no free space {PERSON_CLEARANCE} m from walls "
                         "near the locations for people to walk in")
    picks = rng.choice(len(rows), size=min(PERSON_POINTS, len(rows)), replace=False)
    return [[round(float(v), 2) for v in grid.cell_to_world(rows[k], cols[k])]
            for k in sorted(picks)]
