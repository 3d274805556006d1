"""Writes the scenario field reference (docs/scenario_reference.md) from the schema itself,
so the documentation cannot drift from the code: ``python -m mrta_drake.scenario.field_reference``.
A test checks the committed file is what this prints."""

import dataclasses
import inspect
import math
import re
import sys
import typing

from mrta_drake.scenario import schema, section_files
from mrta_drake.scenario.typed_yaml import yaml_key
from mrta_drake.stack.blocks import block_kinds, block_type
from mrta_drake.world import floor_plan_format, ros_map

SECTIONS = [
    (schema.Scenario, ""),
    (schema.WorldConfig, "world."),
    (schema.RobotConfig, "robots[]."),
    (schema.LocationConfig, "locations[]."),
    (schema.RoadwaysConfig, "roadways."),
    (schema.TasksConfig, "tasks."),
    (schema.TaskBatch, "tasks.stream[]."),
    (schema.TaskConfig, "tasks.stream[].tasks[]."),
    (schema.TaskGenerationConfig, "tasks.generate."),
    (schema.HumansConfig, "humans."),
    (schema.HumanConfig, "humans.walkers[]."),
    (schema.HumanGroupConfig, "humans.groups[]."),
    (schema.BlocksConfig, "blocks."),
    (schema.BlockConfig, "blocks.<slot>."),
    (schema.RatesConfig, "rates."),
    (schema.DisturbancesConfig, "disturbances."),
    (schema.BlockageConfig, "disturbances.blockages[]."),
    (schema.BreakdownConfig, "disturbances.breakdowns[]."),
    (schema.OutageConfig, "disturbances.outages[]."),
    (schema.CommunicationConfig, "communication."),
]

FILES = [  # files a scenario names, with their own formats
    (floor_plan_format.FloorPlanFile, ""),
    (floor_plan_format.WallSpec, "walls[]."),
    (floor_plan_format.DoorSpec, "walls[].doors[]."),
    (floor_plan_format.FurnitureSpec, "furniture[]."),
    (floor_plan_format.BoxSpec, "furniture[].box."),
    (floor_plan_format.CylinderSpec, "furniture[].cylinder."),
    (floor_plan_format.ArcSpec, "furniture[].arc."),
    (ros_map.RosMapFile, ""),
    (section_files.RobotSetupFile, ""),
    (section_files.MrtaSimRobotSetupFile, ""),
    (section_files.MrtaSimAgent, "agents.<name>."),
    (section_files.TaskStreamFile, ""),
    (section_files.MrtaSimTaskFile, ""),
    (section_files.MrtaSimBatch, "tasks_stream[]."),
    (section_files.MrtaSimTask, "tasks_stream[].tasks[]."),
]


def _type_name(tp) -> str:
    text = getattr(tp, "__name__", None) if not typing.get_args(tp) else None
    text = text or re.sub(r"\b[\w.]+\.(\w+)", r"\1", str(tp))
    return text.replace("|", "\\|")  # inside a markdown table


def _default(f: dataclasses.Field):
    if f.default is not dataclasses.MISSING:
        value = f.default
    elif f.default_factory is not dataclasses.MISSING:
        value = f.default_factory()
    else:
        return "required"
    if isinstance(value, schema.BlockConfig):
        return f"kind `{value.kind}`"
    if dataclasses.is_dataclass(value):
        return "section"
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    return f"`{value!r}`" if isinstance(value, str) else f"`{value}`"


def _rows(cls, prefix: str) -> list[str]:
    hints = typing.get_type_hints(cls)
    rows = []
    for f in dataclasses.fields(cls):
        if dataclasses.is_dataclass(hints[f.name]) and prefix.startswith("blocks"):
            rows += _rows(hints[f.name], f"{prefix}{f.name}.")
            continue
        rows.append(f"| `{prefix}{yaml_key(f)}` | {_type_name(hints[f.name])} | {_default(f)} |")
    return rows


def _section(title: str, cls, prefix: str) -> str:
    doc = inspect.cleandoc(cls.__doc__ or "")
    lines = [f"### {title}", ""]
    if doc and not doc.startswith(cls.__name__ + "("):
        lines += [doc, ""]
    rows = _rows(cls, prefix)
    if rows:
        lines += ["| field | type | default |", "|---|---|---|", *rows, ""]
    else:
        lines += ["No parameters.", ""]
    return "\n".join(lines)


def reference() -> str:
    """The whole reference page, markdown."""
    parts = [
        "# Scenario field reference",
        "",
        "Generated from `mrta_drake/scenario/schema.py` and the blocks' parameter dataclasses "
        "by `python -m mrta_drake.scenario.field_reference > docs/scenario_reference.md`; "
        "do not edit by hand. Units: m, rad, s, Hz. See [scenario.md](scenario.md) for a "
        "guided tour.",
        "",
        "## Sections",
        "",
    ]
    parts += [_section(cls.__name__, cls, prefix) for cls, prefix in SECTIONS]
    parts += ["## Files a scenario names", "",
              "Floor plans (`world.floor_plan`), ROS maps (`world.kind: ros_map`), robot "
              "setups (`robots: <file>`) and task files (`tasks.file`), ours and the original "
              "MRTA-Sim ones; every field without a default is required.", ""]
    parts += [_section(cls.__name__, cls, prefix) for cls, prefix in FILES]
    parts += ["## Block implementations (`blocks.<slot>.kind`, `blocks.<slot>.params`)", ""]
    for slot in ("allocator", "waypoints", "queues", "planner", "controller", "robots",
                 "humans", "watchdog"):
        for kind in block_kinds(slot):
            params = block_type(slot, kind).params
            parts.append(_section(f"`blocks.{slot}`: `{kind}` ({params.__name__})", params,
                                  f"blocks.{slot}.params."))
    return "\n".join(parts).rstrip() + "\n"


if __name__ == "__main__":
    sys.stdout.write(reference())
