"""The recorder's compact sample logs keep every sample exactly, in blocks of numbers."""

import numpy as np

from mrta_drake.payloads import ControllerTelemetry
from mrta_drake.stack import sample_log
from mrta_drake.stack.sample_log import RowLog, TelemetryLog


def test_a_row_log_across_blocks_gives_back_every_row(monkeypatch):
    monkeypatch.setattr(sample_log, "BLOCK_ROWS", 3)
    log = RowLog((2,), np.int8)
    rows = [[k, -k] for k in range(7)]
    for row in rows:
        log.append(row)
    assert len(log) == 7 and log.array().tolist() == rows
    assert log[-1].tolist() == [6, -6] and [r.tolist() for r in log[2:4]] == rows[2:4]
    assert not log[0].flags.writeable
    assert RowLog((2,)).array().shape == (0, 2)


def test_a_telemetry_log_rebuilds_each_sample_and_shares_repeated_clusters(monkeypatch):
    monkeypatch.setattr(sample_log, "BLOCK_ROWS", 2)
    ticks = [ControllerTelemetry(time=0.1 * k, min_barrier_wall=np.inf, max_slack=0.5 * k,
                                 clusters=((0, 1), (2,)) if k % 2 else (),
                                 qp_calls=((2, 0.001 * k),) * (k % 3), failures=k,
                                 leader_disagreement=k == 3, stale_commands=k // 2)
             for k in range(5)]
    log = TelemetryLog()
    for tick in ticks:
        log.append(tick)
    assert list(log) == ticks and [log[k] for k in range(5)] == ticks and log[-2] == ticks[3]
    assert log.column("max_slack").tolist() == [0.0, 0.5, 1.0, 1.5, 2.0]
    assert log[1].clusters is log[3].clusters
