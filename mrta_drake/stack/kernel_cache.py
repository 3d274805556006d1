"""Whether numba's on-disk cache already holds the stack's compiled kernels.

The first run after installing (or with an empty ``NUMBA_CACHE_DIR``, or after a kernel's source
changed) compiles the kernels, which takes tens of seconds once; later runs load them from the
cache in well under a second. ``cold_kernel_seconds`` looks at the cache index of each entry
kernel of the default stack (one small file read each, nothing compiled) and estimates how long
compiling the missing ones will take, so that the CLI can say so before the run starts.
"""

import importlib
import pickle

# Entry kernels of the default stack (module, function) and the CPU s of compiling each with
# everything it calls: the quickstart's ~31 s of compiling split as numba's compile events
# shared it out, on the benchmark host (docs/benchmarks.md).
ENTRY_KERNELS = {
    ("mrta_drake.control.tick_kernel", "plan_tick"): 6.7,
    ("mrta_drake.control.tick_qps", "_group_rows"): 6.1,
    ("mrta_drake.control.qp_solver", "_prepare"): 2.0,
    ("mrta_drake.control.wall_rays", "_wall_hits"): 0.8,
    ("mrta_drake.navigation.grid_planner", "_path_points"): 3.0,
    ("mrta_drake.navigation.grid_planner", "_search"): 1.2,
    ("mrta_drake.robots.unicycle_robots", "_step"): 0.3,
    ("mrta_drake.world.obstacles", "closest_points_of"): 1.5,
    ("mrta_drake.humans.social_force_humans", "_step_people"): 9.9,
}


def is_cached(dispatcher) -> bool:
    """Whether numba's cache holds a compiled version of ``dispatcher`` (an ``njit(cache=True)``
    function) for its current source and numba version. Reads numba's cache index through its
    internal ``_cache`` attribute; a numba without it counts as cached (nothing announced)."""
    cache_file = getattr(getattr(dispatcher, "_cache", None), "_cache_file", None)
    if cache_file is None:
        return True
    try:
        return bool(cache_file._load_index())
    except (OSError, EOFError, ValueError, pickle.UnpicklingError):  # numba then recompiles
        return False


def cold_kernel_seconds() -> float:
    """Estimated CPU seconds of compiling the entry kernels missing from the cache (0.0 when
    the cache is warm)."""
    total = 0.0
    for (module, name), seconds in ENTRY_KERNELS.items():
        if not is_cached(getattr(importlib.import_module(module), name)):
            total += seconds
    return total
