"""The stack: the block registry, the diagram wiring, ``simulate``, and the blocks that watch a run
(recorder, Meshcat overlay, disturbance schedule, contact recorder)."""
