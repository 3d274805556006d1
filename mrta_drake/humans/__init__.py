"""People: who walks where (``people``), the social-force block that moves them, and the driver
of their bodies in the physics backend."""
