"""Tutorial 1: build the hospital diagram by hand, run it, and look at its ports.

``mrta_drake.stack.simulate(scenario)`` builds the whole simulation and runs it. Underneath, it is
one plain Drake diagram, and this tutorial builds it by hand so that you can add systems of
your own:

1. ``load_scenario`` reads the scenario YAML into a frozen ``Scenario`` dataclass and checks
   it (a bad field is one clear ``InputError`` line naming file, field and value).
2. ``add_stack(builder, scenario)`` adds the world (a ``MultibodyPlant`` + ``SceneGraph``
   holding the hospital, robots and people) and every block of the scenario to your
   ``DiagramBuilder`` as named subsystems (``allocator``, ``waypoints``,
   ``room_queues``, ``planner``, ``controller``, ``robots``, ``humans``, ``recorder``) and
   connects them. It returns a ``Stack``: handles to each block.
3. Before ``builder.Build()`` you may add and connect anything. Here: ``SpeedMonitor``, a
   ``LeafSystem`` that reads the robots' ``state`` port ([x, y, theta, v] per robot) and
   keeps each robot's top speed in its discrete state. Like every block of mrta-drake it
   changes state only in an update event (never in a publish event), so runs stay
   deterministic, takes its rate (``rate_hz``) from the scenario's ``rates:`` section, and
   lists its ports in its docstring's ``.. pydrake_system::`` block.
4. Drake's ``Simulator`` runs the built diagram. Afterwards you can evaluate any output port
   in the final context (here the allocator's ``plan`` and the controller's ``telemetry``)
   and read what the ``recorder`` block sampled (``stack.recorder.arrays()``).

The tables printed: every block with its input and output ports, what feeds the controller,
the top speeds our monitor saw against the recorder's samples, and each robot's plan at the
end. ``docs/architecture.md`` lists every block's ports and payloads.

Run (headless by default; ``--meshcat`` to watch in the browser at real time; ``--out DIR``
also writes the recorder's timeline.csv and events.jsonl and the diagram as diagram.dot)::

    python tutorials/01_build_the_diagram.py [--duration 20] [--meshcat] [--out DIR]
"""

import os
import pathlib
import re

import numpy as np
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder, LeafSystem
from tutorial_common import open_meshcat, options

from mrta_drake import add_stack, load_scenario
from mrta_drake.payloads import ROBOT_STATE_SIZE
from mrta_drake.results.report import text_table

SCENARIO = pathlib.Path(__file__).resolve().parent.parent / "scenarios/hospital_6_robots.yaml"


class SpeedMonitor(LeafSystem):
    """Each robot's top speed so far (m/s).

    .. pydrake_system::

        name: SpeedMonitor
        input_ports:
        - robot_state
        output_ports:
        - top_speed

    Input ``robot_state`` (4N): [x, y, theta, v] per robot in ``robot_names`` order. Output
    ``top_speed`` (N): the largest |v| seen at its periodic update (``rate_hz``), kept in
    discrete state.
    """

    def __init__(self, robot_names, *, rate_hz: float):
        super().__init__()
        self._n = len(robot_names)
        self.DeclareVectorInputPort("robot_state", ROBOT_STATE_SIZE * self._n)
        top = self.DeclareDiscreteState(self._n)
        self.DeclareStateOutputPort("top_speed", top)
        self.DeclarePeriodicDiscreteUpdateEvent(1.0 / rate_hz, 0.0, self._update)

    def _update(self, context, discrete_state):
        states = self.get_input_port().Eval(context).reshape(self._n, ROBOT_STATE_SIZE)
        top = context.get_discrete_state_vector().value()
        discrete_state.set_value(np.maximum(top, np.abs(states[:, 3])))


def _port_names(ports) -> str:
    """Port names, those named after each robot (``progress_robot1``...) as one entry."""
    names = [port.get_name() for port in ports]
    per_robot = re.compile(r"^(\w+?)_robot\d+$")
    shown = dict.fromkeys(per_robot.sub(r"\1_<robot>", name) for name in names)
    return ", ".join(shown) or "-"


def main(argv=None) -> dict:
    args = options(__doc__, duration=20.0).parse_args(argv)
    scenario = load_scenario(SCENARIO)
    meshcat = open_meshcat(args.meshcat)
    builder = DiagramBuilder()
    stack = add_stack(builder, scenario, meshcat=meshcat, out_dir=args.out)
    names = [robot.name for robot in scenario.robots]
    monitor = builder.AddNamedSystem("speed_monitor",
                                     SpeedMonitor(names, rate_hz=scenario.rates.robots))
    builder.Connect(stack.robots.GetOutputPort("state"), monitor.get_input_port())
    diagram = builder.Build()

    print("Blocks and their ports, inputs -> outputs (one port per robot written <robot>):")
    for system in diagram.GetSystems():
        inputs = _port_names(system.get_input_port(i) for i in range(system.num_input_ports()))
        outputs = _port_names(system.get_output_port(i)
                              for i in range(system.num_output_ports()))
        print(f"  {system.get_name():<17} {inputs} -> {outputs}")
    print("\nWhat feeds the controller (diagram.connection_map()):")
    feeds = [[f"controller.{into.get_input_port(i).get_name()}",
              f"{source.get_name()}.{source.get_output_port(o).get_name()}"]
             for (into, i), (source, o) in diagram.connection_map().items()
             if into is stack.controller]
    print(text_table(["input", "from"], sorted(feeds)))

    simulator = Simulator(diagram)
    simulator.set_target_realtime_rate(1.0 if meshcat else 0.0)
    simulator.AdvanceTo(args.duration)
    context = simulator.get_context()
    diagram.ForcedPublish(context)  # the recorder's last sample
    stack.recorder.close()
    if args.out:
        with open(os.path.join(args.out, "diagram.dot"), "w") as f:
            f.write(diagram.GetGraphvizString(max_depth=1))

    top_speed = monitor.GetOutputPort("top_speed").Eval(monitor.GetMyContextFromRoot(context))
    times, states, _ = stack.recorder.arrays()
    recorded = np.abs(states[..., 3]).max(axis=0)
    print(f"\nTop speeds over {args.duration:g} s (m/s): our monitor at 20 Hz, the recorder's "
          f"{len(times)} samples at {scenario.rates.logging:g} Hz:")
    print(text_table(["robot", "monitor", "recorder"],
                     [[n, f"{a:.3f}", f"{b:.3f}"] for n, a, b in
                      zip(names, top_speed, recorded, strict=True)]))

    plan = stack.allocator.GetOutputPort("plan").Eval(
        stack.allocator.GetMyContextFromRoot(context))
    telemetry = stack.controller.GetOutputPort("telemetry").Eval(
        stack.controller.GetMyContextFromRoot(context))
    print(f"\nThe allocator's plan at {args.duration:g} s (revision {plan.revision}): stop "
          "(predicted completion, s)")
    print(text_table(["robot", "stops"], [
        [p.robot, ", ".join(f"{s.key} ({s.planned_time:.0f})" for s in p.stops) or "-"]
        for p in plan.plans]))
    clusters = [[names[i] for i in c] for c in telemetry.clusters if len(c) > 1]
    print(f"Controller clusters at {telemetry.time:.2f} s (leader first): {clusters or 'none'}")
    return {"systems": [s.get_name() for s in diagram.GetSystems()], "feeds": dict(feeds),
            "top_speed": np.array(top_speed), "recorded_top_speed": recorded, "plan": plan,
            "times": times}


if __name__ == "__main__":
    main()
