"""The learned travel-time model: estimators, the fleet-wide ratio, margins."""

import numpy as np
import pytest

from mrta_drake.allocation.feedback_params import FeedbackParams
from mrta_drake.allocation.travel_time_model import (
    Estimator,
    LearnedTravelTimes,
    TravelTimeModel,
)
from mrta_drake.errors import InputError

PRIOR = np.array([[0, 10, 20], [10, 0, 10], [20, 10, 0]])


@pytest.mark.parametrize("estimator, expected", [
    (Estimator("mean"), 7 / 3),
    (Estimator("recent", recent_weight=0.5), 2.5),
    (Estimator("quantile", quantile=1.0), 3.0),
    (Estimator("quantile", quantile=0.5, window=2), 2.0),
])
def test_each_estimator_summarises_the_ratios(estimator, expected):
    summary = ()
    for ratio in (3.0, 1.0, 3.0):
        summary = estimator.add(summary, ratio)
    assert estimator.count(summary) == (2 if estimator.window == 2 else 3)
    assert estimator.value(summary) == pytest.approx(expected)


def test_nothing_learned_plans_with_the_matrix_plus_the_margin():
    model = TravelTimeModel(PRIOR, margin=2.5)
    planned = model.matrix(LearnedTravelTimes())
    assert planned.tolist() == [[0, 13, 23], [13, 0, 13], [23, 13, 0]]
    assert np.array_equal(TravelTimeModel(PRIOR).matrix(LearnedTravelTimes()), PRIOR)


def test_a_driven_pair_teaches_the_others_through_the_fleet_ratio():
    model = TravelTimeModel(PRIOR, prior_samples=1.0)
    learned = model.observe(LearnedTravelTimes(), 0, 1, 15.0)  # ratio 1.5
    learned = model.observe(learned, 0, 1, 15.0)
    learned = model.observe(learned, 1, 2, 30.0)  # ratio 3
    assert learned.legs == 3
    planned = model.matrix(learned)
    # fleet: mean 2; pair 0 -> 1: (2 x 1.5 + 1 x 2) / 3; pair 1 -> 2: (3 + 2) / 2
    assert planned[0, 1] == np.ceil(10 * 5 / 3)
    assert planned[1, 2] == 25
    assert planned[2, 0] == 40 and planned[1, 0] == 20
    assert np.all(np.diag(planned) == 0)


def test_rounding_to_the_nearest_second_is_unbiased():
    # fleet ratio 1.33: 13.3 s, 26.7 s; up gives 14 and 27, nearest 13 and 27
    for rounding, planned in (("up", [14, 27]), ("nearest", [13, 27])):
        model = TravelTimeModel(PRIOR, prior_samples=1.0, rounding=rounding)
        learned = model.observe(LearnedTravelTimes(), 0, 1, 40 / 3)
        assert [model.matrix(learned)[1, 2], model.matrix(learned)[0, 2]] == planned


def test_legs_in_place_teach_nothing():
    model = TravelTimeModel(PRIOR)
    nothing = LearnedTravelTimes()
    assert model.observe(nothing, 1, 1, 8.0) is nothing


@pytest.mark.parametrize("field, value, message", [
    ("travel_time_estimator", "median", "unknown estimator 'median'"),
    ("recent_weight", 0.0, "recent_weight: must be in"),
    ("quantile", 1.5, "quantile: must be in"),
    ("quantile_window", 0, "quantile_window: must be >= 1"),
    ("drift_margin", -1.0, "drift_margin: must be >= 0"),
    ("travel_time_rounding", "down", "travel_time_rounding: unknown rounding 'down'"),
    ("write_off_lateness", -1.0, "write_off_lateness: must be >= 0"),
])
def test_bad_feedback_settings_are_input_errors(field, value, message):
    with pytest.raises(InputError, match=message):
        FeedbackParams(**{field: value})
