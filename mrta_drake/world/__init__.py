"""The world: floor plans, ROS maps, Scenic-placed objects, obstacles and their occupancy grid,
and the building, robots and people in a ``MultibodyPlant`` + ``SceneGraph``."""
