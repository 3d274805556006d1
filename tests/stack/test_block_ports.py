"""Every block documents its ports in Drake's ``.. pydrake_system::`` block in its class
docstring; the documented input and output names must be exactly the declared ones.

Checked for every registered kind of every block slot and for the blocks ``add_stack`` adds
itself, each built by ``add_stack`` for the hospital with disturbances (people, a blockage,
a breakdown and an outage; the lift bank for the two-floor clinic, the one with lifts; the
network with a lossy ``communication:``): a kind is swapped in with ``replace_block``; the
overlay needs a Meshcat, the contact recorder and the people's body driver the physics
robots. A per-robot port is documented with the placeholder ``<robot>``
(``progress_<robot>``), which stands for one port per robot name.
"""

import dataclasses
import inspect
import pathlib
import re
import textwrap

import pytest
import yaml
from pydrake.geometry import Meshcat
from pydrake.systems.framework import DiagramBuilder

from mrta_drake.scenario.loading import load_scenario
from mrta_drake.scenario.schema import BlocksConfig, CommunicationConfig
from mrta_drake.stack.blocks import NETWORK, block_kinds, replace_block
from mrta_drake.stack.diagram import add_stack

ROOT = pathlib.Path(__file__).resolve().parents[2]
SCENARIO = ROOT / "scenarios/hospital_disturbances.yaml"
LIFTS_SCENARIO = ROOT / "scenarios/two_floor_6_robots.yaml"
ROBOT = "<robot>"
OPTIONAL = " (optional)"
# The name in the diagram of the (first) system of each block slot.
SYSTEM_OF_SLOT = {"allocator": "allocator", "waypoints": "waypoints",
                  "queues": "room_queues", "planner": "planner", "controller": "controller",
                  "robots": "robots", "humans": "humans", "lifts": "lift_bank",
                  "watchdog": "watchdog"}
# A kind that is one system per robot: the name of the first robot's.
SYSTEM_OF_KIND = {("waypoints", "roadway_per_robot"): "waypoints_robot1"}
# The blocks add_stack adds itself: (name in the diagram, the robots kind it needs).
STACK_BLOCKS = [("recorder", None), ("meshcat_overlay", None), ("disturbances", None),
                ("contacts", "physics"), ("human_bodies", "physics")]
LOSSY = CommunicationConfig(latency=0.2, loss=0.1)  # not ideal: add_stack adds the network


def _cases():
    defaults = BlocksConfig()
    cases = [pytest.param(name, "robots", robots_kind, id=name)
             for name, robots_kind in STACK_BLOCKS]
    for slot in (f.name for f in dataclasses.fields(BlocksConfig)):
        for kind in block_kinds(slot):
            swapped = None if kind == getattr(defaults, slot).kind else kind
            system = SYSTEM_OF_KIND.get((slot, kind), SYSTEM_OF_SLOT[slot])
            cases.append(pytest.param(system, slot, swapped,
                                      id=f"{slot}-{kind}"))
    cases += [pytest.param(NETWORK, NETWORK, kind, id=f"{NETWORK}-{kind}")
              for kind in block_kinds(NETWORK)]
    return cases


@pytest.fixture(scope="module")
def built():
    """``built(slot, kind)``: the systems (by name) and robot names of the scenario's
    diagram with ``kind`` in ``slot`` (None: the scenario's own), built once each."""
    scenario = load_scenario(SCENARIO)
    diagrams = {}

    def build(slot: str, kind: str | None):
        key = (slot, kind) if kind is not None or slot == "lifts" else None
        if key not in diagrams:
            base = load_scenario(LIFTS_SCENARIO) if slot == "lifts" else scenario
            if slot == NETWORK:
                swapped = dataclasses.replace(base, communication=dataclasses.replace(
                    LOSSY, kind=kind))
            else:
                swapped = replace_block(base, slot, kind) if kind else base
            builder = DiagramBuilder()
            add_stack(builder, swapped, meshcat=Meshcat() if kind is None else None)
            diagram = builder.Build()
            diagrams[key] = ({s.get_name(): s for s in diagram.GetSystems()},
                             [r.name for r in swapped.robots])
        return diagrams[key]

    return build


def documented_ports(cls) -> tuple[list[str], list[str]]:
    """The input and output port names of ``cls``'s ``.. pydrake_system::`` block, without
    `` (optional)``; a missing block, a wrong ``name`` or a bad entry fails the test."""
    doc = inspect.getdoc(cls) or ""
    found = re.search(r"^\.\. pydrake_system::\n\n((?: {4}.*\n?)+)", doc, re.MULTILINE)
    assert found, f"{cls.__name__}'s docstring has no `.. pydrake_system::` block"
    block = yaml.safe_load(textwrap.dedent(found.group(1)))
    assert block["name"] == cls.__name__
    assert set(block) <= {"name", "input_ports", "output_ports"}, sorted(block)
    ports = []
    for key in ("input_ports", "output_ports"):
        entries = block.get(key) or []
        assert all(isinstance(entry, str) for entry in entries), entries
        ports.append([entry.removesuffix(OPTIONAL) for entry in entries])
    return ports[0], ports[1]


def expanded(names: list[str], robots: list[str]) -> list[str]:
    """``names`` with each one holding ``<robot>`` replaced by one name per robot."""
    return [name.replace(ROBOT, robot) for name in names
            for robot in (robots if ROBOT in name else [ROBOT])]


def declared_ports(system) -> tuple[list[str], list[str]]:
    return ([system.get_input_port(i).get_name() for i in range(system.num_input_ports())],
            [system.get_output_port(i).get_name() for i in range(system.num_output_ports())])


@pytest.mark.parametrize(("name", "slot", "kind"), _cases())
def test_documented_ports_are_the_declared_ones(built, name, slot, kind):
    systems, robots = built(slot, kind)
    system = systems[name]
    inputs, outputs = documented_ports(type(system))
    declared_inputs, declared_outputs = declared_ports(system)
    assert sorted(expanded(inputs, robots)) == sorted(declared_inputs)
    assert sorted(expanded(outputs, robots)) == sorted(declared_outputs)


def test_placeholders_expand_to_one_port_per_robot():
    assert expanded(["plan", "progress_<robot>"], ["a", "b"]) == ["plan", "progress_a",
                                                                   "progress_b"]


def test_a_docstring_without_the_block_or_with_another_name_fails():
    class Undocumented:
        """Ports: ``plan``."""

    class Misnamed:
        """.. pydrake_system::

            name: Other
            output_ports:
            - plan
        """

    for cls in (Undocumented, Misnamed):
        with pytest.raises(AssertionError):
            documented_ports(cls)
