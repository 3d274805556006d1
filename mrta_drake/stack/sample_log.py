"""Compact in-memory logs of a run's samples: numbers in numpy blocks, not a Python object per
sample, so an hour-long run's memory grows by its numbers alone (``RunRecorder``)."""

from collections.abc import Sequence
from dataclasses import fields
from operator import attrgetter

import numpy as np

from mrta_drake.payloads import ControllerTelemetry

BLOCK_ROWS = 4096  # rows per block of a ``RowLog`` (one block is allocated at a time)


class RowLog(Sequence):
    """Rows of one shape and dtype, appended one at a time and kept in blocks of
    ``BLOCK_ROWS``. Indexing gives a row (a read-only view); ``array()`` all of them as one
    (T, *shape) array (a copy)."""

    def __init__(self, shape=(), dtype=float):
        self._shape = tuple(shape)
        self._dtype = np.dtype(dtype)
        self._blocks: list[np.ndarray] = []
        self._count = 0

    def append(self, row) -> None:
        """Append ``row`` (anything of this log's shape, converted to its dtype)."""
        at = self._count % BLOCK_ROWS
        if at == 0:
            self._blocks.append(np.empty((BLOCK_ROWS,) + self._shape, self._dtype))
        self._blocks[-1][at] = row
        self._count += 1

    def __len__(self) -> int:
        return self._count

    def __getitem__(self, index):
        if isinstance(index, slice):
            return [self[k] for k in range(*index.indices(self._count))]
        k = index + self._count if index < 0 else index
        if not 0 <= k < self._count:
            raise IndexError(index)
        row = self._blocks[k // BLOCK_ROWS][k % BLOCK_ROWS]
        if isinstance(row, np.ndarray):
            row = row.view()
            row.flags.writeable = False
        return row

    def array(self) -> np.ndarray:
        """Every row, (T, *shape)."""
        if not self._blocks:
            return np.zeros((0,) + self._shape, self._dtype)
        return np.concatenate(self._blocks)[:self._count]


_SCALARS = tuple(f.name for f in fields(ControllerTelemetry)
                 if f.name not in ("clusters", "qp_calls"))
_scalars_of = attrgetter(*_SCALARS)  # a telemetry's scalar fields, in ``_SCALARS`` order
_INTEGERS = {"failures": int, "stale_commands": int, "leader_disagreement": bool}


class TelemetryLog(Sequence):
    """``ControllerTelemetry`` per sample, as numbers: the scalar fields in a ``RowLog``, the
    clusters as references to one shared tuple per distinct clustering (they repeat from
    sample to sample), the QP calls as (sample, robots, seconds) rows. Indexing rebuilds a
    sample's ``ControllerTelemetry``; ``column(name)`` gives a scalar field over the
    samples."""

    def __init__(self):
        self._scalars = RowLog((len(_SCALARS),))
        self._clusters: list[tuple] = []
        self._distinct: dict[tuple, tuple] = {}
        self._calls = RowLog((3,))

    def append(self, telemetry: ControllerTelemetry) -> None:
        """Append one sample's telemetry."""
        sample = len(self._scalars)
        self._scalars.append(_scalars_of(telemetry))
        self._clusters.append(self._distinct.setdefault(telemetry.clusters,
                                                        telemetry.clusters))
        for robots, seconds in telemetry.qp_calls:
            self._calls.append((sample, robots, seconds))

    def __len__(self) -> int:
        return len(self._scalars)

    def __getitem__(self, index):
        if isinstance(index, slice):
            return [self[k] for k in range(*index.indices(len(self)))]
        k = index + len(self) if index < 0 else index
        if not 0 <= k < len(self):
            raise IndexError(index)
        values = {name: _INTEGERS.get(name, float)(value)
                  for name, value in zip(_SCALARS, self._scalars[k].tolist(), strict=True)}
        calls = self._calls.array()
        mine = calls[calls[:, 0] == k]
        return ControllerTelemetry(
            clusters=self._clusters[k],
            qp_calls=tuple((int(robots), float(seconds)) for _, robots, seconds in mine),
            **values)

    def __iter__(self):
        calls = self._calls.array()
        ends = np.searchsorted(calls[:, 0], np.arange(len(self)), side="right")
        scalars = self._scalars.array().tolist()
        first = 0
        for k, end in enumerate(ends.tolist()):
            yield ControllerTelemetry(
                clusters=self._clusters[k],
                qp_calls=tuple((int(r), float(s)) for _, r, s in calls[first:end].tolist()),
                **{name: _INTEGERS.get(name, float)(value)
                   for name, value in zip(_SCALARS, scalars[k], strict=True)})
            first = end

    def column(self, name: str) -> np.ndarray:
        """Field ``name`` (a scalar field of ``ControllerTelemetry``) over the samples, (T,)."""
        return self._scalars.array()[:, _SCALARS.index(name)].reshape(len(self))
