"""People: who walks where (``people``), how they walk (``social_force_params``), the
social-force block that moves them, and the driver of their bodies in the physics backend."""
