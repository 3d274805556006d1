"""Wheelchairs parked around the lobby's waiting area and carts left against the west
corridor's outer wall, off the robots' lanes (tutorials/05_humans_and_scenic_objects.py).

Geometry of models/hospital/floor_plan.yaml: the waiting area is around (0, 10), north of the
lobby; the west corridor runs between x -6.4 and -3.6 from the lobby (y 0) south to y -26.
Every object must lie off the lanes (``beside_lanes``, the default region of a
``HospitalObject``) and overlap nothing: Scenic redraws the scene until that holds.
"""

model mrta_drake.world.scenic_model


class Wheelchair(HospitalObject):
    """A wheelchair, as its footprint."""

    width: 0.65
    length: 1.0
    height: 0.9


param wheelchairs = 3
param carts = 2

for _ in range(globalParameters.wheelchairs):
    new Wheelchair at (Range(-7.0, 7.0), Range(8.0, 14.0)), facing Range(0, 360) deg

for _ in range(globalParameters.carts):
    new Cart at (-6.1, Range(-25.0, -1.0)), facing Range(-3, 3) deg
