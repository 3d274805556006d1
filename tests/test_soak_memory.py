"""The soak's memory growth (benchmarks/soak.py): minute 10 to the last sample of the
simulation, not the summary the run writes after it."""

import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "benchmarks"))

import soak  # noqa: E402


def test_growth_leaves_out_the_samples_taken_after_the_simulation():
    samples = [(300.0, 90.0), (600.0, 100.0), (2000.0, 104.0), (3599.0, 105.0),
               (3600.0, 140.0)]  # the last: writing the summary
    assert soak._growth(samples, 600.0, 3600.0) == 5.0


def test_growth_is_none_without_samples_in_the_window():
    assert soak._growth([(100.0, 90.0)], 600.0, 3600.0) is None
