import numpy as np
import pytest

from mrta_drake.results.human_metrics import HumanMetrics, human_metrics


def _walk_past(y, dt=0.25):
    """One robot (radius 0.2) standing at the origin; one human (radius 0.25) walking along
    the line at ``y`` from x = -5 to 5 at 1 m/s, sampled every ``dt`` s."""
    times = np.arange(0.0, 10.0 + 1e-9, dt)
    human = np.column_stack([times - 5.0, np.full_like(times, y)])[:, None, :]
    robot = np.zeros((len(times), 1, 2))
    return times, robot, human


def test_distance_and_personal_space_of_a_passing_human():
    times, robot, human = _walk_past(0.8)
    m = human_metrics(times, robot, human, 0.2, 0.25)
    assert m.min_distance == pytest.approx(0.8 - 0.45)
    assert m.min_distance_time == pytest.approx(5.0)
    # Surface closer than 0.5 m while the centre is within 0.95 m: |x| < 0.512, i.e. the
    # samples at x = -0.5 ... 0.5, each weighing 0.25 s.
    assert m.personal_space_time == pytest.approx(5 * 0.25)
    assert m.contacts == 0


def test_far_passage_has_no_intrusion():
    times, robot, human = _walk_past(1.0)
    m = human_metrics(times, robot, human, [0.2], [0.25])
    assert m.min_distance == pytest.approx(0.55)
    assert m.personal_space_time == 0.0


def test_contact_onsets_are_counted_per_pair():
    times = np.arange(6) * 0.1
    # Human 0 touches robot 0 at samples 0, 2-3 and 5 (three onsets); human 1 touches
    # robot 1 once, at sample 4; robot 1 never touches human 0.
    gap0 = [0.0, 0.3, -0.1, 0.0, 0.3, -0.05]
    human = np.zeros((6, 2, 2))
    human[:, 0, 0] = np.array(gap0) + 0.5
    human[:, 1] = [20.0, 0.0]
    human[4, 1, 0] = 10.5
    robot = np.zeros((6, 2, 2))
    robot[:, 1] = [10.0, 0.0]
    m = human_metrics(times, robot, human, 0.25, 0.25)
    assert m.contacts == 4
    assert m.min_distance == pytest.approx(-0.1)
    assert m.min_distance_time == pytest.approx(0.2)


def test_detour_is_extra_path_while_a_robot_is_near():
    # Point bodies; robot at the origin; the human bows out to y = 1.5 past it.
    human = np.array([[-4.0, 0.5], [-1.5, 0.5], [0.0, 1.5], [1.5, 0.5], [4.0, 0.5]])
    times = np.arange(5.0)
    m = human_metrics(times, np.zeros((5, 1, 2)), human[:, None, :], 0.0, 0.0)
    # Samples 1-3 are within 2 m: path 2 * sqrt(1.5^2 + 1) against a 3 m chord.
    assert m.encounters == 1
    assert m.encounter_length == pytest.approx(2 * np.hypot(1.5, 1.0))
    assert m.detour_length == pytest.approx(2 * np.hypot(1.5, 1.0) - 3.0)
    straight = human.copy()
    straight[2, 1] = 0.5
    assert human_metrics(times, np.zeros((5, 1, 2)), straight[:, None, :], 0.0,
                         0.0).detour_length == pytest.approx(0.0)


def test_turns_at_waypoints_are_not_detours():
    # Point bodies; robot at the origin; the human walks out to its waypoint (1, 0.5) and
    # back, all within 2 m of the robot.
    out = np.column_stack([np.linspace(-1.0, 1.0, 9), np.full(9, 0.5)])
    human = np.vstack([out, out[-2::-1]])[:, None, :]
    times = np.arange(len(human)) * 0.25
    robot = np.zeros((len(human), 1, 2))
    blind = human_metrics(times, robot, human, 0.0, 0.0)
    assert blind.detour_length == pytest.approx(4.0)  # 4 m walked, start = end
    aware = human_metrics(times, robot, human, 0.0, 0.0,
                          human_waypoints=[[(1.0, 0.5), (-3.0, 0.5)]])
    assert aware.encounter_length == pytest.approx(4.0)
    assert aware.detour_length == pytest.approx(0.0)


def test_absent_humans_and_no_robots():
    times, robot, human = _walk_past(0.0)
    human[:20] = np.nan  # enters at t = 5 s, right on the robot
    m = human_metrics(times, robot, human, 0.2, 0.25)
    assert m.min_distance == pytest.approx(-0.45)
    assert m.min_distance_time == pytest.approx(5.0)
    assert m.contacts == 1
    assert m.encounters == 1
    assert m.encounter_length == pytest.approx(2.25)  # x from 0 until the gap reaches 2 m
    nobody = human_metrics(times, np.zeros((len(times), 0, 2)), human, [], 0.25)
    assert nobody == HumanMetrics(float("inf"), nobody.min_distance_time, 0.0, 0, 0, 0.0, 0.0)
    assert np.isnan(nobody.min_distance_time)


def test_shape_mismatch_is_rejected():
    with pytest.raises(ValueError, match="expected"):
        human_metrics(np.arange(3.0), np.zeros((2, 1, 2)), np.zeros((3, 1, 2)), 0.2, 0.25)
