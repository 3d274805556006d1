"""Robot models: the kinematic unicycle block and the physics block that steps the plant."""
