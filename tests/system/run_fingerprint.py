"""The fingerprint of a run: sha256 over the recorded times, robot states, people's positions
and events (less the wall-clock ``solve_time``) of SCENARIO run for DURATION s, with the
scenario fields OVERRIDES (a JSON mapping of dotted names to values, ``load_scenario``'s
``overrides``) set.

Run as a script, in a fresh process, as a user's ``mrta-sim run`` is:
``python run_fingerprint.py SCENARIO DURATION [OVERRIDES]``."""

import hashlib
import json
import sys

WALL_CLOCK_FIELDS = {"solve_time"}


def _without_wall_clock(value):
    if isinstance(value, dict):
        return {k: _without_wall_clock(v) for k, v in value.items() if k not in WALL_CLOCK_FIELDS}
    if isinstance(value, list | tuple):
        return [_without_wall_clock(v) for v in value]
    return value


def fingerprint(path: str, duration: float, overrides: dict | None = None) -> str:
    from mrta_drake import load_scenario, simulate

    result = simulate(load_scenario(path, overrides=overrides), duration=duration, plots=False)
    digest = hashlib.sha256()
    for array in (result.times, result.robot_states, result.human_positions):
        digest.update(array.tobytes())
    events = _without_wall_clock(result.events)
    digest.update(json.dumps(events, sort_keys=True, default=repr).encode())
    return digest.hexdigest()


if __name__ == "__main__":
    print(fingerprint(sys.argv[1], float(sys.argv[2]),
                      json.loads(sys.argv[3]) if len(sys.argv) > 3 else None))
