"""Carts, shelves, bins and beds left in the hospital's corridors and lobby, off the lanes.

Sampled by mrta-drake for a scenario's seed (``world.scenic`` in the scenario); the counts are
parameters a scenario may override (``world.scenic_params: {carts: 5}``). Geometry of
models/hospital/floor_plan.yaml: the east corridor runs between x 3.6 and 6.4, the west
corridor between x -6.4 and -3.6, both from the lobby (y 0) south to y -26. Scenic redraws
the whole scene when any object is misplaced, so raise the counts gradually: about twice
the defaults runs out of tries.
"""

model mrta_drake.world.scenic_model

param carts = 3  # parked against the east corridor's outer wall
param shelves = 2  # against the spine blocks' walls in the west corridor
param bins = 2  # against the outer wall of either corridor
param beds = 1  # waiting in the north of the lobby

for _ in range(globalParameters.carts):
    new Cart at (6.1, Uniform(Range(-8.0, -0.5), Range(-18.9, -13.3))), facing Range(-3, 3) deg

for _ in range(globalParameters.shelves):
    new Bookshelf at (-3.83, Uniform(Range(-6.3, -0.7), Range(-12.4, -10.6), Range(-22.4, -16.7)))

for _ in range(globalParameters.bins):
    new Bin at (Uniform(-6.1, 6.1), Range(-25.0, 3.5))

for _ in range(globalParameters.beds):
    new Bed at (Range(-8.0, 8.0), Range(9.5, 13.0)), facing Range(80, 100) deg
