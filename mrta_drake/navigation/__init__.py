"""Navigation: one-way roadways, the costmap and grid planner, and the blocks that use them
(``PlannerService``, ``FleetWaypoints`` and its ``WaypointPolicy`` per robot,
``RoomQueues``)."""
