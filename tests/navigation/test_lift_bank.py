"""The lift bank: first come first served, one rider per cabin, rides as long as the
elevations say, the rider moved once to the other level, the cabin freed once it has left."""

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator

from mrta_drake.errors import InputError
from mrta_drake.navigation.lift_bank import LiftBank, LiftParams, LiftSpec, LiftStop, ride_time
from mrta_drake.payloads import LiftRequest

LIFT = LiftSpec("lift", (LiftStop("L1", (10.0, 0.0), 0.0, "L1/cabin"),
                         LiftStop("L2", (60.0, 0.0), 8.0, "L2/cabin")), "L1")
NAMES = ("a", "b", "c")
PARAMS = LiftParams(door_time=2.0)


class Bench:
    """A lift bank alone, its inputs set by hand, stepped at 10 Hz."""

    def __init__(self, params=PARAMS, lift=LIFT):
        self.bank = LiftBank(NAMES, [lift], params, rate_hz=10.0)
        self.simulator = Simulator(self.bank)
        self.context = self.simulator.get_mutable_context()
        self.states = np.array([[0.0, 0.0, 0.5, 0.0], [1.0, 5.0, 0.0, 0.0],
                                [2.0, 5.0, 0.0, 0.0]])
        self.requests = {name: LiftRequest(name) for name in NAMES}
        self._apply()

    def _apply(self):
        self.bank.GetInputPort("robot_state").FixValue(self.context, self.states.ravel())
        for name in NAMES:
            self.bank.GetInputPort(f"request_{name}").FixValue(self.context,
                                                               self.requests[name])

    def ask(self, name, lift="lift", from_level="L1", to_level="L2"):
        self.requests[name] = LiftRequest(name, lift, from_level, to_level)
        self._apply()

    def stop_asking(self, name):
        self.requests[name] = LiftRequest(name)
        self._apply()

    def put(self, name, xy):
        self.states[NAMES.index(name), :2] = xy
        self._apply()

    def run(self, seconds):
        self.simulator.AdvanceTo(self.context.get_time() + seconds)

    def status(self):
        return self.bank.GetOutputPort("lift_state").Eval(self.context).lift("lift")

    def moves(self):
        return self.bank.GetOutputPort("relocations").Eval(self.context).moves

    def events(self):
        return [(e.kind, e.robot) for e in self.bank.GetOutputPort("events").Eval(self.context)]


def test_ride_time_follows_the_elevations():
    params = LiftParams(speed=2.0, acceleration=1.2, door_time=4.0)
    # 8 m: 2 m/s reached (3.33 m to speed up and brake) -> 8 / 2 + 2 / 1.2 s.
    assert ride_time(params, 0.0, 8.0) == pytest.approx(4.0 + 4.0 + 2.0 / 1.2)
    # 1 m: never at full speed, a triangle -> 2 sqrt(1 / 1.2) s.
    assert ride_time(params, 4.0, 3.0) == pytest.approx(4.0 + 2.0 * np.sqrt(1.0 / 1.2))
    assert ride_time(params, 0.0, 8.0) == ride_time(params, 8.0, 0.0)


def test_first_come_first_served_and_one_holder():
    bench = Bench()
    bench.ask("b")
    bench.run(0.3)
    bench.ask("a")
    bench.ask("c")
    bench.run(0.3)
    status = bench.status()
    assert status.holder == "b" and status.waiting == ("a", "c")
    bench.run(5.0)  # b does not come: the cabin waits for it, nobody else gets it
    assert bench.status().holder == "b" and bench.status().phase == "open"
    bench.stop_asking("a")
    bench.run(0.2)
    assert bench.status().waiting == ("c",)


def test_a_ride_takes_its_time_moves_the_rider_once_and_frees_the_cabin_after_it_left():
    bench = Bench()
    bench.ask("a")
    bench.ask("b")
    bench.run(0.2)
    bench.put("a", (10.2, 0.1))  # in the cabin on L1
    bench.run(0.2)
    boarded = bench.context.get_time()
    expected = ride_time(PARAMS, 0.0, 8.0)
    bench.run(expected - 0.5)
    assert bench.moves()[0] is None and bench.status().phase in ("closing", "travel")
    bench.run(0.6)
    sequence, pose = bench.moves()[0]
    assert sequence == 1
    assert pose == pytest.approx((60.2, 0.1, 0.5))  # shifted by the cabins' offset, heading kept
    assert bench.status().level == "L2" and bench.status().phase == "out"
    assert bench.context.get_time() - boarded == pytest.approx(expected, abs=0.25)
    bench.stop_asking("a")
    bench.put("a", (60.2, 0.1))  # the robots block applied the pose
    bench.run(1.0)
    assert bench.moves()[0][0] == 1  # moved once only
    assert bench.status().holder == "a"
    bench.put("a", (63.0, 0.0))  # drove out, 2.8 m from the cabin
    bench.run(0.2)
    status = bench.status()
    assert status.holder == "b" and status.phase == "called"  # the cabin goes back for b
    assert bench.events()[:5] == [("request", "a"), ("request", "b"), ("board", "a"),
                                  ("depart", "a"), ("arrive", "a")]
    assert ("leave", "a") in bench.events()


def test_a_holder_that_stops_asking_before_boarding_gives_the_cabin_up():
    bench = Bench()
    bench.ask("a")
    bench.ask("b")
    bench.run(0.3)
    bench.stop_asking("a")
    bench.run(0.2)
    assert bench.status().holder == "b"


@pytest.mark.parametrize("field", ["speed", "acceleration", "board_tolerance",
                                   "leave_distance", "door_time"])
def test_bad_parameters_name_the_field(field):
    with pytest.raises(InputError, match=field):
        LiftParams(**{field: -1.0})
