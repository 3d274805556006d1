"""A sweep on a local Ray instance gives the same results table as on local processes (less the
wall-clock columns), though Ray runs both runs one after the other in one worker process
while the process pool gives each run a fresh one: the SMT allocator searches in every
allocation of these runs, so what z3 did in the first run must not change the second."""

import csv
import pathlib

import pytest
import ray

from mrta_drake.tools.cli import main

HOSPITAL = pathlib.Path(__file__).resolve().parents[2] / "scenarios/hospital_6_robots.yaml"
WALL_CLOCK_COLUMNS = ("real_time_factor", "wall_time")


def table_without_wall_clock(out: pathlib.Path) -> list[dict]:
    with open(out / "results.csv", newline="") as f:
        return [{key: value for key, value in row.items() if key not in WALL_CLOCK_COLUMNS}
                for row in csv.DictReader(f)]


@pytest.fixture
def ray_address():
    """A local Ray instance with one CPU, so that both runs share one worker process."""
    context = ray.init(num_cpus=1, include_dashboard=False, log_to_driver=False)
    yield context.address_info["address"]
    ray.shutdown()


def test_ray_sweep_gives_the_process_pool_table(tmp_path, ray_address):
    spec = tmp_path / "spec.yaml"
    spec.write_text(f"""
scenario: {HOSPITAL}
grid:
  seed: [0, 1]
fixed:
  duration: 40.0
  tasks.generate: {{rate: 0.15, batch_size: [1, 3], slack: [1.2, 3.0]}}
  blocks.allocator.params: {{greedy_start: false}}
""")
    pool, on_ray = tmp_path / "pool", tmp_path / "ray"
    assert main(["sweep", str(spec), "--out", str(pool), "--workers", "2", "--quiet"]) == 0
    assert main(["sweep", str(spec), "--out", str(on_ray), "--ray", ray_address,
                 "--quiet"]) == 0
    rows = table_without_wall_clock(pool)
    assert [row["status"] for row in rows] == ["ok", "ok"]
    assert all(int(row["tasks_assigned"]) >= 3 for row in rows)
    assert table_without_wall_clock(on_ray) == rows
