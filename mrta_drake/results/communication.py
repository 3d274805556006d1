"""The network's figures of a run (``summary.json``'s ``communication``)."""

import numpy as np


def communication_metrics(recorder, sample_period: float) -> dict | None:
    """From a recorder that sampled a network every ``sample_period`` s: the age of
    information (s; ``mean``, ``p95``, ``max`` over every sample of every robot's state of
    each other robot), ``leader_disagreement_time`` (s with some robots seeing a cluster
    differently) and ``stale_command_time`` (robot-s that followers braked for want of a
    fresh command), the last two from the controller telemetry at the samples. None
    without a network."""
    if not recorder.information_ages:
        return None
    ages = recorder.information_ages.array().ravel()
    telemetry = recorder.telemetry
    return {
        "age_of_information": {"mean": float(ages.mean()),
                               "p95": float(np.percentile(ages, 95)),
                               "max": float(ages.max())},
        "leader_disagreement_time": sample_period * float(
            telemetry.column("leader_disagreement").sum()),
        "stale_command_time": sample_period * float(telemetry.column("stale_commands").sum()),
    }
