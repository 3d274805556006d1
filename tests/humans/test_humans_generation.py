import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mrta_drake.errors import InputError
from mrta_drake.humans.people import (
    CROWD_SPEED_FACTOR,
    START_GAP,
    Person,
    generate_people,
    walkable_groups,
)
from mrta_drake.humans.social_force_params import SocialForceParams
from mrta_drake.scenario.schema import HumanConfig, HumanGroupConfig, HumansConfig
from mrta_drake.world.obstacles import Box, Obstacles

# Two 10 x 6 m rooms side by side; a 1.4 m door in the wall between them; a desk in the east.
ROOMS = Obstacles(boxes=(
    Box("north", (0.0, 3.1), (20.4, 0.2)), Box("south", (0.0, -3.1), (20.4, 0.2)),
    Box("west", (-10.1, 0.0), (0.2, 6.4)), Box("east", (10.1, 0.0), (0.2, 6.4)),
    Box("middle_n", (0.0, 1.85), (0.2, 2.3)), Box("middle_s", (0.0, -1.85), (0.2, 2.3)),
    Box("desk", (5.0, 0.0), (1.0, 1.0)),
))
PARAMS = SocialForceParams()
RADIUS = PARAMS.radius
POINTS = [[-8.0, -2.0], [8.0, 2.0], [-5.0, 2.0], [8.0, -2.0]]


def _config(*groups, walkers=()):
    return HumansConfig(walkers=list(walkers), groups=list(groups))


def _legs_clear(person: Person, obstacles=ROOMS) -> bool:
    """Every leg of the person's loop (start first) keeps clearance >= radius."""
    loop = np.array(person.waypoints)
    legs = zip(np.vstack([person.start, loop]), np.vstack([loop, loop[:1]]), strict=True)
    for a, b in legs:
        samples = a + np.linspace(0, 1, 200)[:, None] * (b - a)
        if obstacles.signed_distance(samples).min() < RADIUS - 1e-9:
            return False
    return True


def _check_starts(people):
    starts = np.array([p.start for p in people if p.entry_time == 0])
    gaps = np.linalg.norm(starts[:, None] - starts[None], axis=2) + np.eye(len(starts)) * 99
    assert gaps.min() >= 2 * RADIUS + START_GAP - 1e-9


def test_walkers_start_on_their_first_waypoint_and_loop_as_given():
    config = _config(walkers=[HumanConfig("ann", [[-8, 2], [-2, 2], [-2, -2]]),
                              HumanConfig("", [[5, 2.5]], desired_speed=0.7)])
    ann, other = generate_people(config, PARAMS, 0, ROOMS)
    assert ann == Person("ann", (-8.0, 2.0), ((-2.0, 2.0), (-2.0, -2.0), (-8.0, 2.0)), 1.0)
    assert other == Person("walker1", (5.0, 2.5), ((5.0, 2.5),), 0.7)


def test_visitors_walk_routed_loops_between_points_of_interest():
    people = generate_people(_config(HumanGroupConfig("visitors", 8, points=POINTS)), PARAMS, 3,
                             ROOMS)
    assert [p.name for p in people] == [f"visitors0_{k}" for k in range(8)]
    _check_starts(people)
    crossing = 0
    for person in people:
        assert _legs_clear(person)
        assert ROOMS.signed_distance([person.start])[0] >= RADIUS
        stops = [w for w in person.waypoints if list(w) in POINTS]
        assert len(stops) == 4  # LOOP_STOPS points of interest per loop
        assert all(a != b for a, b in zip(stops, stops[1:] + stops[:1], strict=True))
        crossing += any(abs(w[0]) < 1.5 for w in person.waypoints)  # routed via the door
    assert crossing > 0


def test_crowd_mills_within_spread_of_its_centre():
    group = HumanGroupConfig("crowd", 6, center=[5.0, 0.0], spread=2.0)
    people = generate_people(_config(group), PARAMS, 1, ROOMS)
    assert len(people) == 6
    _check_starts(people)
    for person in people:
        assert person.desired_speed == CROWD_SPEED_FACTOR * 1.0
        points = np.array(person.waypoints)
        assert len(points) == 4
        assert np.linalg.norm(points - [5.0, 0.0], axis=1).max() <= 2.0
        assert ROOMS.signed_distance(points).min() >= RADIUS
        assert _legs_clear(person)


def test_stream_enters_at_its_centre_at_fixed_intervals():
    group = HumanGroupConfig("stream", 4, center=[-9.0, 0.0], points=[[8.0, 0.0], [3.0, 2.0]],
                             interval=5.0, desired_speed=1.2)
    people = generate_people(_config(group), PARAMS, 2, ROOMS)
    assert [p.entry_time for p in people] == [0.0, 5.0, 10.0, 15.0]
    for person in people:
        assert person.start == (-9.0, 0.0)
        assert person.waypoints[-1] == (-9.0, 0.0)  # walks back to the entry, then again
        assert person.desired_speed == 1.2
        assert _legs_clear(person)


def test_named_places_are_the_default_points_of_interest():
    places = {"lobby": (-8.0, -2.0), "ward": (8.0, 2.0)}
    people = generate_people(_config(HumanGroupConfig("visitors", 2)), PARAMS, 0, ROOMS,
                             places=places)
    for person in people:
        assert {(-8.0, -2.0), (8.0, 2.0)} <= set(person.waypoints)


def test_starts_keep_clear_of_given_circles():
    robots = [(x, y, 0.3) for x in range(-9, 10) for y in (-2.0, 0.0, 2.0) if abs(x) > 1]
    people = generate_people(_config(HumanGroupConfig("visitors", 5, points=POINTS)), PARAMS, 4,
                             ROOMS, keep_clear=robots)
    for person in people:
        gaps = [np.hypot(person.start[0] - x, person.start[1] - y) - r - RADIUS
                for x, y, r in robots]
        assert min(gaps) >= START_GAP - 1e-9


def test_same_seed_same_people_other_seed_other_people():
    config = _config(HumanGroupConfig("visitors", 4, points=POINTS),
                     HumanGroupConfig("crowd", 3, center=[-5.0, 0.0]))
    assert generate_people(config, PARAMS, 11, ROOMS) == generate_people(config, PARAMS, 11, ROOMS)
    assert generate_people(config, PARAMS, 11, ROOMS) != generate_people(config, PARAMS, 12, ROOMS)


def test_groups_draw_independent_streams():
    crowd = HumanGroupConfig("crowd", 3, center=[-5.0, 0.0])
    east = [[8.0, 2.0], [8.0, -2.0]]  # far from the crowd: no start conflicts between them
    alone = generate_people(_config(HumanGroupConfig("visitors", 0, points=east), crowd),
                            PARAMS, 5, ROOMS)
    after = generate_people(_config(HumanGroupConfig("visitors", 3, points=east), crowd),
                            PARAMS, 5, ROOMS)
    assert alone == after[3:]


@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 2**31), visitors=st.integers(0, 6), crowd=st.integers(0, 5))
def test_generated_points_are_always_free(seed, visitors, crowd):
    config = _config(HumanGroupConfig("visitors", visitors, points=POINTS),
                     HumanGroupConfig("crowd", crowd, center=[-5.0, 0.0], spread=2.5))
    people = generate_people(config, PARAMS, seed, ROOMS)
    assert len(people) == visitors + crowd
    if people:
        _check_starts(people)
    for person in people:
        points = np.array((person.start,) + person.waypoints)
        assert ROOMS.signed_distance(points).min() >= RADIUS - 1e-9


@pytest.mark.parametrize("config, field, message", [
    (_config(HumanGroupConfig("visitors", 1, points=POINTS), HumanGroupConfig("crowd", -3)),
     "humans.groups[1].count", "must be >= 0, got -3"),
    (_config(HumanGroupConfig("parade", 1)), "humans.groups[0].kind", "must be one of"),
    (_config(HumanGroupConfig("visitors", 1, points=[[0.0, 2.5], [5.0, 2.0]])),
     "humans.groups[0].points[0]", "from an obstacle"),
    (_config(HumanGroupConfig("visitors", 1, points=[[5.0, 2.0]])),
     "humans.groups[0].points", "at least 2 points"),
    (_config(HumanGroupConfig("visitors", 1, points=[[5.0, 2.0], [1.0]])),
     "humans.groups[0].points[1]", "must be [x, y]"),
    (_config(HumanGroupConfig("crowd", 1, center=[5.0, 0.0], spread=0.0)),
     "humans.groups[0].spread", "must be > 0"),
    (_config(HumanGroupConfig("stream", 1, center=[-9.0, 0.0], points=POINTS, interval=-1)),
     "humans.groups[0].interval", "must be > 0"),
    (_config(HumanGroupConfig("visitors", 1, points=POINTS, desired_speed=3.0)),
     "humans.groups[0].desired_speed", "max_speed"),
    (_config(walkers=[HumanConfig("a", [[-8, 2]]), HumanConfig("a", [[8, 2]])]),
     "humans.walkers[1].name", "duplicate"),
    (_config(walkers=[HumanConfig("a", [[-8, 2]]), HumanConfig("b", [[-8, 2.2]])]),
     "humans.walkers[1].waypoints[0]", "too close"),
    (_config(walkers=[HumanConfig("a", [])]), "humans.walkers[0].waypoints", "at least one"),
])
def test_invalid_configs_name_the_field(config, field, message):
    with pytest.raises(InputError, match="humans") as error:
        generate_people(config, PARAMS, 0, ROOMS, file="scenario.yaml")
    assert error.value.file == "scenario.yaml"
    assert error.value.field == field
    assert message in str(error.value)


def test_exact_error_message_for_a_negative_count():
    config = _config(HumanGroupConfig("visitors", 1, points=POINTS),
                     HumanGroupConfig("crowd", -3))
    with pytest.raises(InputError) as error:
        generate_people(config, PARAMS, 0, ROOMS, file="s.yaml")
    assert str(error.value) == "s.yaml: humans.groups[1].count: must be >= 0, got -3"


def test_unreachable_point_of_interest_is_an_input_error():
    closed = ROOMS.added(boxes=[Box("door", (0.0, 0.0), (0.2, 1.6))])
    with pytest.raises(InputError, match="no walkable path"):
        generate_people(_config(HumanGroupConfig("visitors", 1, points=POINTS)), PARAMS, 0,
                        closed)


def test_walkable_groups_split_at_a_closed_door_and_a_narrow_one():
    # POINTS: two in the west room (0, 2), two in the east room (1, 3).
    assert walkable_groups(POINTS, ROOMS, PARAMS) == [[0, 1, 2, 3]]
    closed = ROOMS.added(boxes=[Box("door", (0.0, 0.0), (0.2, 1.6))])
    assert walkable_groups(POINTS, closed, PARAMS) == [[0, 2], [1, 3]]
    # A 0.8 m door: a person fits, but not ROUTE_MARGIN (0.2 m) beside them, as
    # generate_people routes; routing between the rooms fails there too.
    narrow = ROOMS.added(boxes=[Box("door_n", (0.0, 0.55), (0.2, 0.3)),
                                Box("door_s", (0.0, -0.55), (0.2, 0.3))])
    assert walkable_groups(POINTS, narrow, PARAMS) == [[0, 2], [1, 3]]
    with pytest.raises(InputError, match="no walkable path"):
        generate_people(_config(HumanGroupConfig("visitors", 1, points=POINTS)), PARAMS, 0,
                        narrow)
    assert walkable_groups([], ROOMS) == []
    assert walkable_groups(POINTS, Obstacles()) == [[0, 1, 2, 3]]
