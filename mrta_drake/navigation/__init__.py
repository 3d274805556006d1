"""Navigation: one-way roadways, the costmap and grid planner, and the blocks that use them
(``PlannerService``, ``WaypointGenerator``, ``RoomQueues``)."""
