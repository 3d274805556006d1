"""The run's plots are written as real, non-blank PNG files."""

import pathlib

import numpy as np
import pytest
from PIL import Image

from mrta_drake import load_scenario, simulate
from mrta_drake.payloads import DROPOFF, PICKUP
from mrta_drake.results.plots import plot_clearances, plot_gantt, plot_legs, plot_trajectories
from mrta_drake.world.occupancy_grid import OccupancyGrid

ROOT = pathlib.Path(__file__).resolve().parents[2]
ROUTES = ROOT / "scenarios/hospital_routes_6_robots.yaml"


def _assert_picture(path: pathlib.Path) -> None:
    assert path.is_file() and path.stat().st_size > 5000
    pixels = np.asarray(Image.open(path).convert("RGB"), dtype=float)
    assert pixels.shape[0] > 200 and pixels.shape[1] > 200
    assert pixels.std() > 5.0  # not a blank canvas


def _legs():
    return [
        {"robot": "r0", "key": "t0/pickup", "task": 0, "action": PICKUP, "location": 1,
         "start": 0.0, "end": 20.0, "actual": 20.0, "predicted": 15.0},
        {"robot": "r0", "key": "t0/dropoff", "task": 0, "action": DROPOFF, "location": 2,
         "start": 20.0, "end": 50.0, "actual": 30.0, "predicted": 32.0},
        {"robot": "r1", "key": "r1/visit0", "task": None, "action": "visit", "location": 3,
         "start": 0.0, "end": 40.0, "actual": 40.0, "predicted": None},
    ]


def test_each_plot_draws_synthetic_data(tmp_path):
    times = np.linspace(0.0, 60.0, 601)
    robots = np.stack([np.stack([times / 10, np.sin(times / 10)], axis=1),
                       np.stack([-times / 10, np.cos(times / 10)], axis=1)], axis=1)
    humans = np.full((601, 1, 2), np.nan)
    humans[300:, 0] = [1.0, -1.0]
    occupied = np.zeros((80, 160), bool)
    occupied[[0, -1], :] = occupied[:, [0, -1]] = True
    grid = OccupancyGrid(occupied, 0.1, (-8.0, -4.0))
    deadlock = {"robot": "r1", "start": 30.0, "end": None, "position": (-3.0, 0.0)}
    tasks = [{"id": 0, "robot": "r0", "deadline": 45.0, "deadline_met": False}]

    plot_trajectories(tmp_path / "t.png", grid, ["r0", "r1"], robots, humans,
                      {1: (2.0, 2.0)}, [deadlock])
    plot_gantt(tmp_path / "g.png", ["r0", "r1"], _legs(), tasks, 60.0)
    plot_legs(tmp_path / "l.png", ["r0", "r1"], _legs())
    gap = np.abs(np.sin(times / 5))
    plot_clearances(tmp_path / "c.png", times, gap, gap + 0.3, np.full(601, np.inf),
                    [deadlock])
    for name in ("t", "g", "l", "c"):
        _assert_picture(tmp_path / f"{name}.png")


def test_legs_plot_says_so_when_there_are_no_predictions(tmp_path):
    legs = [leg | {"predicted": None} for leg in _legs()]
    plot_legs(tmp_path / "l.png", ["r0", "r1"], legs)
    _assert_picture(tmp_path / "l.png")


@pytest.mark.parametrize("plots", [True, False])
def test_run_with_out_writes_the_five_plots_unless_switched_off(tmp_path, plots):
    simulate(load_scenario(ROUTES), duration=3.0, out_dir=str(tmp_path), plots=plots)
    names = ("trajectories.png", "gantt.png", "legs.png", "clearances.png", "drift.png")
    if plots:
        for name in names:
            _assert_picture(tmp_path / name)
    else:
        assert not any((tmp_path / name).exists() for name in names)
        assert (tmp_path / "summary.json").is_file()
