"""The one place a run's scheduled disturbances come from."""

from collections.abc import Sequence

import numpy as np
from pydrake.common.value import Value
from pydrake.systems.framework import BasicVector, LeafSystem

from mrta_drake.payloads import (
    ROBOT_STATE_SIZE,
    Blockage,
    Breakdown,
    Disturbances,
    Outage,
    frozen_array,
)
from mrta_drake.scenario.disturbances import in_force

# Period of the events that fire once at each change time: longer than any run.
_ONCE = 1e9


class DisturbanceSchedule(LeafSystem):
    """Outputs the disturbances in force (``Disturbances``), changing exactly at the start
    and end of each scheduled window (``disturbances.in_force``: from ``start`` on, no
    longer at ``end``).

    .. pydrake_system::

        name: DisturbanceSchedule
        input_ports:
        - robot_state
        output_ports:
        - disturbances

    Input ``robot_state`` (4N): [x, y, theta, v] per robot in ``robot_names`` order, world
    frame, m, rad, m/s; read when an outage starts, to freeze the states the cut-off robot
    and the others last exchanged. Output ``disturbances`` (abstract ``Disturbances``), from
    the state.

    The abstract state is the output payload; one unrestricted update at each distinct
    start or end time (an event at every later time only repeats the same state) recomputes
    it, so between those times the schedule costs nothing. Blocks updated at the same
    instant see the change from their next update on.

    ``blockages``, ``breakdowns``: the scheduled windows (payloads, see
    ``disturbances.blockages``); ``outages``: (robot index, start, end) s.
    """

    def __init__(self, robot_names: Sequence[str], blockages: Sequence[Blockage] = (),
                 breakdowns: Sequence[Breakdown] = (),
                 outages: Sequence[tuple[int, float, float]] = ()):
        super().__init__()
        self._blockages = tuple(blockages)
        self._breakdowns = tuple(breakdowns)
        self._outages = tuple(sorted(outages, key=lambda o: (o[1], o[0])))
        self._robot_state = self.DeclareVectorInputPort(
            "robot_state", BasicVector(ROBOT_STATE_SIZE * len(robot_names)))
        self._state_index = self.DeclareAbstractState(Value[object](Disturbances()))
        self.DeclareStateOutputPort("disturbances", self._state_index)
        windows = [(w.start, w.end) for w in self._blockages + self._breakdowns]
        windows += [(start, end) for _, start, end in self._outages]
        for time in sorted({t for window in windows for t in window if np.isfinite(t)}):
            self.DeclarePeriodicUnrestrictedUpdateEvent(_ONCE, time, self._update)

    def _update(self, context, state) -> None:
        now = context.get_time()
        old = context.get_abstract_state(self._state_index).get_value()
        frozen = {o.robot: o for o in old.outages}
        outages = []
        for robot, start, end in self._outages:
            if not in_force(start, end, now):
                continue
            outage = frozen.get(robot)
            if outage is None or outage.start != start:
                states = self._robot_state.Eval(context).reshape(-1, ROBOT_STATE_SIZE)
                outage = Outage(robot, start, end, frozen_array(states))
            outages.append(outage)
        state.get_mutable_abstract_state(self._state_index).set_value(Disturbances(
            tuple(b for b in self._blockages if in_force(b.start, b.end, now)),
            tuple(b for b in self._breakdowns if in_force(b.start, b.end, now)),
            tuple(outages)))
