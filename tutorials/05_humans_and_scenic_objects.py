"""Tutorial 5: fill the hospital with people and objects placed by a Scenic program, then
close a corridor.

Three sections of a scenario make the world busy:

- ``humans:`` people moved by the social-force ``humans`` block; they steer around walls,
  objects, each other and the robots. ``walkers`` are named people looping through given
  waypoints; ``groups`` are generated for the scenario's seed: ``visitors`` (loops through
  random points), a ``crowd`` milling around a ``center`` within ``spread`` m, or a
  ``stream`` of people entering at ``center`` every ``interval`` s and walking to some of the
  ``points``. Here: a nurse pacing the east corridor, a crowd of four in the waiting area
  and three visitors coming in at the north entrance.
- ``world.scenic``: a Scenic 3 program (``tutorials/hospital_wheelchairs.scenic``) that
  places objects, sampled for the seed; ``world.scenic_params`` overrides its ``param``
  values. Its objects join the floor plan's obstacles, the one obstacle source, so the
  physics, the planner's costmap, the controller's wall rays, the people and Meshcat all see
  them. By default a program's objects must stay off the robots' lanes and queues (the
  ``beside_lanes`` region of ``mrta_drake/world/scenic_model.scenic``); Scenic redraws the scene
  until no object breaks a rule. One seed gives one scene; another seed, another scene.
- ``disturbances.blockages``: a box closed for a time window (``start`` to ``end``, s). While
  it is closed it is lethal in the planner's costmap, the roadway lanes through it are shut
  and the controller's wall rays see it; robots whose leg runs through it are re-routed
  (a ``detour`` event), or wait when no lane is left. Here cross corridor 1, between the
  east and the west corridor, is closed from 2 s to 35 s: the robots heading across it go
  round by another cross corridor. (``disturbances`` also schedules ``breakdowns`` and
  communication ``outages``: see docs/scenario.md.)

All are set here as ``load_scenario`` overrides (dotted field names, set before the
scenario is checked), the same values you would write in the YAML file. The base is the
hospital with fixed routes and nobody about; the busy copy drives the same routes, and the
blocked copy is the busy one with the corridor closed. The tables list the objects of this
seed's scene and of the next seed's, the people, the blockage's effect (which robots were
re-routed or left waiting, from the ``disturbances`` section of the summary), and the three
runs side by side: clearances to people, walls and objects (``min robot-wall`` counts
objects too), how far and how long the robots drove, and the people's own figures
(``mrta_drake/results/human_metrics.py``: closest approach, time a robot spent in someone's
personal space, encounters, detours).

Run (``--meshcat`` shows the runs live, one after the other)::

    python tutorials/05_humans_and_scenic_objects.py [--duration 40] [--meshcat] [--out DIR]
"""

import dataclasses
import pathlib

from tutorial_common import options, run_each

from mrta_drake import load_scenario
from mrta_drake.results.report import format_runs, text_table
from mrta_drake.stack.blocks import BuildContext
from mrta_drake.world.plant import load_floor_plan_of

HERE = pathlib.Path(__file__).resolve().parent
SCENARIO = HERE.parent / "scenarios/hospital_routes_6_robots.yaml"
BUSY = {
    "world.scenic": str(HERE / "hospital_wheelchairs.scenic"),
    "world.scenic_params": {"wheelchairs": 3, "carts": 2},
    "humans.walkers": [{"name": "nurse", "waypoints": [[5.0, -2.0], [5.0, -20.0]]}],
    "humans.groups": [
        {"kind": "crowd", "count": 4, "center": [0.0, 10.0], "spread": 2.0},
        {"kind": "stream", "count": 3, "center": [0.0, 17.0], "interval": 10.0,
         "points": [[0.0, 3.0], [-5.0, -12.0], [5.0, -12.0]]},
    ],
}
# Cross corridor 1, wall to wall, halfway between the east and the west corridor (m, s).
BLOCKAGE = {"name": "cross_corridor_1", "box": [-1.0, 1.0, -10.0, -7.0], "start": 2.0,
            "end": 35.0}


def placed_objects(scenario) -> list:
    """The boxes and cylinders the scenario's Scenic program adds for its seed."""
    base = load_floor_plan_of(scenario, objects=False).obstacles
    full = BuildContext.for_scenario(scenario).obstacles
    return [*full.boxes[len(base.boxes):], *full.cylinders[len(base.cylinders):]]


def main(argv=None) -> dict:
    args = options(__doc__, duration=40.0).parse_args(argv)
    scenarios = {
        "empty": load_scenario(SCENARIO),
        "busy": load_scenario(SCENARIO, overrides=BUSY),
        "blocked": load_scenario(SCENARIO, overrides=BUSY | {
            "disturbances.blockages": [BLOCKAGE]}),
    }
    busy = scenarios["busy"]
    objects = {seed: placed_objects(dataclasses.replace(busy, seed=seed))
               for seed in (busy.seed, busy.seed + 1)}
    print("Objects placed by the Scenic program (centre x, y in m):")
    print(text_table(["object", *(f"seed {seed}" for seed in objects)], [
        [obj.name, *(f"({o.center[0]:.2f}, {o.center[1]:.2f})" for o in others)]
        for obj, *others in zip(objects[busy.seed], *objects.values(), strict=True)]))

    runs = run_each(scenarios, args)
    people = runs["busy"].stack.humans.people
    print(f"\nPeople in the busy hospital ({len(people)}):")
    print(text_table(["person", "start x, y", "enters at s", "speed m/s"], [
        [p.name, f"({p.start[0]:.1f}, {p.start[1]:.1f})", f"{p.entry_time:g}",
         f"{p.desired_speed:.2f}"] for p in people]))
    blockage = runs["blocked"].summary["disturbances"][0]
    print(f"\nWhile {blockage['name']} was closed ({blockage['start']:g}-{blockage['end']:g} s):")
    print(text_table(["re-routed", "waited", "detours"], [[
        ", ".join(blockage["robots_rerouted"]) or "-", ", ".join(blockage["robots_waited"]) or "-",
        blockage["detours"]]]))
    print()
    print(format_runs({name: run.summary for name, run in runs.items()}))
    humans = runs["busy"].summary["humans"]
    print("\nThe people's figures in the busy run:")
    print(text_table(["figure", "value"], [[key, "-" if value is None else f"{value:.2f}"]
                                           for key, value in humans.items()]))
    return {"objects": objects, "runs": runs}


if __name__ == "__main__":
    main()
