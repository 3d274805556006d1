"""Profiles: named sets of switches applied when a scenario is loaded (its ``profile:``).

``mrta_drake`` (the default) is this project's behaviour and sets nothing. ``paper`` sets
every switch by which this project departs from the MRTA-Sim paper and its original stack
back to the paper's value (docs/fidelity.md says what each does and why it is off here).
Each switch is an ordinary scenario field that a user can also set alone; a profile only
fills the fields the scenario leaves unset, so ``profile: paper`` plus one field set in the
scenario (or in ``load_scenario``'s ``overrides``) is the paper but for that field. A
block's parameters are set only when the scenario uses the block kind they belong to.
"""

from collections.abc import Mapping
from dataclasses import dataclass

from mrta_drake.errors import InputError
from mrta_drake.scenario.schema import BlocksConfig


@dataclass(frozen=True)
class Switch:
    """One deviation's switch: scenario field ``field`` (dotted name) takes ``value``. For a
    field under ``blocks.<slot>.params``, ``kind`` is the block kind it belongs to."""

    field: str
    value: object
    kind: str = ""

    @property
    def slot(self) -> str:
        """The block slot of a ``blocks.<slot>.params`` field ('' for other fields)."""
        parts = self.field.split(".")
        return parts[1] if parts[0] == "blocks" else ""


PAPER_SWITCHES = (
    Switch("blocks.controller.params.coordination.followers", "all", "cluster_cbf"),
    Switch("blocks.controller.params.coordination.leader_rule", "largest_priority",
           "cluster_cbf"),
    Switch("blocks.controller.params.nominal.heading_speed_factor", True, "cluster_cbf"),
    Switch("blocks.controller.params.nominal.corner_steering", False, "cluster_cbf"),
    Switch("blocks.controller.params.nominal.pass_offset", 0.0, "cluster_cbf"),
    Switch("blocks.controller.params.nominal.min_speed", 0.0, "cluster_cbf"),
    Switch("blocks.controller.params.coordination.stalled_leader_hands_on", False,
           "cluster_cbf"),
    Switch("blocks.controller.params.nominal.braking_profile", False, "cluster_cbf"),
    Switch("blocks.controller.params.predict_latency", False, "cluster_cbf"),
    Switch("blocks.controller.params.sensing.closest_point_range", 0.0, "cluster_cbf"),
    Switch("blocks.allocator.params.greedy_start", False, "smt"),
    Switch("blocks.allocator.params.append_only", True, "smt"),
    Switch("blocks.allocator.params.learn_travel_times", False, "smt"),
    Switch("blocks.allocator.params.replan_on_delay", False, "smt"),
    Switch("blocks.allocator.params.earliest_drop_offs", False, "smt"),
    Switch("blocks.allocator.params.defer_hopeless", False, "smt"),
    Switch("blocks.planner.params.cost_resting_robots", False, "grid_astar"),
    Switch("blocks.waypoints.params.door_wait", False, "roadway"),
    Switch("blocks.waypoints.params.parking", False, "roadway"),
    Switch("blocks.humans.params.wall_strength", 0.0, "social_force"),
    Switch("blocks.humans.params.yield_to_robots", False, "social_force"),
    Switch("blocks.watchdog.params.enabled", False, "back_off"),
)

PROFILES: dict[str, tuple[Switch, ...]] = {"mrta_drake": (), "paper": PAPER_SWITCHES}


def with_profile(raw: dict, path: str) -> dict:
    """The raw scenario ``raw`` (a mapping read from ``path``) with its ``profile``'s
    switches set where it leaves them unset (a new mapping; ``raw`` is not changed)."""
    name = raw.get("profile", "mrta_drake")
    if name not in PROFILES:
        raise InputError(path, "profile", f"unknown profile {name!r} "
                         f"(one of {', '.join(PROFILES)})")
    result = dict(raw)
    for switch in PROFILES[name]:
        if switch.kind and _kind_of(result, switch.slot) != switch.kind:
            continue
        result = _set_unless_present(result, switch.field.split("."), switch.value)
    return result


def _kind_of(raw: Mapping, slot: str) -> object:
    """The block kind the raw scenario chooses for ``slot`` (the default when unset)."""
    blocks = raw.get("blocks")
    chosen = blocks.get(slot) if isinstance(blocks, Mapping) else None
    if isinstance(chosen, Mapping) and "kind" in chosen:
        return chosen["kind"]
    return getattr(BlocksConfig(), slot).kind


def _set_unless_present(node: Mapping, keys: list[str], value) -> dict:
    """A copy of ``node`` with ``value`` at the path ``keys`` unless something is there
    already (a value that is not a mapping on the way also stops it: the loader reports
    it)."""
    result = dict(node)
    key = keys[0]
    if len(keys) == 1:
        result.setdefault(key, value)
        return result
    child = result.get(key)
    if child is None:
        child = {}
    if isinstance(child, Mapping):
        result[key] = _set_unless_present(child, keys[1:], value)
    return result
