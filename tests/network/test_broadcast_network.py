"""The broadcast network: latency, jitter, loss, commands to followers, determinism."""

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator

from mrta_drake.network.broadcast_network import BroadcastNetwork
from mrta_drake.payloads import CommandMessages, frozen_array
from mrta_drake.scenario.schema import CommunicationConfig

STARTS = np.array([[0.0, 0.0, 0.0, 0.0], [5.0, 0.0, np.pi, 0.0], [0.0, 5.0, 0.0, 0.0]])
RATE = 20.0  # Hz


def _views_at(time: float, config: CommunicationConfig, seed: int = 0, commands=None):
    """The network's views at ``time`` with the robots standing still at ``STARTS``
    (moved 1 m east, so a state received is told from the start), ``commands`` fixed."""
    network = BroadcastNetwork(["a", "b", "c"], STARTS, config, seed, rate_hz=RATE)
    context = network.CreateDefaultContext()
    moved = STARTS + [1.0, 0.0, 0.0, 0.0]
    network.GetInputPort("robot_state").FixValue(context, moved.ravel())
    if commands is not None:
        network.GetInputPort("leader_commands").FixValue(context, commands)
    Simulator(network, context).AdvanceTo(time)
    return network.GetOutputPort("views").Eval(context)


def test_a_state_arrives_the_latency_after_it_was_sent():
    views = _views_at(1.01, CommunicationConfig(latency=0.2))
    off_diagonal = ~np.eye(3, dtype=bool)
    np.testing.assert_allclose(views.sent_at[off_diagonal], 0.8)
    np.testing.assert_allclose(views.states[0, 1], STARTS[1] + [1.0, 0.0, 0.0, 0.0])


def test_before_the_first_message_a_robot_knows_the_others_at_their_starts():
    views = _views_at(0.1, CommunicationConfig(latency=0.2))
    np.testing.assert_allclose(views.states[0, 1], STARTS[1])
    assert views.sent_at[0, 1] == 0.0


def test_lost_messages_leave_older_states_and_the_same_seed_loses_the_same_ones():
    lossy = CommunicationConfig(latency=0.1, loss=0.5)
    views = _views_at(2.0, lossy, seed=3)
    ages = views.time - views.sent_at[~np.eye(3, dtype=bool)]
    assert ages.min() == pytest.approx(0.1) and ages.max() > 0.1
    np.testing.assert_array_equal(views.sent_at, _views_at(2.0, lossy, seed=3).sent_at)
    assert not np.array_equal(views.sent_at, _views_at(2.0, lossy, seed=4).sent_at)


def test_with_jitter_a_link_keeps_its_newest_state():
    config = CommunicationConfig(latency=0.1, jitter=0.3)
    times = np.arange(0.51, 2.0, 0.05)
    seen = [_views_at(t, config, seed=1) for t in times]
    assert all(np.all(later.sent_at >= earlier.sent_at)
               for earlier, later in zip(seen, seen[1:], strict=False))
    assert max((v.time - v.sent_at).max() for v in seen) <= 0.1 + 0.3 + 1 / RATE + 1e-9


def test_a_leaders_command_reaches_only_its_follower_after_the_latency():
    commands = CommandMessages(0.5, (-1, 0, -1), frozen_array([[0, 0], [0.3, -0.1], [0, 0]]))
    config = CommunicationConfig(latency=0.2)
    early, views = _views_at(0.66, config, commands=commands), _views_at(0.71, config,
                                                                          commands=commands)
    assert early.command_from == (-1, -1, -1)
    assert views.command_from == (-1, 0, -1)
    np.testing.assert_allclose(views.commands[1], [0.3, -0.1])
    assert views.command_sent_at[1] == 0.5
    assert views.fresh_command(1, 0) and not views.fresh_command(1, 2)
    assert views.max_age == pytest.approx(0.2 + 0.1)


def test_a_command_older_than_the_max_age_is_stale():
    commands = CommandMessages(0.5, (-1, 0, -1), frozen_array(np.zeros((3, 2))))
    views = _views_at(0.86, CommunicationConfig(latency=0.2, stale_after=0.1),
                      commands=commands)
    assert views.command_from[1] == 0 and not views.fresh_command(1, 0)
