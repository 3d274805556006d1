import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

from mrta_drake.robots.unicycle_robots import UnicycleParams, UnicycleRobots, unicycle_step


def _run(starts, commands, duration, params=None, relocations=True):
    builder = DiagramBuilder()
    robots = builder.AddSystem(UnicycleRobots([f"r{i}" for i in range(len(starts))], starts,
                                              params or UnicycleParams(), rate_hz=20.0,
                                              relocations=relocations))
    source = builder.AddSystem(ConstantVectorSource(np.ravel(commands)))
    builder.Connect(source.get_output_port(), robots.GetInputPort("commands"))
    diagram = builder.Build()
    simulator = Simulator(diagram)
    simulator.AdvanceTo(duration)
    context = robots.GetMyContextFromRoot(simulator.get_context())
    return robots.GetOutputPort("state").Eval(context).reshape(-1, 4)


def test_straight_line_respects_acceleration_and_speed_limits():
    params = UnicycleParams(max_speed=1.0, max_acceleration=0.5)
    state = _run([[0.0, 0.0, 0.0]], [[5.0, 0.0]], 4.0, params)[0]
    # 2 s ramp to 1 m/s (1 m), then 2 s at 1 m/s (2 m).
    np.testing.assert_allclose(state, [3.0, 0.0, 0.0, 1.0], atol=1e-9)


def test_constant_turn_follows_a_circle_exactly():
    params = UnicycleParams(max_acceleration=100.0)
    v, omega = 1.0, 0.5
    state = _run([[0.0, 0.0, 0.0]], [[v, omega]], 2 * np.pi / omega, params)[0]
    # After the first step the robot drives at v on a circle of radius v / omega; a full
    # period later it is back where the first step left it.
    first = unicycle_step(np.array([[0.0, 0.0, 0.0, 0.0]]), np.array([[v, omega]]), params,
                          0.05)[0]
    radius = v / omega
    centre = first[:2] + radius * np.array([-np.sin(first[2]), np.cos(first[2])])
    assert np.linalg.norm(state[:2] - centre) == pytest.approx(radius, abs=1e-9)


def test_yaw_rate_is_clipped_and_heading_wrapped():
    state = _run([[0.0, 0.0, 3.0]], [[0.0, 10.0]], 1.0)[0]
    expected = np.mod(3.0 + 2.0 + np.pi, 2 * np.pi) - np.pi
    assert state[2] == pytest.approx(expected)


def test_robots_are_independent_and_plant_positions_match():
    starts = [[0.0, 0.0, 0.0], [5.0, 5.0, np.pi / 2]]
    states = _run(starts, [[1.0, 0.0], [0.0, 0.0]], 3.0)
    assert states[0, 0] > 2.0
    np.testing.assert_allclose(states[1], [5.0, 5.0, np.pi / 2, 0.0])


@pytest.mark.parametrize("omega", [0.0, 1e-322, -1e-322, -1e-300, 1e-9])
def test_vanishing_turn_rates_step_straight_without_dividing_by_zero(omega):
    # A QP can hand back a yaw rate so small that half of a turn underflows to zero
    # (1e-322 rad/s: the turn over 0.05 s is the smallest subnormal, its half is 0).
    state = np.array([[1.0, 2.0, 0.3, 0.5]])
    new = unicycle_step(state, np.array([[0.5, omega]]), UnicycleParams(), 0.05)
    distance = 0.5 * 0.05
    np.testing.assert_allclose(new[0, :2], [1.0 + distance * np.cos(0.3),
                                            2.0 + distance * np.sin(0.3)], rtol=0, atol=1e-12)
    assert np.isfinite(new).all()


def test_a_relocation_is_applied_once_when_its_sequence_number_is_new():
    from mrta_drake.payloads import Relocations

    robots = UnicycleRobots(["a", "b"], [[0.0, 0.0, 0.0], [5.0, 0.0, 0.0]],
                            UnicycleParams(max_acceleration=100.0), rate_hz=20.0)
    simulator = Simulator(robots)
    context = simulator.get_mutable_context()
    robots.GetInputPort("commands").FixValue(context, [1.0, 0.0, 0.0, 0.0])
    moves = Relocations((None, (1, (50.0, 2.0, 0.0))))
    robots.GetInputPort("relocations").FixValue(context, moves)
    simulator.AdvanceTo(1.0)
    state = robots.GetOutputPort("state").Eval(context).reshape(-1, 4)
    # Robot b was put on the pose at the first step and stood still since (no command);
    # robot a drove on, untouched.
    np.testing.assert_allclose(state[1], [50.0, 2.0, 0.0, 0.0])
    assert state[0, 0] == pytest.approx(1.0, abs=0.06)
    robots.GetInputPort("commands").FixValue(context, [0.0, 0.0, 1.0, 0.0])
    simulator.AdvanceTo(2.0)  # the same sequence number: not applied again
    state = robots.GetOutputPort("state").Eval(context).reshape(-1, 4)
    assert state[1, 0] == pytest.approx(51.0, abs=0.06)
    robots.GetInputPort("relocations").FixValue(context, Relocations(
        (None, (2, (7.0, 7.0, 0.0)))))
    simulator.AdvanceTo(2.1)
    x, y = robots.GetOutputPort("state").Eval(context).reshape(-1, 4)[1, :2]
    assert 7.0 <= x <= 7.15 and y == pytest.approx(7.0)  # moved there, then drove on


def test_without_relocations_the_robots_have_no_relocation_update_and_step_alike(
        monkeypatch):
    # A run without lifts: no relocation update (its dispatch costs at every step) and no
    # state for it, the same steps.
    calls = []
    relocate = UnicycleRobots._relocate
    monkeypatch.setattr(UnicycleRobots, "_relocate",
                        lambda self, *args: calls.append(1) or relocate(self, *args))
    robots = UnicycleRobots(["a"], [[0.0, 0.0, 0.0]], rate_hz=20.0, relocations=False)
    assert robots.num_abstract_states() == 0
    starts, commands = [[0.0, 0.0, 0.0], [5.0, 5.0, 1.0]], [[1.0, 0.3], [0.5, -0.2]]
    without = _run(starts, commands, 3.0, relocations=False)
    assert not calls
    np.testing.assert_array_equal(without, _run(starts, commands, 3.0))
    assert calls  # the default block has the update
