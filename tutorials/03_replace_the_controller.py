"""Tutorial 3: replace the controller and watch the safety figures change.

The ``controller`` block turns every robot's planned path into ``[v, omega]`` commands at
20 Hz. The default, ``cluster_cbf`` (``ClusterCbfController``, docs/control.md), filters the
path-following command through control barrier functions solved as a QP, keeping robots
clear of walls, people and each other. Swapping it is one line in a scenario file::

    blocks:
      controller: {kind: go_to_goal}

or, in Python, ``replace_block(scenario, "controller", "go_to_goal")``. ``go_to_goal``
(``GoToGoalController``) is the same path following with no safety filter at all.

A controller of your own is a ``LeafSystem`` with the slot's ports: inputs ``robot_state``
(4N: [x, y, theta, v] per robot, world frame), ``paths`` (``FleetPaths``) and, optionally,
``human_states`` (``HumanStates``) and ``disturbances`` (``Disturbances``: robots broken down
or cut off from messages, corridors blocked), outputs ``commands`` (2N: [v, omega], m/s,
rad/s) and ``telemetry`` (``ControllerTelemetry``); ``mrta_drake.control.controller_common``
declares them and runs the update for you. The quickest way is to subclass one controller
and change its ``control`` method, which maps the states to accelerations and turn rates
``[a, omega]`` per robot each tick. ``StopAndGoController`` below is go-to-goal plus the
simplest safety rule there is: brake while anyone is less than a metre ahead.
``register_block`` makes it the ``stop_and_go`` kind of the controller slot, with the
go-to-goal parameters (``GoToGoalParams``: ``blocks.controller.params.nominal`` and so on).

All three drive the six-robot hospital scenario with its people for the same time. The
table compares the runs' figures (``summary.json``): the smallest surface-to-surface
clearances robot-robot, robot-wall and robot-human (m; negative means overlap), the contact
counts (how often bodies started to overlap), how far the robots drove and the deadlocks.
Go-to-goal drives into robots and nearer walls and people (people step out of its way:
they yield to robots, docs/humans.md); stop-and-go keeps off the robots in front of it; the
CBF controller keeps its distances to all of them.

Run (``--meshcat`` shows the runs live, one after the other)::

    python tutorials/03_replace_the_controller.py [--duration 40] [--meshcat] [--out DIR]
"""

import math
import pathlib

import numpy as np
from tutorial_common import options, run_each

from mrta_drake import GoToGoalController, load_scenario, register_block
from mrta_drake.control import GoToGoalParams, slow_down
from mrta_drake.payloads import ROBOT_STATE_SIZE, HumanStates
from mrta_drake.results.report import format_runs
from mrta_drake.stack.blocks import BlockType, replace_block

SCENARIO = pathlib.Path(__file__).resolve().parent.parent / "scenarios/hospital_6_robots.yaml"
STOP_DISTANCE = 1.0  # m, centre to centre
AHEAD = math.radians(60.0)  # half-angle of the cone counted as ahead


class StopAndGoController(GoToGoalController):
    """Go-to-goal path following; a robot brakes (``control.slow_down``) while another robot
    or a person is within ``STOP_DISTANCE`` of it and ``AHEAD`` of its heading."""

    def control(self, time, states, paths, human_states=None, disturbances=None):
        u, telemetry = super().control(time, states, paths, human_states, disturbances)
        states = np.asarray(states, dtype=float).reshape(-1, ROBOT_STATE_SIZE)
        people = (human_states or HumanStates()).positions.reshape(-1, 2)
        bodies = np.vstack([states[:, :2], people])
        for i, (x, y, theta, v) in enumerate(states):
            offsets = bodies - (x, y)
            distance = np.hypot(offsets[:, 0], offsets[:, 1])
            ahead = offsets @ (math.cos(theta), math.sin(theta)) > distance * math.cos(AHEAD)
            ahead[i] = False
            if np.any(ahead & (distance < STOP_DISTANCE)):
                u[i] = slow_down(v, self.params.nominal)
        return u, telemetry


register_block("controller", "stop_and_go", BlockType(GoToGoalParams, lambda ctx, params: (
    StopAndGoController(ctx.robot_names, ctx.obstacles, params,
                        rate_hz=ctx.rates.controller))))

CONTROLLERS = ("cluster_cbf", "go_to_goal", "stop_and_go")


def main(argv=None) -> dict:
    args = options(__doc__, duration=40.0).parse_args(argv)
    scenario = load_scenario(SCENARIO)
    runs = run_each({kind: replace_block(scenario, "controller", kind) for kind in CONTROLLERS},
                    args)
    summaries = {kind: run.summary for kind, run in runs.items()}
    print(format_runs(summaries))
    for kind, summary in summaries.items():
        safety = summary["safety"]
        closest = [f"{pair} {' and '.join(safety[f'min_{pair}_between'])} at "
                   f"{safety[f'min_{pair}_time']:.1f} s"
                   for pair in ("robot_robot", "robot_human") if safety[f"min_{pair}"] is not None]
        print(f"{kind}: closest {'; '.join(closest)}")
    return {"summaries": summaries}


if __name__ == "__main__":
    main()
