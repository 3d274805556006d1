"""Real-time factor of the two robot backends, and the physics backend's time step and shape.

- ``backends``: the whole stack (``simulate``) on the same scenarios with the kinematic
  unicycle robots and the physics robots (defaults), 2 and 6 robots, 30 s: the fixed-route
  hospital (no people) and the task-stream hospital (10 people, whose bodies are in the
  physics backend's plant too).
- ``time_steps``: the physics backend at plant steps of 5, 10 and 20 ms: the whole stack
  (fixed routes, 6 robots, 30 s); the plant alone (the hospital, 6 robots driving circles
  into the walls under constant commands, 30 s, with its contacts); and the deepest
  penetration of a robot driving head-on into a wall at 1.0 and 1.5 m/s, the worst over
  ``PHASES`` start offsets spread over one step's travel (the first contact is found only
  once the bodies overlap, so it depends on where the last step before it ended).
- ``shapes``: sphere against cylinder collision shapes: the plant alone and the stack.

Real-time factor = simulated time / time spent simulating (``simulate``'s ``cpu_time`` and
``wall_time``; building the diagram and imports excluded). The tables show it for CPU time
(``time.process_time``: the machine is shared), the JSON also for wall-clock time; each
figure is the best of ``--repeats`` runs.

Run from the repository root with the package importable (``pip install -e .``):
``python benchmarks/physics_backend.py [--repeats N] [--duration S]``; prints tables and
writes ``benchmarks/results/physics_backend.json``.
"""

import argparse
import dataclasses
import json
import os
import pathlib
import platform
import time

import numpy as np
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

from mrta_drake import load_scenario, simulate
from mrta_drake.robots.physics_robots import PhysicsRobotParams, PhysicsRobots
from mrta_drake.robots.plant_stepping import add_plant_stepping
from mrta_drake.stack.blocks import replace_block
from mrta_drake.world.floor_plan import FloorPlan
from mrta_drake.world.obstacles import Box, Obstacles
from mrta_drake.world.plant import Body, PlantPhysics, build_world, load_floor_plan_of

ROOT = pathlib.Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks/results/physics_backend.json"
SCENARIOS = {"routes": ROOT / "scenarios/hospital_routes_6_robots.yaml",
             "tasks+people": ROOT / "scenarios/hospital_6_robots.yaml"}
TIME_STEPS = (5e-3, 1e-2, 2e-2)
SHAPES = ("sphere", "cylinder")
CRASH_SPEEDS = (1.0, 1.5)  # m/s
PHASES = 8


def _scenario(name: str, robots: int, kind: str, **params):
    scenario = load_scenario(SCENARIOS[name])
    scenario = dataclasses.replace(scenario, robots=scenario.robots[:robots])
    return replace_block(scenario, "robots", kind, **params) if kind != "kinematic" else scenario


def stack(name: str, robots: int, kind: str, duration: float, repeats: int, **params) -> dict:
    """The whole stack's real-time factors (best of ``repeats``) and what the run did."""
    scenario = _scenario(name, robots, kind, **params)
    runs = [simulate(scenario, duration=duration, plots=False).summary for _ in range(repeats)]
    contacts = runs[0]["physics_contacts"]
    return {
        "rtf_cpu": max(duration / r["cpu_time"] for r in runs),
        "rtf_wall": max(duration / r["wall_time"] for r in runs),
        "stops": sum(r["stops_completed"] for r in runs[0]["robots"].values()),
        "contacts": contacts["count"] if contacts else None,
        "max_penetration": contacts["max_penetration"] if contacts else None,
    }


def _robot_world(floor_plan, poses, params: PhysicsRobotParams, commands):
    """A diagram of the physics robots alone under constant ``commands`` (N, 2)."""
    builder = DiagramBuilder()
    world = build_world(builder, floor_plan,
                        robots=[Body(f"robot{k + 1}", 0.22, tuple(p)) for k, p in
                                enumerate(poses)],
                        physics=PlantPhysics(params.time_step, params.mass,
                                             params.collision_shape))
    robots = builder.AddNamedSystem("robots", PhysicsRobots(world.plant, world.robots, params))
    source = builder.AddSystem(ConstantVectorSource(np.ravel(commands)))
    builder.Connect(source.get_output_port(), robots.GetInputPort("commands"))
    contacts = add_plant_stepping(builder, world, robots)
    return builder.Build(), robots, contacts


def plant_alone(params: PhysicsRobotParams, duration: float, repeats: int) -> dict:
    """The hospital plant with the 6 robots driving circles (0.8 m/s, 0.4 rad/s)."""
    scenario = load_scenario(SCENARIOS["routes"])
    floor_plan = load_floor_plan_of(scenario)
    poses = [(list(r.start) + [0.0])[:3] for r in scenario.robots]
    best_cpu = best_wall = 0.0
    for _ in range(repeats):
        diagram, _, contacts = _robot_world(floor_plan, poses, params,
                                            [[0.8, 0.4]] * len(poses))
        simulator = Simulator(diagram)
        simulator.Initialize()
        cpu, wall = time.process_time(), time.perf_counter()
        simulator.AdvanceTo(duration)
        best_cpu = max(best_cpu, duration / (time.process_time() - cpu))
        best_wall = max(best_wall, duration / (time.perf_counter() - wall))
    summary = contacts.summary()
    return {"rtf_cpu": best_cpu, "rtf_wall": best_wall, "contacts": summary["count"],
            "max_penetration": summary["max_penetration"]}


def crash_penetration(time_step: float, speed: float) -> float:
    """Deepest penetration (m) of a robot (radius 0.22 m) driven head-on into a wall at
    ``speed``, the worst over ``PHASES`` start offsets within one step's travel."""
    wall = Obstacles((Box("wall", (2.0, 0.0), (0.2, 4.0), height=2.5),))
    floor_plan = FloorPlan("wall", (-3.0, 3.0, -3.0, 3.0), 2.5, wall)
    params = PhysicsRobotParams(time_step=time_step, max_traction_force=20.0)
    worst = 0.0
    for offset in np.linspace(0.0, speed * time_step, PHASES, endpoint=False):
        diagram, _, contacts = _robot_world(floor_plan, [(offset, 0.0, 0.0)], params,
                                            [[speed, 0.0]])
        Simulator(diagram).AdvanceTo(2.0)
        worst = max(worst, contacts.summary()["max_penetration"])
    return worst


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--duration", type=float, default=30.0)
    args = parser.parse_args()
    duration, repeats = args.duration, args.repeats
    default = PhysicsRobotParams()

    backends = []
    for name in SCENARIOS:
        for robots in (2, 6):
            for kind in ("kinematic", "physics"):
                row = {"scenario": name, "robots": robots, "backend": kind}
                backends.append(row | stack(name, robots, kind, duration, repeats))
    time_steps = []
    for time_step in TIME_STEPS:
        params = dataclasses.replace(default, time_step=time_step)
        time_steps.append({
            "time_step": time_step,
            "stack": stack("routes", 6, "physics", duration, repeats, time_step=time_step),
            "plant": plant_alone(params, duration, repeats),
            "crash_penetration": {str(v): crash_penetration(time_step, v)
                                  for v in CRASH_SPEEDS},
        })
    shapes = []
    for shape in SHAPES:
        params = dataclasses.replace(default, collision_shape=shape)
        shapes.append({"shape": shape,
                       "stack": stack("routes", 6, "physics", duration, repeats,
                                      collision_shape=shape),
                       "plant": plant_alone(params, duration, repeats)})

    print(f"Whole stack, {duration:g} s simulated, real-time factor (CPU)")
    print(f"{'scenario':<14}{'robots':>7}{'kinematic':>11}{'physics':>9}{'ratio':>7}"
          f"{'contacts':>10}")
    for k in range(0, len(backends), 2):
        kin, phy = backends[k], backends[k + 1]
        print(f"{kin['scenario']:<14}{kin['robots']:>7}{kin['rtf_cpu']:>11.1f}"
              f"{phy['rtf_cpu']:>9.1f}{phy['rtf_cpu'] / kin['rtf_cpu']:>7.2f}"
              f"{phy['contacts']:>10}")
    print("\nPhysics time step: real-time factor (CPU) and penetration")
    print(f"{'step (s)':<10}{'stack':>7}{'plant':>8}{'plant pen (mm)':>16}"
          + "".join(f"{f'crash {v} m/s (mm)':>20}" for v in CRASH_SPEEDS))
    for row in time_steps:
        print(f"{row['time_step']:<10g}{row['stack']['rtf_cpu']:>7.1f}"
              f"{row['plant']['rtf_cpu']:>8.0f}{1e3 * row['plant']['max_penetration']:>16.1f}"
              + "".join(f"{1e3 * row['crash_penetration'][str(v)]:>20.1f}"
                        for v in CRASH_SPEEDS))
    print(f"\nCollision shape at {default.time_step:g} s: real-time factor (CPU)")
    print(f"{'shape':<10}{'stack':>7}{'plant':>8}")
    for row in shapes:
        print(f"{row['shape']:<10}{row['stack']['rtf_cpu']:>7.1f}{row['plant']['rtf_cpu']:>8.0f}")

    os.makedirs(RESULTS.parent, exist_ok=True)
    with open(RESULTS, "w") as f:
        json.dump({"machine": platform.platform(), "processor": platform.processor(),
                   "duration": duration, "repeats": repeats,
                   "defaults": dataclasses.asdict(default), "backends": backends,
                   "time_steps": time_steps, "shapes": shapes}, f, indent=2)
    print(f"\nwrote {RESULTS.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
