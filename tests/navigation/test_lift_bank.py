"""The lift bank: first come first served, as many riders per cabin as it has berths, a
robot sent to the lift of its bank it waits least for, rides as long as the elevations say,
the riders moved once to the other level, the cabin freed once they have left."""

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator

from mrta_drake.errors import InputError
from mrta_drake.navigation.lift_bank import (
    LiftBank,
    LiftParams,
    LiftSpec,
    LiftStop,
    cabin_berths,
    ride_time,
)
from mrta_drake.payloads import LiftRequest

LIFT = LiftSpec("lift", (LiftStop("L1", (10.0, 0.0), 0.0, "L1/cabin"),
                         LiftStop("L2", (60.0, 0.0), 8.0, "L2/cabin")), "L1")
NAMES = ("a", "b", "c")
PARAMS = LiftParams(door_time=2.0)


class Bench:
    """A lift bank alone, its inputs set by hand, stepped at 10 Hz."""

    def __init__(self, params=PARAMS, lifts=(LIFT,)):
        self.bank = LiftBank(NAMES, lifts, params, rate_hz=10.0)
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

    def status(self, lift="lift"):
        return self.bank.GetOutputPort("lift_state").Eval(self.context).lift(lift)

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
    assert status.riders == ("b",) and status.waiting == ("a", "c")
    bench.run(5.0)  # b does not come: the cabin waits for it, nobody else gets it
    assert bench.status().riders == ("b",) and bench.status().phase == "open"
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
    assert bench.status().riders == ("a",)
    bench.put("a", (63.0, 0.0))  # drove out, 2.8 m from the cabin
    bench.run(0.2)
    status = bench.status()
    assert status.riders == ("b",) and status.phase == "called"  # the cabin goes back for b
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
    assert bench.status().riders == ("b",)


@pytest.mark.parametrize("field", ["speed", "acceleration", "board_tolerance",
                                   "leave_distance", "door_time", "berth_clearance", "board_wait",
                                   "bank_distance", "approach_speed"])
def test_bad_parameters_name_the_field(field):
    with pytest.raises(InputError, match=field):
        LiftParams(**{field: -1.0})


# A 2.5 x 2.5 m cabin (door on its -y face) on two levels, and a second lift 4 m east of
# it: one bank.
WIDE = LiftSpec("wide", (LiftStop("L1", (10.0, 0.0), 0.0, "L1/wide", (10.0, 0.0), (10.0, -1.25)),
                         LiftStop("L2", (60.0, 0.0), 8.0, "L2/wide", (60.0, 0.0), (60.0, -1.25))),
                "L1", width=2.5, depth=2.5)
NEXT = LiftSpec("next", (LiftStop("L1", (14.0, 0.0), 0.0, "L1/next"),
                         LiftStop("L2", (64.0, 0.0), 8.0, "L2/next")), "L1")


def test_a_cabin_has_a_berth_for_each_robot_that_fits_farthest_from_the_door_first():
    berths = cabin_berths(WIDE, "L1", robot_radius=0.22, clearance=0.5)
    # 2.5 m across: robots 0.44 m wide, 0.5 m apart and 0.5 m from the walls -> 2 x 2.
    assert len(berths) == 4
    assert all(abs(x - 10.0) + 0.22 + 0.5 <= 1.25 and abs(y) + 0.22 + 0.5 <= 1.25
               for x, y in berths)
    assert min(np.hypot(*np.subtract(a, b)) for k, a in enumerate(berths)
               for b in berths[k + 1:]) >= 0.94 - 1e-9
    door_gaps = [np.hypot(x - 10.0, y + 1.25) for x, y in berths]
    assert door_gaps == sorted(door_gaps, reverse=True)
    # Bigger robots: one only, at the cabin's point; a cabin without a size likewise.
    assert cabin_berths(WIDE, "L2", robot_radius=0.6, clearance=0.5) == ((60.0, 0.0),)
    assert cabin_berths(LIFT, "L1", robot_radius=0.22, clearance=0.5) == ((10.0, 0.0),)


def test_robots_with_the_same_trip_share_the_cabin_and_ride_together():
    bench = Bench(lifts=[WIDE])
    assert bench.bank.capacity("wide") == 4
    bench.ask("a", lift="wide")
    bench.ask("b", lift="wide")
    bench.ask("c", lift="wide", from_level="L1", to_level="L1")  # another trip: waits
    bench.run(0.2)
    status = bench.status("wide")
    assert status.riders == ("a", "b") and status.waiting == ("c",)
    assert len(set(status.berths)) == 2
    for name in ("a", "b"):
        bench.put(name, status.berth(name))
    bench.run(0.2)
    assert bench.status("wide").phase == "closing"  # both aboard: the doors close
    bench.run(ride_time(PARAMS, 0.0, 8.0) + 0.2)
    moves = bench.moves()
    assert moves[0][1][:2] == pytest.approx(np.add(status.berth("a"), (50.0, 0.0)))
    assert moves[1][1][:2] == pytest.approx(np.add(status.berth("b"), (50.0, 0.0)))
    assert [kind for kind, robot in bench.events() if robot in "ab"].count("arrive") == 2
    out = bench.status("wide")
    assert out.phase == "out" and out.berth("a") == pytest.approx(moves[0][1][:2])
    bench.put("a", (64.0, 0.0))  # a drove out; b still in: the cabin stays
    bench.run(0.2)
    assert bench.status("wide").riders == ("b",)
    bench.put("b", (64.0, 1.0))
    bench.run(0.2)
    assert bench.status("wide").riders == ("c",)


def test_a_robot_is_sent_to_the_lift_of_the_bank_it_waits_least_for():
    bench = Bench(lifts=[WIDE, NEXT])
    bench.ask("a", lift="wide")
    bench.run(0.2)
    assert bench.status("wide").riders == ("a",)
    bench.put("a", bench.status("wide").berth("a"))
    bench.run(0.3)
    assert bench.status("wide").phase in ("closing", "travel")
    # b, between the two, asks for the lift that is leaving: the idle one is sooner.
    bench.put("b", (12.0, -3.0))
    bench.ask("b", lift="wide")
    bench.run(0.2)
    assert bench.status("next").riders == ("b",) and "b" not in bench.status("wide").waiting
    # Both idle on b's level: the nearer one.
    bench = Bench(lifts=[WIDE, NEXT])
    bench.put("c", (15.0, -3.0))
    bench.ask("c", lift="wide")
    bench.run(0.2)
    assert bench.status("next").riders == ("c",)
    request = [e for e in bench.bank.GetOutputPort("events").Eval(bench.context)
               if e.kind == "request"]
    assert [(e.lift, e.robot) for e in request] == [("next", "c")]


def test_lifts_far_apart_are_no_bank():
    far = LiftSpec("far", (LiftStop("L1", (40.0, 0.0), 0.0, "L1/far"),
                           LiftStop("L2", (90.0, 0.0), 8.0, "L2/far")), "L1")
    bench = Bench(lifts=[WIDE, far])
    bench.put("a", (39.0, 0.0))  # next to the far lift, but asking for the wide one
    bench.ask("a", lift="wide")
    bench.run(0.2)
    assert bench.status("wide").riders == ("a",) and bench.status("far").riders == ()


def test_the_doors_wait_board_wait_for_a_late_rider_then_leave_without_it():
    bench = Bench(params=LiftParams(door_time=2.0, board_wait=5.0), lifts=[WIDE])
    bench.ask("a", lift="wide")
    bench.ask("b", lift="wide")
    bench.run(0.2)
    bench.put("a", bench.status("wide").berth("a"))  # b stays away
    bench.run(4.5)
    assert bench.status("wide").phase == "open" and bench.status("wide").riders == ("a", "b")
    bench.run(1.0)
    status = bench.status("wide")
    assert status.phase in ("closing", "travel") and status.riders == ("a",)
    assert status.waiting == ("b",)
