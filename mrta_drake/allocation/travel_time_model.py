"""Travel times learned from a run: an online estimate per ordered pair of locations.

Every leg a robot completes gives one sample: the seconds from setting off for a stop to
completing it, less the service time (so queue waits at the stop count as travel). A sample
is kept as a *ratio* to the scenario's matrix (measured or estimated), so what one pair
teaches (people in the corridors, queues, other robots) carries over to the pairs not yet
driven:

- a fleet-wide ratio summarises every sample;
- a pair's ratio summarises its own samples, shrunk towards the fleet-wide one with the
  weight of ``prior_samples`` samples;
- the planned time of a pair is its matrix time times its ratio (the fleet-wide one until
  it is driven), plus ``margin`` seconds, rounded to whole seconds: up (``"up"``: a leg is
  never planned shorter than estimated, so plans lean late by half a second a leg on
  average) or to the nearest (``"nearest"``: unbiased).

How a sequence of ratios is summarised is the swappable ``Estimator``: the mean, a
recent-weighted mean, or a chosen quantile of the recent samples. Everything here is an
immutable value, so it can live in a Drake block's abstract state.
"""

from dataclasses import dataclass

import numpy as np

from mrta_drake.errors import InputError

ESTIMATORS = ("mean", "recent", "quantile")
ROUNDINGS = ("up", "nearest")


@dataclass(frozen=True)
class Estimator:
    """How ratio samples are summarised: ``kind`` ``"mean"`` (all samples alike),
    ``"recent"`` (exponentially weighted, each new sample with weight ``recent_weight``) or
    ``"quantile"`` (the ``quantile`` of the last ``window`` samples). A summary is a small
    tuple: ``(count, value)`` for the means, the samples themselves for the quantile."""

    kind: str = "mean"
    recent_weight: float = 0.3
    quantile: float = 0.8
    window: int = 20

    def __post_init__(self):
        if self.kind not in ESTIMATORS:
            raise InputError(None, "travel_time_estimator", f"unknown estimator "
                             f"{self.kind!r} (one of {', '.join(ESTIMATORS)})")
        if not 0 < self.recent_weight <= 1:
            raise InputError(None, "recent_weight", f"must be in (0, 1], got "
                             f"{self.recent_weight}")
        if not 0 <= self.quantile <= 1:
            raise InputError(None, "quantile", f"must be in [0, 1], got {self.quantile}")
        if self.window < 1:
            raise InputError(None, "quantile_window", f"must be >= 1, got {self.window}")

    def add(self, summary: tuple, sample: float) -> tuple:
        """``summary`` with one more ``sample``."""
        if self.kind == "quantile":
            return (*summary, sample)[-self.window:]
        count, value = summary or (0, 0.0)
        weight = 1.0 / (count + 1) if self.kind == "mean" else self.recent_weight
        return count + 1, sample if count == 0 else value + weight * (sample - value)

    def count(self, summary: tuple) -> int:
        return len(summary) if self.kind == "quantile" else (summary[0] if summary else 0)

    def value(self, summary: tuple) -> float:
        """The summarised ratio (1.0 without samples)."""
        if not summary:
            return 1.0
        if self.kind == "quantile":
            return float(np.quantile(summary, self.quantile))
        return summary[1]


@dataclass(frozen=True)
class LearnedTravelTimes:
    """What a run has taught about travel times so far: the fleet-wide ratio summary and
    one per driven ordered pair ``((origin, destination), summary)``, sorted, and how many
    legs were learned from."""

    fleet: tuple = ()
    pairs: tuple[tuple[tuple[int, int], tuple], ...] = ()
    legs: int = 0

    def __deepcopy__(self, memo):
        return self  # immutable: Drake's copies of the state can share it


@dataclass(frozen=True)
class TravelTimeModel:
    """Plans with ``prior`` ((L, L) matrix, s) corrected by what was learned; see the
    module docstring. ``margin`` (s) is added to every leg planned; ``rounding`` (one of
    ``ROUNDINGS``) says how a leg's time is rounded to whole seconds."""

    prior: np.ndarray
    estimator: Estimator = Estimator()
    prior_samples: float = 2.0
    margin: float = 0.0
    rounding: str = "nearest"

    def __post_init__(self):
        if self.rounding not in ROUNDINGS:
            raise InputError(None, "travel_time_rounding", f"unknown rounding "
                             f"{self.rounding!r} (one of {', '.join(ROUNDINGS)})")

    def observe(self, learned: LearnedTravelTimes, origin: int, destination: int,
                seconds: float) -> LearnedTravelTimes:
        """``learned`` with one leg from ``origin`` to ``destination`` that took ``seconds``
        (s, driving and queueing); legs staying in place or with no matrix time teach
        nothing."""
        expected = float(self.prior[origin, destination])
        if origin == destination or expected <= 0:
            return learned
        ratio = max(seconds, 0.0) / expected
        pairs = dict(learned.pairs)
        key = (origin, destination)
        pairs[key] = self.estimator.add(pairs.get(key, ()), ratio)
        return LearnedTravelTimes(self.estimator.add(learned.fleet, ratio),
                                  tuple(sorted(pairs.items())), learned.legs + 1)

    def matrix(self, learned: LearnedTravelTimes) -> np.ndarray:
        """The (L, L) whole-second travel times to plan with (s)."""
        estimator = self.estimator
        fleet = estimator.value(learned.fleet)
        ratios = np.full(self.prior.shape, fleet)
        for (origin, destination), summary in learned.pairs:
            n = estimator.count(summary)
            ratios[origin, destination] = ((n * estimator.value(summary)
                                            + self.prior_samples * fleet)
                                           / (n + self.prior_samples))
        planned = np.maximum(self.prior * ratios + self.margin, 0.0)
        np.fill_diagonal(planned, 0.0)
        if self.rounding == "nearest":
            return np.floor(planned + 0.5)
        return np.ceil(planned - 1e-9)

