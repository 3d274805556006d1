"""Command-line tools: ``mrta-sim`` (``cli``), sweeps and travel-time collection."""
