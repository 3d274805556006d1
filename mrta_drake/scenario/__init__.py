"""Scenario files: the typed schema, loading and validation, task streams, travel-time files,
disturbance checks, and the generated field reference."""
