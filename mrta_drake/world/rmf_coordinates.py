"""Coordinate systems of Open-RMF building files, and each level's transform to metres.

Three systems, all brought to the world frame (x east, y north, metres):

- ``reference_image``: pixels of a drawing, origin top-left, v down. Points are flipped,
  p = (u, -v), and scaled by s, the mean of distance / pixel length over the reference
  level's measurements: P = s p. Another level is aligned to the reference level by the
  fiducials the two share by name: for each pair i < j of shared fiducials, the bearing
  difference (level minus reference) and the length ratio rho_ij (level over reference);
  theta = -atan2(sum sin, sum cos) of the differences, rho = mean rho_ij, and
  P = (s / rho) R(theta) p + t with t = s (mean f_ref - mean R(theta) f_level / rho). A level
  sharing fewer than two fiducials is taken as drawn in the reference level's frame
  (P = s p), where Open-RMF's generator would leave it in pixels.
- ``cartesian_meters``: already metres, y north; unchanged.
- ``wgs84``: longitude, latitude (degrees) projected to easting, northing in the file's
  ``generate_crs`` with pyproj (extra ``rmf_wgs84``), minus ``suggested_offset_x/y`` so
  the map sits near the origin.
"""

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar

from mrta_drake.errors import InputError

PYPROJ_HINT = "pip install 'mrta-drake[rmf_wgs84]'"


@dataclass(frozen=True)
class CoordinateSystem:
    """How a building file gives positions: ``kind`` (one of ``KINDS``); for ``wgs84``
    the projected ``crs`` (e.g. "EPSG:3414") and the ``offset`` (m) subtracted after
    projecting."""

    kind: str
    crs: str = ""
    offset: tuple[float, float] = (0.0, 0.0)

    KINDS: ClassVar[tuple[str, ...]] = ("reference_image", "cartesian_meters", "wgs84")

    @classmethod
    def of(cls, kind: str, params: Mapping) -> "CoordinateSystem":
        """The system named ``kind`` with the file's top-level ``parameters`` (coerced);
        ValueError saying what is wrong."""
        if kind not in cls.KINDS:
            raise ValueError(f"{kind!r} is not supported (supported: {', '.join(cls.KINDS)})")
        if kind != "wgs84":
            return cls(kind)
        crs = params.get("generate_crs", "")
        if not isinstance(crs, str) or not crs:
            raise ValueError("wgs84 maps need generate_crs, the projected CRS to use "
                             "(e.g. [1, EPSG:3414])")
        offset = []
        for key in ("suggested_offset_x", "suggested_offset_y"):
            value = params.get(key, 0.0)
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ValueError(f"{key} must be a number, got {value!r}")
            offset.append(float(value))
        return cls(kind, crs, (offset[0], offset[1]))


@dataclass(frozen=True)
class Similarity:
    """P = ``scale`` R(``rotation``) (x, -y if ``flip`` else y) + ``offset``: raw units to
    metres; ``rotation`` (rad) is also added to the yaw of what is placed on the level."""

    scale: float
    rotation: float = 0.0
    offset: tuple[float, float] = (0.0, 0.0)
    flip: bool = False

    def point(self, xy) -> tuple[float, float]:
        x, y = float(xy[0]), -float(xy[1]) if self.flip else float(xy[1])
        c, s = math.cos(self.rotation), math.sin(self.rotation)
        return (self.scale * (c * x - s * y) + self.offset[0],
                self.scale * (s * x + c * y) + self.offset[1])


@dataclass(frozen=True, eq=False)
class Projection:
    """Longitude, latitude (degrees) to metres in ``system``'s CRS, minus its offset."""

    system: CoordinateSystem
    transformer: object
    rotation: float = 0.0

    @classmethod
    def of(cls, system: CoordinateSystem, path: str) -> "Projection":
        try:
            from pyproj import Transformer
            from pyproj.exceptions import CRSError
        except ImportError:
            raise InputError(path, "coordinate_system", f"wgs84 maps need pyproj: "
                             f"{PYPROJ_HINT}") from None
        try:
            transformer = Transformer.from_crs("EPSG:4326", system.crs, always_xy=True)
        except CRSError:
            raise InputError(path, "parameters.generate_crs",
                             f"unknown CRS {system.crs!r}") from None
        return cls(system, transformer)

    def point(self, xy) -> tuple[float, float]:
        x, y = self.transformer.transform(float(xy[0]), float(xy[1]))
        return (x - self.system.offset[0], y - self.system.offset[1])


def level_transforms(system: CoordinateSystem, levels: Mapping, reference: str,
                     path: str) -> dict:
    """Per level name, the transform (``Similarity`` or ``Projection``) from the file's raw
    positions to metres. ``levels`` are the building's levels in raw units (with
    ``measurements``, ``fiducials`` and ``point(i)``)."""
    if system.kind == "cartesian_meters":
        return {name: Similarity(1.0) for name in levels}
    if system.kind == "wgs84":
        projection = Projection.of(system, path)
        return {name: projection for name in levels}
    scale = _reference_scale(levels[reference], path)
    base = Similarity(scale, flip=True)
    ref_fiducials = {f.name: _flipped(f.xy) for f in levels[reference].fiducials}
    return {name: base if name == reference else _aligned(level, ref_fiducials, scale)
            for name, level in levels.items()}


def _reference_scale(level, path: str) -> float:
    """Metres per pixel: the mean of distance / pixel length over the level's
    measurements."""
    ratios = []
    for i, measurement in enumerate(level.measurements):
        pixels = math.dist(level.point(measurement.start), level.point(measurement.end))
        if pixels < 1e-9:
            raise InputError(path, f"levels.{level.name}.measurements[{i}]",
                             f"vertices {measurement.start} and {measurement.end} coincide")
        ratios.append(measurement.distance / pixels)
    if not ratios:
        raise InputError(path, f"levels.{level.name}.measurements",
                         "none on the reference level: a reference_image map needs at least "
                         "one measurement to scale pixels to metres")
    return sum(ratios) / len(ratios)


def _aligned(level, ref_fiducials: Mapping, scale: float) -> Similarity:
    """The transform of a non-reference level, aligned by the fiducials it shares with the
    reference level (see the module docstring)."""
    own = {f.name: _flipped(f.xy) for f in level.fiducials}
    shared = [name for name in own if name in ref_fiducials]
    if len(shared) < 2:
        return Similarity(scale, flip=True)
    sin_sum = cos_sum = 0.0
    ratios = []
    for i, a in enumerate(shared):
        for b in shared[i + 1:]:
            la, lb, ra, rb = own[a], own[b], ref_fiducials[a], ref_fiducials[b]
            if min(math.dist(la, lb), math.dist(ra, rb)) < 1e-9:
                continue  # two names on one point give no bearing
            difference = _bearing(la, lb) - _bearing(ra, rb)
            sin_sum += math.sin(difference)
            cos_sum += math.cos(difference)
            ratios.append(math.dist(la, lb) / math.dist(ra, rb))
    if not ratios:
        return Similarity(scale, flip=True)
    theta = -math.atan2(sin_sum, cos_sum)
    rho = sum(ratios) / len(ratios)
    c, s = math.cos(theta), math.sin(theta)
    mean_ref = [sum(ref_fiducials[n][k] for n in shared) / len(shared) for k in (0, 1)]
    mean_own = [sum(own[n][k] for n in shared) / len(shared) for k in (0, 1)]
    turned = (c * mean_own[0] - s * mean_own[1], s * mean_own[0] + c * mean_own[1])
    offset = (scale * (mean_ref[0] - turned[0] / rho), scale * (mean_ref[1] - turned[1] / rho))
    return Similarity(scale / rho, theta, offset, flip=True)


def _flipped(xy) -> tuple[float, float]:
    return (float(xy[0]), -float(xy[1]))


def _bearing(a, b) -> float:
    return math.atan2(b[1] - a[1], b[0] - a[0])
