"""Clusters as robots see them over a network."""

import numpy as np

from mrta_drake.control.cluster_views import cluster_of, cut_off, group_of, views_disagree
from mrta_drake.payloads import Disturbances, Outage, frozen_array


def test_a_robots_cluster_is_the_one_that_holds_it():
    assert cluster_of(((2, 0), (1,)), 0) == (2, 0)
    assert group_of(((2, 0), (1,)), 1) == 1


def test_views_agree_when_every_member_sees_the_same_leader_and_members():
    assert not views_disagree([(1, 0), (1, 0), (2,)])
    assert not views_disagree([(0,), (1,)])


def test_views_disagree_on_another_leader_or_other_members():
    assert views_disagree([(0, 1), (1, 0)])  # each sees itself leading
    assert views_disagree([(0, 1), (0, 1, 2), (0, 1, 2)])  # robot 2 unseen by 0 and 1


def test_cut_off_plans_a_robot_alone_against_its_view():
    view = np.arange(8.0).reshape(2, 4)
    d = cut_off(Disturbances(), 1, 3.0, view)
    assert d.cut_off == (1,)
    states = np.zeros((2, 4))
    np.testing.assert_array_equal(d.seen_by(states, 1)[0], view[0])  # the others as heard
    np.testing.assert_array_equal(d.seen_by(states, 1)[1], states[1])  # itself as it is


def test_a_robot_already_cut_off_keeps_its_outage():
    outage = Outage(0, 1.0, 5.0, frozen_array(np.zeros((2, 4))))
    d = Disturbances(outages=(outage,))
    assert cut_off(d, 0, 3.0, np.ones((2, 4))) is d
