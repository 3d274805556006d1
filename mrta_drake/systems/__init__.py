"""The blocks of the mrta-drake diagram, one LeafSystem per module."""
