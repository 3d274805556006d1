"""mrta-drake's Scenic world model: the hospital floor's free space and movable objects.

Scenic programs placing objects for mrta-drake start with ``model mrta_drake.world.scenic_model``
and are run in 2D mode by ``mrta_drake.world.scenic_objects``, which sets the parameters below from
the scenario (see that module). Units: metres; world frame x east, y north; a Scenic heading
is counterclockwise from north (+y), the direction of an object's ``length``.

Every object must lie inside ``workspace`` (the free space) and must not overlap another
object; a ``HospitalObject`` must also lie in ``beside_lanes`` (off the robots' lanes, queues
and room entries) unless it is given another region, e.g.
``new Bed at (4.7, -18), with regionContainedIn workspace`` to block a corridor. Scenic
resamples until all of this holds.
"""

param free_space = None  # PolygonalRegion: the floor plan's free space (the workspace)
param lanes = None  # PolygonalRegion: where robots drive and wait, widened (None: no lanes)
param beside_lanes = None  # PolygonalRegion: free_space less lanes
param places = {}  # the floor plan's named places, name -> (x, y)

if globalParameters.free_space is None:
    raise RuntimeError("sample this program with mrta_drake.world.scenic_objects (no free space)")

workspace = Workspace(globalParameters.free_space)
free_space = globalParameters.free_space
lanes = globalParameters.lanes
beside_lanes = globalParameters.beside_lanes
places = globalParameters.places


class HospitalObject:
    """Something standing on the floor: a box obstacle of width x length x height, or with
    ``cylinder`` True an upright cylinder of diameter max(width, length). (Scenic's 2D mode
    has boxes only; a cylinder inside its box is clear wherever the box is.)"""

    width: 0.5
    length: 0.5
    height: 1.0
    cylinder: False
    regionContainedIn: beside_lanes
    requireVisible: False  # there is no ego to see it


class Bed(HospitalObject):
    """A hospital bed on wheels."""

    width: 1.0
    length: 2.1
    height: 0.6


class Cart(HospitalObject):
    """A supply or meal cart."""

    width: 0.55
    length: 0.9
    height: 1.1


class Bookshelf(HospitalObject):
    """A shelf unit."""

    width: 0.4
    length: 1.2
    height: 1.8


class Bin(HospitalObject):
    """A round waste bin."""

    width: 0.45
    length: 0.45
    height: 0.8
    cylinder: True
