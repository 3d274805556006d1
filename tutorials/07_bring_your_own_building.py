"""Tutorial 7: bring your own building: import an Open-RMF building with two floors and
lifts, run it, and see the robots ride between the floors.

Any ``*.building.yaml`` drawn with Open-RMF's traffic editor (or written by hand, as this
project's ``models/two_floor_clinic/two_floor_clinic.building.yaml``) is a world
(docs/worlds.md):

1. ``import_building`` (``mrta-sim import X.building.yaml --out DIR``) writes a runnable
   folder: a copy of the building, ``navigation.yaml`` (the task locations, the one-way
   roadways derived from its lanes, and the lift rides) and ``scenario.yaml`` (robots on its
   chargers and parking spots, shared over the floors, and a generated task stream sized so
   that the robots can serve it in the run: only legs up to a fifth of the run, so a run of
   400 s lets tasks cross floors, legs of up to 80 s through a lift here). With
   several levels and no ``--level`` every floor runs at once: the floors lie side by side
   in one plane, 30 m apart (``LevelLayout``), so nothing on one floor sees the other.
2. ``load_scenario`` and ``simulate`` run it like any scenario. A task whose pickup and
   drop-off are on different floors sends its robot through a lift: its waypoint generator
   asks the ``lift_bank`` for the lift near the cabin; the bank sends it to the lift of
   that bank it waits least for; it waits its turn, drives to its berth in the cabin (a
   cabin carries as many robots as fit, robots with the same trip ride together), and the
   bank moves the riders to the cabin on the other floor once the ride's time (doors, then
   2 m/s with 1.2 m/s^2 over the floors' height difference) has passed. With ``--meshcat``
   the floors are shown stacked at their elevations (``world.levels_view``), the cabins
   moving between them.
3. The run's events (type ``lift``: request, board, depart, arrive, leave) and the summary's
   ``lifts`` section (rides, waits) say what the lifts did; ``LevelLayout.level_of`` tells on
   which floor each task's pickup and drop-off were.

Run::

    python tutorials/07_bring_your_own_building.py [--duration 400] [--meshcat] [--out DIR]
        [--building X.building.yaml] [--robots 4]
"""

import collections
import pathlib
import tempfile

from tutorial_common import open_meshcat, options

from mrta_drake import load_scenario, simulate
from mrta_drake.tools.building_import import ImportOptions, import_building
from mrta_drake.world.rmf_scenario import imported_levels

BUILDING = (pathlib.Path(__file__).resolve().parent.parent
            / "models/two_floor_clinic/two_floor_clinic.building.yaml")


def main(argv=None) -> dict:
    parser = options(__doc__, duration=400.0)
    parser.add_argument("--building", default=str(BUILDING), help="an Open-RMF building")
    parser.add_argument("--robots", type=int, default=4, help="robots, shared over floors")
    args = parser.parse_args(argv)
    out = pathlib.Path(args.out or tempfile.mkdtemp(prefix="mrta_building_"))

    # 1. Import: a runnable folder.
    report = import_building(args.building, str(out / "imported"),
                             ImportOptions(robots=args.robots, seed=1, duration=args.duration,
                                           tasks_per_robot=0.01))
    print("\n".join(report.lines))
    scenario = load_scenario(report.scenarios[0])
    layout = imported_levels(scenario.world.floor_plan, scenario.world.graph).layout
    for level in layout.levels:
        print(f"level {level.name}: {level.elevation:g} m up, drawn {level.offset:g} m east")

    # 2. Run.
    meshcat = open_meshcat(args.meshcat)
    result = simulate(scenario, duration=args.duration, meshcat=meshcat,
                      realtime_rate=1.0 if meshcat else 0.0,
                      out_dir=str(out / "run") if args.out else None, plots=False)
    summary = result.summary

    # 3. What happened.
    level_of = {loc.id: layout.level_of(loc.point) for loc in scenario.locations}
    done = collections.Counter(
        f"{level_of[task['pickup']]} -> {level_of[task['dropoff']]}"
        for task in summary["tasks"]["per_task"] if task["actual_dropoff"] is not None)
    print(f"\n{summary['tasks']['completed']} of {summary['tasks']['released']} released "
          f"tasks completed, by floors: {dict(done)}")
    for name, lift in summary["lifts"].items():
        wait = "-" if lift["mean_wait"] is None else f"{lift['mean_wait']:.1f} s"
        print(f"{name}: {lift['rides']} rides, mean wait {wait}")
    rides = [e for e in result.events if e["type"] == "lift" and e["kind"] == "arrive"]
    for event in rides[:5]:
        print(f"  {event['at']:6.1f} s: {event['robot']} arrived on {event['level']} "
              f"by {event['lift']}")
    safety = summary["safety"]
    print(f"contacts: robot-robot {safety['robot_robot_contacts']}, robot-wall "
          f"{safety['robot_wall_contacts']}; deadlocks {summary['deadlocks']['count']}")
    return {"summary": summary, "rides": rides, "by_floors": done, "layout": layout}


if __name__ == "__main__":
    main()
