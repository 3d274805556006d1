"""The original system's six-robot case with a 6+6 task stream and the hospital's ten people:
with the default allocator (feedback loop on) every task is done on time."""

import pathlib

from mrta_drake import load_scenario, simulate

SCENARIO = pathlib.Path(__file__).resolve().parents[2] / "scenarios" / "hospital_6_plus_6.yaml"


def test_every_task_of_the_6_plus_6_stream_is_on_time():
    scenario = load_scenario(SCENARIO)
    assert [len(batch.tasks) for batch in scenario.tasks.stream] == [6, 6]
    assert len(scenario.humans.walkers) + sum(g.count for g in scenario.humans.groups) == 10
    last_deadline = max(task.deadline for batch in scenario.tasks.stream for task in batch.tasks)
    tasks = simulate(scenario, duration=last_deadline + 1.0, plots=False).summary["tasks"]
    assert (tasks["total"], tasks["completed"], tasks["on_time"]) == (12, 12, 12)
