"""How well the allocator's predictions held: the ``predictions`` section of ``summary.json``.

From ``timing.task_rows``, ``timing.leg_rows`` and the allocator's events (the ``event``
dicts of the recorder's ``allocation`` events), all times in s:

- ``dropoff_error`` and ``leg_error``: actual minus predicted (a drop-off's completion time,
  a stop's duration), over what has both: ``count``, ``median_abs`` and ``p90_abs`` (of the
  absolute errors), ``bias`` (mean signed error; positive = later than predicted), ``max``.
- ``promised``: tasks planned on time at their last allocation (the last event predicting
  their drop-off); ``broken_promises``: those whose deadline was then missed;
  ``unpromised``: tasks their last allocation predicted late (it could not promise them).
- ``replans``: allocations made between batches because the plan drifted (``ReplanEvent``):
  ``count``, ``reasons`` (count per kind, ``late`` or ``drift``) and ``events`` (``time``
  and ``reason`` of each).
- ``drift``: per completed task with a prediction, ``[actual drop-off, actual - predicted]``,
  in completion order (the plot of drift over time).
"""

from collections import Counter

import numpy as np

REPLAN_EVENT = "ReplanEvent"


def predictions(tasks: list[dict], legs: list[dict], allocations: list[dict]) -> dict:
    """The ``predictions`` section (see the module docstring)."""
    done = [t for t in tasks
            if t["actual_dropoff"] is not None and t["predicted_dropoff"] is not None]
    last_prediction = {}
    for event in allocations:
        for task, time in event.get("predicted", ()):
            last_prediction[task] = (time, task in event.get("late_tasks", ()))
    deadline_met = {t["id"]: t["deadline_met"] for t in tasks}
    promised = sorted(t for t, (_, late) in last_prediction.items() if not late)
    replans = [e for e in allocations if e.get("kind") == REPLAN_EVENT]
    return {
        "dropoff_error": error_stats([t["actual_dropoff"] - t["predicted_dropoff"]
                                      for t in done]),
        "leg_error": error_stats([leg["actual"] - leg["predicted"] for leg in legs
                                  if leg["predicted"] is not None]),
        "promised": len(promised),
        "broken_promises": [t for t in promised if deadline_met.get(t) is False],
        "unpromised": sorted(t for t, (_, late) in last_prediction.items() if late),
        "replans": {
            "count": len(replans),
            "reasons": dict(Counter(e["reason"].split(":")[0] for e in replans)),
            "events": [{"time": e["time"], "reason": e["reason"]} for e in replans],
        },
        "drift": [[t["actual_dropoff"], t["actual_dropoff"] - t["predicted_dropoff"]]
                  for t in sorted(done, key=lambda t: t["actual_dropoff"])],
    }


def error_stats(errors: list[float]) -> dict:
    """``count``, ``median_abs``, ``p90_abs``, ``bias`` and ``max`` of ``errors`` (s; None
    without any)."""
    if not errors:
        return {"count": 0, "median_abs": None, "p90_abs": None, "bias": None, "max": None}
    values = np.asarray(errors, dtype=float)
    return {
        "count": len(errors),
        "median_abs": float(np.median(np.abs(values))),
        "p90_abs": float(np.quantile(np.abs(values), 0.9)),
        "bias": float(np.mean(values)),
        "max": float(np.max(values)),
    }
