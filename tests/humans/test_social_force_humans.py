import dataclasses
from dataclasses import dataclass

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder, LeafSystem
from pydrake.systems.primitives import LogVectorOutput, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from mrta_drake.control.barriers import BarrierRates, SafetyDistances, cbf_rhs, point_barrier
from mrta_drake.humans.people import Person, generate_people
from mrta_drake.humans.social_force_humans import ROBOT_STANDOFF, SocialForceHumans
from mrta_drake.humans.social_force_params import SocialForceParams
from mrta_drake.scenario.schema import HumanGroupConfig, HumansConfig
from mrta_drake.world.obstacles import Box, Cylinder, Obstacles

PERIOD = 0.05
OPEN = Obstacles()
DEFAULTS = SocialForceParams()
CORRIDOR = Obstacles(boxes=(Box("north", (0.0, 1.6), (20.0, 0.2)),
                            Box("south", (0.0, -1.6), (20.0, 0.2))))
# 1.2 m wide, closed at x = -3: no room to pass a robot, nowhere to back away to.
DEAD_END = Obstacles(boxes=(Box("north", (2.0, 0.7), (10.4, 0.2)),
                            Box("south", (2.0, -0.7), (10.4, 0.2)),
                            Box("end", (-3.1, 0.0), (0.2, 1.6))))
ROBOT_RADIUS = 0.2


@dataclass
class Walk:
    """A simulated walk: sample ``times`` (T,), people's positions ``xy`` (T, M, 2),
    ``heading`` (T, M) and ``present`` (T, M), the robots' states (T, N, 4), the humans
    system and its context."""

    times: np.ndarray
    xy: np.ndarray
    heading: np.ndarray
    present: np.ndarray
    robots: np.ndarray
    humans: LeafSystem
    context: object

    def gaps(self, robot: int = 0) -> np.ndarray:
        """Surface gaps (T, M) of every person to ``robot``, m."""
        centres = np.linalg.norm(self.xy - self.robots[:, None, robot, :2], axis=2)
        return centres - DEFAULTS.radius - ROBOT_RADIUS


def _straight(robots, duration):
    """Robot states (4N) over ``duration`` s for robots driving straight at constant speed
    from the rows [x, y, theta, v]."""
    rows = np.atleast_2d(np.asarray(robots, dtype=float))
    end = rows.copy()
    end[:, 0] += duration * rows[:, 3] * np.cos(rows[:, 2])
    end[:, 1] += duration * rows[:, 3] * np.sin(rows[:, 2])
    return PiecewisePolynomial.FirstOrderHold([0.0, duration],
                                              np.column_stack([rows.ravel(), end.ravel()]))


def _run(people, duration, obstacles=OPEN, params=DEFAULTS, robots=None) -> Walk:
    """Simulates the humans. ``robots``: rows [x, y, theta, v] of robots (radius
    ``ROBOT_RADIUS``) driving straight at constant speed, or their state trajectory (4N)."""
    builder = DiagramBuilder()
    if robots is not None and not isinstance(robots, PiecewisePolynomial):
        robots = _straight(robots, duration)
    count = 0 if robots is None else robots.rows() // 4
    names = [f"r{k}" for k in range(count)]
    humans = builder.AddSystem(SocialForceHumans(people, params, obstacles, names,
                                                 np.full(count, ROBOT_RADIUS),
                                                 rate_hz=1.0 / PERIOD))
    robot_log = None
    if robots is not None:
        source = builder.AddSystem(TrajectorySource(robots))
        builder.Connect(source.get_output_port(), humans.GetInputPort("robot_state"))
        robot_log = LogVectorOutput(source.get_output_port(), builder, PERIOD)
    poses = LogVectorOutput(humans.GetOutputPort("plant_positions"), builder, PERIOD)
    active = LogVectorOutput(humans.GetOutputPort("active"), builder, PERIOD)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    simulator.AdvanceTo(duration)
    root = simulator.get_context()
    pose_log = poses.FindLog(root)
    times = pose_log.sample_times()
    data = pose_log.data().T.reshape(len(times), len(people), 3)
    states = (np.zeros((len(times), 0, 4)) if robot_log is None
              else robot_log.FindLog(root).data().T.reshape(len(times), count, 4))
    return Walk(times, data[..., :2], data[..., 2], active.FindLog(root).data().T > 0.5,
                states, humans, humans.GetMyContextFromRoot(root))


def test_lone_human_reaches_and_loops_its_waypoints():
    square = ((3.0, 0.0), (3.0, 3.0), (0.0, 3.0), (0.0, 0.0))
    path = _run([Person("p", (1.0, -0.5), square, 1.0)], 30.0).xy[:, 0]
    speed = np.linalg.norm(np.diff(path, axis=0), axis=1) / PERIOD
    assert speed.max() <= 1.5 + 1e-9
    # Times the human comes within the switching tolerance (plus one step) of each corner,
    # in the loop's order: it keeps visiting them in sequence.
    order = []
    for k, p in enumerate(path):
        near = [i for i, w in enumerate(square) if np.linalg.norm(p - w) < 0.3 + 0.08]
        if near and (not order or order[-1] != near[0]):
            order.append(near[0])
        assert k == 0 or len(near) <= 1
    assert len(order) >= 6
    assert order == [i % 4 for i in range(len(order))]


def test_two_humans_head_on_pass_without_overlapping():
    people = [Person("east", (-5.0, 0.0), ((6.0, 0.0),), 1.0),
              Person("west", (5.0, 0.0), ((-6.0, 0.0),), 1.0)]
    xy = _run(people, 14.0, CORRIDOR).xy
    gap = np.linalg.norm(xy[:, 0] - xy[:, 1], axis=1) - 2 * 0.25
    assert gap.min() > 0.05
    assert xy[-1, 0, 0] > 5.5 and xy[-1, 1, 0] < -5.5
    # They kept right: the eastbound one passed south, the westbound one north.
    passing = np.argmin(gap)
    assert xy[passing, 0, 1] < 0 < xy[passing, 1, 1]


def test_repulsion_cut_off_leaves_out_only_forces_below_negligible_force():
    # Two people walking east 9.5 m apart: beyond the people's cut-off (sigma ln(V0 2 2 /
    # (sigma 1e-9)) = 6.6 m plus both radii and the other's walk), where each one's force on
    # the other is ~1e-13 m/s^2; a third walks beside the first, 1 m away, within it.
    people = [Person("a", (0.0, 0.0), ((20.0, 0.0),), 1.0),
              Person("b", (0.0, 9.5), ((20.0, 9.5),), 1.0),
              Person("c", (0.0, -1.0), ((20.0, -1.0),), 1.0)]
    every = _run(people, 1.0, params=dataclasses.replace(DEFAULTS, negligible_force=0.0)).xy
    cut = _run(people, 1.0).xy
    apart = np.abs(cut - every).max()
    assert 0.0 < apart < 1e-9  # m: 1 s of a force below 1e-9 m/s^2 moves nobody further
    # b's pull on a and c is left out: the two alone walk exactly as with b.
    pair = _run([people[0], people[2]], 1.0, params=dataclasses.replace(
        DEFAULTS, negligible_force=0.0)).xy
    assert np.array_equal(cut[:, [0, 2]], pair)


@pytest.mark.parametrize("wall_strength", [10.0, 0.0])
def test_human_never_enters_a_wall(wall_strength):
    # A wall crossed at 30 degrees and a corner walked into: both targets lie behind walls.
    walls = Obstacles(boxes=(Box("wall", (3.0, 0.0), (0.2, 10.0)),
                             Box("corner_a", (-3.0, 3.0), (4.0, 0.2)),
                             Box("corner_b", (-5.0, 1.0), (0.2, 4.0))),
                      cylinders=(Cylinder("pillar", (0.0, -3.0), 0.3),))
    people = [Person("slanted", (0.0, 0.0), ((6.0, 3.5),), 1.0),
              Person("cornered", (-2.0, 0.0), ((-6.0, 4.0),), 1.2),
              Person("pillar", (0.0, -1.0), ((0.0, -5.0),), 1.5)]
    params = SocialForceParams(wall_strength=wall_strength)
    xy = _run(people, 12.0, walls, params).xy
    clearance = walls.signed_distance(xy.reshape(-1, 2))
    assert clearance.min() >= params.radius - 1e-9
    # The slanted walker slid along the wall toward its target instead of stopping dead.
    assert xy[-1, 0, 1] > 2.5


def _passing(walk: Walk, robot_x: float) -> int:
    """The first sample at which the (first) person is past ``robot_x``."""
    return int(np.argmax(walk.xy[:, 0, 0] > robot_x))


def test_person_slows_steps_right_and_passes_a_robot_standing_in_a_corridor():
    people = [Person("p", (-4.0, 0.0), ((6.0, 0.0),), 1.0)]
    alone = _run(people, 15.0, CORRIDOR)
    assert np.abs(alone.xy[:, 0, 1]).max() < 1e-3  # only the walls' weak, flipping push
    walk = _run(people, 15.0, CORRIDOR, robots=[[0.0, 0.0, np.pi, 0.0]])
    speed = np.linalg.norm(np.diff(walk.xy[:, 0], axis=0), axis=1) / PERIOD
    gap = walk.gaps()[:, 0]
    passing = _passing(walk, 0.0)
    assert 0 < passing < len(walk.times) - 1, "it passed the robot"
    # Slower near the robot than alone, before the robot is passed.
    assert speed[:passing][gap[1:passing + 1] < DEFAULTS.yield_distance].min() < 0.5
    # Aside to its right (south, walking east), the robot passed with the passing gap.
    assert walk.xy[passing, 0, 1] < -(DEFAULTS.radius + ROBOT_RADIUS + DEFAULTS.passing_gap)
    assert gap.min() >= DEFAULTS.passing_gap
    assert walk.xy[-1, 0, 0] > 4.0
    assert np.abs(walk.heading[:, 0]).max() > 0.2  # it visibly turned


def test_a_person_who_does_not_yield_walks_on_at_full_speed_into_the_robot_s_way():
    people = [Person("p", (-4.0, 0.0), ((6.0, 0.0),), 1.0)]
    robot = [[0.0, 0.0, np.pi, 0.0]]
    params = dataclasses.replace(DEFAULTS, yield_to_robots=False)
    yielding = _run(people, 4.0, CORRIDOR, robots=robot)
    walking_on = _run(people, 4.0, CORRIDOR, robots=robot, params=params)
    # Without yielding, only the repulsion and the no-overlap stop act: the person comes
    # nearer the robot, sooner, than one who yields.
    assert walking_on.gaps()[:, 0].min() < yielding.gaps()[:, 0].min()
    assert walking_on.xy[80, 0, 0] > yielding.xy[80, 0, 0] + 0.1  # 4 s: further on
    assert walking_on.gaps().min() >= 0.0  # it still never steps into the robot


def test_person_passes_on_the_left_when_only_the_left_has_room():
    people = [Person("p", (-4.0, -0.6), ((6.0, -0.6),), 1.0)]
    # 0.4 m between the robot and the south wall: too narrow for a person.
    walk = _run(people, 15.0, CORRIDOR, robots=[[0.0, -0.9, np.pi, 0.0]])
    passing = _passing(walk, 0.0)
    assert 0 < passing < len(walk.times) - 1
    assert walk.xy[passing, 0, 1] > -0.9 + DEFAULTS.radius + ROBOT_RADIUS + DEFAULTS.passing_gap
    assert walk.gaps().min() > 0.0


def test_person_waits_for_a_robot_blocking_the_way_then_goes_on():
    people = [Person("p", (-2.5, 0.0), ((6.0, 0.0),), 1.0)]
    # The robot stands in the 1.2 m corridor for 6 s, then drives on east at 1 m/s.
    robot = PiecewisePolynomial.FirstOrderHold(
        [0.0, 6.0, 6.05, 20.0],
        np.array([[0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0], [0.05, 0.0, 0.0, 1.0],
                  [13.95, 0.0, 0.0, 1.0]]).T)
    walk = _run(people, 20.0, DEAD_END, robots=robot)
    x, gap = walk.xy[:, 0, 0], walk.gaps()[:, 0]
    assert np.ptp(x[(walk.times >= 3.0) & (walk.times < 6.0)]) < 0.05, "it stood and waited"
    assert gap[walk.times < 6.0].min() >= DEFAULTS.waiting_gap
    assert np.abs(walk.xy[:, 0, 1]).max() < 0.05  # no room to step aside: it did not try
    assert walk.xy[-1, 0, 0] > 3.0, "it went on once the robot had gone"


def test_person_walking_at_a_standing_robot_slows_as_the_robot_s_person_row_assumes():
    # A 1.2 m corridor with no room to pass: the person walks at a robot standing in it.
    # The robot's CBF row for the person (constant-velocity prediction, default safety
    # distance and rates) must hold with the robot not moving: a standing robot can hardly
    # back away, so a person closing faster than the row allows costs the controller slack.
    # Yielding by the gap less the robot's approach alone broke it (by 2.7 m^2/s^2).
    narrow = Obstacles(boxes=(Box("north", (0.0, 0.7), (20.0, 0.2)),
                              Box("south", (0.0, -0.7), (20.0, 0.2))))
    people = [Person("p", (-6.0, 0.0), ((6.0, 0.0),), 1.0)]
    walk = _run(people, 12.0, narrow, robots=[[0.0, 0.0, np.pi, 0.0]])
    velocity = np.diff(walk.xy[:, 0], axis=0) / PERIOD  # the state's velocity at each sample
    rates = BarrierRates()
    terms = point_barrier(walk.robots[1:, 0, :2], np.pi, 0.0, walk.xy[1:, 0], velocity,
                          SafetyDistances().human)
    assert cbf_rhs(terms, rates.alpha1_human, rates.alpha2_human).max() <= 0.0
    assert velocity[:, 0].max() > 0.95  # it walked at its speed while far
    assert walk.gaps()[:, 0].min() >= DEFAULTS.waiting_gap


def test_people_pinned_in_a_dead_end_never_step_into_the_robot_driving_in():
    # Two people walking out of a dead end, the one behind pushing the one in front; a
    # robot drives in at 0.5 m/s and on into them: they cannot get out of its way.
    people = [Person("front", (-2.2, 0.0), ((6.0, 0.0),), 1.0),
              Person("behind", (-2.7, 0.0), ((6.0, 0.0),), 1.3)]
    walk = _run(people, 12.4, DEAD_END, robots=[[3.5, 0.0, np.pi, 0.5]])
    gaps = walk.gaps()
    assert gaps.min() < -0.05, "the robot drove into someone"
    # Each person's own step, with the robot where it ended up after the step, never took
    # the person nearer it than the standoff (or its gap before the step, if nearer).
    robot_next = walk.robots[1:, None, 0, :2]
    after = np.linalg.norm(walk.xy[1:] - robot_next, axis=2) - DEFAULTS.radius - ROBOT_RADIUS
    before = np.linalg.norm(walk.xy[:-1] - robot_next, axis=2) - DEFAULTS.radius - ROBOT_RADIUS
    assert (after >= np.minimum(ROBOT_STANDOFF, before) - 1e-9).all()
    assert DEAD_END.signed_distance(walk.xy.reshape(-1, 2)).min() >= DEFAULTS.radius - 1e-9


def test_waypoint_taken_by_a_robot_counts_as_reached_nearby():
    people = [Person("p", (-3.0, 0.0), ((0.0, 0.0), (0.0, -1.2)), 1.0)]
    robot = [[0.0, 0.0, 0.0, 0.0]]  # parked on the first waypoint
    xy = _run(people, 8.0, CORRIDOR, robots=robot).xy
    assert np.linalg.norm(xy[:, 0] - [0.0, -1.2], axis=1).min() < 0.3 + 0.08


def test_deterministic_under_a_seed():
    config = HumansConfig(groups=[
        HumanGroupConfig(kind="visitors", count=6, points=[[-8, 0], [8, 0], [0, 1], [4, -1]]),
        HumanGroupConfig(kind="stream", count=3, center=[-9, 0], points=[[8, 1]], interval=2),
    ])
    robots = [[0.0, 0.0, 0.0, 0.5], [3.0, -0.5, np.pi, 0.3]]

    def run():
        people = generate_people(config, DEFAULTS, 7, CORRIDOR)
        return _run(people, 8.0, CORRIDOR, robots=robots).xy

    first, second = run(), run()
    assert np.array_equal(first, second)


def test_waiting_person_is_parked_until_entry_and_a_clear_start():
    people = [Person("early", (0.0, 0.0), ((5.0, 0.0),), 1.0),
              Person("late", (0.0, 0.0), ((5.0, 0.0),), 1.0, entry_time=1.0),
              Person("blocked", (-5.0, 0.0), ((5.0, 0.0),), 1.0, entry_time=0.5)]
    robot = [[-5.0, 0.3, 0.0, 0.0]]  # stands on the blocked person's entry point
    walk = _run(people, 3.0, CORRIDOR, robots=robot)
    times, xy, present, humans = walk.times, walk.xy, walk.present, walk.humans
    # Entry at 1.0 s ("early" has moved on; its start is clear). The log shows an update's
    # result from the next sample on.
    entered = times[np.argmax(present[:, 1])]
    assert 1.0 - 1e-9 <= entered <= 1.0 + PERIOD + 1e-9
    assert present[:, 1].sum() == np.sum(times >= entered)
    assert not present[:, 2].any()
    parked = xy[~present[:, 1], 1]
    assert np.all(parked[:, 0] < -10.0 - 1.0 + 1e-9)  # west of the world, out of the way
    assert CORRIDOR.signed_distance(parked).min() > 1.0
    # Everyone is reported, the waiting person standing still at its parking spot.
    states = humans.GetOutputPort("human_states").Eval(walk.context)
    assert states.names == ("early", "late", "blocked") == humans.human_names
    np.testing.assert_array_equal(states.positions[2], xy[-1, 2])
    np.testing.assert_array_equal(states.velocities[2], [0.0, 0.0])
    assert np.linalg.norm(states.velocities[1]) > 0.5
    np.testing.assert_array_equal(states.radii, [0.25, 0.25, 0.25])


def test_heading_follows_velocity():
    people = [Person("north", (0.0, 0.0), ((0.0, 10.0),), 1.0)]
    assert _run(people, 2.0).heading[-1, 0] == pytest.approx(np.pi / 2)


def test_no_humans_and_bad_robot_radii():
    system = SocialForceHumans([], DEFAULTS, Obstacles(), rate_hz=20.0)
    context = system.CreateDefaultContext()
    assert system.GetOutputPort("plant_positions").Eval(context).shape == (0,)
    with pytest.raises(ValueError, match="robot_radii"):
        SocialForceHumans([], DEFAULTS, Obstacles(), ["r0", "r1"], [0.2], rate_hz=20.0)
