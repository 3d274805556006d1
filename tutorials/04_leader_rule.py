"""Tutorial 4: change who leads a cluster of robots.

The ``cluster_cbf`` controller groups robots within ``coordination.cluster_radius`` (4 m) of
each other, transitively, into clusters (``mrta_drake/control/clusters.py``). In each cluster
one robot leads: it keeps its path-following command, the others in its way get a slow-down
command (``mrta_drake/control/followers.py``), and one QP over all members' inputs keeps
everyone safe. So the leader is the robot that goes first.
Which one leads is a *leader rule*: a function of the members' ``priorities`` (smaller leads;
the robots' ``priority:`` fields, by default their order in the scenario) and their
``distances_to_goal`` (m, straight line to the end of their path) that returns one sort key
per robot, smallest leads. (Robots with nowhere to go, and leaders that stood still for
``coordination.stall_time``, come after the others whatever the rule.)

The rule is a controller parameter, by name::

    blocks:
      controller: {kind: cluster_cbf, params: {coordination: {leader_rule: distance_to_goal}}}

Built in: ``priority`` (default) and ``distance_to_goal`` (the robot nearest its goal leads:
it clears the way soonest). Your own is a plain function registered under a name with
``register_leader_rule`` (in this process; a sweep's worker processes would not know it).
Here, ``nearly_there_first``: robots within ``NEARLY_THERE`` m of their goal lead, the
others by priority.

The scenario is the hospital with fixed routes (``allocator: fixed``, no people), so that
only the controller differs between the runs. The tables show, per rule, how often each
robot led a cluster of two or more, how often the lead changed hands, and the results; then
the first moment each rule chose another leader than ``priority`` did for the same cluster.
Until then the runs are identical, bit for bit.

Run (``--meshcat`` shows the runs live, one after the other)::

    python tutorials/04_leader_rule.py [--duration 40] [--meshcat] [--out DIR]
"""

import pathlib

import numpy as np
from tutorial_common import options, run_each

from mrta_drake import load_scenario
from mrta_drake.control import register_leader_rule
from mrta_drake.results.report import format_runs, text_table
from mrta_drake.stack.blocks import replace_block

SCENARIO = (pathlib.Path(__file__).resolve().parent.parent
            / "scenarios/hospital_routes_6_robots.yaml")
NEARLY_THERE = 3.0  # m
RULES = ("priority", "distance_to_goal", "nearly_there_first")


def nearly_there_first(priorities: np.ndarray, distances_to_goal: np.ndarray) -> np.ndarray:
    """Robots within ``NEARLY_THERE`` m of their goal lead; within each of the two groups
    (near, not near) the smaller priority leads."""
    return np.where(distances_to_goal < NEARLY_THERE, priorities - 1e6, priorities)


register_leader_rule("nearly_there_first", nearly_there_first)


def leaders(telemetry) -> list[dict]:
    """Per recorder sample: each cluster of two or more robots (as a frozenset of robot
    indices) -> its leader's index."""
    return [{frozenset(c): c[0] for c in t.clusters if len(c) > 1} for t in telemetry]


def first_difference(a: list[dict], b: list[dict]):
    """The first sample index at which one cluster (same members) has different leaders in
    ``a`` and ``b``, with that cluster; None if there is none."""
    for k, (here, there) in enumerate(zip(a, b, strict=False)):
        for members, leader in here.items():
            if there.get(members, leader) != leader:
                return k, members
    return None


def main(argv=None) -> dict:
    args = options(__doc__, duration=40.0).parse_args(argv)
    scenario = load_scenario(SCENARIO)
    names = [robot.name for robot in scenario.robots]
    runs = run_each({rule: replace_block(scenario, "controller", "cluster_cbf",
                                         coordination={"leader_rule": rule})
                     for rule in RULES}, args)
    led = {rule: leaders(run.stack.recorder.telemetry) for rule, run in runs.items()}

    print(f"\nSamples (of {len(runs['priority'].times)}, at 10 Hz) in which each robot led a "
          "cluster of two or more:")
    print(text_table(["robot", *RULES], [
        [name, *(sum(i in sample.values() for sample in led[rule]) for rule in RULES)]
        for i, name in enumerate(names)]))
    handovers = {rule: sum(before.get(members) not in (None, leader)
                           for before, now in zip(led[rule], led[rule][1:], strict=False)
                           for members, leader in now.items()) for rule in RULES}
    print("Lead handed over:", ", ".join(f"{rule} {n} times" for rule, n in handovers.items()))
    print(format_runs({rule: run.summary for rule, run in runs.items()}))

    reference = runs["priority"]
    divergence = {}
    for rule in RULES[1:]:
        found = first_difference(led["priority"], led[rule])
        if found is None:
            print(f"{rule}: the same leaders as priority throughout")
            continue
        k, members = found
        same = np.array_equal(reference.robot_states[:k], runs[rule].robot_states[:k])
        divergence[rule] = (float(reference.times[k]), members, same)
        first, then = (names[led[r][k][members]] for r in ("priority", rule))
        print(f"{rule}: first differs at {reference.times[k]:.1f} s, cluster "
              f"{sorted(names[i] for i in members)}: priority lets {first} lead, {rule} "
              f"{then}; the runs were {'identical' if same else 'already different'} until "
              "then")
    return {"runs": runs, "leaders": led, "divergence": divergence}


if __name__ == "__main__":
    main()
