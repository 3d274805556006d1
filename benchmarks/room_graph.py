"""Travel times between the rooms of a building drawn as a corridor graph, after the instance
recipe of SMrTa's single-batch benchmark (github.com/victoria-tuck/SMrTa, ``benchmark/single``).

The facts taken from that recipe (docs/allocation.md, "The tight regime"): 65 locations; the
travel time between two rooms is the shortest path over a sparse room graph, in whole seconds,
symmetric; the longest is 112 s, the mean about 48 s, a room's nearest rooms about 10, 12 and
16 s away. The graph here is our own: rooms at random points on a square floor, joined by the
minimum spanning tree of their distances plus each room's three nearest neighbours; the path
lengths scaled so that with ``DOORS`` s for leaving and entering rooms added the longest takes
``LONGEST`` s, rounded up. ``DOORS`` sets the nearest rooms' times to the recipe's.
"""

import numpy as np
from scipy.sparse.csgraph import minimum_spanning_tree, shortest_path
from scipy.spatial.distance import cdist

NUM_ROOMS = 65
LONGEST = 112  # s, the longest travel time between two rooms
FLOOR = (40.0, 40.0)  # m, where the rooms are drawn (only the shape matters: times are scaled)
NEIGHBOURS = 3  # nearest rooms each room has a corridor to, besides the spanning tree
DOORS = 6  # s, out of one room and into another, on top of the corridor path


def room_graph_travel(rng: np.random.Generator) -> np.ndarray:
    """A ``NUM_ROOMS`` x ``NUM_ROOMS`` matrix of travel times (s, integers, zero diagonal):
    ``DOORS`` plus the shortest path over a random corridor graph, the longest ``LONGEST``."""
    points = rng.uniform((0.0, 0.0), FLOOR, size=(NUM_ROOMS, 2))
    distance = cdist(points, points)
    corridor = minimum_spanning_tree(distance).toarray() > 0
    nearest = np.argsort(distance, axis=1)[:, 1:NEIGHBOURS + 1]
    corridor[np.repeat(np.arange(NUM_ROOMS), NEIGHBOURS), nearest.ravel()] = True
    corridor |= corridor.T
    path = shortest_path(np.where(corridor, distance, 0.0), directed=False)
    seconds = DOORS + np.ceil(path * ((LONGEST - DOORS) / path.max()) - 1e-9).astype(int)
    np.fill_diagonal(seconds, 0)
    return seconds
